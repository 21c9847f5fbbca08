"""The wyvill6 field of sets of ellipsoidal balls, in numpy: exact through a grid of cells (``_Field``)
or sampled on a regular grid and read back trilinearly (``_GridField``), for placing puffs."""
from __future__ import annotations

import numpy as np

from ..scene.blob import rotation_matrix
from .params import THRESHOLD


def _kernel(u):
    """wyvill6, k(u) = (1 - u)^2 (1 - 4u/9) for u < 1, else 0 (docs/model.md §1)."""
    v = np.clip(1.0 - u, 0.0, None)
    return v * v * (5.0 / 9.0 + (4.0 / 9.0) * v)


def iso_u(weight):
    """u at which a lone ball of this weight reaches T: q k(u) = T (0 where q <= T: never inside)."""
    q = np.asarray(weight, dtype=np.float64)
    lo, hi = np.zeros_like(q), np.ones_like(q)
    for _ in range(48):  # k decreases on [0, 1]: bisection, the same steps for every ball
        mid = 0.5 * (lo + hi)
        inside = q * _kernel(mid) >= THRESHOLD
        lo = np.where(inside, mid, lo)
        hi = np.where(inside, hi, mid)
    return np.where(q > THRESHOLD, lo, 0.0)


#: the 27 neighbouring cells of a cell
_OFFSETS = np.stack(np.meshgrid([-1, 0, 1], [-1, 0, 1], [-1, 0, 1], indexing="ij"), -1).reshape(-1, 3)
#: pairs (query, ball) evaluated at once: bounds the temporary memory (~100 bytes a pair)
_CHUNK_PAIRS = 1 << 20
#: groups this small are evaluated ball by ball over all queries
_BRUTE = 24


class _Group:
    """Balls of one level: their field at query points, through a grid of cells as wide as the largest
    support (a query meets only the balls whose centres lie in its cell and the 26 around it)."""

    def __init__(self, centers, radii, angles, weights):
        self.c = np.ascontiguousarray(centers, dtype=np.float64)
        self.q = np.ascontiguousarray(weights, dtype=np.float64)
        radii = np.asarray(radii, dtype=np.float64)
        angles = np.asarray(angles, dtype=np.float64)
        self.sphere = bool(np.all(radii == radii[:, :1]) and not np.any(angles))
        if self.sphere:
            self.inv_r2 = 1.0 / radii[:, 0] ** 2
        else:  # u = |M (x - c)|^2, M = S^-1 Q^T: rows are the ellipsoid's axes over their radii
            m = rotation_matrix(angles).transpose(0, 2, 1) / radii[:, :, None]
            self.m = np.ascontiguousarray(m.reshape(-1, 9))
        self.n = len(self.c)
        if self.n > _BRUTE:
            self.h = float(radii.max()) * 1.0000001
            cells = np.floor(self.c / self.h).astype(np.int64)
            self.lo = cells.min(axis=0) - 1
            self.dims = cells.max(axis=0) - self.lo + 2
            keys = self._keys(cells - self.lo)
            self.order = np.argsort(keys, kind="stable")
            skeys = keys[self.order]
            n_cells = int(np.prod(self.dims))
            if n_cells <= 1 << 21:  # a dense table: start and count of every cell
                self.start = np.searchsorted(skeys, np.arange(n_cells), "left")
                self.count = np.searchsorted(skeys, np.arange(n_cells), "right") - self.start
                self.skeys = None
            else:
                self.skeys = skeys

    def _keys(self, cells):
        return (cells[..., 0] * self.dims[1] + cells[..., 1]) * self.dims[2] + cells[..., 2]

    def _u(self, p, idx):
        d = p - self.c[idx]
        if self.sphere:
            return np.einsum("ij,ij->i", d, d) * self.inv_r2[idx]
        m = self.m[idx]
        u = np.zeros(len(idx))
        for r in range(3):
            v = m[:, 3 * r] * d[:, 0] + m[:, 3 * r + 1] * d[:, 1] + m[:, 3 * r + 2] * d[:, 2]
            u += v * v
        return u

    def add_to(self, points, out):
        n_pts = len(points)
        if n_pts == 0:
            return
        if self.n <= _BRUTE:
            for i in range(self.n):
                idx = np.full(n_pts, i)
                out += self.q[i] * _kernel(self._u(points, idx))
            return
        cells = np.floor(points / self.h).astype(np.int64) - self.lo
        step = max(1, _CHUNK_PAIRS // 64)
        for s in range(0, n_pts, step):
            self._add_chunk(points[s:s + step], cells[s:s + step], out[s:s + step])

    def _add_chunk(self, points, cells, out):
        nb = cells[:, None, :] + _OFFSETS[None, :, :]
        valid = np.all((nb >= 0) & (nb < self.dims), axis=2)
        keys = self._keys(np.where(valid[:, :, None], nb, 0))
        if self.skeys is None:
            start = self.start[keys]
            count = np.where(valid, self.count[keys], 0)
        else:
            start = np.searchsorted(self.skeys, keys, "left")
            count = np.where(valid, np.searchsorted(self.skeys, keys, "right") - start, 0)
        start, count = start.ravel(), count.ravel()
        total = int(count.sum())
        if total == 0:
            return
        query = np.repeat(np.repeat(np.arange(len(points)), 27), count)
        first = np.cumsum(count) - count
        pos = np.arange(total) - np.repeat(first - start, count)
        ball = self.order[pos]
        u = self._u(points[query], ball)
        near = u < 1.0
        out += np.bincount(query[near], weights=self.q[ball[near]] * _kernel(u[near]), minlength=len(points))


class _Field:
    """The field of the levels placed so far: one _Group per level."""

    def __init__(self):
        self.groups = []

    def add(self, centers, radii, angles, weights):
        if len(centers):
            self.groups.append(_Group(centers, radii, angles, weights))

    def __call__(self, points):
        out = np.zeros(len(points))
        for g in self.groups:
            g.add_to(points, out)
        return out


class _GridField:
    """The field of some levels sampled on a regular grid (spacing ``step``) over ``lo``..``hi``, read back
    by trilinear interpolation: what placing the puffs asks of the field, hundreds of thousands of times,
    at a cost per query independent of how many balls overlap there. Each ball is added to the grid points
    of its support's box (vectorised over the balls of a level, in chunks)."""

    def __init__(self, lo, hi, step):
        self.step = float(step)
        self.lo = np.asarray(lo, np.float64) - 2 * self.step
        self.dims = (np.ceil((np.asarray(hi) - self.lo) / self.step).astype(np.int64) + 3)
        self.f = np.zeros(int(np.prod(self.dims)))

    def add(self, centers, radii, angles, weights):
        if not len(centers):
            return
        m = rotation_matrix(angles).transpose(0, 2, 1) / radii[:, :, None]          # (n, 3, 3)
        half = np.sqrt(np.einsum("nkj,nj->nk", rotation_matrix(angles) ** 2, radii ** 2))
        first = np.floor((centers - half - self.lo) / self.step).astype(np.int64)
        span = (np.floor((centers + half - self.lo) / self.step).astype(np.int64) - first + 1)
        # balls of similar spans share one box of offsets: sort by span, chunk, box = the chunk's largest
        order = np.argsort(span.prod(axis=1), kind="stable")
        pos = 0
        while pos < len(order):
            box = span[order[pos]]
            count = max(1, int(_CHUNK_PAIRS // max(int(np.prod(box)), 1)))
            idx = order[pos:pos + count]
            box = span[idx].max(axis=0)
            count = max(1, int(_CHUNK_PAIRS // int(np.prod(box))))
            idx = idx[:count]
            pos += len(idx)
            self._add_chunk(centers[idx], m[idx], weights[idx], first[idx], box)

    def _add_chunk(self, centers, m, weights, first, box):
        # u = x^T G x with G = M^T M, over the box of grid points: one broadcast term per entry of G
        g = np.einsum("nki,nkj->nij", m, m)
        n = len(centers)
        axes = []
        for k in range(3):
            idx = first[:, k, None] + np.arange(box[k])[None, :]                          # (n, b_k)
            x = self.lo[k] + idx * self.step - centers[:, k, None]
            shape = [n, 1, 1, 1]
            shape[k + 1] = box[k]
            axes.append((idx.reshape(shape), x.reshape(shape), (idx >= 0) & (idx < self.dims[k])))
        (ix, x, vx), (iy, y, vy), (iz, z, vz) = axes
        gx = g.reshape(n, 9, 1, 1, 1)
        u = gx[:, 0] * x * x + gx[:, 4] * y * y + gx[:, 8] * z * z
        if np.any(g[:, 0, 1]) or np.any(g[:, 0, 2]) or np.any(g[:, 1, 2]):
            u = u + 2.0 * (gx[:, 1] * x * y + gx[:, 2] * x * z + gx[:, 5] * y * z)
        valid = vx.reshape(n, -1, 1, 1) & vy.reshape(n, 1, -1, 1) & vz.reshape(n, 1, 1, -1)
        near = valid & (u < 1.0)
        flat = (ix * self.dims[1] + iy) * self.dims[2] + iz
        flat = np.broadcast_to(flat, u.shape)[near]
        contrib = (weights.reshape(n, 1, 1, 1) * _kernel(u))[near]
        if len(flat):
            first_point = int(flat.min())
            summed = np.bincount(flat - first_point, weights=contrib)
            self.f[first_point:first_point + len(summed)] += summed

    def __call__(self, points):
        g = (np.asarray(points) - self.lo) / self.step
        i = np.floor(g).astype(np.int64)
        inside = np.all((i >= 0) & (i < self.dims - 1), axis=1)
        i = np.where(inside[:, None], i, 0)
        t = np.where(inside[:, None], g - i, 0.0)
        d1, d2 = self.dims[1] * self.dims[2], self.dims[2]
        base = i[:, 0] * d1 + i[:, 1] * d2 + i[:, 2]
        out = np.zeros(len(g))
        for dx in (0, 1):
            wx = t[:, 0] if dx else 1.0 - t[:, 0]
            for dy in (0, 1):
                wy = t[:, 1] if dy else 1.0 - t[:, 1]
                for dz in (0, 1):
                    wz = t[:, 2] if dz else 1.0 - t[:, 2]
                    out += wx * wy * wz * self.f[base + dx * d1 + dy * d2 + dz]
        return np.where(inside, out, 0.0)


def _grid_for(levels, step, max_points=1 << 22):
    """A _GridField of these levels over their supports (and a margin for the next puffs)."""
    c = np.concatenate([lv.c for lv in levels])
    r = np.concatenate([lv.r for lv in levels])
    a = np.concatenate([lv.a for lv in levels])
    half = np.sqrt(np.einsum("nkj,nj->nk", rotation_matrix(a) ** 2, r ** 2))
    lo, hi = (c - half).min(axis=0), (c + half).max(axis=0)
    step = max(step, (float(np.prod(hi - lo)) / max_points) ** (1.0 / 3.0))
    grid = _GridField(lo - step, hi + step, step)
    for lv in levels:
        grid.add(lv.c, lv.r, lv.a, lv.q)
    return grid


def _solve_u(k_value):
    """u with k(u) = k_value (0 < k_value < 1), by bisection."""
    lo, hi = 0.0, 1.0
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        if _kernel(np.array(mid)) > k_value:
            lo = mid
        else:
            hi = mid
    return lo
