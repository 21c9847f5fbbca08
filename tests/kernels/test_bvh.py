"""The BVH (cloudmeta.kernels.bvh) against its naive twin (tests/naive.py): a walk returns every ball whose
box the ray meets (or that holds the point), and only balls of the blob it starts from."""
import numpy as np

from cloudmeta.kernels.bvh import STACK, build_bvh, bvh_candidates, bvh_point_candidates, misses_root_boxes
from cloudmeta.kernels.records import BVH
from tests import naive
from tests.conftest import random_blob, random_rays


def one_bvh(blob):
    return BVH(*build_bvh(blob.bounds, 0), np.zeros(1, np.int64))


def test_ray_walk_finds_every_box_the_ray_meets(rng):
    for n, ellipsoids in ((1, False), (9, True), (300, False), (2000, True)):
        blob = random_blob(rng, n, ellipsoids=ellipsoids, box=4.0)
        bvh = one_bvh(blob)
        stack, cand = np.empty(2 * STACK, np.int64), np.empty(n, np.int64)
        o, d = random_rays(rng, 60, box=4.0)
        d[:5] = [[1, 0, 0], [0, 1, 0], [0, 0, -1], [1, 1, 0], [0, 1, 1]]  # axis-parallel: 1/d = inf
        d[:5] /= np.linalg.norm(d[:5], axis=1)[:, None]
        for k in range(len(o)):
            for tmin, tmax in ((0.0, np.inf), (5.0, 14.0)):
                m = bvh_candidates(o[k], d[k], tmin, tmax, bvh, 0, stack, cand)
                got = set(cand[:m].tolist())
                assert len(got) == m  # no ball twice
                assert set(naive.boxes_on_ray(blob.bounds, o[k], d[k], tmin, tmax).tolist()) <= got
            # the root box is the union of the balls' boxes: missing it is missing every ball's box
            lo, hi = blob.bbox
            root_met = len(naive.boxes_on_ray(np.concatenate([lo, hi])[None], o[k], d[k])) == 1
            assert misses_root_boxes(o[k], d[k], bvh) == (not root_met)
            if not root_met:
                assert len(naive.boxes_on_ray(blob.bounds, o[k], d[k])) == 0


def test_point_walk_finds_every_box_that_holds_the_point(rng):
    blob = random_blob(rng, 500, ellipsoids=True, box=3.0)
    bvh = one_bvh(blob)
    stack, cand = np.empty(2 * STACK, np.int64), np.empty(500, np.int64)
    points = np.concatenate([rng.uniform(-5, 5, (200, 3)), blob.bounds[:20, :3], blob.bounds[:20, 3:]])
    for x in points:  # box corners included: the bounds are closed
        m = bvh_point_candidates(x, bvh, 0, stack, cand)
        assert set(naive.boxes_holding(blob.bounds, x).tolist()) <= set(cand[:m].tolist())


def test_leaves_hold_every_ball_once():
    rng = np.random.default_rng(11)
    blob = random_blob(rng, 777, box=6.0)
    box, a, b, n, items = build_bvh(blob.bounds, 5)
    leaves = np.flatnonzero(n > 0)
    held = np.concatenate([items[a[k]:a[k] + n[k]] for k in leaves])
    assert sorted(held.tolist()) == list(range(5, 5 + 777))  # first_index shifts every item
    for k in leaves:  # a leaf's box holds its balls' boxes
        mine = blob.bounds[items[a[k]:a[k] + n[k]] - 5]
        assert np.all(box[k, :3] <= mine[:, :3]) and np.all(mine[:, 3:] <= box[k, 3:])
