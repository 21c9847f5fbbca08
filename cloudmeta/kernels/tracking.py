"""Tracked flights of the multiple-scattering paths: delta tracking and residual ratio tracking against a
majorant grid whose bounds are exact (docs/model.md §10.1).

Beyond the first vertices, inverting the exact optical depth and delta tracking sample the same free-flight
distribution, and the transmittance a vertex needs towards a light has
unbiased estimators that cost a few point evaluations of the field instead of a whole exact sweep. The
grid (records.MajorantGrid, built by ``cell_bounds``) holds per cell an upper bound sigma_max and a lower
bound sigma_min of sigma_t (summed over the media) at every point of the cell, and the balls that can reach
the cell; a point's sigma_t sums those balls' falloffs exactly (metaball.ball_field), so the tracked media
are the exact field, with no voxel in between.

Why the bounds hold. Every kernel's k(u) is non-increasing in u on [0, inf) (k = 0 for u >= 1; blinn drops
to 0 at u = 1), so over a cell a ball of weight q > 0 contributes at most q k(u_min) and at least
q k(u_max), and one of weight q < 0 at least q k(u_min) and at most 0, where u_min and u_max bound u over
the cell (``ball_u_range``). F's bounds are their sums; rho is non-decreasing in F in every density mode
(field F, excess F - T, uniform 1), and sigma_t = scale rho(F) where F >= T, else 0. So sigma_max =
sum over media of scale rho(F_max) where F_max >= T, and sigma_min the same of F_min. Rounding: u_min is
lowered and u_max raised by 1e-12 relative, F's bounds widened by 1e-9 sum |q| of the cell's balls, and the
cell's box by the grid's pad.

Random numbers come from sampling.uniform keyed by (seed, pixel, path, vertex, dimension), one dimension per
draw counted from a base per estimator: a path's numbers do not depend on any other pixel or thread.
"""
import math

import numpy as np
from numba import njit
from numba.core import types
from numba.extending import overload

from .config import NJIT, NJIT_INLINE, OVERLOAD
from .density import rho_value
from .grid import cell_index
from .metaball import ball_field, falloff
from .records import TrackWork, Walk
from .sampling import uniform

#: the first random dimension of a delta-tracked flight; of the transmittance towards light li
#: (DIM_LIGHT + li * DIM_SPAN). Far apart: a walk draws 2 per tentative point
DIM_FLIGHT = 1 << 20
DIM_LIGHT = 3 << 20
DIM_SPAN = 1 << 20
#: a transmittance estimate below this plays Russian roulette (survives with probability 1/2, doubled)
ROULETTE_BELOW = 0.1
#: a transmittance walk stops once the control part of the depth passes this (e^-50 < 2e-22, as the exact
#: shadow rays' TAU_STOP)
TAU_STOP = 50.0
#: the rounding margins of the bounds (module docstring)
U_MARGIN = 1e-12
F_MARGIN = 1e-9


@njit(**NJIT)
def alloc_track_work(n_media):
    """One thread's records.TrackWork."""
    m = max(n_media, 1)
    return TrackWork(sigma=np.zeros(m), at_vertex=np.zeros(m), x=np.zeros(3))


@njit(**NJIT_INLINE)
def release_track(own):
    """The last use of a TrackWork whose arrays a kernel borrowed (as kernels.borrow.release)."""
    own.x[0] += 0.0


# --- the bounds ----------------------------------------------------------------------------------------------

@njit(**NJIT_INLINE)
def ball_u_range(center, frame, inv_r_min, inv_r_max, lo, hi):
    """(u_min, u_max): bounds of u(x) = |frame (x - c)|^2 over the box [lo, hi]. |x - c| / r_max <= |frame (x - c)|
    <= |x - c| / r_min with the box's nearest and farthest distances from c (equalities for a sphere), and,
    about the box's centre p with half-diagonal h, |frame (x - c)| within |frame (p - c)| +- h / r_min."""
    near2 = 0.0
    far2 = 0.0
    h2 = 0.0
    for a in range(3):
        e = max(lo[a] - center[a], 0.0, center[a] - hi[a])
        near2 += e * e
        f = max(abs(center[a] - lo[a]), abs(center[a] - hi[a]))
        far2 += f * f
        half = 0.5 * (hi[a] - lo[a])
        h2 += half * half
    u_min = near2 * inv_r_max * inv_r_max
    u_max = far2 * inv_r_min * inv_r_min
    if inv_r_min != inv_r_max:
        px = 0.5 * (lo[0] + hi[0]) - center[0]
        py = 0.5 * (lo[1] + hi[1]) - center[1]
        pz = 0.5 * (lo[2] + hi[2]) - center[2]
        p2 = 0.0
        for a in range(3):
            q = frame[a, 0] * px + frame[a, 1] * py + frame[a, 2] * pz
            p2 += q * q
        p = math.sqrt(p2)
        reach = math.sqrt(h2) * inv_r_min
        near = max(p - reach, 0.0)
        u_min = max(u_min, near * near)
        u_max = min(u_max, (p + reach) * (p + reach))
    return u_min * (1.0 - U_MARGIN), u_max * (1.0 + U_MARGIN)


@njit(**NJIT_INLINE)
def _sigma_of_field(f, med, m):
    """sigma_t of medium m where its field is f (0 outside, f < T)."""
    if f >= med.threshold[m]:
        return med.scale[m] * rho_value(f, med.mode[m], med.threshold[m])
    return 0.0


@njit(**NJIT)
def cell_bounds(med, ball_medium, inv_radii, origin, size, dims, pad, start, items, sigma_max, sigma_min):
    """sigma_max[c], sigma_min[c]: bounds of sigma_t (all media) over every cell c of the grid (module
    docstring). inv_radii (N, 2): 1 / the smallest and 1 / the largest radius of each ball; start, items: the
    balls binned into the cells (grid.bin_balls) with the same pad."""
    n_med = med.start.shape[0] - 1
    f_hi = np.zeros(max(n_med, 1))
    f_lo = np.zeros(max(n_med, 1))
    slack = np.zeros(max(n_med, 1))
    lo = np.empty(3)
    hi = np.empty(3)
    nx, ny = dims[0], dims[1]
    for c in range(sigma_max.shape[0]):
        ijk = (c % nx, (c // nx) % ny, c // (nx * ny))
        for a in range(3):
            lo[a] = origin[a] + ijk[a] * size - pad
            hi[a] = origin[a] + (ijk[a] + 1) * size + pad
        for m in range(n_med):
            f_hi[m] = 0.0
            f_lo[m] = 0.0
            slack[m] = 0.0
        for k in range(start[c], start[c + 1]):
            b = items[k]
            m = ball_medium[b]
            u_min, u_max = ball_u_range(med.centers[b], med.frames[b], inv_radii[b, 0], inv_radii[b, 1], lo, hi)
            q = med.weights[b]
            near = falloff(med.kernel[m], u_min, med.blobbiness[m])
            if q > 0.0:
                f_hi[m] += q * near
                f_lo[m] += q * falloff(med.kernel[m], u_max, med.blobbiness[m])
            else:
                f_lo[m] += q * near
            slack[m] += abs(q)
        s_max = 0.0
        s_min = 0.0
        for m in range(n_med):
            s_max += _sigma_of_field(f_hi[m] + F_MARGIN * slack[m], med, m)
            s_min += _sigma_of_field(f_lo[m] - F_MARGIN * slack[m], med, m)
        sigma_max[c] = s_max
        sigma_min[c] = min(s_min, s_max)


# --- a point, and the walk through the cells -----------------------------------------------------------------

@njit(**NJIT_INLINE)
def point_sigma(x, grid, med, c, sigma):
    """(sigma_t, sigma_s) at x, a point of cell c, summed over the media; sigma[m] = medium m's sigma_t."""
    n_med = med.start.shape[0] - 1
    for m in range(n_med):
        sigma[m] = 0.0
    for k in range(grid.start[c], grid.start[c + 1]):
        b = grid.items[k]
        m = grid.ball_medium[b]
        inv_r2 = grid.inv_r2[b]
        if inv_r2 > 0.0:  # a sphere: u = |x - c|^2 / R^2, without the frame (a third of the work)
            dx = x[0] - med.centers[b, 0]
            dy = x[1] - med.centers[b, 1]
            dz = x[2] - med.centers[b, 2]
            u = (dx * dx + dy * dy + dz * dz) * inv_r2
            if u < 1.0:
                sigma[m] += med.weights[b] * falloff(med.kernel[m], u, med.blobbiness[m])
        else:
            sigma[m] += ball_field(x, med.centers[b], med.frames[b], med.weights[b], med.kernel[m], med.blobbiness[m])
    sigma_t = 0.0
    sigma_s = 0.0
    for m in range(n_med):
        s = _sigma_of_field(sigma[m], med, m)
        sigma[m] = s
        sigma_t += s
        sigma_s += med.albedo[m] * s
    return sigma_t, sigma_s


@njit(**NJIT_INLINE)
def _axis_walk(o, d, grid, t0, a):
    """(cell, step, where the ray leaves the cell across axis a's walls, the distance between them) of the
    walk along axis a, from the point at t0."""
    i = cell_index(o[a] + t0 * d[a], grid.origin[a], grid.size, grid.dims[a])
    if d[a] > 0.0:
        return i, 1, (grid.origin[a] + (i + 1) * grid.size - o[a]) / d[a], grid.size / d[a]
    if d[a] < 0.0:
        return i, -1, (grid.origin[a] + i * grid.size - o[a]) / d[a], -grid.size / d[a]
    return i, 0, np.inf, np.inf


@njit(**NJIT_INLINE)
def walk_start(o, d, t_max, grid):
    """Clip o + t d, t in [0, t_max], to the grid's box and start the walk in the cell where it enters.
    Returns (t_enter, t_exit, records.Walk); the ray misses the box when t_enter >= t_exit."""
    t0 = 0.0
    t1 = t_max
    for a in range(3):
        lo = grid.origin[a]
        hi = lo + grid.dims[a] * grid.size
        if d[a] != 0.0:
            ta = (lo - o[a]) / d[a]
            tb = (hi - o[a]) / d[a]
            t0 = max(t0, min(ta, tb))
            t1 = min(t1, max(ta, tb))
        elif o[a] < lo or o[a] > hi:
            t0 = 0.0
            t1 = -1.0
    if t0 >= t1:
        return t0, t1, Walk(0, 0, 0, 0, 0, 0, np.inf, np.inf, np.inf, np.inf, np.inf, np.inf)
    ix, sx, nx, dx = _axis_walk(o, d, grid, t0, 0)
    iy, sy, ny, dy = _axis_walk(o, d, grid, t0, 1)
    iz, sz, nz, dz = _axis_walk(o, d, grid, t0, 2)
    return t0, t1, Walk(ix, iy, iz, sx, sy, sz, nx, ny, nz, dx, dy, dz)


@njit(**NJIT_INLINE)
def walk_cell(grid, walk):
    """The walk's current cell (flat index) and where the ray leaves it."""
    c = walk.ix + grid.dims[0] * (walk.iy + grid.dims[1] * walk.iz)
    return c, min(walk.nx, walk.ny, walk.nz)


@njit(**NJIT_INLINE)
def walk_next(grid, walk, t_out, t_end):
    """(whether the walk goes on, the walk) once the ray leaves its cell at t_out: it stops at t_end or where
    the ray leaves the grid, and otherwise steps into the next cell. Every tracked loop ends a cell here."""
    if t_out >= t_end:
        return False, walk
    return walk_advance(grid, walk)


@njit(**NJIT_INLINE)
def walk_advance(grid, walk):
    """(whether the ray is still in the grid, the walk) after stepping into the next cell along the ray."""
    ix, iy, iz, sx, sy, sz, nx, ny, nz, dx, dy, dz = walk
    a = 0
    best = nx
    if ny < best:
        a = 1
        best = ny
    if nz < best:
        a = 2
    if a == 0:
        ix += sx
        nx += dx
        inside = 0 <= ix < grid.dims[0]
    elif a == 1:
        iy += sy
        ny += dy
        inside = 0 <= iy < grid.dims[1]
    else:
        iz += sz
        nz += dz
        inside = 0 <= iz < grid.dims[2]
    return inside, Walk(ix, iy, iz, sx, sy, sz, nx, ny, nz, dx, dy, dz)


@njit(**NJIT_INLINE)
def _exponential(key, vertex, dim):
    return -math.log1p(-uniform(key.seed, key.pixel, key.path, vertex, dim))


@njit(**NJIT_INLINE)
def pick_medium(sigma, med, sigma_s, u):
    """The medium whose phase function turns the path at a tracked vertex: m with probability
    albedo_m sigma[m] / sigma_s."""
    pick = u * sigma_s
    acc = 0.0
    chosen = 0
    for m in range(med.start.shape[0] - 1):
        part = med.albedo[m] * sigma[m]
        if part > 0.0:
            chosen = m
            acc += part
            if pick < acc:
                break
    return chosen


# --- the estimators ------------------------------------------------------------------------------------------

def tentative_collision(tally, x, d, sigma, sigma_maj, med):
    """What a flight's ``tally`` does at each of its tentative collisions x (null or real; sigma[m] medium m's
    sigma_t there, sigma_maj the majorant): nothing without one (None, or left out). A kernel module that
    passes a tally adds its own overload for the tally's type (kernels.fluence)."""
    return None


@overload(tentative_collision, **OVERLOAD)
def _no_tally(tally, x, d, sigma, sigma_maj, med):
    if isinstance(tally, (types.NoneType, types.Omitted)):
        return lambda tally, x, d, sigma, sigma_maj, med: None
    return None


@njit(**NJIT)
def delta_flight(o, d, t_max, grid, med, key, vertex, w, tally=None):
    """Delta tracking along o + t d, t in [0, t_max], against the grid's sigma_max: the first real collision,
    (t, sigma_t, sigma_s there; w.sigma each medium's sigma_t), or (inf, 0, 0) when the flight gets through.
    Its distribution is that of the exact optical depth's inversion: t with density sigma_t(t) e^-tau(t).
    ``tally``: see tentative_collision (the grid method's deposits; compiled to nothing without one)."""
    t, t_end, walk = walk_start(o, d, t_max, grid)
    dim = np.int64(DIM_FLIGHT)
    tau = _exponential(key, vertex, dim)
    dim += 1
    while t < t_end:
        c, t_out = walk_cell(grid, walk)
        t_out = min(t_out, t_end)
        mu = grid.sigma_max[c]
        if mu > 0.0:
            while t + tau / mu < t_out:
                t += tau / mu
                for a in range(3):
                    w.x[a] = o[a] + t * d[a]
                sigma_t, sigma_s = point_sigma(w.x, grid, med, c, w.sigma)
                tentative_collision(tally, w.x, d, w.sigma, mu, med)
                accept = uniform(key.seed, key.pixel, key.path, vertex, dim)
                dim += 1
                if accept * mu < sigma_t:
                    return t, sigma_t, sigma_s
                tau = _exponential(key, vertex, dim)
                dim += 1
            tau = max(tau - mu * (t_out - t), 0.0)
        t = t_out
        going, walk = walk_next(grid, walk, t, t_end)
        if not going:
            break
    return np.inf, 0.0, 0.0


@njit(**NJIT)
def tracked_transmittance(o, d, t_max, grid, med, key, vertex, dim0, w):
    """An unbiased estimate of e^-tau along o + t d, t in [0, t_max]: residual ratio tracking, with the cells'
    sigma_min as the control (its depth is exact) and sigma_max - sigma_min as the residual's majorant;
    Russian roulette below ROULETTE_BELOW. dim0: the first random dimension (DIM_LIGHT ...)."""
    t, t_end, walk = walk_start(o, d, t_max, grid)
    dim = dim0
    ratio = 1.0
    tau_c = 0.0
    while t < t_end:
        c, t_out = walk_cell(grid, walk)
        t_out = min(t_out, t_end)
        mu_c = grid.sigma_min[c]
        mu_r = grid.sigma_max[c] - mu_c
        if t_out > t:
            tau_c += mu_c * (t_out - t)
        if tau_c > TAU_STOP:
            return 0.0
        if mu_r > 0.0:
            s = t
            while True:
                s += _exponential(key, vertex, dim) / mu_r
                dim += 1
                if s >= t_out:
                    break
                for a in range(3):
                    w.x[a] = o[a] + s * d[a]
                sigma_t, _ = point_sigma(w.x, grid, med, c, w.sigma)
                # sigma_min <= sigma_t <= sigma_max: the factor is in [0, 1] (clamped against rounding only)
                ratio *= min(max(1.0 - (sigma_t - mu_c) / mu_r, 0.0), 1.0)
                if ratio * math.exp(-tau_c) < ROULETTE_BELOW:
                    if ratio == 0.0 or uniform(key.seed, key.pixel, key.path, vertex, dim) >= 0.5:
                        return 0.0
                    dim += 1
                    ratio *= 2.0
        t = t_out
        going, walk = walk_next(grid, walk, t, t_end)
        if not going:
            break
    return ratio * math.exp(-tau_c)
