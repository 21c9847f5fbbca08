"""Every kind the kernels switch on, with its scene name: the one place where an integer id is given.

The scene floor validates names against these tables (cloudmeta.scene.vocabulary) and the packing turns
names into ids (cloudmeta.renderer.pack); the kernels compare ids with the module-level constants below,
which numba folds at compile time. Adding a kind means one entry here and one branch in the kernel module
that evaluates it (falloffs: metaball, density modes: density, phases: optics, lights: lighting).
"""
#: falloff k(u) of a ball (docs/model.md §1): kernel name -> id (kernels.metaball)
FALLOFFS = {"wyvill6": 0, "murakami4": 1, "nishimura": 2, "blinn": 3}
WYVILL6 = FALLOFFS["wyvill6"]
MURAKAMI4 = FALLOFFS["murakami4"]
NISHIMURA = FALLOFFS["nishimura"]
BLINN = FALLOFFS["blinn"]

#: density mode rho(F) of a medium (docs/model.md §4): name -> id (kernels.density)
DENSITY_MODES = {"field": 0, "excess": 1, "uniform": 2}
DENSITY_FIELD = DENSITY_MODES["field"]
DENSITY_EXCESS = DENSITY_MODES["excess"]
DENSITY_UNIFORM = DENSITY_MODES["uniform"]

#: phase function of a medium (docs/model.md §4): name -> id (kernels.optics)
PHASES = {"isotropic": 0, "hg": 1, "double_hg": 2, "rayleigh": 3}
ISOTROPIC = PHASES["isotropic"]
HG = PHASES["hg"]
DOUBLE_HG = PHASES["double_hg"]
RAYLEIGH = PHASES["rayleigh"]

#: light kind (docs/model.md §5): name -> id (kernels.lighting)
LIGHTS = {"directional": 0, "point": 1}
DIRECTIONAL = LIGHTS["directional"]
POINT = LIGHTS["point"]
