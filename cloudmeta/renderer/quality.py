"""Quality settings (``render:`` in the scene, docs/model.md §9). ``quality`` picks a preset; any of the other
keys overrides that preset's value:

=============== ======= ======= ======= ========== ====================================================
key             draft   default fine    reference  meaning
=============== ======= ======= ======= ========== ====================================================
tolerance       4e-3    1.5e-3  5e-4    1e-6       error allowed in the light J per unit of optical
                                                   depth (weighted by the view transmittance), relative
                                                   to the brightest J on the ray
max_tau         4.0     2.0     0.7     0.1        thickest step, in optical depth
max_length      1/4     1/16    1/32    1/128      longest step, as a fraction of the scene's length L
                                                   (an explicit ``max_length`` is in scene units)
max_angle       0.4     0.2     0.1     0.025      widest angle (radians) of a step seen from a point light
cutoff          1e-2    1e-3    1e-4    0          stop shading once the view transmittance is below
root_tolerance  1e-9    1e-9    1e-9    1e-9       root tolerance, relative to the scene's length L
=============== ======= ======= ======= ========== ====================================================

The scene's length L is its bounding-box diagonal, unless some of its geometry lies far from the rest:
then the largest diagonal of the groups that far gaps separate (Scene.length_scale), so that a stray
ball far away does not loosen the tolerances of the cloud a ray meets.

Each step of the in-scattering integral takes 7 Gauss nodes; where the two highest Legendre coefficients
of J on them exceed the tolerance, the 8 Kronrod nodes join (G7-K15), and where the two rules still
disagree by more than the tolerance allows the step is halved (at most 6 times). The optical depth, the
view transmittance and the shadow transmittance are exact at every setting; the settings only trade the
quadrature of the in-scattering integral against time.

Opaque surfaces (``surfaces:``, docs/model.md §6) are exact at every setting too: the first root of each
surface's field along the camera ray, the analytic normal, and shadow rays that stop at the first surface
they meet. With ``shadows: map`` the maps hold the media only; surfaces still block every shadow ray
exactly (a first-root test per node and light), so their shadows are as sharp as with ``exact``. A surface
seen through less than ``cutoff`` of view transmittance is not shaded (like the media behind it).
"""
from __future__ import annotations

from dataclasses import dataclass


from ..scene.schema import RenderSettings
from ..scene.vocabulary import QUALITIES

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
assert tuple(PRESETS) == QUALITIES, "every quality name of the scene's vocabulary has a preset"


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
    """The settings of ``settings``' preset with its explicit keys; lengths relative to ``diagonal``, the
    scene's length L (Scene.length_scale)."""
    preset = PRESETS[settings.quality]
    pick = lambda key: preset[key] if getattr(settings, key) is None else getattr(settings, key)  # noqa: E731
    max_length = preset["max_length"] * diagonal if settings.max_length is None else settings.max_length
    return Quality(tolerance=float(pick("tolerance")), max_tau=float(pick("max_tau")), max_length=float(max_length),
                   max_angle=float(pick("max_angle")), cutoff=float(pick("cutoff")),
                   tol_t=float(pick("root_tolerance")) * diagonal)


def scene_quality(scene) -> Quality:
    return resolve_quality(scene.render, scene.length_scale())
