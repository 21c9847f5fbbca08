"""Quality settings (``render:`` in the scene, docs/model.md §9). ``quality`` picks a preset; any of the other
keys overrides that preset's value:

=============== ======= ======= ======= ========== ====================================================
key             draft   default fine    reference  meaning
=============== ======= ======= ======= ========== ====================================================
(target)        3e-3    1e-3    3e-4    -          the image's RMSE against the converged image over its
                                                   mean scattered radiance, that the preset keeps
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
transmittance e^-u adds its error to the image times e^-u, so the step limits grow as e^(growth u) (issue #23
item 3: on the 77-ball cumulus at 256 x 256 this took 1.6-1.9x fewer nodes at equal error, on the 1,200-ball
bank none; docs/error_estimate.md "Steps that grow with depth"); ``reference`` keeps equal steps. The optical
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
from dataclasses import dataclass


from ..scene.model import RenderSettings
from ..scene.vocabulary import HYBRID_SHARE, QUALITIES

#: the quadrature presets (issue #23): each is a target of the image's RMSE over its mean scattered radiance
#: (draft 3e-3, default 1e-3, fine 3e-4), with ``tolerance`` equal to the target (relative to the pilot's
#: scattered-light scale). max_tau and cutoff were chosen as the cheapest on the 14 scenes of the accuracy
#: suite that kept every scene at or below half its target (docs/error_estimate.md "Presets"); the six
#: black-background scenes of the suite were held out of that choice
PRESETS = {
    "draft": dict(tolerance=3e-3, max_tau=1.0, max_length=1 / 4, max_angle=0.4, cutoff=1e-4, root_tolerance=1e-9,
                  growth=1.0),
    "default": dict(tolerance=1e-3, max_tau=0.5, max_length=1 / 16, max_angle=0.2, cutoff=1e-4,
                    root_tolerance=1e-9, growth=1.0),
    "fine": dict(tolerance=3e-4, max_tau=0.175, max_length=1 / 32, max_angle=0.1, cutoff=1e-5, root_tolerance=1e-9,
                 growth=1.0),
    "reference": dict(tolerance=1e-6, max_tau=0.1, max_length=1 / 128, max_angle=0.025, cutoff=0.0,
                      root_tolerance=1e-9, growth=0.0),
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
    #: the frame's scattered-light scale (renderer.pilot; RGB sum): ``tolerance`` is relative to it; 0 where
    #: it is not measured, and then relative to each ray's brightest J
    light_scale: float = 0.0
    #: the share of ``tolerance`` a shadow map's interpolation may take at a node before an exact shadow ray
    #: replaces it: HYBRID_SHARE for ``shadows: hybrid``, inf for ``map`` (always trusted), 0 for ``exact``
    map_share: float = 0.0
    #: the step limits at view depth u are max_tau and max_length times e^(growth u) (the preset's; 0: equal steps)
    growth: float = 0.0


def resolve_quality(settings: RenderSettings, diagonal: float) -> Quality:
    """The settings of ``settings``' preset with its explicit keys; lengths relative to ``diagonal``, the
    scene's length L (Scene.length_scale)."""
    preset = PRESETS[settings.quality]
    pick = lambda key: preset[key] if getattr(settings, key) is None else getattr(settings, key)  # noqa: E731
    max_length = preset["max_length"] * diagonal if settings.max_length is None else settings.max_length
    return Quality(tolerance=float(pick("tolerance")), max_tau=float(pick("max_tau")), max_length=float(max_length),
                   max_angle=float(pick("max_angle")), cutoff=float(pick("cutoff")),
                   tol_t=float(pick("root_tolerance")) * diagonal,
                   map_share={"map": math.inf, "hybrid": HYBRID_SHARE}.get(settings.shadows, 0.0),
                   growth=float(preset["growth"]))


def scene_quality(scene) -> Quality:
    return resolve_quality(scene.render, scene.length_scale())
