"""Opaque metaball surfaces (docs/model.md §6) along one ray: where a camera ray first meets one, whether a
shadow ray is blocked, and the normal at a hit.

Each surface is its own blob, drawn as its isosurface F = T: the fields of two surfaces do not add. An
opaque surface needs only the first root of each blob, never the segments after it: sweep.first_inside
walks the ray's intervals in order and stops at the first entry (camera rays) or the first blocker (shadow
rays), with the answer of the full sweep (sweep.first_entry) bit for bit.
The surfaces are one records.Surfaces (cloudmeta.renderer.pack.pack_surfaces).
"""
import math

import numpy as np
from numba import njit

from .config import NJIT, NJIT_INLINE
from .bvh import bvh_candidates, bvh_point_candidates
from .metaball import gradient_sum
from .records import BlobRecord
from .sweep import first_inside

#: a surface point's shadow ray starts this many root tolerances off the surface, along the normal: the
#: hit is within one root tolerance of the isosurface, so the shadow ray starts outside it and the
#: surface does not shadow itself
SHADOW_OFFSET = 8.0


@njit(**NJIT_INLINE)
def n_surfaces(surf):
    return surf.start.shape[0] - 1


@njit(**NJIT_INLINE)
def surface_blob(surf, s):
    """Surface s as the sweep reads a blob."""
    return BlobRecord(surf.centers, surf.frames, surf.weights, surf.kernel[s], surf.blobbiness[s],
                      surf.threshold[s])


@njit(**NJIT)
def surface_entry(o, d, tmax, surf, s, tol_t, scratch, cand, stack):
    """Where the ray o + t d, t in [0, tmax], first is inside surface s: 0 if it starts inside, inf if
    never. Returns (scratch, t)."""
    n_cand = bvh_candidates(o, d, 0.0, tmax, surf.bvh, surf.bvh.root[s], stack, cand)
    if n_cand == 0:
        return scratch, np.inf
    return first_inside(o, d, 0.0, tmax, surface_blob(surf, s), tol_t, cand, n_cand, scratch)


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
    """n = -grad F / |grad F| of surface s at x (the analytic gradient, docs/model.md §6), into n_out; where the
    gradient vanishes (a camera inside a surface, at a critical point) n = -d, facing the viewer."""
    n_cand = bvh_point_candidates(x, surf.bvh, surf.bvh.root[s], stack, cand)
    gx, gy, gz = gradient_sum(x, surface_blob(surf, s), cand, 0, n_cand)
    g = math.sqrt(gx * gx + gy * gy + gz * gz)
    if g > 0.0 and g < np.inf:
        n_out[0] = -gx / g
        n_out[1] = -gy / g
        n_out[2] = -gz / g
    else:
        for c in range(3):
            n_out[c] = -d[c]
