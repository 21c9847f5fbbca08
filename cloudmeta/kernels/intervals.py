"""Per-ray work shared by the estimators: one thread's work arrays (records.RayWork) and the stage that
turns a ray's media pieces into elementary intervals with exact optical depth (docs/model.md §4)."""
import numpy as np
from numba import njit

from .bernstein import NCOEF, bernstein_cumulative, bernstein_mean, subdivide
from .bvh import STACK
from .config import NJIT, NJIT_INLINE
from .optional import surface_balls
from .lighting import N_COUNTS
from .media import alloc_ray_pieces, n_media
from .records import NodeWork, RayWork
from .sweep import advance_active, alloc_scratch, sort_breakpoints

#: most quadrature nodes per step of the single-scattering estimator (the work rows are sized by it)
MAX_NODES = 16


@njit(**NJIT)
def alloc_node_work(n_lights):
    """The small per-ray work vectors of the radiance kernels (a records.NodeWork)."""
    return NodeWork(light=np.empty((n_lights, 6)), pos=np.empty(3), l_dir=np.empty(3), x=np.empty(3),
                    normal=np.empty(3), x_off=np.empty(3), node_w=np.empty(MAX_NODES),
                    j_val=np.empty((4, MAX_NODES)), split_u=np.empty(MAX_NODES),
                    split_h=np.empty(MAX_NODES), split_depth=np.empty(MAX_NODES), count=np.zeros(N_COUNTS))


@njit(**NJIT)
def alloc_ray_work(scene):
    """One thread's work arrays for camera rays (a records.RayWork): the sweep scratch and ray pieces
    (both grow when a ray needs more), the candidate list (room for the most balls of media or of
    surfaces), the BVH stack and the node work vectors."""
    n_balls = max(scene.media.centers.shape[0], surface_balls(scene.surfaces))
    # np.int64: the literal 64 would compile both allocators once more for Literal[int](64)
    return RayWork(alloc_scratch(np.int64(64)), alloc_ray_pieces(np.int64(64), n_media(scene.media)),
                   np.empty(max(n_balls, 1), np.int64), np.empty(2 * STACK, np.int64),
                   alloc_node_work(scene.lights.kind.shape[0]))


@njit(**NJIT)
def elementary_intervals(n, rp):
    """Cut the ray at every piece end of rp (a records.RayPieces); per interval, sigma_t of each medium
    and of all, and the optical depth from the ray's start. Returns the number of intervals."""
    sort_breakpoints(rp.t0, rp.t1, n, rp.bp, rp.order)
    n_act = 0
    i_s = 0
    n_el = 0
    rp.el_u0[0] = 0.0
    for k in range(2 * n - 1):
        ta = rp.bp[k]
        tb = rp.bp[k + 1]
        if tb <= ta:
            continue
        n_act, i_s = advance_active(ta, rp.t0, rp.t1, rp.order, rp.act, n_act, i_s, n)
        if n_act == 0:
            continue
        _interval_sigma(rp, n_el, n_act, ta, tb)
        rp.el_t0[n_el] = ta
        rp.el_t1[n_el] = tb
        rp.el_u0[n_el + 1] = rp.el_u0[n_el] + (tb - ta) * bernstein_mean(rp.el_S[n_el])
        n_el += 1
    return n_el


@njit(**NJIT_INLINE)
def _interval_sigma(rp, n_el, n_act, ta, tb):
    """el_sig[n_el, m] = sigma_t of medium m on [ta, tb], el_S[n_el] = their sum, from the active pieces."""
    el_S = rp.el_S[n_el]
    el_S[:] = 0.0
    rp.el_sig[n_el, :, :] = 0.0
    for q in range(n_act):
        i = rp.act[q]
        span = rp.t1[i] - rp.t0[i]
        s0 = min(max((ta - rp.t0[i]) / span, 0.0), 1.0)
        s1 = min(max((tb - rp.t0[i]) / span, 0.0), 1.0)
        sig = rp.el_sig[n_el, rp.medium[i]]
        subdivide(rp.c[i], s0, s1, sig)  # pieces of one medium never overlap
        for c in range(NCOEF):
            el_S[c] += sig[c]


@njit(**NJIT)
def depth_at(t, k, n_el, rp):
    """(optical depth at t, the interval holding t), searching forward from interval k."""
    el_t0, el_t1, el_u0, el_S = rp.el_t0, rp.el_t1, rp.el_u0, rp.el_S
    while k < n_el - 1 and el_t1[k] <= t:
        k += 1
    w = el_t1[k] - el_t0[k]
    s = min(max((t - el_t0[k]) / w, 0.0), 1.0)
    return el_u0[k] + w * bernstein_cumulative(el_S[k], s), k
