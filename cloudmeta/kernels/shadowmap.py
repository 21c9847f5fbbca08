"""Light-space shadow maps for directional lights (``render: {shadows: map}``).

A map is a square grid perpendicular to the light that covers the media's bounding sphere. Through the
centre of each texel runs a ray from the light's side, along -l; the engine traces it through every
medium and the map keeps its inside pieces: sigma_t as Bernstein control values on [t0, t1], with the
running sum of their exact integrals. The optical depth towards the light at depth s on a texel's ray is
therefore exact in depth; across texels it is interpolated bilinearly.

The maps are one records.ShadowMaps (cloudmeta.renderer.pack.build_shadow_maps). One map's arrays: geo (13,) =
origin (3), e1 (3), e2 (3), ray direction -l (3), texel size; res (texels per side); start (res^2 + 1,)
offsets of each texel's pieces; t0, t1 (P,), c (P, 7) sigma_t, cum (P,) the running integral within the
texel, reach (P,) the running max of t1 within the texel. Several maps are concatenated (``base`` gives
each map's first texel, ``start`` holds global piece offsets).
"""
import numpy as np
from numba import njit

from .config import NJIT, NJIT_INLINE
from .bernstein import bernstein_cumulative, bernstein_mean
from .media import alloc_ray_pieces, collect_media
from .sweep import alloc_scratch, insertion_argsort
from .borrow import borrow


@njit(**NJIT)
def _texel_origin(geo, i, j, o):
    for c in range(3):
        o[c] = geo[c] + (i + 0.5) * geo[12] * geo[3 + c] + (j + 0.5) * geo[12] * geo[6 + c]


@njit(**NJIT)
def trace_texel_chunk(geo, res, med, tol_t, chunk, n_chunks, cap, counts, used, rows):
    """Trace the rays of chunk ``chunk`` of n_chunks of the texels, once, writing their pieces, texel
    after texel, to rows [chunk * cap, chunk * cap + used[chunk]) of ``rows`` (a records.MapPieces);
    counts[k] is the number of pieces of texel k. Every piece is counted even past cap, so used[chunk] >
    cap tells the caller to call again with a larger cap (the chunk's rows are then incomplete). nogil,
    with its own work arrays: cloudmeta.renderer.pack runs the chunks on several threads."""
    n = res * res
    med = borrow(med)  # the caller holds the medium records for the whole call (kernels.borrow)
    scratch = alloc_scratch(np.int64(64))
    rp = alloc_ray_pieces(np.int64(64), med.start.shape[0] - 1)
    cand = np.empty(max(med.centers.shape[0], 1), np.int64)
    stack = np.empty(128, np.int64)
    order = np.empty(64, np.int64)
    o = np.empty(3)
    d = np.empty(3)
    for q in range(3):
        d[q] = geo[9 + q]
    n_used = 0
    for k in range(chunk * n // n_chunks, (chunk + 1) * n // n_chunks):
        _texel_origin(geo, k // res, k % res, o)
        scratch, rp, m = collect_media(o, d, np.inf, med, tol_t, scratch, rp, cand, stack)
        counts[k] = m
        if n_used + m <= cap:
            # pieces of several media come medium by medium: order them by t0 for the lookup
            if m > order.shape[0]:
                order = np.empty(2 * m, np.int64)
            insertion_argsort(rp.t0, order, m)
            _store_texel(rp, m, order, chunk * cap + n_used, rows)
        n_used += m
    used[chunk] = n_used


@njit(**NJIT)
def _store_texel(rp, m, order, p0, rows):
    """The texel's m pieces, in the given order, into rows p0 .. p0 + m - 1 of rows (records.MapPieces),
    with their running integral and running reach."""
    acc = 0.0
    far = -np.inf
    for r in range(m):
        i = order[r]
        p = p0 + r
        rows.t0[p] = rp.t0[i]
        rows.t1[p] = rp.t1[i]
        rows.c[p, :] = rp.c[i]
        acc += (rows.t1[p] - rows.t0[p]) * bernstein_mean(rows.c[p])
        rows.cum[p] = acc
        far = max(far, rows.t1[p])
        rows.reach[p] = far


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
def _map_coordinates(x, geo):
    """(u, v, s): x's place on a map, in texels (texel centres at integers) and in depth along its rays."""
    px = x[0] - geo[0]
    py = x[1] - geo[1]
    pz = x[2] - geo[2]
    u = (px * geo[3] + py * geo[4] + pz * geo[5]) / geo[12] - 0.5
    v = (px * geo[6] + py * geo[7] + pz * geo[8]) / geo[12] - 0.5
    s = px * geo[9] + py * geo[10] + pz * geo[11]
    return u, v, s


@njit(**NJIT_INLINE)
def _texel_depth(maps, res, base, i, j, s):
    """The optical depth at depth s on the ray of texel (i, j), clamped to the map."""
    i = min(max(i, 0), res - 1)
    j = min(max(j, 0), res - 1)
    k = base + i * res + j
    return texel_optical_depth(s, maps.start[k], maps.start[k + 1], maps.t0, maps.t1, maps.c, maps.cum, maps.reach)


@njit(**NJIT_INLINE)
def map_optical_depth(x, maps, mi):
    """(tau, tau_lo, tau_hi): the optical depth from x towards the light of map mi of ``maps`` (a
    records.ShadowMaps), exact along texel rays and bilinear across them, and the least and greatest of the
    four texels' depths (where the depth is monotone across the cell, tau lies between them)."""
    res = maps.res[mi]
    base = maps.base[mi]
    u, v, s = _map_coordinates(x, maps.geo[mi])
    i0 = int(np.floor(u))
    j0 = int(np.floor(v))
    return _bilinear(_texel_depth(maps, res, base, i0, j0, s), _texel_depth(maps, res, base, i0, j0 + 1, s),
                     _texel_depth(maps, res, base, i0 + 1, j0, s), _texel_depth(maps, res, base, i0 + 1, j0 + 1, s),
                     u - i0, v - j0)


@njit(**NJIT_INLINE)
def _bilinear(t00, t01, t10, t11, fu, fv):
    """(tau, lo, hi): the bilinear blend of the depths at the four corners (t_ij at texel (i0 + i, j0 + j)) at
    fractions fu, fv past corner 00, and the least and greatest of the four."""
    tau = ((1.0 - fu) * (1.0 - fv) * t00 + (1.0 - fu) * fv * t01 + fu * (1.0 - fv) * t10 + fu * fv * t11)
    return tau, min(t00, t01, t10, t11), max(t00, t01, t10, t11)


@njit(**NJIT)
def fill_volume_chunk(maps, mi, geo, res, depth_n, chunk, n_chunks, tau):
    """Chunk ``chunk`` of n_chunks of the texels of a light volume (records.LightVolumes) over map mi of
    ``maps``: tau[(i res + j) depth_n + k] = the map's optical depth at the volume's texel (i, j) and depth
    k geo[12]. A volume on the map's own texels reads each texel's ray exactly; another resolution reads the
    map bilinearly. nogil, writing only its own texels: cloudmeta.renderer.pack runs chunks on threads."""
    maps = borrow(maps)  # the caller holds the maps for the whole call (kernels.borrow)
    n = res * res
    same = maps.res[mi] == res
    base = maps.base[mi]
    o = np.empty(3)
    x = np.empty(3)
    for q in range(chunk * n // n_chunks, (chunk + 1) * n // n_chunks):
        i = q // res
        j = q % res
        _texel_origin(geo, i, j, o)
        for k in range(depth_n):
            s = k * geo[12]
            if same:
                value = _texel_depth(maps, res, base, i, j, s)
            else:
                for c in range(3):
                    x[c] = o[c] + s * geo[9 + c]
                value = map_optical_depth(x, maps, mi)[0]
            tau[q * depth_n + k] = value


@njit(**NJIT_INLINE)
def volume_optical_depth(x, vols, vi):
    """(tau, tau_lo, tau_hi) as map_optical_depth, from volume vi of ``vols`` (a records.LightVolumes):
    trilinear, 23-40 ns against the map's ~1 us inside a cloud. lo and hi are the least and greatest of
    the four texel columns' depths at x's depth: along the light the depth only grows, and its linear
    interpolation is second order, so the spread that says how far the estimate may be off is the sideways
    one, as the map's."""
    geo = vols.geo[vi]
    res = vols.res[vi]
    n_s = vols.depth_n[vi]
    base = vols.base[vi]
    u, v, s = _map_coordinates(x, geo)
    w = s / geo[12]
    k0 = min(max(int(np.floor(w)), 0), n_s - 2)
    fw = min(max(w - k0, 0.0), 1.0)
    i0 = int(np.floor(u))
    j0 = int(np.floor(v))
    return _bilinear(_column_depth(vols, res, n_s, base, i0, j0, k0, fw),
                     _column_depth(vols, res, n_s, base, i0, j0 + 1, k0, fw),
                     _column_depth(vols, res, n_s, base, i0 + 1, j0, k0, fw),
                     _column_depth(vols, res, n_s, base, i0 + 1, j0 + 1, k0, fw), u - i0, v - j0)


@njit(**NJIT_INLINE)
def _column_depth(vols, res, n_s, base, i, j, k0, fw):
    """The depth on texel (i, j)'s column of a light volume (clamped to it), fw of the way from sample k0 to
    k0 + 1."""
    i = min(max(i, 0), res - 1)
    j = min(max(j, 0), res - 1)
    q = base + (i * res + j) * n_s + k0
    return (1.0 - fw) * vols.tau[q] + fw * vols.tau[q + 1]
