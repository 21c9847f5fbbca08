"""The tracked flights (cloudmeta.kernels.tracking, docs/model.md §10.1): the majorant grid's bounds on 10^6
random points of scenes with every kernel, ellipsoids, negative weights, every density mode and two media;
a point's sigma_t against the naive field; the grid walk against the cells a fine march visits; delta
tracking's flight distribution and ratio tracking's mean against the exact optical depth."""
from types import SimpleNamespace

import numpy as np
import pytest
from numba import njit

from cloudmeta.kernels.borrow import borrow
from cloudmeta.kernels.grid import cell_index
from cloudmeta.kernels.records import PathKey
from cloudmeta.kernels.tracking import (DIM_LIGHT, alloc_track_work, delta_flight, point_sigma,
                                        tracked_transmittance, walk_advance, walk_cell, walk_start)
from cloudmeta.renderer.pack import pack_media
from cloudmeta.renderer.tracking import majorant_grid
from cloudmeta.scene.model import Density, Medium, Phase
from tests import naive
from tests.conftest import random_blob

#: per scene, its two media: (kernel, ellipsoids, negative weights, density mode, scale)
SCENES = [
    [("wyvill6", False, False, "field", 2.0), ("murakami4", True, False, "uniform", 0.7)],
    [("nishimura", True, True, "excess", 3.0), ("blinn", False, False, "field", 1.5)],
    [("blinn", True, True, "uniform", 1.0), ("wyvill6", True, True, "excess", 4.0)],
    [("murakami4", False, True, "field", 2.5), ("nishimura", False, False, "uniform", 0.4)],
]


def _media(rng, spec, n=40):
    media = []
    for k, (kernel, ellipsoids, negative, mode, scale) in enumerate(spec):
        blob = random_blob(rng, n, kernel=kernel, ellipsoids=ellipsoids, negative=negative, threshold=0.4, box=2.5)
        media.append(Medium(f"m{k}", blob, Density(mode, scale), 0.9, Phase()))
    return tuple(media)


def _naive_sigma(media, points):
    sigma = np.zeros(len(points))
    for m in media:
        f = naive.field(m.blob, points)
        rho = {"field": f, "excess": f - m.blob.threshold, "uniform": np.ones_like(f)}[m.density.mode]
        sigma += np.where(f >= m.blob.threshold, m.density.scale * rho, 0.0)
    return sigma


@njit
def _evaluate(points, grid, med):
    """Per point: sigma_t (point_sigma), and the sigma_max and sigma_min of its cell; -1 outside the grid."""
    w = alloc_track_work(med.start.shape[0] - 1)
    out = np.full((points.shape[0], 3), -1.0)
    for i in range(points.shape[0]):
        x = points[i]
        c = 0
        inside = True
        for a in range(2, -1, -1):
            lo = grid.origin[a]
            if x[a] < lo or x[a] > lo + grid.dims[a] * grid.size:
                inside = False
            c = c * grid.dims[a] + cell_index(x[a], lo, grid.size, grid.dims[a])
        if inside:
            out[i, 0], _ = point_sigma(x, grid, med, c, w.sigma)
            out[i, 1] = grid.sigma_max[c]
            out[i, 2] = grid.sigma_min[c]
    return out


@pytest.mark.parametrize("spec", SCENES)
def test_bounds_hold_on_random_points(spec):
    """250,000 points per scene (10^6 over the four): sigma_min <= sigma_t <= sigma_max in every cell,
    sigma_t = 0 outside the grid, and a point's sigma_t is the naive field's."""
    rng = np.random.default_rng(len(spec[0][0]) * 7 + len(spec[1][0]))
    media = _media(rng, spec)
    med = pack_media(media)
    grid = majorant_grid(SimpleNamespace(media=media), med, cells=24)
    lo = grid.origin
    hi = grid.origin + grid.dims * grid.size
    # mostly in the grid, some just outside it, many on cell faces (where rounding picks a neighbour)
    points = lo - 0.1 * (hi - lo) + rng.random((250_000, 3)) * 1.2 * (hi - lo)
    faces = rng.random(len(points)) < 0.2
    points[faces, 0] = lo[0] + np.round((points[faces, 0] - lo[0]) / grid.size) * grid.size
    got = _evaluate(points, grid, med)
    inside = got[:, 0] >= 0.0
    assert inside.mean() > 0.5 and np.count_nonzero(got[:, 0] > 0) > 10_000
    sigma, s_max, s_min = got[inside].T
    assert np.all(sigma <= s_max)
    assert np.all(sigma >= s_min)
    assert np.count_nonzero(s_min > 0) > 1000  # the minorant is not trivially zero
    assert s_max.sum() < 4.0 * sigma.sum()  # nor the majorant trivially loose
    outside = points[~inside][:5000]
    assert np.all(_naive_sigma(media, outside) == 0.0)
    sample = rng.choice(np.flatnonzero(inside), 5000, replace=False)
    np.testing.assert_allclose(got[sample, 0], _naive_sigma(media, points[sample]), rtol=1e-11, atol=1e-12)


@njit
def _walk_cells(o, d, t_max, grid):
    out = []
    t, t_end, walk = walk_start(o, d, t_max, grid)
    while t < t_end:
        c, t_out = walk_cell(grid, walk)
        out.append((c, t, min(t_out, t_end)))
        t = t_out
        if t >= t_end:
            break
        inside, walk = walk_advance(grid, walk)
        if not inside:
            break
    return out


def test_walk_visits_the_cells_along_the_ray():
    """The spans the walk lists tile [enter, exit], each span's midpoint lies in its cell, and every point of a
    fine march along the ray (off the cell faces) lies in a cell the walk listed."""
    rng = np.random.default_rng(3)
    media = _media(rng, SCENES[0])
    grid = majorant_grid(SimpleNamespace(media=media), pack_media(media), cells=16)
    dims, size = grid.dims, grid.size

    def cell_of(x):
        ijk = [cell_index(x[a], grid.origin[a], size, dims[a]) for a in range(3)]
        return ijk[0] + dims[0] * (ijk[1] + dims[1] * ijk[2])

    walked = 0
    for _ in range(200):
        o = grid.origin + (rng.random(3) * 1.4 - 0.2) * dims * size
        d = rng.normal(size=3)
        if rng.random() < 0.2:
            d[rng.integers(3)] = 0.0  # parallel to a plane of cell faces
        d /= np.linalg.norm(d)
        cells = _walk_cells(o, d, np.inf, grid)
        if not cells:
            continue
        walked += 1
        for (c, t0, t1), nxt in zip(cells, cells[1:]):
            assert nxt[1] == t1
        for c, t0, t1 in cells:
            assert t0 <= t1
            if t1 - t0 > 1e-9 * size:
                assert cell_of(o + 0.5 * (t0 + t1) * d) == c
        seen = {c for c, _, _ in cells}
        for t in np.linspace(cells[0][1], cells[-1][2], 500)[1:-1]:
            x = o + t * d
            off_faces = np.all(np.abs((x - grid.origin) / size - np.round((x - grid.origin) / size)) > 1e-9)
            assert cell_of(x) in seen or not off_faces
    assert walked > 50


@njit
def _flights(o, d, grid, med, n, mode):
    w_own = alloc_track_work(med.start.shape[0] - 1)
    w = borrow(w_own)
    out = np.empty(n)
    for p in range(n):
        key = PathKey(7, 11, p)
        if mode == 0:
            out[p], _, _ = delta_flight(o, d, np.inf, grid, med, key, np.int64(2), w)
        else:
            out[p] = tracked_transmittance(o, d, np.inf, grid, med, key, np.int64(2), np.int64(DIM_LIGHT), w)
    w_own.x[0] += 0.0
    return out


def _polynomial_scene():
    rng = np.random.default_rng(9)
    media = _media(rng, [("wyvill6", True, True, "field", 1.2), ("murakami4", False, False, "excess", 3.0)], n=25)
    return media, pack_media(media)


def test_delta_tracking_samples_the_exact_free_flight():
    """20,000 flights through two media: P(t < t_q) = 1 - e^-tau(t_q) at ten depths, and the escapes'
    share e^-tau, each within 4 binomial standard errors of the exact optical depth (naive twin)."""
    media, med = _polynomial_scene()
    grid = majorant_grid(SimpleNamespace(media=media), med)
    o, d = np.array([-6.0, 0.3, -0.2]), np.array([1.0, 0.05, 0.02])
    d /= np.linalg.norm(d)
    n = 20_000
    t = _flights(o, d, grid, med, n, 0)
    blobs = [(m.blob, m.density.mode, m.density.scale) for m in media]
    total = naive.media_optical_depth(blobs, o, d)
    assert total > 1.0
    for tq in np.linspace(4.0, 9.0, 10):
        p = 1.0 - np.exp(-naive.media_optical_depth(blobs, o, d, tq))
        assert abs(np.mean(t < tq) - p) < 4 * np.sqrt(p * (1 - p) / n) + 1e-9
    p_escape = np.exp(-total)
    assert abs(np.mean(np.isinf(t)) - p_escape) < 4 * np.sqrt(p_escape * (1 - p_escape) / n)


def test_ratio_tracking_is_unbiased():
    """The mean of 20,000 residual-ratio-tracking estimates is e^-tau within 4 standard errors, on a ray
    that crosses the cloud and on one that starts inside it."""
    media, med = _polynomial_scene()
    grid = majorant_grid(SimpleNamespace(media=media), med)
    blobs = [(m.blob, m.density.mode, m.density.scale) for m in media]
    for o, d in ((np.array([-6.0, 0.3, -0.2]), np.array([1.0, 0.05, 0.02])),
                 (np.array([0.2, 0.1, 0.0]), np.array([0.3, -1.0, 0.4]))):
        d = d / np.linalg.norm(d)
        est = _flights(o, d, grid, med, 20_000, 1)
        want = np.exp(-naive.media_optical_depth(blobs, o, d))
        assert 0.0 < want < 0.9
        assert abs(est.mean() - want) < 4 * est.std() / np.sqrt(len(est))
        assert est.min() >= 0.0
