"""The cell grid of cloudmeta.api.viewer (cloudmeta.kernels.grid) against its naive twin: every ball's padded
box in every cell it touches, in ball order, and the culled field equal to the unculled sum."""
import numpy as np

from cloudmeta.api.rays import blob_record
from cloudmeta.kernels.grid import bin_balls, sample_field
from cloudmeta.kernels.records import CellGrid
from tests import naive
from tests.conftest import random_blob


def test_binning_matches_the_naive_twin(rng):
    blob = random_blob(rng, 120, ellipsoids=True, box=3.0)
    origin, size, dims, pad = np.array([-4.0, -4.5, -3.0]), 1.3, np.array([6, 7, 5], np.int64), 0.01
    start, items = bin_balls(blob.bounds, pad, origin, size, dims)
    want = naive.bin_balls(blob.bounds, pad, origin, size, dims)
    for c in range(int(np.prod(dims))):
        assert items[start[c]:start[c + 1]].tolist() == want.get(c, [])


def test_culled_field_equals_the_unculled_sum(rng):
    blob = random_blob(rng, 60, negative=True, box=2.5)
    origin, spacing, dims = np.array([-4.0, -4.0, -4.0]), np.array([0.5, 0.45, 0.4]), np.array([17, 18, 20], np.int64)
    cell_origin, size, cell_dims = np.array([-4.5, -4.5, -4.5]), 1.5, np.array([6, 6, 6], np.int64)
    start, items = bin_balls(blob.bounds, 1e-9, cell_origin, size, cell_dims)
    out = np.empty(int(np.prod(dims)))
    sample_field(origin, spacing, dims, blob_record(blob), CellGrid(cell_origin, size, cell_dims, start, items), out)
    k, j, i = np.meshgrid(*(np.arange(n) for n in dims[::-1]), indexing="ij")
    points = origin + np.stack([i.ravel(), j.ravel(), k.ravel()], axis=1) * spacing
    np.testing.assert_allclose(out, naive.field(blob, points), rtol=1e-12, atol=1e-14)
