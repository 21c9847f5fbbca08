"""Every medium along one ray: the pieces a camera ray integrates over, and the optical depth of a
shadow ray. The media are packed as one ``med`` tuple (see cloudmeta.render.PackedMedia.args):
(centers, frames, weights, start, kernel, threshold, mode, scale, albedo, phase,
 node_box, node_a, node_b, node_n, items, root, blobbiness)."""
import math

import numpy as np
from numba import njit

from ..config import NJIT, NJIT_INLINE
from .bernstein import NCOEF
from .bvh import bvh_candidates
from .sweep import DENSITY_EXCESS, DENSITY_UNIFORM, pieces_optical_depth, trace_blob


@njit(**NJIT)
def alloc_ray_pieces(capacity, n_media):
    """Pieces of all media on one ray: t0, t1, sigma_t control values, medium; the interval sweep's
    breakpoints, start order and active list; and the ray's elementary intervals (between consecutive
    piece ends): t0, t1, optical depth from the ray's start to t0, sigma_t of all media, and of each."""
    p = max(capacity, 1)
    return (np.empty(p), np.empty(p), np.empty((p, NCOEF)), np.empty(p, np.int64),
            np.empty(2 * p), np.empty(p, np.int64), np.empty(p, np.int64),
            np.empty(2 * p), np.empty(2 * p), np.empty(2 * p + 1), np.empty((2 * p, NCOEF)),
            np.empty((2 * p, max(n_media, 1), NCOEF)))


@njit(**NJIT_INLINE)
def medium_pieces(o, d, tmax, med, m, tol_t, scratch, cand, stack):
    """Inside pieces of medium m on the ray (in scratch); returns (scratch, n_pieces)."""
    centers, frames, weights, kernel, threshold = med[0], med[1], med[2], med[4], med[5]
    n_cand = bvh_candidates(o, d, 0.0, tmax, med[15][m], med[10], med[11], med[12], med[13], med[14],
                            stack, cand)
    if n_cand == 0:
        return scratch, 0
    scratch, n_out, _ = trace_blob(o, d, 0.0, tmax, centers, frames, weights, kernel[m], med[16][m], threshold[m],
                                   tol_t, cand, n_cand, False, scratch)
    return scratch, n_out


@njit(**NJIT)
def collect_media(o, d, tmax, med, tol_t, scratch, rp, cand, stack):
    """Trace the ray through every medium; copy each inside piece, as sigma_t, into rp.
    Returns (scratch, rp, number of pieces)."""
    threshold, mode, scale_m = med[5], med[6], med[7]
    n = 0
    for m in range(med[3].shape[0] - 1):
        scratch, n_out = medium_pieces(o, d, tmax, med, m, tol_t, scratch, cand, stack)
        if n + n_out > rp[0].shape[0]:
            bigger = alloc_ray_pieces(2 * (n + n_out), med[3].shape[0] - 1)
            bigger[0][:n] = rp[0][:n]
            bigger[1][:n] = rp[1][:n]
            bigger[2][:n] = rp[2][:n]
            bigger[3][:n] = rp[3][:n]
            rp = bigger
        o_t0, o_t1, o_c = scratch[10], scratch[11], scratch[12]
        scale = scale_m[m]
        for k in range(n_out):
            rp[0][n] = o_t0[k]
            rp[1][n] = o_t1[k]
            for q in range(NCOEF):
                if mode[m] == DENSITY_UNIFORM:
                    rp[2][n, q] = scale
                elif mode[m] == DENSITY_EXCESS:
                    rp[2][n, q] = scale * (o_c[k, q] - threshold[m])
                else:
                    rp[2][n, q] = scale * o_c[k, q]
            rp[3][n] = m
            n += 1
    return scratch, rp, n


@njit(**NJIT)
def shadow_transmittance(x, l, tmax, med, tol_t, tau_stop, scratch, cand, stack):
    """T_l = exp(-tau) from x along l up to tmax through every medium; stops once tau > tau_stop."""
    tau = 0.0
    for m in range(med[3].shape[0] - 1):
        scratch, n_out = medium_pieces(x, l, tmax, med, m, tol_t, scratch, cand, stack)
        tau += pieces_optical_depth(n_out, med[6][m], med[5][m], med[7][m], scratch)
        if tau > tau_stop:
            break
    return scratch, math.exp(-tau)


