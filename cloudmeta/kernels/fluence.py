"""Approximate multiple scattering, method ``grid`` (docs/approximate.md): the scattered radiance field on a
grid of cells, deposited by light paths, gathered by the single-scattering quadrature.

Light paths (photons) leave the lights and the environment, are delta-tracked through the exact field
against the majorant grid (kernels.tracking: no voxel in the medium itself), scatter with the media's albedo
and phase functions, and deposit along every flight the track-length estimate of the low spherical-harmonic
moments of the radiance field they carry: in cell c, L_k(c) = (1 / V) sum over flights of (power) x (length in
c) x Y_k(direction), k over the real harmonics of degree l <= 2 (records.RadianceGrid). What is deposited is
the radiance that order 1 of the single-scattering renderer does not count exactly: a light's photon from
its first scattering on (its straight flight is the light's exact order 1, already in the image), an
environment photon from its entry (the single-scattering renderer has no order of the environment).

At a quadrature node x seen along d, medium m scatters sigma_s,m sum_l lambda_l,m sum_k L_lk(x) Y_lk(-d) towards the
camera (Funk-Hecke: lambda_l = 2 pi int p(mu) P_l(mu) dmu, g^l for HG; records.RadianceGrid.moments),
with L trilinear between cell centres and the sum clamped at 0 (a truncated expansion can dip below).

Random numbers: a photon's emission (block 0) and the directions it scatters into (block = vertex) come from
the quasi-random stream sampling.sobol4 keyed by (seed, source, photon's index in its source), so that a
source's photons are stratified; roulette, the medium and the tracked flights from sampling.uniform keyed by
(seed, photon, PHOTON_PATH, vertex, dimension). Photons are cut into a fixed number of batches, each depositing into its
own array, summed in order (renderer.fluence): the grid is bit-identical whatever the thread count.
"""
import math

import numpy as np
from numba import njit

from .camera import background_radiance
from .config import NJIT, NJIT_INLINE
from .kinds import DIRECTIONAL, POINT
from .records import PathKey
from .sampling import sample_phase_cos, sobol4, turn, uniform
from .tracking import alloc_track_work, delta_flight, pick_medium, walk_advance, walk_cell, walk_start

#: a photon source that is the environment (the others are kinds.LIGHTS)
ENVIRONMENT = 2
#: the path index of every photon's random key (the camera paths' are their index in the pixel, small)
PHOTON_PATH = 1 << 40
#: a photon vertex's random dimensions (kernels.tracking's flights use theirs, from 1 << 20)
DIM_ROULETTE = 5
DIM_MEDIUM = 6
#: real spherical harmonics of degree 0, 1, 2: their normalising constants
Y0 = 0.28209479177387814
Y1 = 0.4886025119029199
Y2 = 1.0925484305920792
Y20 = 0.31539156525252005
Y22 = 0.5462742152960396


@njit(**NJIT_INLINE)
def sh_basis(w, y):
    """y[k] = Y_k(w), the 9 real spherical harmonics of degree <= 2 (k = l^2 + l + m), orthonormal on the sphere."""
    x, yy, z = w[0], w[1], w[2]
    y[0] = Y0
    y[1] = Y1 * yy
    y[2] = Y1 * z
    y[3] = Y1 * x
    y[4] = Y2 * x * yy
    y[5] = Y2 * yy * z
    y[6] = Y20 * (3.0 * z * z - 1.0)
    y[7] = Y2 * x * z
    y[8] = Y22 * (x * x - yy * yy)


@njit(**NJIT)
def deposit(o, w, t_max, rg, coef, rgb, y, walk):
    """coef[c, col, k] += rgb[col] y[k] times the length of o + t w, t in [0, t_max], inside cell c of the
    grid rg, for every cell the segment crosses."""
    t, t_end = walk_start(o, w, t_max, rg, walk)
    n_sh = coef.shape[2]
    while t < t_end:
        c, t_out = walk_cell(rg, walk)
        t_out = min(t_out, t_end)
        length = t_out - t
        if length > 0.0:
            for col in range(3):
                a = rgb[col] * length
                for k in range(n_sh):
                    coef[c, col, k] += a * y[k]
        t = t_out
        if t >= t_end or not walk_advance(rg, walk):
            break


@njit(**NJIT_INLINE)
def _disk_point(centre, w, radius, u1, u2, out):
    """out = a point uniform on the disk of ``radius`` about ``centre`` perpendicular to the unit w, moved back
    along w by ``radius`` (so that o + t w, t >= 0, crosses the whole sphere)."""
    r = radius * math.sqrt(u1)
    phi = 2.0 * math.pi * u2
    sign = 1.0 if w[2] >= 0.0 else -1.0  # an orthonormal frame about w (Duff et al. 2017)
    a = -1.0 / (sign + w[2])
    b = w[0] * w[1] * a
    t0, t1, t2 = 1.0 + sign * w[0] * w[0] * a, sign * b, -sign * w[0]
    b0, b1, b2 = b, sign + w[1] * w[1] * a, -w[1]
    x = r * math.cos(phi)
    yv = r * math.sin(phi)
    out[0] = centre[0] + x * t0 + yv * b0 - radius * w[0]
    out[1] = centre[1] + x * t1 + yv * b1 - radius * w[1]
    out[2] = centre[2] + x * t2 + yv * b2 - radius * w[2]


@njit(**NJIT_INLINE)
def _sphere_direction(u1, u2, out):
    z = 1.0 - 2.0 * u1
    s = math.sqrt(max(0.0, 1.0 - z * z))
    phi = 2.0 * math.pi * u2
    out[0] = s * math.cos(phi)
    out[1] = s * math.sin(phi)
    out[2] = z


@njit(**NJIT_INLINE)
def _source_of(first, p):
    s = 0
    while first[s + 1] <= p:
        s += 1
    return s


@njit(**NJIT)
def emit(src, s, seed, p, o, w, rgb):
    """Photon p of source s: its start o, direction w and power rgb (records.PhotonSources)."""
    u1, u2, u3, u4 = sobol4(seed, s, p - src.first[s], 0)  # a source's photons stratified
    kind = src.kind[s]
    for c in range(3):
        rgb[c] = src.rgb[s, c]
    if kind == DIRECTIONAL:  # parallel light over the disk that covers the sphere about the media
        for c in range(3):
            w[c] = -src.vec[s, c]
        _disk_point(src.centre, w, src.radius, u1, u2, o)
    elif kind == POINT:  # isotropic from the light's position
        _sphere_direction(u1, u2, w)
        for c in range(3):
            o[c] = src.vec[s, c]
    else:  # the environment: a direction uniform on the sphere, then a point on the disk across it
        _sphere_direction(u1, u2, w)
        for c in range(3):
            o[c] = -w[c]  # where the light comes from (o is set below)
        r, g, b = background_radiance(src.background, o)
        _disk_point(src.centre, w, src.radius, u3, u4, o)
        rgb[0] *= r
        rgb[1] *= g
        rgb[2] *= b


@njit(**NJIT)
def trace_photons(med, mgrid, src, rg, coef, seed, first, last, max_order, rr_order):
    """Photons first .. last - 1 (numbered over all sources, records.PhotonSources.first) deposit into coef
    (cells, 3, n_sh) of the grid rg: every flight that carries scattered light (module docstring) and whose
    light reaches the camera at an order <= max_order. Russian roulette from rr_order scatterings on, with
    survival min(1, weight)."""
    n_med = med.start.shape[0] - 1
    track = alloc_track_work(n_med)
    walk = alloc_track_work(n_med)
    o = np.empty(3)
    w = np.empty(3)
    w_new = np.empty(3)
    x = np.empty(3)
    rgb = np.empty(3)
    power = np.empty(3)
    y = np.empty(9)
    for p in range(first, last):
        s = _source_of(src.first, p)
        emit(src, s, seed, p, o, w, rgb)
        from_light = src.kind[s] != ENVIRONMENT
        key = PathKey(seed, p, PHOTON_PATH)
        weight = 1.0
        scatterings = 0
        vertex = 0
        while True:
            t, sigma_t, sigma_s = delta_flight(o, w, np.inf, mgrid, med, key, vertex, track)
            # this flight's light reaches the camera at order scatterings + 1 (the node's own scattering)
            if not (from_light and scatterings == 0):
                sh_basis(w, y)
                for c in range(3):
                    power[c] = rgb[c] * weight
                deposit(o, w, t, rg, coef, power, y, walk)
            if t == np.inf or sigma_t <= 0.0:
                break
            scatterings += 1
            if scatterings + 1 > max_order:
                break
            weight *= sigma_s / sigma_t
            vertex += 1
            if weight <= 0.0:
                break
            if scatterings >= rr_order:
                q = min(1.0, weight)
                if uniform(seed, p, PHOTON_PATH, vertex, DIM_ROULETTE) >= q:
                    break
                weight /= q
            for c in range(3):
                x[c] = o[c] + t * w[c]
            m = pick_medium(track.sigma, med, sigma_s, uniform(seed, p, PHOTON_PATH, vertex, DIM_MEDIUM))
            ph = med.phase[m]
            _, u_cos, u_phi, u_lobe = sobol4(seed, s, p - src.first[s], vertex)
            cos_theta = sample_phase_cos(ph[0], ph[1], ph[2], ph[3], u_lobe, u_cos)
            turn(w, cos_theta, u_phi, w_new)
            for c in range(3):
                w[c] = w_new[c]
                o[c] = x[c]


@njit(**NJIT_INLINE)
def _axis(xa, origin, size, n):
    """The two cell indices along one axis that a point lies between (cell centres) and its weight on the
    second; clamped to the edge cells."""
    f = (xa - origin) / size - 0.5
    if f <= 0.0:
        return 0, 0, 0.0
    if f >= n - 1:
        return n - 1, n - 1, 0.0
    i = int(f)
    return i, i + 1, f - i


@njit(**NJIT_INLINE)
def grid_scattered(rg, x, d, m):
    """(r, g, b): what medium m scatters at x towards the camera that looks along d, per unit sigma_s: the
    phase function convolved with the grid's radiance (module docstring), clamped at 0."""
    ix0, ix1, fx = _axis(x[0], rg.origin[0], rg.size, rg.dims[0])
    iy0, iy1, fy = _axis(x[1], rg.origin[1], rg.size, rg.dims[1])
    iz0, iz1, fz = _axis(x[2], rg.origin[2], rg.size, rg.dims[2])
    # Y_k(-d), times the phase's band factor lambda_l
    lam = rg.moments[m]
    vx, vy, vz = -d[0], -d[1], -d[2]
    k0 = lam[0] * Y0
    k1 = lam[1] * Y1
    k2 = lam[2]
    ya = k1 * vy
    yb = k1 * vz
    yc = k1 * vx
    yd = k2 * Y2 * vx * vy
    ye = k2 * Y2 * vy * vz
    yf = k2 * Y20 * (3.0 * vz * vz - 1.0)
    yg = k2 * Y2 * vx * vz
    yh = k2 * Y22 * (vx * vx - vy * vy)
    nx, ny = rg.dims[0], rg.dims[1]
    coef = rg.coef
    n_sh = coef.shape[2]
    r = 0.0
    g = 0.0
    b = 0.0
    for corner in range(8):
        i = ix1 if corner & 1 else ix0
        j = iy1 if corner & 2 else iy0
        k = iz1 if corner & 4 else iz0
        wt = (fx if corner & 1 else 1.0 - fx) * (fy if corner & 2 else 1.0 - fy) * (fz if corner & 4 else 1.0 - fz)
        if wt == 0.0:
            continue
        c = i + nx * (j + ny * k)
        row = coef[c]
        s0 = k0 * row[0, 0] + ya * row[0, 1] + yb * row[0, 2] + yc * row[0, 3]
        s1 = k0 * row[1, 0] + ya * row[1, 1] + yb * row[1, 2] + yc * row[1, 3]
        s2 = k0 * row[2, 0] + ya * row[2, 1] + yb * row[2, 2] + yc * row[2, 3]
        if n_sh > 4:
            s0 += yd * row[0, 4] + ye * row[0, 5] + yf * row[0, 6] + yg * row[0, 7] + yh * row[0, 8]
            s1 += yd * row[1, 4] + ye * row[1, 5] + yf * row[1, 6] + yg * row[1, 7] + yh * row[1, 8]
            s2 += yd * row[2, 4] + ye * row[2, 5] + yf * row[2, 6] + yg * row[2, 7] + yh * row[2, 8]
        r += wt * s0
        g += wt * s1
        b += wt * s2
    return max(r, 0.0), max(g, 0.0), max(b, 0.0)
