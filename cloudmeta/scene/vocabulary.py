"""Every name a scene file and the command line may use, defined once: the kinds (from kernels.kinds,
where their ids are), the quality presets' names, shadow and scattering modes, and the defaults
that more than one floor needs. cloudmeta.scene validates against these, the CLI builds its ``choices=``
from them, and the renderer keys its tables by them (and asserts it covers each)."""
from enum import StrEnum

from ..kernels.kinds import DENSITY_MODES as _DENSITY_IDS
from ..kernels.kinds import FALLOFFS as _FALLOFF_IDS
from ..kernels.kinds import LIGHTS as _LIGHT_IDS
from ..kernels.kinds import PHASES as _PHASE_IDS
from ..kernels.records import SHADOW_MODES as _SHADOW_IDS

#: ball kernels (falloffs k(u)), density modes, phase functions and light types, as a scene names them
FALLOFFS = tuple(_FALLOFF_IDS)
DENSITY_MODES = tuple(_DENSITY_IDS)
PHASES = tuple(_PHASE_IDS)
LIGHT_TYPES = tuple(_LIGHT_IDS)

#: phase type -> its parameters (all required when the type is named)
PHASE_PARAMS = {"isotropic": (), "hg": ("g",), "double_hg": ("g1", "g2", "w"), "rayleigh": ()}
assert tuple(PHASE_PARAMS) == PHASES

#: render.quality: the presets (renderer.quality.PRESETS holds what each means: its target, quadrature,
#: calibration start and grid)
QUALITIES = ("draft", "default", "fine", "reference")


class ShadowMode(StrEnum):
    """render.shadows: exact shadow rays; light-space maps for directional lights; or maps where their own
    bound on their error keeps the quality's tolerance and exact shadow rays elsewhere (hybrid). A str, so a
    scene's ``shadows == "map"`` still holds; ``kernel_id`` is what kernels.records.Quadrature.shadow_mode holds."""
    EXACT = "exact"
    MAP = "map"
    HYBRID = "hybrid"

    @property
    def builds_maps(self):
        """Whether a frame in this mode builds shadow maps (for its directional lights)."""
        return self is not ShadowMode.EXACT

    @property
    def kernel_id(self):
        return _SHADOW_IDS[self.value]


SHADOW_MODES = tuple(mode.value for mode in ShadowMode)
assert SHADOW_MODES == tuple(_SHADOW_IDS), "every shadow mode has a kernel id"
#: render.shadows that build shadow maps
MAP_SHADOWS = tuple(mode.value for mode in ShadowMode if mode.builds_maps)
#: the share of the quality's tolerance a hybrid map's interpolation may take at a node (renderer.pack.quadrature)
HYBRID_SHARE = 0.25
#: render.scattering: the estimators (renderer.frame.ESTIMATORS)
SCATTERING_MODES = ("single", "multiple", "approximate")
#: render.method of the approximate mode (renderer.approximate)
APPROXIMATE_METHODS = ("octaves", "grid", "shared")
#: render.grid.deposit: where the grid method's photons deposit (docs/approximate.md)
GRID_DEPOSITS = ("flights", "collisions")
#: render.octaves when not given: (count, a, b, c), fitted by validation/accuracy/approximate.py on scenes
#: that are not the ones its error is reported on (docs/approximate.md)
OCTAVES = (4, 0.5, 0.6, 0.45)
#: texels per side of a shadow map when render.shadow_map is not given
SHADOW_MAP_RESOLUTION = 384

#: CSV headers of a balls file -> does it describe ellipsoids
CSV_HEADERS = {("x", "y", "z", "radius", "weight"): False,
               ("x", "y", "z", "rx", "ry", "rz", "ax", "ay", "az", "weight"): True}

#: output.display: the PNG's display transform (cloudmeta.api.display): the ACES output transform through
#: OpenColorIO, or linear times the exposure under the sRGB curve
DISPLAYS = ("aces", "raw")
#: output.white_balance besides a CIE illuminant's name: balance to the scene's light, or not at all
WHITE_BALANCE_WORDS = ("scene", "none")
#: output.exposure: chosen from the image (cloudmeta.api.display.auto_exposure), else a number of stops
AUTO_EXPOSURE = "auto"
