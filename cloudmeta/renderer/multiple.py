"""Multiple scattering (``render: {scattering: multiple}``): the Monte Carlo part of the image.

Order 1 of every light stays the deterministic single-scattering renderer's (exact shadows, the
quadrature of cloudmeta.renderer.single); ``render_multiple`` adds, by path tracing
(cloudmeta.kernels.multiple: exact flights first, tracked ones from ``render.track_from`` on,
renderer.tracking), the orders 2 .. ``max_order`` of the lights and the orders 1 .. ``max_order`` of the
environment, the scene's uniform ``background``. It returns the per-pixel mean and its standard
error, so every multiple-scattering image comes with its own error estimate.

Both estimators read one packing of the scene (cloudmeta.renderer.pack.pack_scene); with ``shadows: map`` the
paths' next-event shadow rays read the same maps as the single-scattering renderer (at exact vertices as
they are, at tracked ones as a control variate).

``ambient`` is refused in multiple mode: the background already lights the medium at every order, and
an ambient term on top would count the sky twice.
"""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numba
import numpy as np

from ..errors import SceneError
from ..kernels.multiple import render_paths
from ..scene.limits import MAX_SPP
from .threads import progress_bar, tile_window
from .pack import pack_scene
from .tracking import path_settings, paths_grid, paths_volumes


def check_multiple(scene):
    """Refuse what multiple scattering cannot take (one line naming the file and the key)."""
    if scene.ambient is not None:
        raise SceneError(scene.path, "ambient", "not allowed with render.scattering: multiple (the background "
                                                "lights the medium at every order; ambient would count it twice)")


#: the planned paths (render.ms_spp auto): a pilot of PILOT_PATHS paths per pixel over the whole frame measures
#: each pixel's per-path variance, and the frame's blocks of BLOCK x BLOCK pixels get the path counts that reach
#: the target with the fewest paths (the count of a block in proportion to its pixels' RMS per-path standard
#: deviation); every block gets at least MIN_PATHS (a wisp that the pilot missed keeps an unbiased estimate),
#: and the plan asks for MARGIN^2 times the paths its own noisy variances call for. A block whose own paths then
#: show more variance than the pilot saw (rare bright paths that 4 paths a pixel missed) is topped up at the
#: frame's rate from a stream of its own (``TOPUP_STREAM``): a decision that reads the block alone, so a tile
#: makes the same as the frame
PILOT_PATHS = 4
BLOCK = 16
MIN_PATHS = 4
MARGIN = 1.15
#: the pilot's random numbers: a stream of their own, apart from every seed's paths
PILOT_STREAM = 0x9E3779B97F4A7C15 >> 2
TOPUP_STREAM = 0x632BE59BD9B4E019 >> 2
#: a block is topped up where its own paths call for more than TOPUP times what it was given
TOPUP = 1.2
#: paths per pixel where neither render.ms_spp nor a target says (``render_multiple`` called with neither)
FALLBACK_PATHS = 16


@dataclass(frozen=True)
class PathPlan:
    """Planned paths: ``paths`` (blocks down x blocks across, int64) per block of BLOCK x BLOCK pixels of the
    frame; the target and what the pilot measured (the frame's mean scattered light, single and multiple, the
    denominator of the target; the relative RMSE the plan predicts)."""
    paths: np.ndarray
    target: float
    scattered_mean: float
    predicted: float
    #: the allocation's rate (``allocation_rate``, times the margin^2): the frame's, which a block's
    #: top-up applies to the variance its own paths measured; 0 where the pilot saw no light
    scale: float = 0.0

    def mean_paths(self, height, width):
        """Paths per pixel over the frame, on average."""
        per_pixel = np.repeat(np.repeat(self.paths, BLOCK, 0), BLOCK, 1)[:height, :width]
        return float(per_pixel.mean())


def plan_paths(scene, packed, target, single_mean, seed=0, progress=False) -> PathPlan:
    """The paths per block that bring the frame's Monte Carlo part to ``target`` relative RMSE against its
    scattered light (``single_mean``, the pilot's mean single-scattered radiance, plus the paths' own mean),
    from a pilot over the whole frame: the same plan for every tile of the frame."""
    h, w = scene.image.height, scene.image.width
    mean, stderr = _paths_over(scene, packed, ((0, h), (0, w)), lambda r, c: PILOT_PATHS,
                               (seed + PILOT_STREAM) % (1 << 62), progress)
    variance = np.where(np.isfinite(stderr), stderr * stderr * PILOT_PATHS, 0.0)  # per path, per pixel and RGB
    norm = float(single_mean) + float(mean.mean())
    total, size = _block_sums(variance)                                    # S_b, |b|
    scale = 0.0
    if not norm > 0.0 or not total.sum() > 0.0:
        paths = np.full(total.shape, MIN_PATHS, np.int64)
    else:  # the frame's sum of squared errors allowed: (target x norm)^2 per value
        scale = MARGIN * MARGIN * allocation_rate(total, size, (target * norm) ** 2 * (h * w * 3))
        paths = np.clip(np.ceil(paths_at_rate(scale, total, size)), MIN_PATHS, MAX_SPP).astype(np.int64)
    predicted = float(np.sqrt((total / paths).sum() / (h * w * 3))) / norm if norm > 0.0 else 0.0
    return PathPlan(paths=paths, target=float(target), scattered_mean=norm, predicted=predicted, scale=scale)


def _block_sums(values):
    """Sums over each block of BLOCK x BLOCK pixels and RGB of ``values`` (a block-aligned window of the frame),
    and the number of values in each."""
    h, w = values.shape[:2]
    nb_r, nb_c = -(-h // BLOCK), -(-w // BLOCK)
    pad = np.zeros((nb_r * BLOCK, nb_c * BLOCK, 3))
    pad[:h, :w] = values
    ones = np.zeros((nb_r * BLOCK, nb_c * BLOCK))
    ones[:h, :w] = 3.0
    return (pad.reshape(nb_r, BLOCK, nb_c, BLOCK, 3).sum(axis=(1, 3, 4)),
            ones.reshape(nb_r, BLOCK, nb_c, BLOCK).sum(axis=(1, 3)))


def allocation_rate(total, size, allowed):
    """The rate r of the fewest paths sum_b n_b size_b that keep sum_b total_b / n_b <= ``allowed``, where
    total_b is the sum of the per-path variances of block b's values and size_b their number (Lagrange):
    n_b = r sqrt(total_b / size_b) (``paths_at_rate``) with r = sum_b sqrt(total_b size_b) / allowed."""
    return float(np.sqrt(total * size).sum()) / allowed


def paths_at_rate(rate, total, size):
    """Paths per block (float) at the allocation's ``rate``: in proportion to the RMS per-path standard
    deviation of each block's values."""
    return rate * np.sqrt(total / size)


def _tracked_records(scene, packed, max_order):
    """(the majorant grid, the light volumes) of the tracked flights: neither depends on the number of paths."""
    base = path_settings(scene, 1, max_order)
    return paths_grid(scene, packed.records.media, base), paths_volumes(scene, packed, base)


def _paths_over(scene, packed, window, paths_at, seed, progress, max_order=None, tracked=None):
    """(mean, stderr), H x W x 3 over the frame (zero outside ``window``): paths_at(block_row, block_col) paths
    per pixel in each block of BLOCK x BLOCK pixels within the tile ``window``, one call of the kernel per row
    of a block on threads (each pixel's numbers are keyed by the pixel: the result depends neither on the
    threads nor on the tile). ``tracked``: (grid, volumes) of ``_tracked_records``, made here when None."""
    max_order = scene.render.max_order if max_order is None else int(max_order)
    camera, records, quad = packed.camera._replace(seed=seed), packed.records, packed.quadrature
    grid, volumes = _tracked_records(scene, packed, max_order) if tracked is None else tracked
    w, h = scene.image.width, scene.image.height
    mean = np.zeros((h, w, 3))
    stderr = np.zeros((h, w, 3))
    (r_lo, r_hi), (c_lo, c_hi) = window
    runs = []  # (row, first column, end column, settings): the blocks of a row with the same count as one run
    settings_of = {}
    for r in range(r_lo, r_hi):
        c0 = c_lo
        while c0 < c_hi:
            count = paths_at(r // BLOCK, c0 // BLOCK)
            c1 = min(c_hi, (c0 // BLOCK + 1) * BLOCK)
            while c1 < c_hi and paths_at(r // BLOCK, c1 // BLOCK) == count:
                c1 = min(c_hi, c1 + BLOCK)
            if count > 0:  # (a block given no paths keeps zeros)
                if count not in settings_of:
                    settings_of[count] = path_settings(scene, count, max_order)
                runs.append((r, c0, c1, settings_of[count]))
            c0 = c1
    threads = numba.get_num_threads()
    chunks = [runs[i::threads * 8] for i in range(min(len(runs), threads * 8))]
    bar = progress_bar(len(runs), progress)

    def chunk(todo):
        for row, c0, c1, settings in todo:
            render_paths(camera, records, quad, settings, grid, volumes, row, c0, c1, mean, stderr)
        return len(todo)

    with ThreadPoolExecutor(threads) as pool:
        for done in pool.map(chunk, chunks):
            bar.update(done)
    bar.close()
    return mean, stderr


def render_multiple(scene, paths=None, max_order=None, seed=0, progress=False, rows=None, columns=None,
                    packed=None, target=None, single_mean=0.0, plan=None):
    """The Monte Carlo part of a multiple-scattering render: (radiance, stderr), both H x W x 3 float64,
    linear RGB. radiance is the mean of the paths per pixel of the light the deterministic renderer leaves out
    (orders >= 2 of the lights, >= 1 of the environment), up to ``max_order`` (default ``render.max_order``);
    stderr its standard error per pixel and channel (inf with one path). The paths per pixel: ``paths``, else
    ``render.ms_spp``, else planned (``plan_paths``) to ``target`` (default: the preset's, renderer.quality)
    relative RMSE against the frame's scattered light (``single_mean``: the pilot's mean single-scattered
    radiance, renderer.calibrate; 0 counts the paths' light alone); ``plan``: a PathPlan made already.
    Bit-identical for any number of threads. ``rows`` and ``columns`` as in cloudmeta.renderer.render (a tile:
    the same numbers as those pixels of the whole frame; a planned tile plans over the whole frame);
    ``packed``: the render's pack.Packed of the same scene and seed, so the scene is packed once."""
    check_multiple(scene)
    window = tile_window(rows, scene.image.height, "rows"), tile_window(columns, scene.image.width, "columns")
    packed = pack_scene(scene, seed) if packed is None else packed
    if paths is None and scene.render.ms_spp is None and plan is None:
        if target is None:
            from .quality import resolve_settings
            target = resolve_settings(scene).paths_target
        if target is not None:
            plan = plan_paths(scene, packed, target, single_mean, seed, progress)
    (r_lo, r_hi), (c_lo, c_hi) = window
    if plan is None:
        count = int(paths if paths is not None else scene.render.ms_spp or FALLBACK_PATHS)
        mean, stderr = _paths_over(scene, packed, window, lambda i, j: count, packed.camera.seed, progress,
                                   max_order)
        return mean[r_lo:r_hi, c_lo:c_hi], stderr[r_lo:r_hi, c_lo:c_hi]
    mean, stderr = _planned(scene, packed, window, plan, progress, max_order)
    return mean[r_lo:r_hi, c_lo:c_hi], stderr[r_lo:r_hi, c_lo:c_hi]


def _planned(scene, packed, window, plan, progress, max_order):
    """The planned paths over the whole blocks that ``window`` touches, each block topped up where its own
    paths call for more (PathPlan.scale); (mean, stderr) over the frame."""
    h, w = scene.image.height, scene.image.width
    (r_lo, r_hi), (c_lo, c_hi) = window
    b_r0, b_c0 = r_lo // BLOCK, c_lo // BLOCK
    blocks = ((b_r0 * BLOCK, min(h, -(-r_hi // BLOCK) * BLOCK)), (b_c0 * BLOCK, min(w, -(-c_hi // BLOCK) * BLOCK)))
    (R0, R1), (C0, C1) = blocks
    max_order = scene.render.max_order if max_order is None else int(max_order)
    tracked = _tracked_records(scene, packed, max_order)  # once for both passes
    mean, stderr = _paths_over(scene, packed, blocks, lambda i, j: int(plan.paths[i, j]), packed.camera.seed,
                               progress, max_order, tracked)
    if not plan.scale > 0.0:
        return mean, stderr
    n = plan.paths[b_r0:-(-R1 // BLOCK), b_c0:-(-C1 // BLOCK)]
    n1 = n.repeat(BLOCK, 0).repeat(BLOCK, 1)[:R1 - R0, :C1 - C0, None].astype(np.float64)
    total, size = _block_sums(stderr[R0:R1, C0:C1] ** 2 * n1)
    wanted = np.clip(np.ceil(paths_at_rate(plan.scale, total, size)), 0, MAX_SPP)
    extra = np.where(wanted > TOPUP * n, wanted - n, 0).astype(np.int64)
    if not extra.any():
        return mean, stderr
    more_mean, more_err = _paths_over(scene, packed, blocks, lambda i, j: int(extra[i - b_r0, j - b_c0]),
                                      (packed.camera.seed + TOPUP_STREAM) % (1 << 62), progress, max_order, tracked)
    # the two passes pooled: means weighted by their paths, per-path variances likewise
    n2 = extra.repeat(BLOCK, 0).repeat(BLOCK, 1)[:R1 - R0, :C1 - C0, None].astype(np.float64)
    m1, m2 = mean[R0:R1, C0:C1], more_mean[R0:R1, C0:C1]
    v1 = stderr[R0:R1, C0:C1] ** 2 * n1
    v2 = np.where(n2 > 1, more_err[R0:R1, C0:C1] ** 2 * np.maximum(n2, 1.0), 0.0)
    both = n1 + n2
    pooled = (n1 * (v1 + m1 * m1) + n2 * (v2 + m2 * m2)) / both
    mean[R0:R1, C0:C1] = (n1 * m1 + n2 * m2) / both
    stderr[R0:R1, C0:C1] = np.sqrt(np.maximum(pooled - mean[R0:R1, C0:C1] ** 2, 0.0) / both)
    return mean, stderr
