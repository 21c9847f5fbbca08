"""The pilot: how bright a frame's scattered light is, measured before the frame is rendered
(docs/model.md §11, docs/error_estimate.md).

The presets are targets for the image's RMSE against the converged image divided by the mean scattered
radiance. The scattered radiance is the image less what is computed exactly: the background seen through
the media, and the shading of surfaces. A tolerance relative to each ray's own brightest light cannot keep
such a target. A thin wisp, or a small cloud in a large frame, makes the image's scattered light small
while the ray's own light stays bright.

So the in-scattering quadrature's tolerance is absolute, relative to one scale per frame. A pilot
measures that scale: it renders the scattered light alone (black background, black surfaces) at
``draft`` on a coarse grid over the frame. The scale is the RMS over the pilot's pixels of r + g + b, the
unit of the kernels' J sums. If every cloud pixel has the same absolute error, the image's RMSE is that
error times the square root of the cloud's coverage, and sqrt(mean S^2) = mean S / sqrt(coverage).

The pilot depends on the whole frame alone, never on a tile, a thread count or a worker, so every tile of a
frame gets the same tolerance and renders stay bit-identical. A pilot that sees no scattered light gives
scale 0. The quadrature then falls back to a tolerance relative to each ray's brightest J.

**Calibration** (the preset is a target, checked on the scene at hand rather than tuned on a
suite). A preset's fixed settings keep its target on the hardest scenes of the accuracy suite, so they do
several times too much work on easy ones: the shipped cumulus at ``default`` lands at 1.2e-4 against its 1e-3.
Where FrameSettings.calibrate holds, a calibration grid of the frame's rays (``calibration_size``) is rendered on one
ladder of settings, LADDER's preset scaled by ``level`` steps of renderer.estimate's factors
(``scaled_quality``), each preset starting at its own level (renderer.quality.Preset.start): one step below
the start (the calibration's reference, with exact shadow rays under ``shadows: hybrid``), then above it. The frame takes the coarsest level, up to
MAX_LEVEL above the start, whose relative RMSE against that reference is at most SHARE of the target
(``calibrated_level``): the step above the start first; where it fails, a try below it aimed as if the error grew
GROWTH times a step, and the start itself only where that fails too; then regula falsi between the last level that
passed and the first that failed, each try rendered only where the frame's nodes it would spare outweigh its own
(``worth`` in ``calibrate``: at 64 x 48 the grid is the frame, and no try between is worth it). Where the start
itself measures above the limit, the frame is rendered up to one step finer, or two where the reference's own
error, extrapolated from the errors of the start and of the step above it, is above that too.
Where more than KRONROD_SHARE of the reference's steps took the Kronrod nodes, the search runs on the shorter ladder:
steps SHORTER_TAU as thick at SHORTER_LEVEL steps coarser (the 1,200-ball bank: 36.2 -> 31.5 nodes per media pixel at
512 x 512); the fallbacks below level 0 stay on the ladder.
Under ``shadows: hybrid``, a grid that trusts fewer than MIN_TRUSTED of its lookups turns the frame to exact
shadow rays, and the search starts again with exact rays. Like the scale, the level depends on the whole frame.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..scene.vocabulary import ShadowMode
from .estimate import scaled_quality
from .pack import Packed, pack_camera, quadrature
from .quality import QUADRATURE_KEYS, preset_quality
from .single import render_single
from ..kernels.lighting import COUNT_KRONROD, COUNT_NODES, COUNT_STEPS

#: the pilot samples every STRIDE-th pixel of the frame in each direction, or fewer so that its shorter side
#: keeps MIN_SIDE pixels (all of them where the frame's is shorter still); its aspect is the frame's. The scale only
#: sets the unit of the tolerance, and a calibrated frame measures its error at the settings that unit gives: 1/256
#: of the rays (32 x 32 at 512 x 512) costs a quarter of 1/64's (0.011 s against 0.036 s on the front-lit cumulus)
STRIDE = 16
MIN_SIDE = 16
#: calibration: the frame's settings are the coarsest whose error on the calibration grid is at most SHARE of
#: the target, at most MAX_LEVEL steps above the preset's start on the ladder (each step: tolerance and cutoff
#: x 3, max_tau, max_length and max_angle x 2); a level found between two steps is kept if its own error passes
SHARE = 0.5
MAX_LEVEL = 3.0
#: the calibration's grid keeps at least this many rays (calibration_size): quadrature errors gather in a few
#: pixels (folds, entries), and the 352 rays of a 64 x 48 frame's pilot grid measured them 3x too low
CALIBRATION_RAYS = 4096
#: renders spent between the last whole step that passed and the first that failed
BETWEEN_TRIES = 3
#: a try between a level that passed and one that failed is aimed at AIM x the limit, or at NARROW_AIM x the limit
#: where the two are at most NARROW steps apart (``_between``)
AIM = 0.9
NARROW_AIM = 0.95
NARROW = 0.25
#: a try between two levels is rendered only where the frame's nodes it would spare (at the rate the grid's nodes
#: fell between the two) are WORTH times its own: it may fail, and then spares nothing (``calibrate``)
WORTH = 1.5
#: where level 1 fails, the first try below it is aimed as if the error grew GROWTH times a step (the tolerance's own
#: factor); only where that try fails too is level 0 rendered. At 512 x 512 the grid's error grew 3.45x / 3.0x / 2.6x
#: from level 0 to 1 on the front-lit cumulus, the back-lit one and the bank
GROWTH = 3.0
#: calibrated frames take their settings on one ladder: LADDER's preset scaled by 3^level / 2^level, each preset
#: starting at its own level (renderer.quality.Preset.start)
LADDER = "default"
#: the preset the pilot measures the scattered light at
PILOT = "draft"
#: ``shadows: hybrid``: where the calibration's grid, at the level chosen, trusted fewer than this share of its map
#: lookups, the frame traces exact shadow rays instead (more accurate, never less). A failed lookup costs its time on
#: top of the exact ray, a small fraction of it: at 512 x 512 the front-lit cumulus, trusting 25 %,
#: rendered in 0.84x the time of exact shadows; the 1,200-ball bank, trusting 0.5 %, gained nothing
MIN_TRUSTED = 0.1
#: where more than this share of the calibration reference's steps took the Kronrod nodes, the search runs on the
#: shorter ladder: steps SHORTER_TAU as thick at SHORTER_LEVEL steps coarser (the 1,200-ball bank: 39 % of its
#: reference's steps; the front- and back-lit cumulus 16 % and 9 %)
KRONROD_SHARE = 0.35
SHORTER_LEVEL = 0.5
SHORTER_TAU = 0.5


@dataclass(frozen=True)
class LightScale:
    """What the pilot measured: ``mean``, the mean over its pixels and RGB of the scattered radiance (the
    denominator of the presets' relative RMSE; on a calibrated frame, that of the calibration's reference);
    ``scale``, the RMS over its pixels of r + g + b (the quadrature's absolute unit); ``width`` x ``height``, the
    pilot's grid."""
    mean: float
    scale: float
    width: int
    height: int
    #: the calibration (module docstring): the settings' level on the ladder (0: LADDER's preset's own) and the
    #: relative RMSE the pilot measured there; None where the frame was not calibrated
    level: float | None = None
    predicted: float | None = None
    rays: int = 0
    #: ``shadows: hybrid``, calibrated: the share of map lookups the grid trusted at the level chosen (below
    #: MIN_TRUSTED the frame's shadow rays are all exact); None otherwise
    trusted: float | None = None
    #: calibrated: whether the frame took the shorter steps (``calibrate``: max_tau halved, SHORTER_LEVEL coarser)
    shorter: bool = False


def pilot_size(width, height):
    """The pilot grid of a width x height frame: each side divided by one stride, at most STRIDE, so that
    the shorter side keeps at least MIN_SIDE pixels."""
    stride = max(1, min(STRIDE, min(width, height) // MIN_SIDE))
    return -(-width // stride), -(-height // stride)


def calibration_size(width, height):
    """The calibration's grid of a width x height frame: every stride-th pixel, the stride the largest that
    keeps at least CALIBRATION_RAYS rays (under 4x as many; the whole frame where it has fewer)."""
    stride = max(1, int(math.sqrt(width * height / CALIBRATION_RAYS)))
    return -(-width // stride), -(-height // stride)


def pilot_image(scene, packed, quality, size=None):
    """The pilot's H x W x 4 image at ``quality`` (a renderer.quality.Quality): the scattered light alone on
    the pilot grid (or a grid of ``size``, (width, height)), rendered by the single-scattering driver with
    ``packed``'s scene records (BVHs, shadow maps), the background and the surfaces' colours blackened, so
    that it compiles nothing new."""
    return pilot_render(scene, packed, quality, size)[0]


def pilot_render(scene, packed, quality, size=None):
    """(image, counts): pilot_image's image and its per-pixel counts (renderer.single.render_single)."""
    width, height = size or pilot_size(scene.image.width, scene.image.height)
    small = replace(scene, image=replace(scene.image, width=width, height=height, spp=1))
    rec = packed.records
    surfaces = rec.surfaces
    if surfaces is not None:
        surfaces = surfaces._replace(colour=np.zeros_like(surfaces.colour))
    records = rec._replace(background=np.zeros((1, 3)), surfaces=surfaces)
    pilot = Packed(camera=pack_camera(small, 0), records=records, quadrature=quadrature(quality))
    image, _, counts = render_single(small, pilot, ((0, height), (0, width)), False)
    return image, counts


def light_scale(scene, packed, shadows=ShadowMode.EXACT) -> LightScale:
    """The frame's scattered-light scale, measured by the pilot at PILOT's preset (this module's docstring), with
    the frame's ``shadows``."""
    quality = replace(preset_quality(PILOT, scene.length_scale(), shadows), tol_t=packed.quadrature.tol_t)
    image = pilot_image(scene, packed, quality)
    rgb = image[..., :3]
    total = rgb.sum(axis=-1)
    return LightScale(mean=float(rgb.mean()), scale=float(np.sqrt(np.mean(total * total))),
                      width=image.shape[1], height=image.shape[0])


def a_twentieth_above(passed, failed, level):
    """``calibrated_level``'s default ``worth``: a try between two levels is rendered where it is at least a twentieth
    of a step above the level that passed."""
    return level >= passed + 0.05


def calibrated_level(error_at, target, worth=a_twentieth_above):
    """(level, its measured error or None): the coarsest level in [0, MAX_LEVEL] whose error_at(level) is at
    most SHARE x target, searched at whole steps from 1 (most scenes pass there: it spares level 0's render);
    where 1 fails, at a level below it aimed with GROWTH (where that passes, level 0's render is spared too); then
    between the last that passed and the first that failed (``_between``, each try where ``worth`` holds); where
    level 0 itself measures above that, a level between -1 (one step finer than the preset) and 0, or -2 where
    even the reference at -1 seems to err too much (``_finer``)."""
    limit = SHARE * target
    e_one = error_at(1.0)
    if e_one > limit:
        failed, e_failed = 1.0, e_one
        # aimed below 1 with the ladder's own growth: where it passes, level 0's render is spared
        aimed = 1.0 - math.log(e_one / (AIM * limit)) / math.log(GROWTH)
        if aimed > 0.0:
            e_aimed = error_at(aimed)
            if e_aimed <= limit:
                return _between(error_at, aimed, e_aimed, 1.0, e_one, limit, worth)
            failed, e_failed = aimed, e_aimed
        e_zero = error_at(0.0)
        if e_zero > limit:
            return _finer(error_at, e_one, e_zero, limit)
        return _between(error_at, 0.0, e_zero, failed, e_failed, limit, worth)
    last, e_last = 1.0, e_one
    while last < MAX_LEVEL:
        e = error_at(last + 1.0)
        if e > limit:
            return _between(error_at, last, e_last, last + 1.0, e, limit, worth)
        last, e_last = last + 1.0, e
    return last, e_last


def _finer(error_at, e_one, e_zero, limit):
    """(level, error or None) where level 0 measured e_zero above ``limit`` (and level 1 e_one): the level in
    (-1, 0) where the error, growing by ``growth`` a step, reaches 0.9 x limit, if its own error passes; growth is
    first e_one / e_zero, then refitted from e_zero and each try that failed (at most BETWEEN_TRIES tries; at least
    1.5x a step). Else -1, the calibration's reference, unmeasured. Its own error is then extrapolated: the error
    grew e_one / e_zero from level 0 to 1, so the reference errs about e_zero times e_zero / e_one (at most
    e_zero / 1.5). Where that is above the limit too, the frame goes one step finer still, to -2, unmeasured.
    (Keeping level 0 wherever it stayed within the whole target left the suite's rotated_side at `fine` at 0.95 of
    its target once the steps grew with depth; keeping -1 left generated_grazing at `draft` at 0.88 of its target
    once the Gauss test counted a tenth of the tail, where this extrapolation put the reference at 2.4e-3 and it
    measured 2.65e-3. A single try aimed with a growth of 3 missed the shipped generated cumulus at 512 x 512 by 9 %,
    and the frame fell back to -1: 14.6 s against 12.3 s before.)"""
    measured = max(e_one / e_zero, 1.5)
    growth = measured
    level, e_level = 0.0, e_zero
    for _ in range(BETWEEN_TRIES):
        level = max(-1.0, level + math.log(0.9 * limit / e_level) / math.log(growth))
        if level <= -0.95:
            break
        e = error_at(level)
        if e <= limit:
            return level, e
        growth = max((e_zero / e) ** (1.0 / -level), 1.5)
        e_level = e
    return (-2.0 if e_zero / measured > limit else -1.0), None


def _between(error_at, passed, e_passed, failed, e_failed, limit, worth):
    """(level, error): the coarsest level found between ``passed`` and ``failed`` whose error is at most
    ``limit``, by at most BETWEEN_TRIES steps of regula falsi on the log of the error, each aimed at AIM x
    ``limit``, or NARROW_AIM x ``limit`` where the two are at most NARROW apart (aimed at the limit itself, a
    curved error lands just above it and the step is lost; between close levels the log of the error is nearly
    straight); else ``passed``. A try is rendered only where worth(passed, failed, level) holds."""
    for _ in range(BETWEEN_TRIES):
        aim = (NARROW_AIM if failed - passed <= NARROW else AIM) * limit
        if not 0.0 < e_passed < aim < e_failed:
            break
        level = passed + (failed - passed) * math.log(aim / e_passed) / math.log(e_failed / e_passed)
        if not worth(passed, failed, level):
            break
        e = error_at(level)
        if e <= limit:
            passed, e_passed = level, e
        else:
            failed, e_failed = level, e
        if failed - passed < 0.1:
            break
    return passed, e_passed


def calibrate(scene, packed, quality, scale, preset):
    """(the frame's Quality, its LightScale with the level): LADDER's settings, with ``quality``'s scale and
    shadow mode, at the calibrated level for ``preset``'s target (a renderer.quality.Preset; module docstring;
    levels relative to the preset's start)."""
    target = preset.target
    size = calibration_size(scene.image.width, scene.image.height)
    on_ladder = preset_quality(LADDER, scene.length_scale())
    ladder = replace(quality, **{key: getattr(on_ladder, key) for key in QUADRATURE_KEYS})
    start = preset.start
    # (level, exact) -> the grid's image and its per-pixel counts (nodes, exact rays, lookups, trusted lookups): a
    # search restarted with exact rays reuses its renders
    images = {}
    counts = {}

    def render_grid(q, exact):
        """(the grid's scattered light as float64, its per-pixel counts) at Quality q (with exact shadow rays)."""
        image, grid_counts = pilot_render(scene, packed, replace(q, shadows=ShadowMode.EXACT) if exact else q, size)
        return image[..., :3].astype(np.float64), grid_counts

    # with hybrid shadows the reference traces exact shadow rays: a hybrid map's error, which need not shrink
    # with the tolerance (a puff between texel rays), then counts in full in every level's measure (``shadows:
    # map`` always interpolates: its error is the user's choice, and the calibration scales the quadrature)
    hybrid = quality.shadows == ShadowMode.HYBRID
    images[-1.0, hybrid], counts[-1.0, hybrid] = render_grid(scaled_quality(ladder, start - 1.0), hybrid)
    reference = images[-1.0, hybrid]
    mean = float(reference.mean())
    if mean <= 0.0:
        return quality, scale
    # where most of the reference's steps took the Kronrod nodes, the search runs on the shorter ladder
    shorter = kronrod_share(counts[-1.0, hybrid]) > KRONROD_SHARE

    def settings(level):
        """The settings at ``level``: on the ladder, or on the shorter ladder (steps SHORTER_TAU as thick,
        SHORTER_LEVEL steps coarser)."""
        if not shorter:
            return scaled_quality(ladder, start + level)
        q = scaled_quality(ladder, start + level + SHORTER_LEVEL)
        return replace(q, max_tau=q.max_tau * SHORTER_TAU)

    def pilot_at(level, exact=False):
        if (level, exact) not in images:
            images[level, exact], counts[level, exact] = render_grid(settings(level), exact)
        return images[level, exact]

    def rel_rmse(image):
        return float(np.sqrt(np.mean((image - reference) ** 2))) / mean

    # a hybrid grid that trusts fewer than MIN_TRUSTED of its lookups makes the frame trace exact rays: the search
    # then starts again with exact rays, so that the level is not chosen by the error of lookups the frame refuses
    exact_from = []  # the share trusted where the search turned to exact rays

    def error_at(level):
        image = pilot_at(level, exact=bool(exact_from))
        if hybrid and not exact_from:
            share = trusted_share(counts[level, False])
            if share < MIN_TRUSTED:
                exact_from.append(share)
                raise _ExactRays
        return rel_rmse(image)

    def nodes_at(level):
        return float(counts[level, bool(exact_from)][..., COUNT_NODES].sum())

    grid_rays = size[0] * size[1]
    frame_rays = scene.image.width * scene.image.height

    def worth(passed, failed, level):
        """Whether the grid's render at ``level`` may pay for itself: the share of the frame's nodes it would spare,
        at the rate the grid's nodes fell from ``passed`` to ``failed``, times the frame's rays over the grid's, is at
        least WORTH (it costs about one grid's nodes)."""
        n_passed, n_failed = nodes_at(passed), nodes_at(failed)
        if not 0.0 < n_failed < n_passed:
            return False
        spared = 1.0 - (n_failed / n_passed) ** ((level - passed) / (failed - passed))
        return spared * frame_rays / grid_rays >= WORTH

    try:
        level, predicted = calibrated_level(error_at, target, worth)
    except _ExactRays:
        level, predicted = calibrated_level(error_at, target, worth)
    # (the fallbacks -1 and -2, unmeasured, stay on the ladder: -1 is the reference itself)
    took_shorter = shorter and predicted is not None
    chosen = settings(level) if took_shorter else scaled_quality(ladder, start + level)
    trusted = None
    if hybrid:
        # (level -1 is the exact reference's render: no lookups, so exact rays; -2, finer still, likewise)
        trusted = exact_from[0] if exact_from else trusted_share(counts[max(level, -1.0), level <= -1.0])
        if trusted < MIN_TRUSTED:  # the lookups would cost more than they spare: exact rays (only more exact)
            chosen = replace(chosen, shadows=ShadowMode.EXACT)
    # the frame's mean scattered radiance becomes the reference's: more rays at finer settings than the pilot's, whose
    # few rays can miss a small bright spot (a lamp inside a deck: 25x too dark at 64 x 48, and every estimate 25x high)
    return chosen, replace(scale, mean=mean, level=start + level, predicted=predicted, rays=grid_rays,
                           trusted=trusted, shorter=took_shorter)


def kronrod_share(counts):
    """The share of a grid's quadrature steps that took the Kronrod nodes, from its per-pixel counts."""
    tally = counts.sum(axis=(0, 1))
    return float(tally[COUNT_KRONROD] / tally[COUNT_STEPS]) if tally[COUNT_STEPS] > 0.0 else 0.0


class _ExactRays(Exception):
    """Raised by the calibration's search where a hybrid grid trusts too few lookups (``calibrate``)."""


def trusted_share(counts):
    """The share of a grid's map lookups it trusted, from its per-pixel counts (0 without lookups)."""
    tally = counts.sum(axis=(0, 1))
    return float(tally[3] / tally[2]) if tally[2] > 0.0 else 0.0


def pilot_quality(scene, packed, settings):
    """(the frame's Quality, its LightScale): the quadrature of ``settings`` (the frame's
    renderer.quality.FrameSettings) with the pilot's scattered-light scale, calibrated where settings.calibrate
    holds (single scattering or the approximate mode, whose quadrature is single scattering's with a smoother
    source, at a preset with a target, no quadrature key given explicitly, no ``render.error``: that mode refines
    on its own estimate, and ``render.calibrate`` on; multiple scattering is not: its Monte Carlo paths are its
    error)."""
    scale = light_scale(scene, packed, settings.shadows)
    quality = replace(settings.quadrature, light_scale=scale.scale)
    if scale.scale > 0.0 and settings.calibrate:
        return calibrate(scene, packed, quality, scale, settings.calibration_preset())
    return quality, scale
