"""Approximate multiple scattering (``render: {scattering: approximate}``), and its measured error.

``method: octaves`` (Wrenninge, "Oz: the great and volumetric", SIGGRAPH 2013 talk; also in "Production
Volume Rendering", SIGGRAPH 2017 course): the single-scattering quadrature is kept as it is, and at every
node each light's E_l T_l p(theta) becomes sum_i c^i E_l T_l^(a^i) p(theta; g b^i): octave i sees the light
through a^i times the optical depth (light that scattered many times has crossed less material on its
way), with b^i times the phase function's asymmetry (many scatterings forget the direction) and weight
c^i. No extra shadow rays: T_l^(a^i) comes from the exact T_l the node computes anyway. The environment
(the background, a uniform colour or a sky) lights the media as a uniform ambient radiance equal to its
solid-angle mean, which is exact for a conservative medium (albedo 1) in a uniform environment (the white
furnace) and ignores the cloud's shadowing of the sky otherwise. Order 1 of the lights is not exact in
this mode (the first octave is single scattering; the others add to it).

The approximation's error is measured, not assumed: ``approximation_error`` renders a sample of cloud
pixels both ways, the approximate mode and the unbiased estimator (single scattering + Monte Carlo
paths of renderer.multiple), and estimates the image's relative RMSE against the unbiased image,
relative to the scattered light (docs/approximate.md says how good that estimate is).
"""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace

import numba
import numpy as np

from ..errors import SceneError
from ..kernels.lighting import N_COUNTS
from ..kernels.multiple import render_paths
from ..kernels.single import render_pixels
from ..scene.limits import MAX_SHARED_TAILS
from .pack import background_along, pixel_directions, single_octave
from .fluence import fluence_cache
from .shared import CACHE_SEED, SPLIT, deep_share, plan_tails, shared_light, tail_tracks
from .tracking import path_settings, paths_grid, paths_volumes

#: the approximation's error estimate: cloud pixels sampled, unbiased paths per sampled pixel (at first)
ERROR_PIXELS = 128
#: the shared method's: its error sits in fewer pixels (a smoothed peak, a noisy block), and the estimate over 128
#: of them spread 2x between seeds on the bank at 512 wide
SHARED_ERROR_PIXELS = 512
ERROR_PATHS = 64
#: the paths are quadrupled, up to MAX_ERROR_PATHS, while the estimate's standard error is above this share of
#: it (or it is not above the paths' own noise): a small error needs quieter unbiased pixels to be seen
ERROR_PRECISION = 0.35
MAX_ERROR_PATHS = 1024


def check_approximate(scene):
    """Refuse what the approximate mode cannot take (one line naming the file and the key)."""
    if scene.render.method in ("grid", "shared") and scene.surfaces:
        raise SceneError(scene.path, "render.method", f"{scene.render.method} does not take opaque surfaces (its "
                                                      "light paths do not meet them); use method: octaves or "
                                                      "scattering: multiple")
    if scene.ambient is not None:
        raise SceneError(scene.path, "ambient", "not allowed with render.scattering: approximate (the background "
                                                "lights the medium as its own ambient term; ambient would count "
                                                "it twice)")


def approximate_light(scene, packed, settings, image, window, seed, progress=False, single_mean=0.0):
    """What the approximate method adds to the deterministic image ``image`` (the tile ``window``, H x W x 4) after
    it is rendered: (light, stderr, plan), light and stderr H x W x 3, with ``method: shared`` (renderer.shared:
    stderr is the tails' noise, not the sharing's bias; plan a shared.TailPlan where the tails were planned
    against ``single_mean``, the frame pilot's mean single-scattered radiance, else None), else None (the
    octaves and the grid are inside the quadrature)."""
    if scene.render.method != "shared":
        return None
    shared = settings.shared
    # the cache of the deep orders, one for the pilot and every sample ray (the same on every tile); the preset's is
    # left out where the orders beyond it carry too little of the light to pay for its photons
    tracks = tail_tracks(scene, packed)  # every lattice's grid and light volumes, built once
    order, share = shared.cache_order, None
    if order > 0 and not shared.cache_chosen:
        share = deep_share(scene, packed, seed, order, tracks)
        order = order if share >= shared.cache_min_share else 0
    cache = fluence_cache(scene, packed.records, seed ^ CACHE_SEED, order, shared.cache_cells, shared.cache_photons)
    plan = None
    tails = shared.tails
    if tails is None:
        plan = plan_tails(scene, packed, shared.stride, shared.target, single_mean, seed, MAX_SHARED_TAILS, cache,
                          tracks)
        plan = replace(plan, cache_order=int(cache.order), deep_share=share)
        tails = plan.tails
    light, stderr, _ = shared_light(scene, packed, window, image[..., 3], seed, shared.stride, tails, SPLIT,
                                    progress=progress, cache=cache, tracks=tracks)
    return light, stderr, plan


@dataclass(frozen=True)
class ApproximationError:
    """The approximate image's estimated relative RMSE against the unbiased image (``rel_rmse``), relative
    to the mean scattered radiance; ``stderr`` the standard error of that estimate (from the sampling of
    pixels and the paths' noise); ``pixels`` sampled cloud pixels of ``cloud_pixels``, ``paths`` per pixel."""
    rel_rmse: float
    stderr: float
    pixels: int
    cloud_pixels: int
    paths: int

    @property
    def resolved(self) -> bool:
        """Whether the estimate rose above its own noise: positive, its standard error within ERROR_PRECISION of
        it. An estimate that did not is no measure of the error, only a bound on it (``bound``)."""
        return 0.0 < self.rel_rmse < np.inf and self.stderr <= ERROR_PRECISION * self.rel_rmse

    @property
    def bound(self) -> float:
        """The estimate plus two standard errors: an upper bound on the error (one-sided, about 97.5 %), resolved or
        not (inf: nothing is known)."""
        return self.rel_rmse + 2.0 * self.stderr


def sample_pixels(alpha, n, seed):
    """Up to n cloud pixels (alpha > 0), drawn without replacement by a generator keyed by seed, sorted."""
    flat = np.flatnonzero(alpha.ravel() > 0.0)
    if flat.size <= n:
        return flat
    return np.sort(np.random.default_rng([seed, 0xA55]).choice(flat, n, replace=False))


def approximation_error(scene, image, packed, window, seed=0, pixels=None, paths=ERROR_PATHS):
    """An ApproximationError of the approximate ``image`` (the tile ``window`` of the frame, H x W x 4)
    rendered from ``packed``: on a sample of its cloud pixels (``pixels``; None: ERROR_PIXELS, SHARED_ERROR_PIXELS
    with the shared method) the unbiased estimate U (single scattering
    with exact order 1, plus ``paths`` Monte Carlo paths of the orders above) against A, the image's pixel.
    The paths are quadrupled while the estimate is not resolved (ERROR_PRECISION) and they stay within
    MAX_ERROR_PATHS; the exact part, the paths' grid and maps are computed once.

    The image's squared error is the mean over all pixels of (A - U)^2; background pixels have none, so
    it is the cloud fraction times the mean over cloud pixels, estimated on the sample, less the paths'
    own variance (their squared standard error, which inflates (A - U)^2 on average by exactly that).
    Divided by the mean scattered radiance: U less the background seen through the media."""
    if pixels is None:
        pixels = SHARED_ERROR_PIXELS if scene.render.method == "shared" else ERROR_PIXELS
    (r_lo, r_hi), (c_lo, c_hi) = window
    tile = image[..., 3]
    chosen = sample_pixels(tile, pixels, seed)
    if chosen.size == 0:
        return ApproximationError(0.0, 0.0, 0, 0, paths)
    cloud = int(np.count_nonzero(tile > 0.0))
    tw = c_hi - c_lo
    rows, cols = r_lo + chosen // tw, c_lo + chosen % tw
    camera, records, quad = packed.camera, packed.records, packed.quadrature
    single = records._replace(octaves=single_octave(), ambient=np.zeros(3), radiance=None, view_media=records.media)
    settings = path_settings(scene, paths, scene.render.max_order)
    grid = paths_grid(scene, records.media, settings)  # neither depends on the number of paths
    volumes = paths_volumes(scene, packed, settings)
    h, w = scene.image.height, scene.image.width
    exact = np.zeros((h, w, 4))
    nearest = np.full((h, w), np.inf)
    counts = np.zeros((h, w, N_COUNTS))
    mean = np.zeros((h, w, 3))
    stderr = np.zeros((h, w, 3))

    def each_pixel(job):  # each pixel writes its own entries; every random number is keyed by the pixel
        with ThreadPoolExecutor(numba.get_num_threads()) as pool:
            list(pool.map(lambda k: job(np.int64(rows[k]), np.int64(cols[k])), range(chosen.size)))

    each_pixel(lambda i, j: render_pixels(camera, single, quad, i, j, j + 1, exact, nearest, counts))
    approx = image[rows - r_lo, cols - c_lo, :3]
    background = background_along(records.background, pixel_directions(camera, rows, cols))
    if packed.ground is not None:  # the clouds' shadow on the ground (renderer.ground), over the frame's tile
        background = background - packed.ground[rows - r_lo, cols - c_lo]
    frac = cloud / tile.size
    while True:
        settings = settings._replace(paths=int(paths))
        each_pixel(lambda i, j: render_paths(camera, single, quad, settings, grid, volumes, i, j, j + 1, mean, stderr))
        est = _estimate(exact[rows, cols], mean[rows, cols], stderr[rows, cols], approx, background, frac,
                        int(chosen.size), cloud, paths)
        if est.resolved or paths * 4 > MAX_ERROR_PATHS:
            return est
        paths *= 4


def _estimate(exact, mean, stderr, approx, background, frac, n, cloud, paths):
    """The ApproximationError from the sampled pixels' exact part (n, 4), paths' mean and standard error
    (n, 3), the approximate pixels and the background along them (n, 3); approximation_error says how."""
    unbiased = exact[:, :3] + mean
    sq = ((approx - unbiased) ** 2 - stderr ** 2).mean(axis=1)  # per sampled pixel, over the channels
    scattered = unbiased - background * (1.0 - exact[:, 3:4])
    mean_scattered = frac * float(scattered.mean())
    if mean_scattered <= 0.0:
        return ApproximationError(np.inf, np.inf, n, cloud, paths)
    ms = max(frac * float(sq.mean()), 0.0)
    rel = np.sqrt(ms) / mean_scattered
    # the estimate's own spread: the sampling error of the mean of sq, through the square root
    se_ms = frac * float(sq.std(ddof=1)) / np.sqrt(sq.size) if sq.size > 1 else np.inf
    se = 0.5 * se_ms / (np.sqrt(ms) * mean_scattered) if ms > 0 else np.inf
    return ApproximationError(float(rel), float(se), n, cloud, int(paths))
