"""The render settings of a frame, each decided once (``render:`` in the scene, docs/model.md §9).

``resolve_settings`` turns the scene's ``render:`` into one FrameSettings where the frame starts: the preset
(PRESETS, the one table of what each ``quality`` means: its target, its quadrature, its calibration start on
the ladder, its grid), the shadow mode (a vocabulary.ShadowMode), the resolved quadrature (Quality), whether
the pilot calibrates it, and the grid method's cells and photons. The drivers read its fields; the kernels
read its quadrature as records.Quadrature, with the shadow mode as an explicit id. ``quality`` picks a
preset; any of the other keys overrides that preset's value:

=============== ======= ======= ======= ========== ====================================================
key             draft   default fine    reference  meaning
=============== ======= ======= ======= ========== ====================================================
(target)        3e-3    1e-3    3e-4    -          the image's RMSE against the converged image over its
                                                   mean scattered radiance, that the preset keeps
                                                   (the shared method's quadrature: SHARED_QUADRATURE of
                                                   the paths target below, 0.03 / 0.009 / 0.003)
tolerance       3e-3    1e-3    3e-4    1e-6       error allowed in the light J per unit of optical
                                                   depth (weighted by the view transmittance), relative
                                                   to the frame's scattered-light scale (renderer.pilot)
max_tau         1.0     0.5     0.175   0.1        thickest step, in optical depth
max_length      1/4     1/16    1/32    1/128      longest step, as a fraction of the scene's length L
                                                   (an explicit ``max_length`` is in scene units)
max_angle       0.4     0.2     0.1     0.025      widest angle (radians) of a step seen from a point light
cutoff          1e-4    1e-4    1e-5    0          stop shading once the view transmittance is below
root_tolerance  1e-9    1e-9    1e-9    1e-9       root tolerance, relative to the scene's length L
growth          1       1       1       0          the step limits max_tau and max_length grow as
                                                   e^(growth u) with the view's optical depth u (not a key)
(start)         1       0       -1      -          the calibration's first level on its ladder
                                                   (renderer.calibrate.LADDER)
(grid)          24^3    40^3    56^3    56^3       the grid method's cells and photons
                2^21    2^23    2^25    2^25       (renderer.fluence; ``render.grid`` overrides)
(shared)        8       4       2       1          the shared method's stride (at a longer side of 512
                                                   pixels, scaled with it; renderer.shared;
                                                   ``render.shared``)
(cache)         5       6       8       none       the shared method's tails trace the orders up to this
                48^3    48^3    48^3               one and read the cache of the rest, built by this
                2^20    2^21    2^22               many cells and photons (renderer.fluence;
                0.15    0.05    0.05               ``render.shared.cache`` sets the order, 0: none)
                                                   where the orders beyond it carry at least this share
                                                   of the light (renderer.shared.deep_share): a preset
                                                   with more tails per photon gains at a lower share
(paths)         0.10    0.03    0.01    0.003      multiple scattering: the relative RMSE of the paths'
                                                   part against the scattered light that the planned
                                                   paths aim at (renderer.multiple; ``render.ms_spp``
                                                   gives a fixed count instead), and that the shared
                                                   method's planned tails aim at (``render.shared.tails``
                                                   gives a fixed count instead)
=============== ======= ======= ======= ========== ====================================================

The scene's length L is its bounding-box diagonal, unless some of its geometry lies far from the rest:
then the largest diagonal of the groups that far gaps separate (Scene.length_scale), so that a stray
ball far away does not loosen the tolerances of the cloud a ray meets.

The pilot (renderer.pilot) renders the frame's scattered light alone on a coarse grid at draft before the
frame; the RMS of its r + g + b is the scale the tolerance is relative to, so that one absolute tolerance
holds over the frame whatever its share of sky, cloud or wisps. Where J is the same everywhere (ambient
light alone, one albedo), the integral is closed form and takes no nodes.

Each step of the in-scattering integral takes 7 Gauss nodes; where the two highest Legendre coefficients
of J on them exceed the tolerance (a tenth of them counts where the nodes' shadow rays show no fold of the
light's optical depth: kernels.single.TAIL_SHARE), the 8 Kronrod nodes join (G7-K15), and where the two rules
still disagree by more than the tolerance allows the step is split (at most 6 halvings deep). A step seen through a view
transmittance e^-u adds its error to the image times e^-u, so the step limits grow as e^(growth u) (on the 77-ball cumulus at 256 x 256 this took 1.6-1.9x fewer nodes at equal error, on the 1,200-ball
bank none; CHANGELOG.md "Steps that grow with depth"); ``reference`` keeps equal steps. The optical
depth, the view transmittance and the shadow transmittance are exact at every setting; the settings only trade the
quadrature of the in-scattering integral against time.

Opaque surfaces (``surfaces:``, docs/model.md §6) are exact at every setting too: the first root of each
surface's field along the camera ray, the analytic normal, and shadow rays that stop at the first surface
they meet. With ``shadows: hybrid`` a node takes T_l from the map only where the spread of the four texels
around it, in the light it scatters, is within HYBRID_SHARE of the tolerance (kernels.lighting.light_at_node).
With ``shadows: map`` or ``hybrid`` the maps hold the media only; surfaces still block every shadow ray
exactly (a first-root test per node and light), so their shadows are as sharp as with ``exact``. A surface
seen through less than ``cutoff`` of view transmittance is not shaded (like the media behind it).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import NamedTuple

from ..kernels.fluence import COLLISIONS, FLIGHTS
from ..scene.model import RenderSettings
from ..scene.vocabulary import QUALITIES, SHADOW_MAP_RESOLUTION, ShadowMode


class SharedSettings(NamedTuple):
    """The approximate mode's shared method (renderer.shared): the preset's stride where render.shared leaves it
    out; render.shared.tails, else None and the tails are planned to ``target``, the preset's paths target
    (renderer.shared.plan_tails); the cache of the deep orders (renderer.fluence.fluence_cache): the order the
    tails trace up to (render.shared.cache, else the preset's; 0: no cache), its cells and photons; cache_chosen:
    whether the scene set the order, else the preset's cache is left out where the orders beyond it carry less than
    cache_min_share of the light (renderer.shared.deep_share)."""
    stride: int
    tails: int | None
    target: float
    cache_order: int
    cache_cells: int
    cache_photons: int
    cache_chosen: bool = False
    cache_min_share: float = 0.0


@dataclass(frozen=True)
class Preset:
    """What one ``quality`` means, in every mode (this module's table)."""
    #: the image's relative RMSE against the converged image that the preset keeps (docs/error_estimate.md);
    #: None: no target (``reference``), and then no calibration
    target: float | None
    #: the quadrature's settings, as the table above gives them (max_length relative to the scene's length L)
    quadrature: dict
    #: the calibration's first level on its ladder (renderer.calibrate; None: not calibrated)
    start: float | None
    #: the approximate mode's grid method: (cells, as the side of a cube of cells of the media's box's volume;
    #: photons) (renderer.fluence)
    grid: tuple
    #: the approximate mode's shared method: pixels between the coarsest sample rays at a longer side of
    #: SHARED_SIDE (renderer.shared; its tails are planned to ``paths_target``)
    shared: int
    #: the shared method's cache of the deep orders: (order, cells, photons, the least share of the light beyond the
    #: order for which it is built); order 0: none (renderer.fluence.fluence_cache, renderer.shared.deep_share)
    cache: tuple = (0, 48, 1 << 20, 0.0)
    #: multiple scattering: the relative RMSE of the image's Monte Carlo part, against the frame's scattered
    #: light, that the planned paths aim at (renderer.multiple); None: no plan, ``render.ms_spp`` or its fallback
    paths_target: float | None = None


#: the presets: each is a target of the image's RMSE over its mean scattered radiance
#: (draft 3e-3, default 1e-3, fine 3e-4), with ``tolerance`` equal to the target (relative to the pilot's
#: scattered-light scale). max_tau and cutoff were chosen as the cheapest on the 14 scenes of the accuracy
#: suite that kept every scene at or below half its target (docs/settings.md "The presets"); the six
#: black-background scenes of the suite were held out of that choice. The calibration starts draft one step
#: coarser than default's settings and fine one finer (draft's fixed settings are about one step coarser than
#: default's, fine's one finer; on the cumulus at 256 x 256 fine's own settings, calibrated, took 3.5 s where
#: default's reached lower error in 2.3 s). ``reference`` has no target: it is neither calibrated nor given a
#: grid of its own (fine's)
PRESETS = {
    "draft": Preset(paths_target=0.10, target=3e-3, start=1.0, grid=(24, 1 << 21), quadrature=dict(
        tolerance=3e-3, max_tau=1.0, max_length=1 / 4, max_angle=0.4, cutoff=1e-4, root_tolerance=1e-9, growth=1.0),
        shared=8, cache=(5, 48, 1 << 20, 0.15)),
    "default": Preset(paths_target=0.03, target=1e-3, start=0.0, grid=(40, 1 << 23), quadrature=dict(
        tolerance=1e-3, max_tau=0.5, max_length=1 / 16, max_angle=0.2, cutoff=1e-4, root_tolerance=1e-9,
        growth=1.0), shared=4, cache=(6, 48, 1 << 21, 0.05)),
    "fine": Preset(paths_target=0.01, target=3e-4, start=-1.0, grid=(56, 1 << 25), quadrature=dict(
        tolerance=3e-4, max_tau=0.175, max_length=1 / 32, max_angle=0.1, cutoff=1e-5, root_tolerance=1e-9,
        growth=1.0), shared=2, cache=(8, 48, 1 << 22, 0.05)),
    "reference": Preset(paths_target=0.003, target=None, start=None, grid=(56, 1 << 25), quadrature=dict(
        tolerance=1e-6, max_tau=0.1, max_length=1 / 128, max_angle=0.025, cutoff=0.0, root_tolerance=1e-9,
        growth=0.0), shared=1),
}
assert tuple(PRESETS) == QUALITIES, "every quality name of the scene's vocabulary has a preset"
#: the shared method's quadrature (its exact order 1) is calibrated to this share of the preset's paths target
#: instead of the preset's own target: the calibration keeps it at most half that (renderer.calibrate SHARE), so it
#: takes at most (0.5 x 0.3)^2 = 2.25 % of the image's error variance, where the preset's own target (draft 3e-3
#: against the tails' 0.10) cost up to two thirds of the frame's time for 0.02 % of it (docs/approximate.md)
SHARED_QUADRATURE = 0.3
#: the quadrature keys that, given explicitly, turn calibration off (the user chose the settings)
QUADRATURE_KEYS = ("tolerance", "max_tau", "max_length", "max_angle", "cutoff")


@dataclass(frozen=True)
class Quality:
    """The resolved quadrature settings of one render (all lengths in scene units)."""
    tolerance: float
    max_tau: float
    max_length: float
    max_angle: float
    cutoff: float
    tol_t: float
    #: the frame's scattered-light scale (renderer.pilot; RGB sum): ``tolerance`` is relative to it; 0 where
    #: it is not measured, and then relative to each ray's brightest J
    light_scale: float = 0.0
    #: where the nodes' shadow transmittance comes from: with HYBRID a map's interpolation may take
    #: vocabulary.HYBRID_SHARE of the tolerance before an exact shadow ray replaces it (renderer.pack.quadrature)
    shadows: ShadowMode = ShadowMode.EXACT
    #: the step limits at view depth u are max_tau and max_length times e^(growth u) (the preset's; 0: equal steps)
    growth: float = 0.0


@dataclass(frozen=True)
class FrameSettings:
    """Every render setting of a frame, decided once from the scene's ``render:`` (``resolve_settings``)."""
    quality: str                 #: the preset's name
    preset: Preset               #: PRESETS[quality]
    shadows: ShadowMode
    #: texels per side of each directional light's shadow map (render.shadow_map, else the default; read where
    #: ``shadows.builds_maps``)
    shadow_map: int
    #: the quadrature: the preset's settings with the scene's explicit keys, before the pilot's scale
    quadrature: Quality
    #: whether the pilot calibrates the quadrature (renderer.calibrate: single scattering or the approximate mode,
    #: a preset with a target, no quadrature key given, no render.error, render.calibrate on)
    calibrate: bool
    #: render.error: a target relative RMSE the quadrature is refined to (renderer.estimate), else None
    error: float | None
    #: the approximate mode's grid method: (cells, photons, deposit: kernels.fluence.FLIGHTS or COLLISIONS), the
    #: preset's where render.grid leaves them out; None in every other mode
    grid: tuple | None = field(default=None)
    #: the approximate mode's shared method (a SharedSettings); None in every other mode
    shared: SharedSettings | None = None
    #: multiple scattering: paths per pixel (render.ms_spp), or None where they are planned to ``paths_target``
    paths: int | None = None
    #: multiple scattering with planned paths: the relative RMSE they aim at (render.error where given, else the
    #: preset's); None in every other case
    paths_target: float | None = None

    @property
    def quadrature_target(self):
        """The relative RMSE that the calibration keeps the quadrature to: the preset's target, or with the shared
        method SHARED_QUADRATURE of its paths target (None: no target)."""
        if self.shared is None or self.preset.target is None:
            return self.preset.target
        return SHARED_QUADRATURE * float(self.preset.paths_target)

    @property
    def target(self):
        """The relative RMSE the frame aims at: render.error where given, else the quadrature's (None: none); with
        planned multiple-scattering paths, theirs (the paths' noise is then most of the image's error)."""
        if self.paths_target is not None:
            return self.paths_target
        return self.error if self.error is not None else self.quadrature_target

    def calibration_preset(self):
        """The preset with the target its calibration keeps (renderer.calibrate)."""
        return replace(self.preset, target=self.quadrature_target)


def resolve_quality(settings: RenderSettings, diagonal: float) -> Quality:
    """The settings of ``settings``' preset with its explicit keys; lengths relative to ``diagonal``, the
    scene's length L (Scene.length_scale)."""
    preset = PRESETS[settings.quality].quadrature
    pick = lambda key: preset[key] if getattr(settings, key) is None else getattr(settings, key)  # noqa: E731
    max_length = preset["max_length"] * diagonal if settings.max_length is None else settings.max_length
    return Quality(tolerance=float(pick("tolerance")), max_tau=float(pick("max_tau")), max_length=float(max_length),
                   max_angle=float(pick("max_angle")), cutoff=float(pick("cutoff")),
                   tol_t=float(pick("root_tolerance")) * diagonal, shadows=ShadowMode(settings.shadows),
                   growth=float(preset["growth"]))


def preset_quality(name, diagonal, shadows=ShadowMode.EXACT) -> Quality:
    """The preset ``name``'s own settings, no key of the scene's (the pilot's draft, the calibration's ladder)."""
    return resolve_quality(RenderSettings(quality=name, shadows=shadows), diagonal)


#: the image's longer side at which the shared method's presets take their own stride (renderer.shared)
SHARED_SIDE = 512


def shared_stride(stride, width, height):
    """The preset's stride at SHARED_SIDE, scaled with the image's longer side to the nearest power of 2 (at least 1):
    the sharing's bias goes with the angle between sample rays, not with their number of pixels."""
    scaled = stride * max(width, height) / SHARED_SIDE
    return int(max(1, 2 ** round(math.log2(scaled))))


def resolve_settings(scene) -> FrameSettings:
    """The frame's FrameSettings: every key of ``scene.render`` decided once."""
    r = scene.render
    preset = PRESETS[r.quality]
    grid = None
    if r.scattering == "approximate" and r.method == "grid":
        cells, photons, deposit = r.grid or (None, None, "flights")
        grid = (int(cells or preset.grid[0]), int(photons or preset.grid[1]),
                COLLISIONS if deposit == "collisions" else FLIGHTS)
    shared = None
    if r.scattering == "approximate" and r.method == "shared":
        stride, tails, order = (tuple(r.shared or ()) + (None, None, None))[:3]  # (stride, tails) still reads
        shared = SharedSettings(stride=int(stride or shared_stride(preset.shared, scene.image.width,
                                                                   scene.image.height)),
                                tails=None if tails is None else int(tails), target=float(preset.paths_target),
                                cache_order=int(preset.cache[0] if order is None else order),
                                cache_cells=int(preset.cache[1]), cache_photons=int(preset.cache[2]),
                                cache_chosen=order is not None, cache_min_share=float(preset.cache[3]))
    calibrate = (r.calibrate and r.scattering in ("single", "approximate") and preset.start is not None
                 and r.error is None and all(getattr(r, key) is None for key in QUADRATURE_KEYS))
    paths_target = None
    if r.scattering == "multiple" and r.ms_spp is None:
        paths_target = r.error if r.error is not None else preset.paths_target
    return FrameSettings(quality=r.quality, preset=preset, shadows=ShadowMode(r.shadows),
                         shadow_map=int(r.shadow_map or SHADOW_MAP_RESOLUTION),
                         quadrature=resolve_quality(r, scene.length_scale()), calibrate=bool(calibrate),
                         error=r.error, grid=grid, shared=shared, paths=r.ms_spp, paths_target=paths_target)
