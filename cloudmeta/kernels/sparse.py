"""Sparse matrices of kernel values for the fit (cloudmeta.fit): building the columns, and the products.

A matrix is held as compressed columns (CSC: ``indptr`` int64, ``indices`` int32, ``data`` float32), one
column a ball, its rows the voxels the ball reaches in ascending order. The products run on every core and
give the same bits whatever the number of threads: each output entry is summed by one thread, over its
row's entries in their stored order, in double precision, the gradient ``A^T r`` in blocks of rows fixed by
the caller (``gradient``). The products read the rows, a transpose built once per solve (``transpose``: a
counting sort, its rows' entries in ascending column order).
"""
import numpy as np
from numba import njit, prange

from .config import NJIT, NJIT_INLINE, NJIT_PARALLEL
from .kinds import WYVILL6
from .metaball import falloff


@njit(**NJIT)
def _reach(idx, r, n):
    """The voxel range [lo, hi] (clamped to [0, n - 1]) around continuous index ``idx`` within ``r`` voxels."""
    lo = int(np.ceil(idx - r))
    hi = int(np.floor(idx + r))
    if lo < 0:
        lo = 0
    if hi > n - 1:
        hi = n - 1
    return lo, hi


@njit(**NJIT)
def _ball_column(j, idx, radius, h, shape, rows, vals, write):
    """Counts (and, where ``write`` >= 0, stores from position ``write``) ball j's kernel values
    k(u) (wyvill6, metaball.falloff), u = |x_v - c|^2 / R^2 < 1, at the voxel centres x_v, voxels ascending."""
    r2 = radius[j] * radius[j]
    i0, i1 = _reach(idx[j, 0], radius[j] / h[0], shape[0])
    j0, j1 = _reach(idx[j, 1], radius[j] / h[1], shape[1])
    k0, k1 = _reach(idx[j, 2], radius[j] / h[2], shape[2])
    m = 0
    for a in range(i0, i1 + 1):
        dx = (a - idx[j, 0]) * h[0]
        for b in range(j0, j1 + 1):
            dy = (b - idx[j, 1]) * h[1]
            dxy = dx * dx + dy * dy
            if dxy >= r2:
                continue
            for c in range(k0, k1 + 1):
                dz = (c - idx[j, 2]) * h[2]
                u = (dxy + dz * dz) / r2
                if u < 1.0:
                    if write >= 0:
                        rows[write + m] = (a * shape[1] + b) * shape[2] + c
                        vals[write + m] = np.float32(falloff(WYVILL6, u, 0.0))
                    m += 1
    return m


@njit(**NJIT_PARALLEL)
def kernel_columns(idx, radius, h, shape):
    """The CSC matrix (indptr, rows, values) of the wyvill6 kernel of each ball at the voxel centres of a
    grid of ``shape`` (int64 (3,)) with voxel size ``h``: ``idx`` (n, 3) the balls' centres as continuous
    voxel indices ((c - lower) / h - 0.5), ``radius`` (n,) their radii. Rows are flat voxel indices in
    C order."""
    n = idx.shape[0]
    counts = np.zeros(n, np.int64)
    dummy_r = np.zeros(0, np.int32)
    dummy_v = np.zeros(0, np.float32)
    for j in prange(n):
        counts[j] = _ball_column(j, idx, radius, h, shape, dummy_r, dummy_v, np.int64(-1))
    indptr = np.zeros(n + 1, np.int64)
    for j in range(n):
        indptr[j + 1] = indptr[j] + counts[j]
    rows = np.empty(indptr[n], np.int32)
    vals = np.empty(indptr[n], np.float32)
    for j in prange(n):
        _ball_column(j, idx, radius, h, shape, rows, vals, indptr[j])
    return indptr, rows, vals


@njit(**NJIT)
def compact_rows(indices, n_rows):
    """The rows that hold an entry (ascending, int64) and ``indices`` renumbered to their places in it."""
    used = np.zeros(n_rows, np.int32)
    for k in range(indices.shape[0]):
        used[indices[k]] = 1
    m = 0
    for i in range(n_rows):
        if used[i]:
            used[i] = m + 1
            m += 1
    rows = np.empty(m, np.int64)
    for i in range(n_rows):
        if used[i]:
            rows[used[i] - 1] = i
    local = np.empty(indices.shape[0], np.int32)
    for k in range(indices.shape[0]):
        local[k] = used[indices[k]] - 1
    return rows, local


@njit(**NJIT_INLINE)
def _run_within(indices, start, stop, lo, hi):
    """The entries [k0, k1) of one column (its sorted rows ``indices[start:stop]``) whose rows lie in [lo, hi)."""
    rows = indices[start:stop]
    return start + np.searchsorted(rows, lo), start + np.searchsorted(rows, hi)


@njit(**NJIT_PARALLEL)
def transpose(indptr, indices, data, n_rows, blocks):
    """The transpose of a compressed matrix whose rows are ascending within each column (CSC -> CSR):
    (indptr, indices, data), each row's entries in ascending column order. The rows are split into
    ``blocks`` ranges, one thread a range at a time: each finds, in every column that reaches its range,
    the run of entries inside it (the rows are sorted) and counts, then places, them; the result does not
    depend on the number of threads."""
    n = indptr.shape[0] - 1
    out_ptr = np.zeros(n_rows + 1, np.int64)
    for b in prange(blocks):
        lo, hi = b * n_rows // blocks, (b + 1) * n_rows // blocks
        for j in range(n):
            k0, k1 = _run_within(indices, indptr[j], indptr[j + 1], lo, hi)
            for k in range(k0, k1):
                out_ptr[indices[k] + 1] += 1
    for i in range(n_rows):
        out_ptr[i + 1] += out_ptr[i]
    out_idx = np.empty(indices.shape[0], np.int32)
    out_val = np.empty(indices.shape[0], np.float32)
    for b in prange(blocks):
        lo, hi = b * n_rows // blocks, (b + 1) * n_rows // blocks
        fill = out_ptr[lo:hi].copy()
        for j in range(n):
            k0, k1 = _run_within(indices, indptr[j], indptr[j + 1], lo, hi)
            for k in range(k0, k1):
                p = fill[indices[k] - lo]
                out_idx[p] = j
                out_val[p] = data[k]
                fill[indices[k] - lo] = p + 1
    return out_ptr, out_idx, out_val


@njit(**NJIT_PARALLEL)
def select_columns(indptr, indices, data, keep):
    """The columns j with keep[j] (bool), in order: (indptr, indices, data)."""
    n = indptr.shape[0] - 1
    out_ptr = np.zeros(np.int64(keep.sum()) + 1, np.int64)
    where = np.empty(out_ptr.shape[0] - 1, np.int64)
    m = 0
    for j in range(n):
        if keep[j]:
            out_ptr[m + 1] = out_ptr[m] + indptr[j + 1] - indptr[j]
            where[m] = j
            m += 1
    out_idx = np.empty(out_ptr[m], np.int32)
    out_val = np.empty(out_ptr[m], np.float32)
    for q in prange(m):
        j = where[q]
        d = out_ptr[q] - indptr[j]
        for k in range(indptr[j], indptr[j + 1]):
            out_idx[k + d] = indices[k]
            out_val[k + d] = data[k]
    return out_ptr, out_idx, out_val


@njit(**NJIT)
def column_sum(indptr, indices, data, w, out):
    """out = A w for compressed columns A (out zeroed first), in double precision, columns in order."""
    out[:] = 0.0
    for j in range(indptr.shape[0] - 1):
        for k in range(indptr[j], indptr[j + 1]):
            out[indices[k]] += data[k] * w[j]


@njit(**NJIT_PARALLEL)
def column_dots(indptr, indices, data, v, out):
    """out = A^T v for compressed columns A, in double precision: each column's dot product with v."""
    for j in prange(indptr.shape[0] - 1):
        acc = 0.0
        for k in range(indptr[j], indptr[j + 1]):
            acc += data[k] * v[indices[k]]
        out[j] = acc


@njit(**NJIT_PARALLEL)
def gradient(indptr, indices, data, bounds, x, y, r, partial, g):
    """The least-squares residual r = B x - y and gradient g = B^T r of B (rows x columns, compressed rows,
    ``indices`` uint32) in one pass over B: each row's dot product, then its entries times r_i added into the
    partial gradient of its block of rows. ``bounds`` (int64, nb + 1) splits the rows into nb blocks, fixed
    by the caller and not by the number of threads; ``partial`` (nb, columns) float64 is scratch. Each block
    is summed by one thread in row order and the blocks' partials are added in block order: the same bits
    on any number of threads."""
    nb = bounds.shape[0] - 1
    for b in prange(nb):
        p = partial[b]
        p[:] = 0.0
        for i in range(bounds[b], bounds[b + 1]):
            # unsigned loop bounds and indices: no test for negative indices in the inner loops
            start, stop = np.uint64(indptr[i]), np.uint64(indptr[i + 1])
            acc = 0.0
            for k in range(start, stop):
                acc += data[k] * np.float64(x[indices[k]])
            ri = np.float32(acc - y[i])
            r[i] = ri
            for k in range(start, stop):
                p[indices[k]] += data[k] * ri
    for j in prange(g.shape[0]):
        acc = 0.0
        for b in range(nb):
            acc += partial[b, j]
        g[j] = acc


@njit(**NJIT_PARALLEL)
def scale_columns(indptr, data, out):
    """Each column divided by its Euclidean norm (1 for an empty column) into ``out``; returns the norms."""
    n = indptr.shape[0] - 1
    norms = np.empty(n)
    for j in prange(n):
        s = 0.0
        for k in range(indptr[j], indptr[j + 1]):
            s += np.float64(data[k]) * data[k]
        s = np.sqrt(s)
        if s == 0.0:
            s = 1.0
        norms[j] = s
        for k in range(indptr[j], indptr[j + 1]):
            out[k] = np.float32(data[k] / s)
    return norms
