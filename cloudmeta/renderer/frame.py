"""One frame: Scene -> linear image. ``render_frame`` packs the scene once (renderer.pack), runs the
deterministic single-scattering driver (renderer.single) at the frame's settings (renderer.quality.FrameSettings,
resolved once here and handed down), or
under the error estimate (renderer.estimate), and adds the Monte Carlo part of the estimator that
``render.scattering`` names (``ESTIMATORS``). One record, ``RenderResult``, flows back whatever the flags;
``render`` keeps the public API's return values (the image; (image, depth) with ``depth``; error last).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..errors import CloudmetaError, InputError
from ..kernels.lighting import (COUNT_EXACT, COUNT_FOLDS, COUNT_KRONROD, COUNT_LOOKUPS, COUNT_NODES, COUNT_SPLITS,
                                COUNT_STEPS, COUNT_TRUSTED, N_COUNTS)
from ..scene.model import Scene
from ..scene.vocabulary import SCATTERING_MODES, ShadowMode
from .threads import tile_window
from .denoise import aux_images, denoise_paths, require_denoiser
from .fluence import with_radiance_grid
from .ground import ground_shadow
from .estimate import estimated_rel_rmse, frame_scattered_mean, with_estimate
from .approximate import approximate_light, approximation_error, check_approximate
from .multiple import check_multiple, plan_paths, render_multiple
from .pack import pack_scene, quadrature, without_maps
from .calibrate import pilot_quality
from .quality import FrameSettings, resolve_settings
from .single import render_single


@dataclass(frozen=True)
class Estimator:
    """An estimator of ``render.scattering``: what it refuses in a scene (raises SceneError; None: nothing),
    and the Monte Carlo part it adds to the deterministic single-scattering image (None: none), called as
    paths(scene, seed=, progress=, rows=, columns=, packed=, plan=) -> (mean, stderr), both H x W x 3 (plan: the
    frame's renderer.multiple.PathPlan, or None for render.ms_spp's count); and how its
    approximation's error is measured with ``error=True`` (None: it approximates nothing), called as
    approximation(scene, image, packed, window, seed=) -> an approximate.ApproximationError; and the light it adds
    to the deterministic image once that is rendered (None: none), called as light(scene, packed, settings, image,
    window, seed, progress, single_mean=) -> (light, stderr, plan), light and stderr H x W x 3 (single_mean: the
    pilot's mean single-scattered radiance; plan: what the method planned from it, or None), or None where the
    scene's method adds nothing there."""
    check: Callable | None = None
    paths: Callable | None = None
    approximation: Callable | None = None
    light: Callable | None = None


#: render.scattering -> its estimator; a new estimator is one entry here and one driver module
ESTIMATORS = {
    "single": Estimator(),
    "multiple": Estimator(check=check_multiple, paths=render_multiple),
    "approximate": Estimator(check=check_approximate, approximation=approximation_error, light=approximate_light),
}
assert tuple(ESTIMATORS) == SCATTERING_MODES, "every scattering mode of the scene's vocabulary has an estimator"


@dataclass(frozen=True)
class RenderResult:
    """What a render gives back: image (H x W x 4 float32, linear RGB of the working colourspace and
    alpha), depth (H x W float64: the nearest surface hit among a pixel's samples, inf where none), and
    error (H x W x 3 float32, each pixel's estimated absolute error) or None when not asked for; with
    ``render.scattering: approximate`` and the error asked for, ``approximation`` (an
    approximate.ApproximationError): the approximation's estimated relative RMSE against the unbiased image;
    ``scattered`` and ``estimated``: the pilot's measure of the scattered light and the estimated relative
    RMSE of the image (docs/error_estimate.md)."""
    image: np.ndarray
    depth: np.ndarray
    error: np.ndarray | None = None
    approximation: object | None = None
    #: the pilot's measure of the frame's scattered light (a pilot.LightScale), and, with the error asked
    #: for, the image's estimated relative RMSE (the estimate's RMSE over the pilot's mean scattered radiance)
    scattered: object | None = None
    estimated: float | None = None
    #: per pixel what the single-scattering render's light cost (H x W x N_COUNTS float64: quadrature nodes, exact
    #: shadow rays, shadow-map lookups, lookups trusted, steps, steps with Kronrod nodes, splits, splits at
    #: folds; renderer.single.render_single); see ``cost``
    counts: np.ndarray | None = None
    #: with denoise=True, the image before its Monte Carlo part was denoised (renderer.denoise); ``error`` and
    #: ``estimated`` are of this raw image
    raw: np.ndarray | None = None
    #: the frame's settings as resolved once (renderer.quality.FrameSettings: preset, target, shadow mode, ...),
    #: and the quadrature the image was rendered at (a renderer.quality.Quality: calibrated, refined)
    settings: FrameSettings | None = None
    quality: object | None = None
    #: multiple scattering with planned paths: the renderer.multiple.PathPlan (paths per block, what the pilot
    #: measured, the relative RMSE it predicted); the shared method with planned tails: the
    #: renderer.shared.TailPlan; None otherwise
    plan: object | None = None

    def cost(self):
        """Per pixel with media (alpha > 0), the mean count of quadrature nodes, exact shadow rays, map lookups
        and trusted lookups, as a dict (the benchmarks' counters; zeros where no pixel has media)."""
        media = self.image[..., 3] > 0.0
        n = max(int(np.count_nonzero(media)), 1)
        total = self.counts[media].sum(axis=0) if self.counts is not None else np.zeros(N_COUNTS)
        return dict(media_pixels=int(np.count_nonzero(media)),
                    **{name: total[q] / n for name, q in COUNTERS.items()})


#: RenderResult.cost's names of the kernels' counters
COUNTERS = dict(nodes=COUNT_NODES, exact_rays=COUNT_EXACT, lookups=COUNT_LOOKUPS, trusted=COUNT_TRUSTED,
                steps=COUNT_STEPS, kronrod=COUNT_KRONROD, splits=COUNT_SPLITS, folds=COUNT_FOLDS)


def render_frame(scene: Scene, progress=True, seed=0, rows=None, columns=None, error=False,
                 denoise=False) -> RenderResult:
    """Render the scene (or the tile ``rows`` x ``columns`` of it) into a RenderResult; see ``render``.
    With ``denoise=True`` (multiple scattering, a whole frame) the paths' part is denoised
    (renderer.denoise) and ``raw`` keeps the image before it."""
    if not isinstance(scene, Scene):  # the API's wrong types are InputErrors naming the argument
        raise InputError(f"scene: expected a cloudmeta Scene (from load_scene), got {type(scene).__name__}")
    if not isinstance(denoise, (bool, np.bool_)):
        raise InputError(f"denoise: expected True or False, got {denoise!r}")
    denoiser = None
    if denoise:  # checked before any work
        if rows is not None or columns is not None:
            raise InputError("denoise: a whole frame only (the filter reads neighbouring pixels; denoise the "
                             "assembled frame)")
        denoiser = require_denoiser(scene)
    window = tile_window(rows, scene.image.height, "rows"), tile_window(columns, scene.image.width, "columns")
    estimator = ESTIMATORS[scene.render.scattering]
    if estimator.check is not None:
        estimator.check(scene)
    settings = resolve_settings(scene)  # every render setting, decided once for the frame
    # one packing; the pilot (renderer.pilot) measures the frame's scattered light: the quadrature's scale
    packed = with_radiance_grid(scene, pack_scene(scene, seed, settings), seed, settings)  # the grid's photons, once
    quality, scattered = pilot_quality(scene, packed, settings)
    packed = packed._replace(quadrature=quadrature(quality))
    if settings.shadows == ShadowMode.HYBRID and quality.shadows == ShadowMode.EXACT:
        # the calibration turned a hybrid frame to exact shadow rays (renderer.pilot MIN_TRUSTED): the kernel compiled
        # for exact shadows, without the map code, runs it 3 % faster (the 1,200-ball bank at 512 x 512)
        packed = packed._replace(records=without_maps(scene, packed.records))
    target = settings.error
    # the clouds' shadow on a ground the scene places (renderer.ground): what it takes from the background
    packed = packed._replace(ground=ground_shadow(scene, packed.records, packed.camera, packed.quadrature.tol_t, window))

    def single(packed_q):  # the deterministic image, its background shaded where the ground is in shadow
        image, nearest, counts = render_single(scene, packed_q, window, progress)
        if packed.ground is not None:
            image[..., :3] -= packed.ground * (1.0 - image[..., 3:4])
        return image, nearest, counts

    def scattered_norm(image, nearest):  # the estimate's denominator (renderer.estimate.frame_scattered_mean)
        return frame_scattered_mean(image, nearest, packed.camera, packed.records.background, window, scattered.mean,
                                    packed.ground)
    if error or target is not None:  # renderer.estimate: a second, coarser render; refined to the target
        done = {}

        def at(q):  # the image at these settings (the records do not depend on them); kept for the one chosen
            packed_q = packed._replace(quadrature=quadrature(q))
            done[q] = (packed_q, *single(packed_q))
            return done[q][1]

        def norm(image):  # (the surfaces a ray hits do not depend on the settings: any render's nearest will do)
            return scattered_norm(image, next(iter(done.values()))[2])
        image, err, quality, _ = with_estimate(at, quality, target, norm)
        packed, _, nearest, counts = done[quality]
    else:
        err = None
        image, nearest, counts = single(packed)
    added = None if estimator.light is None else estimator.light(scene, packed, settings, image, window, seed,
                                                                         progress, single_mean=scattered.mean)
    plan = tails = None
    if added is not None:  # the approximate method's own light (renderer.shared), its noise, its planned tails
        image[..., :3] += added[0]
        if err is not None:
            err = np.sqrt(err * err + added[1] * added[1])
        tails = added[2]
    if estimator.paths is not None:
        if settings.paths_target is not None:  # planned over the whole frame: the same plan for every tile
            plan = plan_paths(scene, packed, settings.paths_target, scattered.mean, seed, progress)
        mean, stderr = estimator.paths(scene, seed=seed, progress=progress, rows=rows, columns=columns,
                                       packed=packed, plan=plan)
        raw = None
        if denoiser is not None:
            raw = image.copy()
            raw[..., :3] += mean
            albedo, _ = aux_images(scene, packed, window)  # the normals: worse guides here (renderer.denoise)
            try:
                mean = denoise_paths(denoiser, mean, albedo, None, image[..., 3])
            except Exception as exc:  # the library's own errors: one of cloudmeta's classes, one line
                raise CloudmetaError(f"denoise: Intel Open Image Denoise failed: {type(exc).__name__}: {exc}") from exc
        image[..., :3] += mean
        if err is not None:
            err = np.sqrt(err * err + stderr * stderr)
    # the image's estimated relative RMSE, of the error as returned (Monte Carlo standard error included), over the
    # frame's own scattered light where it can tell it
    estimated = None if err is None else estimated_rel_rmse(image, err, scattered_norm(image, nearest))
    if estimated is None and plan is not None:  # the paths' own noise, which planned paths always know
        estimated = estimated_rel_rmse(image, stderr, scattered_norm(image, nearest))
    approximation = None
    if error and estimator.approximation is not None:
        approximation = estimator.approximation(scene, image, packed, window, seed=seed)
    return RenderResult(image=image.astype(np.float32), depth=nearest.copy(),
                        error=None if not error else err.astype(np.float32), approximation=approximation,
                        scattered=scattered, estimated=estimated, counts=counts,
                        raw=None if denoiser is None else raw.astype(np.float32), settings=settings,
                        quality=quality, plan=plan if plan is not None else tails)


def render(scene: Scene, progress=True, seed=0, depth=False, rows=None, columns=None, error=False, denoise=False):
    """Render the scene: an H x W x 4 float32 array, linear RGB of the working colourspace and alpha.

    With ``depth=True`` returns (image, depth): depth (H x W, float64) is, per pixel, the distance along
    the camera ray to the nearest surface hit among its samples (inf where no sample meets a surface).
    ``rows=(r0, r1)`` and ``columns=(c0, c1)`` render only that tile of the frame (rows r0 .. r1 - 1 from
    the top), bit-identical to the same pixels of the whole frame: every pixel's rays and samples depend on
    its place in the frame alone. A tile still allocates the whole frame's arrays (40 bytes a pixel).
    With ``render.scattering: multiple`` the Monte Carlo orders (renderer.multiple) are added to the
    tile's pixels; their random numbers are keyed by the pixel too.

    With ``error=True`` the result gains ``error`` (last: (image, error) or (image, depth, error)), an
    H x W x 3 float32 estimate of each pixel's absolute error: the difference to a render with coarser
    quadrature settings (renderer.estimate; docs/error_estimate.md). With ``render.error`` set (a target
    relative RMSE) the settings are refined until the estimate is at most the target.
    With ``denoise=True`` (``render.scattering: multiple``, a whole frame; the optional extra pyoidn) the
    Monte Carlo part is denoised by Intel Open Image Denoise (renderer.denoise); the error, if asked for,
    stays that of the raw image (``render_frame``'s ``raw``).
    ``render_frame`` gives the same as one RenderResult.
    """
    result = render_frame(scene, progress=progress, seed=seed, rows=rows, columns=columns, error=error,
                          denoise=denoise)
    out = (result.image,) + ((result.depth,) if depth else ()) + ((result.error,) if error else ())
    return out if len(out) > 1 else out[0]
