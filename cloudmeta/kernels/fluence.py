"""Approximate multiple scattering, method ``grid`` (docs/approximate.md): the scattered light towards the
camera on a grid of cells, deposited by light paths, gathered by the single-scattering quadrature.

Light paths (photons) leave the lights and the environment, are delta-tracked through the exact field
against the majorant grid (kernels.tracking: no voxel in the medium itself), and scatter with the media's
albedo and phase functions. Along every flight they deposit the track-length estimate of the light that
each medium would scatter towards the camera: in cell c, for medium m,

    S_m(c) = (1 / V) sum over flights of (power) x (length in c) x p_m(w . v(c)),

w the flight's direction and v(c) the unit direction from the cell's centre to the camera
(records.RadianceGrid). That is the phase function convolved with the radiance field, exactly in angle: the
camera is known when the grid is built, so no angular basis is truncated (a spherical-harmonic basis of
degree 2 missed by 32-34 % on strongly forward-scattering and grazing scenes, docs/approximate.md).
What is deposited is the light that order 1 of the single-scattering renderer does not count: a light's
photon from its first scattering on (its straight flight is the light's exact order 1, already in the
image), an environment photon from its entry (the single-scattering renderer has no order of the
environment).

Inside the cone cos theta > cos_c around v(c) the deposited p_m is clamped to p_c (records.RadianceGrid.peak):
the peak above it is carried by the camera ray as a lower extinction (records.SceneRecords.view_media; the
delta split of docs/approximate.md).

With ``where`` COLLISIONS the photons deposit instead at their tentative collisions (records.FlightTally), each
cell then estimating the integral of sigma_s,m S_m over it; renderer.fluence adds the cells' integral of
sigma_s,m (``cell_scattering``) as RadianceGrid.filled.

With ``where`` MOMENTS the flights deposit instead the real spherical harmonics of degrees 0-3 of their
direction (``deposit_moments``): the radiance's coefficients per cell, without the camera, the shared method's
cache of the deep orders, which its path tails read by the phase function's Legendre coefficients
(``cached_light``).

At a quadrature node x the gather adds (sigma_s,m / sigma_t) S_m(x) to J, S_m trilinear between the cells'
centres (``grid_scattered``).

Random numbers: a photon's emission comes from the quasi-random stream sampling.sobol4 keyed by (seed,
source, the photon's index in its source), so that a source's photons are stratified over its disk and
directions; everything after (flights, roulette, medium, directions) from sampling.uniform keyed by (seed,
photon, PHOTON_PATH, vertex, dimension), a fifth of sobol4's cost per vertex. Photons are cut into a fixed number of batches, each
depositing into its own array, summed in order (renderer.fluence): the grid is bit-identical whatever the
thread count.
"""
import math

import numpy as np
from numba import njit
from numba.core import types
from numba.extending import overload

from .camera import background_radiance
from .config import NJIT, NJIT_INLINE, OVERLOAD
from .kinds import DIRECTIONAL, POINT
from .optics import phase
from .records import FlightTally, PathKey
from .sampling import sample_phase_cos, sobol4, turn, uniform
from .tracking import (alloc_track_work, delta_flight, pick_medium, point_sigma, tentative_collision, walk_cell,
                       walk_next, walk_start)

#: a photon source that is the environment (the others are kinds.LIGHTS)
ENVIRONMENT = 2
#: the path index of every photon's random key (the camera paths' are their index in the pixel, small)
PHOTON_PATH = 1 << 40
#: where the photons deposit (render.grid.deposit): along their flights (track length), or at their tentative
#: collisions, weighted by sigma_s (renderer.fluence then divides by the cells' sigma_s)
FLIGHTS = 0
COLLISIONS = 1
#: or, for the shared method's cache of the deep orders (renderer.shared), the track-length estimates of the
#: radiance's spherical-harmonic coefficients of degrees 0-3 along the flights, without the camera: coef
#: (cells, 3, SH_TERMS)
MOMENTS = 2
SH_TERMS = 16
#: the degree of each of the SH_TERMS harmonics (sh_basis)
SH_DEGREE = (0, 1, 1, 1, 2, 2, 2, 2, 2, 3, 3, 3, 3, 3, 3, 3)
#: a photon vertex's random dimensions (kernels.tracking's flights use theirs, from 1 << 20)
DIM_ROULETTE = 5
DIM_MEDIUM = 6
DIM_LOBE = 7
DIM_COS = 8
DIM_PHI = 9
FOUR_PI = 4.0 * math.pi


@njit(**NJIT_INLINE)
def deposited_phase(phases, peak, m, cos_theta):
    """p_m(cos_theta), clamped to p_c inside the cone cos_theta > cos_c (peak[m] = (cos_c, p_c)): the forward peak
    above the clamp is the camera ray's (records.SceneRecords.view_media), not the grid's."""
    ph = phase(phases[m, 0], phases[m, 1], phases[m, 2], phases[m, 3], cos_theta)
    return min(ph, peak[m, 1]) if cos_theta > peak[m, 0] else ph


@njit(**NJIT)
def deposit(o, w, t_max, rg, coef, rgb, med):
    """coef[c, col, m] += rgb[col] p_m(w . rg.towards[c]) times the length of o + t w, t in [0, t_max], inside
    cell c of the grid rg, for every cell the segment crosses and every medium m."""
    t, t_end, cells = walk_start(o, w, t_max, rg)
    while t < t_end:
        c, t_out = walk_cell(rg, cells)
        t_out = min(t_out, t_end)
        length = t_out - t
        if length > 0.0:
            v = rg.towards[c]
            cos_theta = w[0] * v[0] + w[1] * v[1] + w[2] * v[2]
            for m in range(coef.shape[2]):
                a = length * deposited_phase(med.phase, rg.peak, m, cos_theta)
                for col in range(3):
                    coef[c, col, m] += rgb[col] * a
        t = t_out
        going, cells = walk_next(rg, cells, t, t_end)
        if not going:
            break


@njit(**NJIT_INLINE)
def sh_basis(w, y):
    """y[:16] = the real spherical harmonics of degrees 0-3 at the unit vector w (orthonormal on the sphere)."""
    x, yy, z = w[0], w[1], w[2]
    y[0] = 0.28209479177387814
    y[1] = 0.4886025119029199 * yy
    y[2] = 0.4886025119029199 * z
    y[3] = 0.4886025119029199 * x
    y[4] = 1.0925484305920792 * x * yy
    y[5] = 1.0925484305920792 * yy * z
    y[6] = 0.31539156525252005 * (3.0 * z * z - 1.0)
    y[7] = 1.0925484305920792 * x * z
    y[8] = 0.5462742152960396 * (x * x - yy * yy)
    y[9] = 0.5900435899266435 * yy * (3.0 * x * x - yy * yy)
    y[10] = 2.890611442640554 * x * yy * z
    y[11] = 0.4570457994644658 * yy * (5.0 * z * z - 1.0)
    y[12] = 0.3731763325901154 * z * (5.0 * z * z - 3.0)
    y[13] = 0.4570457994644658 * x * (5.0 * z * z - 1.0)
    y[14] = 1.445305721320277 * z * (x * x - yy * yy)
    y[15] = 0.5900435899266435 * x * (x * x - 3.0 * yy * yy)


@njit(**NJIT)
def deposit_moments(o, w, t_max, rg, coef, rgb, y):
    """coef[c, col, j] += rgb[col] y[j] times the length of o + t w, t in [0, t_max], inside cell c of the grid rg,
    for every cell the segment crosses (y: sh_basis of w): per unit volume, the spherical-harmonic coefficients
    of the radiance the photons carry."""
    t, t_end, cells = walk_start(o, w, t_max, rg)
    while t < t_end:
        c, t_out = walk_cell(rg, cells)
        t_out = min(t_out, t_end)
        length = t_out - t
        if length > 0.0:
            for col in range(3):
                a = rgb[col] * length
                for j in range(SH_TERMS):
                    coef[c, col, j] += a * y[j]
        t = t_out
        going, cells = walk_next(rg, cells, t, t_end)
        if not going:
            break


@njit(**NJIT_INLINE)
def _cell_at(x, origin, size, dims):
    """The flat index of the cell of the box (origin, cubic cells of size, dims) that holds x, -1 outside it."""
    c = 0
    stride = 1
    for a in range(3):
        v = (x[a] - origin[a]) / size
        if not (0.0 <= v < dims[a]):
            return -1
        c += int(v) * stride
        stride *= dims[a]
    return c


@njit(**NJIT)
def collide(x, w, rg, coef, rgb, sigma, sigma_maj, med):
    """coef[c, col, m] += rgb[col] (albedo_m sigma[m] / sigma_maj) p_m(w . rg.towards[c]) at a tentative collision
    x of a flight in direction w against the majorant sigma_maj (sigma[m]: medium m's sigma_t at x), c the cell
    holding x (_deposit_at_tentative)."""
    c = _cell_at(x, rg.origin, rg.size, rg.dims)
    if c < 0:
        return
    v = rg.towards[c]
    cos_theta = w[0] * v[0] + w[1] * v[1] + w[2] * v[2]
    for m in range(coef.shape[2]):
        if sigma[m] <= 0.0:
            continue
        a = med.albedo[m] * sigma[m] / sigma_maj * deposited_phase(med.phase, rg.peak, m, cos_theta)
        for col in range(3):
            coef[c, col, m] += rgb[col] * a


@overload(tentative_collision, **OVERLOAD)
def _deposit_at_tentative(tally, x, d, sigma, sigma_maj, med):
    """With a records.FlightTally, kernels.tracking.delta_flight deposits at every tentative collision (``collide``):
    the tentative collisions are a Poisson process of rate sigma_max, so the sum of rgb sigma_s,m(x) / sigma_max
    p_m(d . v) over those up to the flight's end is an unbiased estimate of the flight's integral of
    sigma_s,m p_m L over each cell, from about sigma_max / sigma_t times as many points as its real collision."""
    if isinstance(tally, types.BaseNamedTuple) and tally.instance_class is FlightTally:
        return lambda tally, x, d, sigma, sigma_maj, med: collide(x, d, tally.grid, tally.coef, tally.rgb, sigma,
                                                                  sigma_maj, med)
    return None


@njit(**NJIT)
def cell_scattering(mgrid, med, rg, n, out):
    """out[c, m] = the integral of sigma_s,m over cell c of rg: the mean over n^3 points (the centres of a
    regular subdivision of the cell) times its volume, sigma from the majorant grid mgrid's ball lists."""
    n_med = med.start.shape[0] - 1
    sigma = np.zeros(n_med)
    x = np.empty(3)
    nx, ny = rg.dims[0], rg.dims[1]
    vol = rg.size ** 3 / n ** 3
    for c in range(out.shape[0]):
        ijk = (c % nx, (c // nx) % ny, c // (nx * ny))
        for q in range(n * n * n):
            sub = (q % n, (q // n) % n, q // (n * n))
            for a in range(3):
                x[a] = rg.origin[a] + (ijk[a] + (sub[a] + 0.5) / n) * rg.size
            mc = _cell_at(x, mgrid.origin, mgrid.size, mgrid.dims)
            if mc < 0 or mgrid.sigma_max[mc] <= 0.0:
                continue
            point_sigma(x, mgrid, med, mc, sigma)
            for m in range(n_med):
                out[c, m] += med.albedo[m] * sigma[m] * vol


@njit(**NJIT_INLINE)
def _disk_point(centre, w, radius, u1, u2, out):
    """out = a point uniform on the disk of ``radius`` about ``centre`` perpendicular to the unit w, moved back
    along w by ``radius`` (so that o + t w, t >= 0, crosses the whole sphere)."""
    turn(w, 0.0, u2, out)  # the unit vector perpendicular to w at azimuth 2 pi u2
    r = radius * math.sqrt(u1)
    for c in range(3):
        out[c] = centre[c] + r * out[c] - radius * w[c]


@njit(**NJIT_INLINE)
def _sphere_direction(u1, u2, out):
    """out = the direction uniform on the sphere at (u1, u2)."""
    z = 1.0 - 2.0 * u1
    s = math.sqrt(max(0.0, 1.0 - z * z))
    phi = 2.0 * math.pi * u2
    out[0] = s * math.cos(phi)
    out[1] = s * math.sin(phi)
    out[2] = z


@njit(**NJIT_INLINE)
def _source_of(first, p):
    """The source whose photons (first[s] .. first[s + 1] - 1) include photon p."""
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


@njit(**NJIT_INLINE)
def in_footprint(src, s, o, w):
    """Whether the parallel photon (o, w) of directional source s starts in a texel of its disk that can meet
    the media (records.PhotonSources.footprint; renderer.fluence.sun_footprint)."""
    n = src.footprint.shape[1]
    px = 2.0 * src.radius / n
    ia = 0
    ib = 0
    for k in range(2):
        q = 0.0
        for c in range(3):  # the point on the disk relative to its centre (kernels.fluence._disk_point)
            q += (o[c] + src.radius * w[c] - src.centre[c]) * src.axes[s, k, c]
        i = int(math.floor((q + src.radius) / px))
        if i < 0 or i >= n:
            return False
        if k == 0:
            ia = i
        else:
            ib = i
    return src.footprint[s, ia, ib] != 0


@njit(**NJIT)
def trace_photons(med, mgrid, src, rg, coef, seed, first, last, max_order, rr_order, where):
    """Photons first .. last - 1 (numbered over all sources, records.PhotonSources.first) deposit into coef
    (cells, 3, media) of the grid rg: every flight that carries scattered light (module docstring) and whose
    light reaches the camera at an order <= max_order, along the flight (where FLIGHTS) or at its tentative
    collisions (COLLISIONS: a records.FlightTally); or (MOMENTS) its radiance's harmonics into coef (cells, 3,
    SH_TERMS). Russian roulette from rr_order scatterings on, with survival
    min(1, weight)."""
    n_med = med.start.shape[0] - 1
    track = alloc_track_work(n_med)
    o = np.empty(3)
    w = np.empty(3)
    w_new = np.empty(3)
    x = np.empty(3)
    rgb = np.empty(3)
    power = np.empty(3)
    y = np.empty(SH_TERMS)
    for p in range(first, last):
        s = _source_of(src.first, p)
        emit(src, s, seed, p, o, w, rgb)
        if src.kind[s] == DIRECTIONAL and not in_footprint(src, s, o, w):
            continue  # its straight flight meets no media: it would scatter nothing and deposit nothing
        from_light = src.kind[s] != ENVIRONMENT
        key = PathKey(seed, p, PHOTON_PATH)
        weight = 1.0
        scatterings = 0
        vertex = 0
        while True:
            # this flight's light reaches the camera at order scatterings + 1 (the node's own scattering)
            deposits = not (from_light and scatterings == 0)
            for c in range(3):
                power[c] = rgb[c] * weight
            if where == COLLISIONS and deposits:
                t, sigma_t, sigma_s = delta_flight(o, w, np.inf, mgrid, med, key, vertex, track,
                                                   FlightTally(rg, coef, power))
            else:
                t, sigma_t, sigma_s = delta_flight(o, w, np.inf, mgrid, med, key, vertex, track)
            if deposits and where == FLIGHTS:
                deposit(o, w, t, rg, coef, power, med)
            elif deposits and where == MOMENTS:
                sh_basis(w, y)
                deposit_moments(o, w, t, rg, coef, power, y)
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
            cos_theta = sample_phase_cos(ph[0], ph[1], ph[2], ph[3], uniform(seed, p, PHOTON_PATH, vertex, DIM_LOBE),
                                         uniform(seed, p, PHOTON_PATH, vertex, DIM_COS))
            turn(w, cos_theta, uniform(seed, p, PHOTON_PATH, vertex, DIM_PHI), w_new)
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
def _around(grid, x):
    """The cells around x between their centres (_axis per axis) and the grid's dims in x and y, for _corner."""
    ix0, ix1, fx = _axis(x[0], grid.origin[0], grid.size, grid.dims[0])
    iy0, iy1, fy = _axis(x[1], grid.origin[1], grid.size, grid.dims[1])
    iz0, iz1, fz = _axis(x[2], grid.origin[2], grid.size, grid.dims[2])
    return ix0, ix1, fx, iy0, iy1, fy, iz0, iz1, fz, grid.dims[0], grid.dims[1]


@njit(**NJIT_INLINE)
def _corner(corner, around):
    """(flat cell index, trilinear weight) of corner 0-7 (bits: x, y, z) of the cells ``around`` a point."""
    ix0, ix1, fx, iy0, iy1, fy, iz0, iz1, fz, nx, ny = around
    i = ix1 if corner & 1 else ix0
    j = iy1 if corner & 2 else iy0
    k = iz1 if corner & 4 else iz0
    wt = (fx if corner & 1 else 1.0 - fx) * (fy if corner & 2 else 1.0 - fy) * (fz if corner & 4 else 1.0 - fz)
    return i + nx * (j + ny * k), wt


@njit(**NJIT_INLINE)
def grid_scattered(rg, x, m):
    """(r, g, b): what medium m scatters at x towards the camera, per unit sigma_s (module docstring): S_m
    trilinear between the cells' centres: sum w_c coef_c / sum w_c filled_c over the 8 cells c around x, w_c the
    trilinear weights (records.RadianceGrid: filled is the cells' mean sigma_s,m where the photons deposited at
    their collisions, 1 where they deposited along their flights)."""
    around = _around(rg, x)
    coef = rg.coef
    r = 0.0
    g = 0.0
    b = 0.0
    total = 0.0
    for corner in range(8):
        c, wt = _corner(corner, around)
        if wt == 0.0:
            continue
        total += wt * rg.filled[c, m]
        r += wt * coef[c, 0, m]
        g += wt * coef[c, 1, m]
        b += wt * coef[c, 2, m]
    if total <= 0.0:
        return 0.0, 0.0, 0.0
    return r / total, g / total, b / total


@njit(**NJIT)
def cached_light(cache, x, d, m, y):
    """(r, g, b): the light that medium m scatters at x into -d per unit sigma_s, from the records.FluenceCache
    (its harmonics trilinear between the cells' centres; y: SH_TERMS scratch): with L = sum c_j Y_j, the phase
    function's convolution int p(d . u) L(-u) du is sum_j (-1)^l k_l c_j Y_j(d), k_l its Legendre coefficients
    (Funk-Hecke); kept >= 0 (a truncated series can dip below)."""
    around = _around(cache, x)
    mom = cache.moments
    sh_basis(d, y)
    for j in range(SH_TERMS):  # the convolution's weight per harmonic, at d
        y[j] *= cache.phase_moments[m, j]
    r = 0.0
    g = 0.0
    b = 0.0
    for corner in range(8):
        c, wt = _corner(corner, around)
        if wt == 0.0:
            continue
        for h in range(SH_TERMS):
            r += wt * mom[c, 0, h] * y[h]
            g += wt * mom[c, 1, h] * y[h]
            b += wt * mom[c, 2, h] * y[h]
    return max(r, 0.0), max(g, 0.0), max(b, 0.0)
