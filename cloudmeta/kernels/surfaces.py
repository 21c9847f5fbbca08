"""Opaque metaball surfaces (MODEL.md §6) along one ray: where a camera ray first meets one, whether a
shadow ray is blocked, and the normal at a hit.

Each surface is its own blob, drawn as its isosurface F = T: the fields of two surfaces do not add. An
opaque surface needs only the first root of each blob (sweep.first_entry), never the segments after it.
The surfaces are packed as one ``surf`` tuple (see cloudmeta.render.PackedSurfaces.args):
(centers, frames, weights, start, kernel, threshold, blobbiness, colour,
 node_box, node_a, node_b, node_n, items, root) -- every surface's balls, per-surface parameters, its BVH.
"""
import math

import numpy as np
from numba import njit

from ..config import NJIT, NJIT_INLINE
from .bvh import bvh_candidates, bvh_point_candidates
from .metaball import ball_gradient
from .sweep import first_entry

#: a surface point's shadow ray starts this many root tolerances off the surface, along the normal: the
#: hit is within one root tolerance of the isosurface, so the shadow ray starts outside it and the
#: surface does not shadow itself
SHADOW_OFFSET = 8.0


@njit(**NJIT_INLINE)
def n_surfaces(surf):
    return surf[3].shape[0] - 1


@njit(**NJIT)
def surface_entry(o, d, tmax, surf, s, tol_t, scratch, cand, stack):
    """Where the ray o + t d, t in [0, tmax], first is inside surface s: 0 if it starts inside, inf if
    never. Returns (scratch, t)."""
    n_cand = bvh_candidates(o, d, 0.0, tmax, surf[13][s], surf[8], surf[9], surf[10], surf[11], surf[12],
                            stack, cand)
    if n_cand == 0:
        return scratch, np.inf
    return first_entry(o, d, 0.0, tmax, surf[0], surf[1], surf[2], surf[4][s], surf[6][s], surf[5][s], tol_t,
                       cand, n_cand, scratch)


@njit(**NJIT)
def first_surface_hit(o, d, surf, tol_t, scratch, cand, stack):
    """The camera ray's first hit over all surfaces: (scratch, t_hit, surface), (scratch, inf, -1) on a
    miss. Each surface after the first is traced only up to the nearest hit so far."""
    t_hit = np.inf
    s_hit = -1
    for s in range(n_surfaces(surf)):
        scratch, t = surface_entry(o, d, t_hit, surf, s, tol_t, scratch, cand, stack)
        if t < t_hit:
            t_hit = t
            s_hit = s
            if t_hit == 0.0:
                break
    return scratch, t_hit, s_hit


@njit(**NJIT)
def surfaces_block(x, l, tmax, surf, tol_t, scratch, cand, stack):
    """Whether any surface meets the shadow ray x + t l, t in [0, tmax]: (scratch, blocked)."""
    for s in range(n_surfaces(surf)):
        scratch, t = surface_entry(x, l, tmax, surf, s, tol_t, scratch, cand, stack)
        if t < np.inf:  # roots lie within [0, tmax]
            return scratch, True
    return scratch, False


@njit(**NJIT)
def surface_normal(x, d, surf, s, cand, stack, n_out):
    """n = -grad F / |grad F| of surface s at x (the analytic gradient, MODEL.md §6), into n_out; where the
    gradient vanishes (a camera inside a surface, at a critical point) n = -d, facing the viewer."""
    n_cand = bvh_point_candidates(x, surf[13][s], surf[8], surf[9], surf[10], surf[11], surf[12], stack, cand)
    centers, frames, weights = surf[0], surf[1], surf[2]
    kernel = surf[4][s]
    b = surf[6][s]
    gx = 0.0
    gy = 0.0
    gz = 0.0
    for k in range(n_cand):
        i = cand[k]
        ax, ay, az = ball_gradient(x, centers[i], frames[i], weights[i], kernel, b)
        gx += ax
        gy += ay
        gz += az
    g = math.sqrt(gx * gx + gy * gy + gz * gz)
    if g > 0.0 and g < np.inf:
        n_out[0] = -gx / g
        n_out[1] = -gy / g
        n_out[2] = -gz / g
    else:
        for c in range(3):
            n_out[c] = -d[c]
