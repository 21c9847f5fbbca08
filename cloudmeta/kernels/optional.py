"""What a scene may lack: opaque surfaces, shadow maps and the approximate mode's radiance grid, compiled only
for the scenes that have them.

cloudmeta.renderer.pack.scene_records gives a scene with neither surfaces nor shadow maps None in their places
(``SceneRecords.surfaces`` and ``Lights.maps``). The helpers here take that record and pick their
implementation by its type when numba compiles the caller (``@overload``): with None they compile to
the trivial answer (no hit, not blocked, no map), so none of the surface or shadow-map code is compiled
for such a scene. With the records they call the real code. A scene has either both records or neither:
each kernel is compiled in at most two versions (with and without), not four.

The radiance grid (``SceneRecords.radiance``, the approximate mode's method grid) is None in every other
scene: ``grid_light`` then compiles to black, and none of kernels.fluence is compiled.

Each helper is also a plain Python function with the same meaning, for calls from Python.
"""
import numpy as np
from numba.core import types
from numba.extending import overload

from .config import OVERLOAD
from .bvh import misses_root_boxes
from .fluence import grid_scattered
from .shadowmap import map_optical_depth
from .surfaces import first_surface_hit, n_surfaces, surfaces_block


def _absent(record_type):
    return isinstance(record_type, types.NoneType)


def misses_surfaces(o, d, surf):
    """Whether the ray misses the root box of every surface (always, for None)."""
    return True if surf is None else misses_root_boxes(o, d, surf.bvh)


def surface_hit(o, d, surf, tol_t, work):
    """The ray's first surface hit: (scratch, t_hit, surface), (scratch, inf, -1) on a miss."""
    if surf is None or n_surfaces(surf) == 0:
        return work.scratch, np.inf, -1
    return first_surface_hit(o, d, surf, tol_t, work.scratch, work.cand, work.stack)


def surfaces_blocking(x, l, tmax, surf, tol_t, scratch, work):
    """Whether a surface meets the shadow ray x + t l, t in [0, tmax]: (scratch, blocked)."""
    if surf is None or n_surfaces(surf) == 0:
        return scratch, False
    return surfaces_block(x, l, tmax, surf, tol_t, scratch, work.cand, work.stack)


def surface_balls(surf):
    """How many balls the surfaces have (0 for None)."""
    return 0 if surf is None else surf.centers.shape[0]


def light_map(maps, li):
    """The shadow map of light li, or -1 for exact shadow rays."""
    return -1 if maps is None else maps.map_of[li]


def map_depth(x, maps, mi):
    """(tau, tau_lo, tau_hi) towards the light of map mi (>= 0) at x, from its shadow map
    (shadowmap.map_optical_depth)."""
    return map_optical_depth(x, maps, mi)


@overload(misses_surfaces, **OVERLOAD)
def _misses_surfaces(o, d, surf):
    if _absent(surf):
        return lambda o, d, surf: True
    return lambda o, d, surf: misses_root_boxes(o, d, surf.bvh)


@overload(surface_hit, **OVERLOAD)
def _surface_hit(o, d, surf, tol_t, work):
    if _absent(surf):
        return lambda o, d, surf, tol_t, work: (work.scratch, np.inf, -1)

    def hit(o, d, surf, tol_t, work):
        if n_surfaces(surf) > 0:
            return first_surface_hit(o, d, surf, tol_t, work.scratch, work.cand, work.stack)
        return work.scratch, np.inf, -1
    return hit


@overload(surfaces_blocking, **OVERLOAD)
def _surfaces_blocking(x, l, tmax, surf, tol_t, scratch, work):
    if _absent(surf):
        return lambda x, l, tmax, surf, tol_t, scratch, work: (scratch, False)

    def blocking(x, l, tmax, surf, tol_t, scratch, work):
        if n_surfaces(surf) > 0:
            return surfaces_block(x, l, tmax, surf, tol_t, scratch, work.cand, work.stack)
        return scratch, False
    return blocking


@overload(surface_balls, **OVERLOAD)
def _surface_balls(surf):
    if _absent(surf):
        return lambda surf: 0
    return lambda surf: surf.centers.shape[0]


@overload(light_map, **OVERLOAD)
def _light_map(maps, li):
    if _absent(maps):
        return lambda maps, li: -1
    return lambda maps, li: maps.map_of[li]


@overload(map_depth, **OVERLOAD)
def _map_depth(x, maps, mi):
    if _absent(maps):
        return lambda x, maps, mi: (0.0, 0.0, 0.0)  # never asked: light_map gives -1 without maps
    return lambda x, maps, mi: map_optical_depth(x, maps, mi)


def grid_light(radiance, x, m):
    """(r, g, b): the light medium m scatters at x towards the camera per unit sigma_s, from the radiance grid
    (kernels.fluence.grid_scattered); black without one (None)."""
    if radiance is None:
        return 0.0, 0.0, 0.0
    return grid_scattered(radiance, x, m)


@overload(grid_light, **OVERLOAD)
def _grid_light(radiance, x, m):
    if _absent(radiance):
        return lambda radiance, x, m: (0.0, 0.0, 0.0)
    return lambda radiance, x, m: grid_scattered(radiance, x, m)


def has_grid(radiance):
    """Whether the scene has a radiance grid (a compile-time constant in the kernels)."""
    return radiance is not None


@overload(has_grid, **OVERLOAD)
def _has_grid(radiance):
    if _absent(radiance):
        return lambda radiance: False
    return lambda radiance: True
