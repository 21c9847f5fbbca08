import numpy as np
import pytest

import cloudmeta as cm


def random_blob(rng, n, kernel="wyvill6", ellipsoids=False, negative=False, threshold=0.5, box=2.0):
    centers = rng.uniform(-box, box, (n, 3))
    if ellipsoids:
        radii = rng.uniform(0.6, 2.0, (n, 3))
        rotations = rng.uniform(0, 360, (n, 3))
    else:
        radii = rng.uniform(0.8, 2.2, n)
        rotations = None
    weights = rng.uniform(0.7, 1.5, n)
    if negative:
        weights[rng.random(n) < 0.3] *= -0.6
    return cm.Blob(centers, radii, weights, kernel=kernel, threshold=threshold, rotations=rotations)


def random_rays(rng, n, box=2.0, dist=12.0):
    """Rays from a sphere of radius ``dist`` aimed at random points of the box."""
    o = rng.normal(size=(n, 3))
    o *= dist / np.linalg.norm(o, axis=1)[:, None]
    target = rng.uniform(-box, box, (n, 3))
    d = target - o
    return o, d / np.linalg.norm(d, axis=1)[:, None]


@pytest.fixture
def rng():
    return np.random.default_rng(20261122)
