"""The field F on a regular grid, with a spatial cull: each sample visits only the balls near it.

Balls are binned by their axis-aligned support boxes into a coarse uniform grid of cells (counting sort
into two flat arrays: ``cell_start`` and ``cell_items``, the balls of cell c being
``cell_items[cell_start[c]:cell_start[c + 1]]`` in increasing ball index). A sample sums the balls of its
cell in that order, so F is bit-for-bit what the unculled sum ``trace.field_at`` gives at the same point:
both add the same non-zero terms in the same order, and balls left out are exactly those whose support
cannot contain the point.

Why that is exact: cell indices are ``clamp(floor((x - cell_origin) / cell_size))``, a non-decreasing
function of x in floating point (subtraction, division by a positive number and floor all preserve
order). A ball whose support holds x has lo - pad <= x <= hi + pad on each axis (pad absorbs rounding
in the box), so the point's cell lies between the cells of lo - pad and hi + pad, which the ball was
binned into.
"""
import numpy as np
from numba import njit, prange

from .config import NJIT, NJIT_PARALLEL
from .metaball import field_sum
from .records import BlobRecord


@njit(**NJIT)
def cell_index(x, cell_origin, cell_size, n_cells):
    """The cell of coordinate x along one axis, clamped to [0, n_cells - 1] (clamped in float, so that a
    far point never converts an out-of-range float to int)."""
    v = (x - cell_origin) / cell_size
    if v < 0.0:
        return 0
    if v >= n_cells:
        return n_cells - 1
    return int(v)


@njit(**NJIT)
def _ball_cells(bounds, b, pad, cell_origin, cell_size, cell_dims):
    """(i0, i1, j0, j1, k0, k1): the inclusive range of cells that ball b's padded box touches."""
    i0 = cell_index(bounds[b, 0] - pad, cell_origin[0], cell_size, cell_dims[0])
    j0 = cell_index(bounds[b, 1] - pad, cell_origin[1], cell_size, cell_dims[1])
    k0 = cell_index(bounds[b, 2] - pad, cell_origin[2], cell_size, cell_dims[2])
    i1 = cell_index(bounds[b, 3] + pad, cell_origin[0], cell_size, cell_dims[0])
    j1 = cell_index(bounds[b, 4] + pad, cell_origin[1], cell_size, cell_dims[1])
    k1 = cell_index(bounds[b, 5] + pad, cell_origin[2], cell_size, cell_dims[2])
    return i0, i1, j0, j1, k0, k1


@njit(**NJIT)
def bin_balls(bounds, pad, cell_origin, cell_size, cell_dims):
    """Counting sort of the balls into cells: (cell_start (n_cells + 1,), cell_items).

    bounds: (N, 6) per-ball support boxes [lo(3), hi(3)]; pad: absolute margin added to every box;
    cell_dims: (3,) cells per axis, cell c = i + nx (j + ny k). Balls are visited in index order in both
    passes, so each cell's list is sorted by ball index (the summation order of the unculled field).
    """
    nx, ny = cell_dims[0], cell_dims[1]
    n_cells = cell_dims[0] * cell_dims[1] * cell_dims[2]
    cell_start = np.zeros(n_cells + 1, np.int64)
    for b in range(bounds.shape[0]):
        i0, i1, j0, j1, k0, k1 = _ball_cells(bounds, b, pad, cell_origin, cell_size, cell_dims)
        for k in range(k0, k1 + 1):
            for j in range(j0, j1 + 1):
                for i in range(i0, i1 + 1):
                    cell_start[i + nx * (j + ny * k) + 1] += 1
    for c in range(n_cells):
        cell_start[c + 1] += cell_start[c]
    cell_items = np.empty(cell_start[n_cells], np.int64)
    fill = cell_start[:n_cells].copy()
    for b in range(bounds.shape[0]):
        i0, i1, j0, j1, k0, k1 = _ball_cells(bounds, b, pad, cell_origin, cell_size, cell_dims)
        for k in range(k0, k1 + 1):
            for j in range(j0, j1 + 1):
                for i in range(i0, i1 + 1):
                    c = i + nx * (j + ny * k)
                    cell_items[fill[c]] = b
                    fill[c] += 1
    return cell_start, cell_items


@njit(**NJIT_PARALLEL)
def sample_field(origin, spacing, dims, blob, cells, out):
    """F at every point origin + (i, j, k) * spacing of a dims[0] x dims[1] x dims[2] grid, written to the
    flat ``out`` with x fastest (index i + nx (j + ny k), VTK's order); ``blob`` a records.BlobRecord,
    ``cells`` its balls binned by bin_balls (a records.CellGrid). One prange iteration per grid row
    (fixed j, k): each writes only its own slice of ``out``, so the result does not depend on threads."""
    # records are unpacked before the prange loop and rebuilt in it (see kernels.trace.trace_rays)
    centers, frames, weights, kernel, blobbiness, threshold = blob
    cell_origin, cell_size, cell_dims, cell_start, cell_items = cells
    nx, ny, nz = dims[0], dims[1], dims[2]
    cnx, cny = cell_dims[0], cell_dims[1]
    for row in prange(ny * nz):
        blob_r = BlobRecord(centers, frames, weights, kernel, blobbiness, threshold)
        j = row % ny
        k = row // ny
        x = np.empty(3)
        x[1] = origin[1] + j * spacing[1]
        x[2] = origin[2] + k * spacing[2]
        cj = cell_index(x[1], cell_origin[1], cell_size, cell_dims[1])
        ck = cell_index(x[2], cell_origin[2], cell_size, cell_dims[2])
        for i in range(nx):
            x[0] = origin[0] + i * spacing[0]
            c = cell_index(x[0], cell_origin[0], cell_size, cell_dims[0]) + cnx * (cj + cny * ck)
            out[i + nx * row] = field_sum(x, blob_r, cell_items, cell_start[c], cell_start[c + 1])
