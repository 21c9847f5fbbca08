"""Every medium along one ray: the pieces a camera ray integrates over, and the optical depth of a
shadow ray. The media are one records.Media (cloudmeta.renderer.pack.pack_media)."""
import math

import numpy as np
from numba import njit

from .config import NJIT, NJIT_INLINE
from .bernstein import NCOEF
from .bvh import bvh_candidates
from .records import BlobRecord, RayPieces
from .shadow import column_density
from .density import rho_value
from .sweep import trace_blob


@njit(**NJIT)
def alloc_ray_pieces(capacity, n_media):
    """Pieces of all media on one ray, room for ``capacity`` (a records.RayPieces)."""
    p = max(capacity, 1)
    return RayPieces(t0=np.empty(p), t1=np.empty(p), c=np.empty((p, NCOEF)), medium=np.empty(p, np.int64),
                     bp=np.empty(2 * p), order=np.empty(p, np.int64), act=np.empty(p, np.int64),
                     el_t0=np.empty(2 * p), el_t1=np.empty(2 * p), el_u0=np.empty(2 * p + 1),
                     el_S=np.empty((2 * p, NCOEF)), el_sig=np.empty((2 * p, max(n_media, 1), NCOEF)))


@njit(**NJIT_INLINE)
def n_media(med):
    return med.start.shape[0] - 1


@njit(**NJIT_INLINE)
def medium_blob(med, m):
    """Medium m as the sweep reads a blob."""
    return BlobRecord(med.centers, med.frames, med.weights, med.kernel[m], med.blobbiness[m], med.threshold[m])


@njit(**NJIT_INLINE)
def medium_pieces(o, d, tmax, med, m, tol_t, scratch, cand, stack):
    """Inside pieces of medium m on the ray (in scratch); returns (scratch, n_pieces)."""
    n_cand = bvh_candidates(o, d, 0.0, tmax, med.bvh, med.bvh.root[m], stack, cand)
    if n_cand == 0:
        return scratch, 0
    scratch, n_out, _ = trace_blob(o, d, 0.0, tmax, medium_blob(med, m), tol_t, cand, n_cand, False, scratch)
    return scratch, n_out


@njit(**NJIT_INLINE)
def grow_ray_pieces(rp, n, need, n_med):
    """A RayPieces with room for 2 * need pieces holding the first n pieces of rp."""
    bigger = alloc_ray_pieces(2 * need, n_med)
    for k in range(n):  # element loops: a slice copy compiles numba's shape-mismatch error path (~1.5 s)
        bigger.t0[k] = rp.t0[k]
        bigger.t1[k] = rp.t1[k]
        bigger.medium[k] = rp.medium[k]
        for q in range(bigger.c.shape[1]):
            bigger.c[k, q] = rp.c[k, q]
    return bigger


@njit(**NJIT_INLINE)
def piece_sigma_t(field_c, mode, threshold, scale, out):
    """out = sigma_t's control values on a piece whose field has control values field_c (docs/model.md §4)."""
    for q in range(NCOEF):
        out[q] = scale * rho_value(field_c[q], mode, threshold)


@njit(**NJIT)
def collect_media(o, d, tmax, med, tol_t, scratch, rp, cand, stack):
    """Trace the ray through every medium; copy each inside piece, as sigma_t, into rp.
    Returns (scratch, rp, number of pieces)."""
    n = 0
    for m in range(n_media(med)):
        scratch, n_out = medium_pieces(o, d, tmax, med, m, tol_t, scratch, cand, stack)
        if n + n_out > rp.t0.shape[0]:
            rp = grow_ray_pieces(rp, n, n + n_out, n_media(med))
        o_t0, o_t1, o_c = scratch.out_t0, scratch.out_t1, scratch.out_c
        for k in range(n_out):
            rp.t0[n] = o_t0[k]
            rp.t1[n] = o_t1[k]
            piece_sigma_t(o_c[k], med.mode[m], med.threshold[m], med.scale[m], rp.c[n])
            rp.medium[n] = m
            n += 1
    return scratch, rp, n


@njit(**NJIT_INLINE)
def shadow_transmittance(x, l, tmax, med, tol_t, tau_stop, scratch, cand, stack):
    """T_l = exp(-tau) from x along l up to tmax through every medium; stops once tau > tau_stop. The
    depth only, without the pieces (kernels.shadow: the fused sweep). Returns (scratch, T_l, the ray's
    entries into the media, counted until it stopped).
    Inlined, with column_density, into each shadow ray's caller: a call passed the scene's media and the sweep
    scratch, about 30 arrays, and took 5-9 % of a shadow ray (512 x 512 renders 6-9 % faster inlined; the
    first cold render of the cumulus compiles 9 s longer, docs/compile.md)."""
    tau = 0.0
    entries = 0
    for m in range(n_media(med)):
        n_cand = bvh_candidates(x, l, 0.0, tmax, med.bvh, med.bvh.root[m], stack, cand)
        if n_cand == 0:
            continue
        scratch, rho_m, n_in = column_density(x, l, 0.0, tmax, medium_blob(med, m), med.mode[m], tol_t, cand,
                                              n_cand, scratch)
        tau += med.scale[m] * rho_m
        entries += n_in
        if tau > tau_stop:
            break
    return scratch, math.exp(-tau), entries
