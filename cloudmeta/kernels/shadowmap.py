"""Light-space shadow maps for directional lights (``render: {shadows: map}``).

A map is a square grid perpendicular to the light that covers the media's bounding sphere. Through the
centre of each texel runs a ray from the light's side, along -l; the engine traces it through every
medium and the map keeps its inside pieces: sigma_t as Bernstein control values on [t0, t1], with the
running sum of their exact integrals. The optical depth towards the light at depth s on a texel's ray is
therefore exact in depth; across texels it is interpolated bilinearly.

One map's arrays: geo (13,) = origin (3), e1 (3), e2 (3), ray direction -l (3), texel size; res (texels
per side); start (res^2 + 1,) offsets of each texel's pieces; t0, t1 (P,), c (P, 7) sigma_t, cum (P,) the
running integral within the texel, reach (P,) the running max of t1 within the texel. Several maps are
concatenated (``base`` gives each map's first texel, ``start`` holds global piece offsets).
"""
import numpy as np
from numba import njit, prange

from ..config import NJIT, NJIT_INLINE, NJIT_PARALLEL
from .bernstein import bernstein_cumulative, bernstein_mean
from .media import alloc_ray_pieces, collect_media
from .sweep import alloc_scratch


@njit(**NJIT)
def _texel_origin(geo, i, j, o):
    for c in range(3):
        o[c] = geo[c] + (i + 0.5) * geo[12] * geo[3 + c] + (j + 0.5) * geo[12] * geo[6 + c]


@njit(**NJIT)
def _order_by_start(t0, m, order):
    """order[:m] = the indices of t0[:m] by increasing value (insertion sort: a texel has few pieces,
    mostly in order already)."""
    for r in range(m):
        order[r] = r
        q = r
        while q > 0 and t0[order[q - 1]] > t0[r]:
            order[q] = order[q - 1]
            q -= 1
        order[q] = r


@njit(**NJIT_PARALLEL)
def trace_texels(geo, res, med, tol_t, n_chunks, cap, counts, used, t0, t1, c, cum, reach):
    """Trace every texel's ray, once. Chunk ch writes the pieces of its texels, texel after texel, to rows
    [ch * cap, ch * cap + used[ch]) of t0, t1, c, cum, reach; counts[k] is the number of pieces of texel
    k. Every piece is counted even past cap, so used[ch] > cap tells the caller to call again with a
    larger cap (the chunks' rows are then incomplete)."""
    n = res * res
    for chunk in prange(n_chunks):
        scratch = alloc_scratch(64)
        rp = alloc_ray_pieces(64, med[3].shape[0] - 1)
        cand = np.empty(max(med[0].shape[0], 1), np.int64)
        stack = np.empty(128, np.int64)
        order = np.empty(64, np.int64)
        o = np.empty(3)
        d = np.empty(3)
        for q in range(3):
            d[q] = geo[9 + q]
        row0 = chunk * cap
        n_used = 0
        for k in range(chunk * n // n_chunks, (chunk + 1) * n // n_chunks):
            _texel_origin(geo, k // res, k % res, o)
            scratch, rp, m = collect_media(o, d, np.inf, med, tol_t, scratch, rp, cand, stack)
            counts[k] = m
            if n_used + m > cap:
                n_used += m
                continue
            # pieces of several media come medium by medium: order them by t0 for the lookup
            if m > order.shape[0]:
                order = np.empty(2 * m, np.int64)
            _order_by_start(rp[0], m, order)
            acc = 0.0
            far = -np.inf
            for r in range(m):
                i = order[r]
                p = row0 + n_used + r
                t0[p] = rp[0][i]
                t1[p] = rp[1][i]
                c[p, :] = rp[2][i]
                acc += (t1[p] - t0[p]) * bernstein_mean(c[p])
                cum[p] = acc
                far = max(far, t1[p])
                reach[p] = far
            n_used += m
        used[chunk] = n_used


@njit(**NJIT)
def texel_optical_depth(s, a, b, t0, t1, c, cum, reach):
    """Optical depth from the light's side to depth s on the ray whose pieces are [a, b)."""
    if b == a or s <= t0[a]:
        return 0.0
    # k: the number of pieces that start before s
    lo = a
    hi = b
    while lo < hi:
        mid = (lo + hi) // 2
        if t0[mid] < s:
            lo = mid + 1
        else:
            hi = mid
    k = lo
    tau = cum[k - 1]
    # pieces that start before s but end after it count only up to s
    j = k - 1
    while j >= a and reach[j] > s:
        if t1[j] > s:
            w = t1[j] - t0[j]
            full = w * bernstein_mean(c[j])
            part = w * bernstein_cumulative(c[j], (s - t0[j]) / w)
            tau -= full - part
        j -= 1
    return tau


@njit(**NJIT_INLINE)
def map_optical_depth(x, geo, res, base, start, t0, t1, c, cum, reach):
    """Optical depth from x towards the light of one map: exact along texel rays, bilinear across them."""
    px = x[0] - geo[0]
    py = x[1] - geo[1]
    pz = x[2] - geo[2]
    u = (px * geo[3] + py * geo[4] + pz * geo[5]) / geo[12] - 0.5
    v = (px * geo[6] + py * geo[7] + pz * geo[8]) / geo[12] - 0.5
    s = px * geo[9] + py * geo[10] + pz * geo[11]
    i0 = int(np.floor(u))
    j0 = int(np.floor(v))
    fu = u - i0
    fv = v - j0
    tau = 0.0
    for di in range(2):
        i = min(max(i0 + di, 0), res - 1)
        wi = fu if di == 1 else 1.0 - fu
        for dj in range(2):
            j = min(max(j0 + dj, 0), res - 1)
            wj = fv if dj == 1 else 1.0 - fv
            k = base + i * res + j
            tau += wi * wj * texel_optical_depth(s, start[k], start[k + 1], t0, t1, c, cum, reach)
    return tau
