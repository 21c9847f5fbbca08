"""Render a scene: resolve the settings, pack the scene (cloudmeta.pack) once, then run the radiance kernel
(cloudmeta.kernels.radiance) over bands of rows on threads, with a progress bar.

Quality settings (``render:`` in the scene, MODEL.md §9). ``quality`` picks a preset; any of the other
keys overrides that preset's value:

=============== ======= ======= ======= ========== ====================================================
key             draft   default fine    reference  meaning
=============== ======= ======= ======= ========== ====================================================
tolerance       1e-2    3e-3    1e-3    1e-6       error allowed in the light J per unit of optical
                                                   depth (weighted by the view transmittance), relative
                                                   to the brightest J on the ray
max_tau         4.0     2.0     1.0     0.1        thickest step, in optical depth
max_length      1/4     1/16    1/32    1/128      longest step, as a fraction of the scene's diagonal
                                                   (an explicit ``max_length`` is in scene units)
max_angle       0.4     0.2     0.1     0.025      widest angle (radians) of a step seen from a point light
cutoff          1e-2    1e-3    1e-4    0          stop shading once the view transmittance is below
root_tolerance  1e-9    1e-9    1e-9    1e-9       root tolerance, relative to the scene's diagonal
=============== ======= ======= ======= ========== ====================================================

Each step of the in-scattering integral takes 7 Gauss nodes; where the two highest Legendre coefficients
of J on them exceed the tolerance, the 8 Kronrod nodes join (G7-K15), and where the two rules still
disagree by more than the tolerance allows the step is halved (at most 6 times). The optical depth, the
view transmittance and the shadow transmittance are exact at every setting; the settings only trade the
quadrature of the in-scattering integral against time.

Opaque surfaces (``surfaces:``, MODEL.md §6) are exact at every setting too: the first root of each
surface's field along the camera ray, the analytic normal, and shadow rays that stop at the first surface
they meet. With ``shadows: map`` the maps hold the media only; surfaces still block every shadow ray
exactly (a first-root test per node and light), so their shadows are as sharp as with ``exact``. A surface
seen through less than ``cutoff`` of view transmittance is not shaded (like the media behind it).
"""
from __future__ import annotations

import operator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numba
import numpy as np

from .kernels.radiance import render_pixels
from .pack import pack_camera, quadrature, scene_records
from .scene import RenderSettings, Scene
from .errors import InputError
from .estimate import with_estimate

#: the quadrature presets, tuned on all 14 scenes of the accuracy suite so that each meets its target
#: (draft 3e-3, default 1e-3, fine 3e-4) with a margin: tolerance was 1e-2, 3e-3, 1e-3 and fine's max_tau 1,
#: which missed by up to 1.6x on the grazing-sun deck and bank and the puffs under a point light
#: (docs/error_estimate.md "Presets"); a tighter tolerance cost the cumulus less than halving max_tau
PRESETS = {
    "draft": dict(tolerance=4e-3, max_tau=4.0, max_length=1 / 4, max_angle=0.4, cutoff=1e-2, root_tolerance=1e-9),
    "default": dict(tolerance=1.5e-3, max_tau=2.0, max_length=1 / 16, max_angle=0.2, cutoff=1e-3,
                    root_tolerance=1e-9),
    "fine": dict(tolerance=5e-4, max_tau=0.7, max_length=1 / 32, max_angle=0.1, cutoff=1e-4, root_tolerance=1e-9),
    "reference": dict(tolerance=1e-6, max_tau=0.1, max_length=1 / 128, max_angle=0.025, cutoff=0.0,
                      root_tolerance=1e-9),
}
#: texels per side of a shadow map when render.shadow_map is not given
SHADOW_MAP_RESOLUTION = 384
#: the image is cut into bands of rows, about this many per thread (uneven rows balance out) and no
#: taller than MAX_BAND_ROWS; the progress bar moves once per band
BANDS_PER_THREAD = 16
MAX_BAND_ROWS = 16


@dataclass(frozen=True)
class Quality:
    """The resolved quadrature settings of one render (all lengths in scene units)."""
    tolerance: float
    max_tau: float
    max_length: float
    max_angle: float
    cutoff: float
    tol_t: float


def resolve_quality(settings: RenderSettings, diagonal: float) -> Quality:
    preset = PRESETS[settings.quality]
    pick = lambda key: preset[key] if getattr(settings, key) is None else getattr(settings, key)  # noqa: E731
    max_length = preset["max_length"] * diagonal if settings.max_length is None else settings.max_length
    return Quality(tolerance=float(pick("tolerance")), max_tau=float(pick("max_tau")), max_length=float(max_length),
                   max_angle=float(pick("max_angle")), cutoff=float(pick("cutoff")),
                   tol_t=float(pick("root_tolerance")) * diagonal)


def render(scene: Scene, progress=True, seed=0, depth=False, rows=None, columns=None, error=False):
    """Render the scene: an H x W x 4 float32 array, linear RGB of the working colourspace and alpha.

    With ``depth=True`` returns (image, depth): depth (H x W, float64) is, per pixel, the distance along
    the camera ray to the nearest surface hit among its samples (inf where no sample meets a surface).
    ``rows=(r0, r1)`` and ``columns=(c0, c1)`` render only that tile of the frame (rows r0 .. r1 - 1 from
    the top), bit-identical to the same pixels of the whole frame: every pixel's rays and samples depend on
    its place in the frame alone. A tile still allocates the whole frame's arrays (40 bytes a pixel).
    With ``render.scattering: multiple`` the Monte Carlo orders (cloudmeta.multiple) are added to the
    tile's pixels; their random numbers are keyed by the pixel too.

    With ``error=True`` the result gains ``error`` (last: (image, error) or (image, depth, error)), an
    H x W x 3 float32 estimate of each pixel's absolute error: the difference to a render with coarser
    quadrature settings (cloudmeta.estimate; docs/error_estimate.md). With ``render.error`` set (a target
    relative RMSE) the settings are refined until the estimate is at most the target.
    """
    if not isinstance(scene, Scene):  # issue #15: the API's wrong types are InputErrors naming the argument
        raise InputError(f"scene: expected a cloudmeta Scene (from load_scene), got {type(scene).__name__}")
    window = _window(rows, scene.image.height, "rows"), _window(columns, scene.image.width, "columns")
    multiple = _multiple_scattering(scene)
    target = scene.render.error
    if error or target is not None:  # cloudmeta.estimate: a second, coarser render; refined to the target
        done = {}

        def at(quality):  # the image at these settings; the packing and depth kept for the one chosen
            packed = pack_scene(scene, seed, quality)
            done[quality] = (packed, *_single_scattering(scene, packed, window, progress))
            return done[quality][1]
        image, err, quality, _ = with_estimate(at, scene_quality(scene), target)
        packed, _, nearest = done[quality]
    else:
        packed, err = pack_scene(scene, seed), None
        image, nearest = _single_scattering(scene, packed, window, progress)
    if multiple is not None:
        image, stderr = multiple(scene, image, seed=seed, progress=progress, rows=rows, columns=columns,
                                 packed=packed)
        if error:
            err = np.sqrt(err * err + stderr * stderr)
    out = (image.astype(np.float32),) + ((nearest.copy(),) if depth else ()) + \
        ((err.astype(np.float32),) if error else ())
    return out if len(out) > 1 else out[0]


def _single_scattering(scene, packed, window, progress):
    """(image, nearest) of the tile ``window``: the deterministic renderer's H x W x 4 and depth."""
    camera, records, quad = packed
    w, h = scene.image.width, scene.image.height
    image = np.zeros((h, w, 4), np.float64)
    nearest = np.full((h, w), np.inf)
    run_bands(lambda row0, p0, p1: render_pixels(camera, records, quad, row0, p0, p1, image, nearest), window, w,
              progress)
    (r_lo, r_hi), (c_lo, c_hi) = window
    return image[r_lo:r_hi, c_lo:c_hi], nearest[r_lo:r_hi, c_lo:c_hi]


def pack_scene(scene, seed, quality=None):
    """(camera, scene records, quadrature): the scene packed once for every estimator (cloudmeta.pack), at
    the scene's quality settings or at ``quality`` (a Quality)."""
    quad = quadrature(scene_quality(scene) if quality is None else quality)
    records = scene_records(scene, quad, scene.render.shadow_map or SHADOW_MAP_RESOLUTION)
    return pack_camera(scene, seed), records, quad


def scene_quality(scene) -> Quality:
    lo, hi = scene.bbox()
    return resolve_quality(scene.render, float(np.linalg.norm(hi - lo)))


def run_bands(kernel, window, width, progress):
    """Call kernel(row0, p0, p1) over the tile ``window`` = ((r_lo, r_hi), (c_lo, c_hi)) of a frame
    ``width`` pixels wide, in bands of rows on threads, with a progress bar."""
    (r_lo, r_hi), (c_lo, c_hi) = window
    bar = _progress(r_hi - r_lo, progress)
    threads = numba.get_num_threads()
    rows = max(1, min(MAX_BAND_ROWS, -(-(r_hi - r_lo) // (BANDS_PER_THREAD * threads))))
    bands = [(r0, min(r_hi, r0 + rows)) for r0 in range(r_lo, r_hi, rows)]

    def band(rows):
        r0, r1 = rows
        # a whole row is one run of pixels; part of a row (a tile) takes one call per row
        runs = [(r0, 0, (r1 - r0) * width)] if (c_lo, c_hi) == (0, width) else [(r, c_lo, c_hi)
                                                                                  for r in range(r0, r1)]
        for row0, p0, p1 in runs:
            kernel(row0, p0, p1)
        return r1 - r0

    # each band is one call of a nogil kernel with its own work arrays, written to its own rows: threads
    # share nothing, so the image does not depend on their number or order
    with ThreadPoolExecutor(threads) as pool:
        for done in pool.map(band, bands):
            bar.update(done)
    bar.close()


def _window(span, size, name):
    """(start, stop) of a tile's ``rows`` or ``columns``: the whole range when None."""
    if span is None:
        return 0, size
    try:
        start, stop = (operator.index(v) for v in span)
    except (TypeError, ValueError):
        start, stop = -1, -1
    if not 0 <= start < stop <= size:
        raise InputError(f"{name}: expected (start, stop) with 0 <= start < stop <= {size}, got {span!r}")
    return start, stop


def _multiple_scattering(scene):
    """With ``render.scattering: multiple``, the hook that adds the Monte Carlo orders to the image
    (cloudmeta.multiple), after checking the scene for it; None for single scattering."""
    if scene.render.scattering != "multiple":
        return None
    from .multiple import add_multiple, check_multiple  # it imports this module
    check_multiple(scene)
    return add_multiple


class _NoBar:
    def update(self, n):
        pass

    def close(self):
        pass


def _progress(rows, enabled):
    if not enabled:
        return _NoBar()
    from tqdm import tqdm
    return tqdm(total=rows, unit="row", desc="render", leave=False, mininterval=0.5)
