"""kernels.shared: a sample ray's optical depth against the naive depth of each medium (tests/naive.py), its
profile NaN where the ray does not reach a node (and at every node of a ray that misses), the first node
always reached, the tails' numbers keyed by the ray's key alone."""
import numpy as np

from cloudmeta.kernels.media import n_media
from cloudmeta.kernels.shared import depth_tails
from cloudmeta.kernels.tracking import alloc_track_work
from cloudmeta.renderer.pack import pack_scene, pixel_directions
from cloudmeta.renderer.shared import TAUS, Lattice
from tests import naive
from tests.kernels.test_ground import two_media_scene


def tails_of(lattice, rows, cols, keys, tails):
    n = len(rows)
    mean, var, depth = np.empty((n, len(TAUS), 3)), np.empty((n, len(TAUS), 3)), np.empty(n)
    rec = lattice.packed.records
    depth_tails(lattice.camera, rec, lattice.packed.quadrature, lattice.path_settings, lattice.grid, lattice.volumes,
                lattice.cache, rows, cols, keys, TAUS, tails, lattice.seed, alloc_track_work(np.int64(n_media(rec.media))), mean,
                var, depth)
    return mean, var, depth


def test_depths_profiles_and_keys(tmp_path, rng):
    s = two_media_scene(tmp_path, rng)
    packed = pack_scene(s, 0)
    lattice = Lattice(s, packed, 3, 8)
    rows = np.repeat(np.arange(4, dtype=np.int64), 4)
    cols = np.tile(np.arange(4, dtype=np.int64), 4)
    mean, var, depth = tails_of(lattice, rows, cols, rows * 4 + cols, np.full(len(TAUS), 4, np.int64))
    media = [(m.blob, m.density.mode, m.density.scale) for m in s.media]
    dirs = pixel_directions(packed.camera, rows, cols)
    want = np.array([naive.media_optical_depth(media, np.asarray(packed.camera.position), d) for d in dirs])
    assert np.count_nonzero(want > 0.0) >= 4
    np.testing.assert_allclose(depth, want, rtol=1e-9, atol=1e-12)
    reached = TAUS[None, :] < depth[:, None]
    reached[:, 0] = depth > 0.0  # the first node moves to half the depth of a thin ray
    assert np.array_equal(~np.isnan(mean[..., 0]), reached)
    assert np.all(var[reached] >= 0.0) and np.all(mean[reached] >= 0.0)
    # a ray's numbers depend on its key alone: the same key elsewhere in the batch, the same values
    again, _, _ = tails_of(lattice, rows[::-1].copy(), cols[::-1].copy(), (rows * 4 + cols)[::-1].copy(),
                           np.full(len(TAUS), 4, np.int64))
    np.testing.assert_array_equal(again[::-1], mean)
    other, _, _ = tails_of(lattice, rows, cols, rows * 4 + cols + 100, np.full(len(TAUS), 4, np.int64))
    assert not np.array_equal(np.nan_to_num(other), np.nan_to_num(mean))
