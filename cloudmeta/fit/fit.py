"""Fit metaballs to a voxel grid: placement, non-negative least squares, refinement (docs/fit.md).

The fitted medium's density is the sum of the ball fields, sigma_t(x) = scale x sum_i q_i k(|x - c_i|^2 / R_i^2)
with the `wyvill6` kernel k and q_i >= 0 (docs/model.md §1, §4: mode `field`, its threshold T at 10^-6 of the
largest weight, the least the loader accepts, so that F < T only where F is within 10^-6 of nothing).

Method:
1. Placement: a lattice over the grid's occupied blocks, spaced so that it holds a third of the ball budget;
   its radius 1.4 or 1.6 lattice steps (4.; compact support: the matrix of kernel values at the voxel
   centres, one column a ball, is sparse).
2. Weights: min ||A q - y||^2 over q >= 0, on every voxel that a ball reaches (the occupied voxels and their
   empty surroundings: without them the weights oscillate). Accelerated projected gradient (FISTA with
   adaptive restart) on columns scaled to unit norm, warm-started between rounds; its products on every
   core (kernels.sparse), the same bits on any number of threads.
3. Refinement (Muraki's splitting, on lattices): each round scores the unused blocks of the next finer
   lattices (spacing halved) by the residual a constant over the block would remove, takes twice as many
   as it adds, tries each at a few radii (RADIUS_CHOICES times its level's radius) and keeps the best by
   the decrease of the squared residual that ball alone would give, (a_j . r)_+^2 / |a_j|^2; adds the best
   of those, solves again and drops balls whose weight fell to 0; until the budget of balls or the target
   error is reached.
4. Radii: the lattice's radius factor is chosen from a few values by the coarse lattice's residual.
Deterministic: no random numbers; ties are broken by index.
"""
from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass, field as dc_field

import numpy as np
import scipy.sparse as sp

from ..errors import InputError
from ..kernels import sparse

#: candidate radii of the coarse lattice, in lattice steps. 1.9 fitted the noise cloud better at many balls
#: (10^5 balls, 128^3: optical depth 0.18 % against 0.22 %), but its matrix holds 1.7 times the values, and
#: the time goes into products over them (docs/fit.md)
RADIUS_FACTORS = (1.4, 1.6)
FIRST_SHARE = 1 / 3               #: share of the ball budget that the first lattice may take
STALL = 2e-4                      #: the solver stops once ten iterations gain less than this share
#: a refinement ball's radius: its level's radius times one of these. Only wider: narrower balls fitted the
#: voxel centres better and the optical depth worse (few centres hold their shape)
RADIUS_CHOICES = (1.0, 1.4, 2.0)
CANDIDATES = 2                    #: blocks whose radii are scored, per ball added
TRIAL_STEPS = 16                  #: the radius trial's box: at most this many lattice steps a side
POWER = 4                         #: power-iteration products for the solver's step
TRANSPOSE_BLOCKS = 64              #: row ranges of the transpose (kernels.sparse.transpose)
BLOCKS = 16                       #: blocks of rows of the solver's products (kernels.sparse.gradient)
THRESHOLD_RATIO = 1.000001e-6       #: T / largest weight: just above the least the loader allows (|q| <= 10^6 T)


@dataclass
class FitResult:
    """The fitted balls (centres, radii in grid units; weights q >= 0 in sigma_t per unit length, scale 1),
    the grid's box, and the fit's record: density L2 error on the grid by the solver's own matrix, balls
    per round, time."""
    centers: np.ndarray
    radii: np.ndarray
    weights: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    density_error: float
    rounds: list = dc_field(default_factory=list)
    seconds: float = 0.0
    cpu_seconds: float = 0.0
    radius_factor: float = 1.6
    source: str = ""
    variable: str = ""
    errors: dict = dc_field(default_factory=dict)
    paths: tuple = ()

    def __len__(self):
        return len(self.weights)

    @property
    def threshold(self):
        return THRESHOLD_RATIO * float(self.weights.max())

    def blob(self):
        """The fitted medium's blob (cloudmeta.Blob: wyvill6, spheres, the threshold written to the scene)."""
        from ..scene.blob import Blob
        return Blob(self.centers, self.radii, self.weights, kernel="wyvill6", threshold=self.threshold)


class _Columns:
    """The kernel matrix of some balls: compressed columns (voxels x balls; ``indptr`` int64, ``indices``
    int32 flat voxel indices ascending within a column, ``data`` float32), kernels.sparse's layout."""

    def __init__(self, indptr, indices, data, n_rows):
        self.indptr, self.indices, self.data, self.n_rows = indptr, indices, data, int(n_rows)

    @property
    def shape(self):
        return self.n_rows, len(self.indptr) - 1

    def dot(self, w):
        """A w (float64, every voxel)."""
        out = np.empty(self.n_rows)
        sparse.column_sum(self.indptr, self.indices, self.data, np.ascontiguousarray(w, dtype=float), out)
        return out

    def tdot(self, v):
        """A^T v (float64, one a ball)."""
        out = np.empty(self.shape[1])
        sparse.column_dots(self.indptr, self.indices, self.data, np.ascontiguousarray(v, dtype=float), out)
        return out

    def select(self, keep):
        return _Columns(*sparse.select_columns(self.indptr, self.indices, self.data,
                                               np.ascontiguousarray(keep, dtype=np.bool_)), self.n_rows)

    @staticmethod
    def hstack(parts):
        offsets = np.cumsum([0] + [len(a.indices) for a in parts[:-1]])
        indptr = np.concatenate([parts[0].indptr[:1]] + [a.indptr[1:] + o for a, o in zip(parts, offsets)])
        return _Columns(indptr, np.concatenate([a.indices for a in parts]),
                        np.concatenate([a.data for a in parts]), parts[0].n_rows)

    def toarray(self):
        return sp.csc_matrix((self.data, self.indices, self.indptr), shape=self.shape).toarray()


class _Problem:
    """The grid, its voxel size and the columns of the kernel matrix of the balls in play."""

    def __init__(self, density, lower, upper):
        self.y = np.ascontiguousarray(density, dtype=float)
        self.shape = np.array(self.y.shape)
        self.lower = np.asarray(lower, dtype=float)
        self.upper = np.asarray(upper, dtype=float)
        self.h = (self.upper - self.lower) / self.shape
        self.yflat = self.y.ravel()
        self.ynorm = float(np.linalg.norm(self.yflat))
        self.occupied = self.y > 0

    def columns(self, centers, radius):
        """The matrix (_Columns: voxels x balls, float32) of k(|x_v - c|^2 / R^2) at the voxel centres x_v;
        ``radius`` one for all or one a ball."""
        centers = np.asarray(centers, dtype=float).reshape(-1, 3)
        idx = np.ascontiguousarray((centers - self.lower) / self.h - 0.5)   # continuous voxel index
        radii = np.ascontiguousarray(np.broadcast_to(np.asarray(radius, dtype=float), (len(centers),)))
        indptr, rows, vals = sparse.kernel_columns(idx, radii, np.ascontiguousarray(self.h, dtype=float),
                                                   self.shape.astype(np.int64))
        return _Columns(indptr, rows, vals, int(np.prod(self.shape)))

    def blocks(self, spacing):
        """The lattice of ``spacing`` (physical; stretched per axis to fill the box): (counts per axis, the
        block index of every voxel, flat, in density.ravel() order, and the stretched step per axis)."""
        counts = np.maximum(1, np.floor((self.upper - self.lower) / spacing + 1e-9).astype(np.int64))
        step = (self.upper - self.lower) / counts
        vidx = [np.minimum(((np.arange(s) + 0.5) * self.h[a] // step[a]).astype(np.int64), counts[a] - 1)
                for a, s in enumerate(self.shape)]
        key = (vidx[0][:, None, None] * counts[1] + vidx[1][None, :, None]) * counts[2] + vidx[2][None, None, :]
        return counts, key.ravel().astype(np.int32 if counts.prod() < 2 ** 31 else np.int64), step

    def lattice(self, spacing):
        """(centres, block keys, largest step) of the lattice of ``spacing`` at the middle of each block of
        voxels that holds density."""
        counts = np.maximum(1, np.floor((self.upper - self.lower) / spacing + 1e-9).astype(np.int64))
        step = (self.upper - self.lower) / counts
        if not hasattr(self, "_occupied_index"):   # the occupied voxels alone: the search tries many spacings
            self._occupied_index = np.nonzero(self.occupied)
        b = [np.minimum(((i + 0.5) * self.h[a] // step[a]).astype(np.int64), counts[a] - 1)
             for a, i in enumerate(self._occupied_index)]
        keys = np.unique((b[0] * counts[1] + b[1]) * counts[2] + b[2])
        bi = np.stack(np.unravel_index(keys, tuple(counts)), axis=1)
        return self.lower + (bi + 0.5) * step, keys, float(step.max())

def _fista(A, y, w0, iterations, tol=STALL):
    """min 0.5 |A w - y|^2, w >= 0: accelerated projected gradient on unit-norm columns, with adaptive
    restart (O'Donoghue & Candes 2015), in single precision (half the memory traffic of the matrix-vector
    products, which take the time; the weights need no more; each product sums in double precision).
    The products run on every core (cloudmeta.kernels.sparse), with the same bits whatever the number of
    threads. Stops after ``iterations`` or once ten iterations lower the squared residual by less than
    ``tol`` of it. Returns w (float64) and the iterations run."""
    indptr = np.asarray(A.indptr, dtype=np.int64)
    # only the voxels that some ball reaches take part (the others add a constant to the residual)
    rows, local = sparse.compact_rows(np.asarray(A.indices, dtype=np.int32), np.int64(A.shape[0]))
    m, n = len(rows), A.shape[1]
    y = y[rows].astype(np.float32)
    data = np.empty(len(local), dtype=np.float32)
    norms = sparse.scale_columns(indptr, np.asarray(A.data, dtype=np.float32), data)
    # B (voxels x balls) read along its rows: the transpose of the columns
    bptr, bidx, bval = sparse.transpose(indptr, local, data, np.int64(m), np.int64(TRANSPOSE_BLOCKS))
    bidx = bidx.view(np.uint32)
    # blocks of rows of about equal entries, as many whatever the number of threads (determinism)
    bounds = np.searchsorted(bptr, np.arange(BLOCKS + 1) * (bptr[-1] / BLOCKS)).astype(np.int64)
    bounds[0], bounds[-1] = 0, m
    partial = np.empty((BLOCKS, n))
    r = np.empty(m, dtype=np.float32)
    g = np.empty(n, dtype=np.float32)

    def gradient(v, target):
        sparse.gradient(bptr, bidx, bval, bounds, v, target, r, partial, g)
        return g

    # step 1 / L, L >= |B|^2: the least of the largest row sum of the non-negative Gram matrix B^T B
    # (Gershgorin, from the first product) and 1.1 x the Rayleigh quotient after POWER steps of the power
    # iteration from the uniform vector (0.94-0.98 of |B|^2 on the fit's matrices, measured)
    zero = np.zeros(m, dtype=np.float32)
    v = np.ones(n, dtype=np.float32)
    lam = np.inf
    for k in range(POWER):
        gv = gradient(v, zero).astype(np.float64)
        if k == 0:
            lam = float(gv.max())
        rayleigh = float(np.dot(v, gv) / np.dot(v, v))
        v = (gv / np.linalg.norm(gv)).astype(np.float32)
    lam = min(lam, 1.1 * rayleigh)
    step = np.float32(1.0 / lam)
    x = np.maximum(w0 * norms, 0.0).astype(np.float32)
    z, t = x.copy(), 1.0
    f_old = np.inf
    for it in range(iterations):
        gradient(z, y)
        x_new = np.maximum(z - step * g, np.float32(0.0))
        t_new = 0.5 * (1.0 + math.sqrt(1.0 + 4.0 * t * t))
        if np.dot(z - x_new, x_new - x) > 0:   # restart: momentum points uphill
            t_new = 1.0
            z = x_new.copy()
        else:
            z = x_new + np.float32((t - 1.0) / t_new) * (x_new - x)
        x, t = x_new, t_new
        if it % 10 == 9:
            f = float(np.dot(r.astype(np.float64), r))
            if f_old - f < tol * f_old:
                break
            f_old = f
    return x.astype(np.float64) / norms, it + 1


def _progress(total, show):
    if not show:
        return None
    from tqdm import tqdm
    return tqdm(total=total, unit="ball", desc="fit", leave=False)


def _quasi_interpolant(A, y):
    """Weights q_j = (a_j . y) / (a_j . A 1): each ball takes the kernel-weighted mean of the grid over its
    support, divided by how many balls cover it there (Shepard's normalisation): a start near the solution
    for a lattice, so that the solver needs fewer iterations."""
    den = A.tdot(A.dot(np.ones(A.shape[1])))
    return np.where(den > 0, A.tdot(y) / np.maximum(den, 1e-300), 0.0)


def _radius_factor(P, centers, step, iterations):
    """The radius of the first lattice, in lattice steps: of RADIUS_FACTORS, the one whose short solve
    leaves the least residual, tried on the middle of the box where the grid is large: its middle eighth,
    or TRIAL_STEPS lattice steps a side where that is less (the lattice is the same there; a few thousand
    balls decide as well as all)."""
    sub, c = P, centers
    if (P.shape >= 32).all():
        half = np.minimum(P.shape // 4, np.ceil(0.5 * TRIAL_STEPS * step / P.h).astype(np.int64))
        lo_i, hi_i = P.shape // 2 - half, P.shape // 2 + half
        lower, upper = P.lower + lo_i * P.h, P.lower + hi_i * P.h
        inner = ((centers > lower) & (centers < upper)).all(axis=1)
        y = P.y[lo_i[0]:hi_i[0], lo_i[1]:hi_i[1], lo_i[2]:hi_i[2]]
        if inner.sum() >= 8 and (y > 0).any():
            sub, c = _Problem(y, lower, upper), centers[inner]
    best = None
    for f in RADIUS_FACTORS:
        A = sub.columns(c, f * step)
        w, _ = _fista(A, sub.yflat, _quasi_interpolant(A, sub.yflat), iterations)
        res = float(np.linalg.norm(A.dot(w) - sub.yflat))
        if best is None or res < best[0] * (1 - 1e-9):
            best = (res, f)
    return best[1]


def _choose_radii(P, levels, order, which, local, r, factor, add):
    """Of the candidate blocks ``order`` (indices into which/local), the ``add`` best, each at the best of
    RADIUS_CHOICES times its level's radius: scored by the decrease of the squared residual that ball alone
    would give, (a_j . r)_+^2 / |a_j|^2. Returns (the chosen entries of order, their radius multipliers)."""
    cc = np.empty((len(order), 3))
    cr = np.empty(len(order))
    for li in range(min(2, len(levels))):
        sel = which[order] == li
        s_l, counts, key, unused, st = levels[li]
        bi = np.stack(np.unravel_index(unused[local[order[sel]]], tuple(counts)), axis=1)
        cc[sel] = P.lower + (bi + 0.5) * st
        cr[sel] = factor * float(st.max())
    best, best_m = np.zeros(len(order)), np.ones(len(order))
    for m in RADIUS_CHOICES:
        C = P.columns(cc, cr * m)
        dots = C.tdot(r)
        norms = sparse.scale_columns(C.indptr, C.data, np.empty_like(C.data))
        score = np.where(dots > 0, dots ** 2 / norms ** 2, 0.0)

        better = score > best * (1 + 1e-12)
        best[better], best_m[better] = score[better], m
    top = np.lexsort((np.arange(len(order)), -best))[:add]
    top = top[best[top] > 0]
    return order[top], best_m[top]


def fit_arrays(density, lower, upper, balls=None, error=None, *, iterations=200, progress=None,
               error_check=None, max_rounds=40, growth=0.5):
    """Fit balls to ``density`` (float (nx, ny, nz), >= 0) on the box [lower, upper]; see ``fit_volume``.
    ``error_check(result) -> float``, if given, is the error that ``error`` targets (else the density L2
    error on the grid). Each round adds ``growth`` times the balls in play (at least 64)."""
    start, cpu0 = time.perf_counter(), time.process_time()
    P = _Problem(density, lower, upper)
    if P.ynorm == 0.0:
        raise InputError("grid: the density is 0 everywhere; there is nothing to fit")
    budget = int(balls) if balls is not None else max(8, int(P.occupied.sum()) // 4)
    if progress is None:
        progress = sys.stderr.isatty()
    bar = _progress(budget, progress)

    # 1. the first lattice: the finest spacing whose occupied blocks stay within FIRST_SHARE of the budget
    target = max(1, int(FIRST_SHARE * budget))
    if error is not None:  # an error target: start coarse (a ball per 4^3 occupied voxels at most), grow
        target = min(target, max(8, int(P.occupied.sum()) // 64))
    hmin = float(P.h.min())
    spacing = float((P.upper - P.lower).max())
    centers, _, step = P.lattice(spacing)
    while spacing / 1.1 >= hmin:
        c2, _, s2 = P.lattice(spacing / 1.1)
        if len(c2) > target:
            break
        spacing, centers, step = spacing / 1.1, c2, s2

    factor = _radius_factor(P, centers, step, iterations // 3)
    radii = np.full(len(centers), factor * step)
    A = P.columns(centers, factor * step)
    w, its = _fista(A, P.yflat, _quasi_interpolant(A, P.yflat), iterations // 2)

    def prune(centers, radii, w, A):
        keep = w > 0
        return centers[keep], radii[keep], w[keep], A.select(keep)

    centers, radii, w, A = prune(centers, radii, w, A)
    r = P.yflat - A.dot(w)             # the residual, kept for the next round's scores
    err = float(np.linalg.norm(r) / P.ynorm)
    rounds = [{"balls": int(len(w)), "spacing": step, "density_error": err, "iterations": its}]
    if bar is not None:
        bar.update(len(w))

    # 2. refinement: finer lattices (spacing halved each), their blocks scored by the residual
    levels = []          # [spacing, counts, block key of every voxel, unused block keys]
    s = spacing / 2
    while s >= 0.5 * hmin and len(levels) < 5:   # down to two balls a voxel
        counts, key, st = P.blocks(s)
        levels.append([s, counts, key, np.unique(key[P.yflat > 0]), st])
        s /= 2
    for _ in range(max_rounds):
        if len(w) >= 0.98 * budget or not levels:  # the last 2 % would cost rounds of little gain
            break
        if error is not None:
            e = err if error_check is None else error_check(
                _result(centers, radii, w, P, err, rounds, start, cpu0, factor))
            rounds[-1]["target_error"] = e
            if e <= error:
                break
        add = max(1, min(budget - len(w), max(int(growth * len(w)), 64)))
        gains, picks = [], []
        for li, (s_l, counts, key, unused, st) in enumerate(levels[:2]):
            total = np.bincount(key, weights=r, minlength=int(np.prod(counts)))[unused]
            n = np.bincount(key, minlength=int(np.prod(counts)))[unused]
            gains.append(np.where(total > 0, total ** 2 / np.maximum(n, 1), 0.0))
            picks.append(np.full(len(unused), li))
        gain = np.concatenate(gains)
        which = np.concatenate(picks)
        local = np.concatenate([np.arange(len(g)) for g in gains])
        multi = len(RADIUS_CHOICES) > 1
        order = np.lexsort((local, which, -gain))[:CANDIDATES * add if multi else add]
        order = order[gain[order] > 0]
        if len(order) == 0:
            break
        mult = np.ones(len(order))
        if multi:
            order, mult = _choose_radii(P, levels, order, which, local, r, factor, add)
        new_c, new_r = [], []
        for li in range(min(2, len(levels))):
            at = np.flatnonzero(which[order] == li)
            if len(at) == 0:
                continue
            sort = np.argsort(local[order[at]], kind="stable")
            chosen, m_l = local[order[at]][sort], mult[at][sort]
            s_l, counts, key, unused, st = levels[li]
            bi = np.stack(np.unravel_index(unused[chosen], tuple(counts)), axis=1)
            new_c.append(P.lower + (bi + 0.5) * st)
            new_r.append(factor * float(st.max()) * m_l)
            levels[li][3] = np.delete(unused, chosen)
        levels = [lv for lv in levels if len(lv[3])]
        new_c, new_r = np.concatenate(new_c), np.concatenate(new_r)
        cols = [P.columns(new_c[new_r == R], R) for R in np.unique(new_r)]
        new_c = np.concatenate([new_c[new_r == R] for R in np.unique(new_r)])
        new_r = np.concatenate([new_r[new_r == R] for R in np.unique(new_r)])
        centers = np.concatenate([centers, new_c])
        radii = np.concatenate([radii, new_r])
        A = _Columns.hstack([A] + cols)
        w, its = _fista(A, P.yflat, np.concatenate([w, np.zeros(len(new_c))]), iterations // 2)
        centers, radii, w, A = prune(centers, radii, w, A)
        r = P.yflat - A.dot(w)
        err_old, err = err, float(np.linalg.norm(r) / P.ynorm)
        rounds.append({"balls": int(len(w)), "spacing": float(radii.min() / factor), "density_error": err,
                       "iterations": its})
        if err > (1.0 - 1e-3) * err_old:  # the candidates left no longer help
            break
        if bar is not None:
            bar.n = min(budget, int(len(w)))
            bar.refresh()
    if bar is not None:
        bar.close()
    w, its = _fista(A, P.yflat, w, iterations)   # a last, longer solve of the final set
    rounds[-1]["last_solve_iterations"] = its
    centers, radii, w, A = prune(centers, radii, w, A)
    err = float(np.linalg.norm(A.dot(w) - P.yflat) / P.ynorm)
    return _result(centers, radii, w, P, err, rounds, start, cpu0, factor)


def _result(centers, radii, w, P, err, rounds, start, cpu0, factor, source="", variable=""):
    return FitResult(centers=centers.copy(), radii=radii.copy(), weights=w.copy(), lower=P.lower.copy(),
                     upper=P.upper.copy(), density_error=err, rounds=list(rounds),
                     seconds=time.perf_counter() - start, cpu_seconds=time.process_time() - cpu0,
                     radius_factor=factor, source=source, variable=variable)


def _as_grid(grid, variable=None, time=None):
    """A VoxelGrid from a VoxelGrid, a path, or a (density, lower, upper) tuple."""
    from .grid import VoxelGrid, read_grid
    if isinstance(grid, VoxelGrid):
        return grid
    if isinstance(grid, tuple) and len(grid) == 3:
        density, lower, upper = grid
        return VoxelGrid(np.asarray(density, dtype=float), np.asarray(lower, float), np.asarray(upper, float),
                         "", "", "")
    return read_grid(grid, variable=variable, time=time)


def check_grid(grid):
    """Refuse a grid that cannot be fitted, in one line naming it."""
    where = grid.source or "grid"
    d = np.asarray(grid.density)
    if d.ndim != 3 or min(d.shape) < 2:
        raise InputError(f"{where}: expected a 3D grid of at least 2 voxels a side, got shape {d.shape}")
    if not np.isfinite(d).all() or (d < 0).any():
        raise InputError(f"{where}: the density must be finite and >= 0")
    if not (d > 0).any():
        raise InputError(f"{where}: the density is 0 everywhere; there is nothing to fit")
    if not (np.asarray(grid.upper, float) > np.asarray(grid.lower, float)).all():
        raise InputError(f"{where}: the box's upper corner must exceed its lower corner on every axis")


def fit_volume(grid, output=None, *, balls=None, error=None, variable=None, time=None, rays=None,
               overwrite=False, progress=None, command=None):
    """Fit metaballs to a voxel cloud and measure the fit (docs/fit.md).

    grid      a VoxelGrid (cloudmeta.fit.read_grid), a path read by read_grid, or (density, lower, upper)
    output    a scene path (.yaml): the scene and its balls file (same name, .csv) are written atomically;
              an existing file is replaced only with ``overwrite`` and only if cloudmeta fit wrote it
    balls     the most balls; error: the target relative RMSE of optical depth along the random rays.
              The fit stops at whichever comes first; with neither, error = 0.03
    variable, time   passed to read_grid for a path
    rays      rays of the optical-depth error (default error.RAYS = 10^4)
    Returns the FitResult with ``errors`` set: {'density', 'depth', 'rays', 'samples'} (cloudmeta.fit.error).
    """
    from . import error as E
    from .writer import check_paths, normalised, write_fit
    for label, v, ok in (("balls", balls, lambda v: isinstance(v, (int, np.integer)) and not isinstance(v, bool)
                          and v >= 1),
                         ("error", error, lambda v: isinstance(v, (int, float)) and not isinstance(v, bool)
                          and 0 < v < 1)):
        if v is not None and not ok(v):
            raise InputError(f"{label}: expected {'an integer >= 1' if label == 'balls' else 'a number in (0, 1)'}"
                             f", got {v!r}"[:200])
    if balls is None and error is None:
        error = 0.03
    g = _as_grid(grid, variable, time)
    check_grid(g)
    inputs = [g.source] if g.source else []
    if output is not None:
        check_paths(output, overwrite, inputs)
    n_rays = E.RAYS if rays is None else int(rays)
    reference = E.depth_reference(g.density, g.lower, g.upper, n_rays)

    def written_blob(result):
        from ..scene.blob import Blob
        c, r, q, scale, threshold = normalised(result)
        return Blob(c, r, q, kernel="wyvill6", threshold=threshold), scale

    def check(result):
        blob, scale = written_blob(result)
        return E.depth_error(blob, scale, g.density, g.lower, g.upper, reference=reference)[0]

    budget = balls
    if budget is None:  # an error target alone: at most a ball for every 2 occupied voxels
        budget = max(8, int((np.asarray(g.density) > 0).sum()) // 2)
    result = fit_arrays(g.density, g.lower, g.upper, balls=budget, error=error, progress=progress,
                        error_check=check if error is not None else None)
    result.source, result.variable = g.source, g.variable
    blob, scale = written_blob(result)
    result.errors = {"density": E.density_error(blob, scale, g.density, g.lower, g.upper),
                     "depth": E.depth_error(blob, scale, g.density, g.lower, g.upper, reference=reference)[0],
                     "rays": n_rays, "samples": E.SAMPLES}
    if output is not None:
        result.paths = write_fit(result, output, result.errors, overwrite, command, inputs)
    return result
