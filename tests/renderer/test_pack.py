"""Packing a scene into the kernels' records (cloudmeta.pack, cloudmeta.kernels.records): merged BVHs
that answer per blob, arrays of one type whatever the scene, the camera basis, the quadrature rule."""
import math
from pathlib import Path

import numpy as np
import pytest

from cloudmeta.renderer import pack
from cloudmeta.kernels import records
from cloudmeta.kernels.bvh import STACK, bvh_point_candidates
from cloudmeta.scene import load_scene
from tests.conftest import random_blob

ROOT = Path(__file__).resolve().parents[2]


def test_merged_bvh_answers_for_each_blob(rng):
    blobs = [random_blob(rng, n, box=b) for n, b in ((7, 2.0), (30, 3.0), (1, 1.0))]
    start = np.concatenate([[0], np.cumsum([len(b) for b in blobs])])
    bvh = pack.merge_bvhs(blobs, start[:-1])
    assert isinstance(bvh, records.BVH) and len(bvh.root) == 3
    stack, cand = np.empty(2 * STACK, np.int64), np.empty(start[-1], np.int64)
    for k, blob in enumerate(blobs):
        for x in rng.uniform(-3, 3, (40, 3)):
            n = bvh_point_candidates(x, bvh, bvh.root[k], stack, cand)
            lo, hi = blob.bounds[:, :3], blob.bounds[:, 3:]
            inside = np.flatnonzero(np.all((lo <= x) & (x <= hi), axis=1)) + start[k]
            got = np.sort(cand[:n])
            assert set(inside) <= set(got)  # every ball whose box holds x, and only balls of blob k
            assert np.all((got >= start[k]) & (got < start[k + 1]))


def _arrays(record):
    for value in record:
        if isinstance(value, tuple):
            yield from _arrays(value)
        elif isinstance(value, np.ndarray):
            yield value


@pytest.mark.parametrize("scene", ["scenes/two_media.yaml", "docs/surfaces.yaml", "scenes/single_ball.yaml"])
@pytest.mark.parametrize("shadows", ["exact", "map"])
def test_scene_records_have_two_types_whatever_the_scene(scene, shadows):
    """Fresh, writable, C-contiguous arrays of fixed dtypes and ranks, with or without surfaces, media
    and maps; and one of two types: None for the surfaces and the maps where a scene has neither (the
    kernels compile without their code), both records otherwise. numba compiles at most two versions."""
    from dataclasses import replace
    s = load_scene(ROOT / scene, width=4, height=4)
    from cloudmeta.renderer.quality import resolve_settings
    s = replace(s, render=replace(s.render, shadows=shadows))
    quad = pack.quadrature(replace(pack_quality(), shadows=resolve_settings(s).shadows))
    assert quad.shadow_mode == {"exact": records.SHADOWS_EXACT, "map": records.SHADOWS_MAP}[shadows]
    rec = pack.scene_records(s, quad, 8)
    full = pack.scene_records(load_scene(ROOT / "docs" / "surfaces.yaml", width=4, height=4), quad, 8)
    lean = pack.scene_records(load_scene(ROOT / "scenes" / "single_ball.yaml", width=4, height=4),
                              pack.quadrature(pack_quality()), 8)
    has_maps = shadows == "map" and bool(s.media)
    if s.surfaces or has_maps:
        assert rec.surfaces is not None and rec.lights.maps is not None
        assert rec.surfaces.start[-1] == len(rec.surfaces.centers)
        assert len(rec.lights.maps.map_of) == len(s.lights)
        assert (rec.lights.maps.map_of >= 0).any() == has_maps
        ref = full
    else:
        assert rec.surfaces is None and rec.lights.maps is None
        ref = lean
    arrays, ref_arrays = list(_arrays(rec)), list(_arrays(ref))
    assert len(arrays) == len(ref_arrays)
    for a, b in zip(arrays, ref_arrays):
        assert a.flags.c_contiguous and a.flags.writeable
        assert (a.dtype, a.ndim) == (b.dtype, b.ndim)
    assert rec.media.start[-1] == len(rec.media.centers)


def pack_quality():
    from cloudmeta.renderer.quality import Quality
    return Quality(tolerance=3e-3, max_tau=2.0, max_length=1.0, max_angle=0.2, cutoff=1e-3, tol_t=1e-9)


def test_camera_basis_spans_the_image_plane():
    s = load_scene(ROOT / "scenes" / "hand.yaml")
    fwd, right, up = pack.camera_basis(s.camera, 480, 640)
    half = math.tan(math.radians(s.camera.fov) / 2)
    assert np.linalg.norm(fwd) == pytest.approx(1.0, rel=1e-15)
    assert np.linalg.norm(up) == pytest.approx(half, rel=1e-14)
    assert np.linalg.norm(right) == pytest.approx(half * 480 / 640, rel=1e-14)
    assert abs(fwd @ right) < 1e-15 and abs(fwd @ up) < 1e-15 and abs(right @ up) < 1e-15
    assert np.cross(right, fwd) @ up > 0  # up points up


def test_quadrature_rule():
    q = pack.quadrature(pack_quality())
    assert isinstance(q, records.Quadrature)
    assert np.all(np.diff(q.kronrod_x) > 0) and 0 < q.kronrod_x[0] and q.kronrod_x[-1] < 1
    np.testing.assert_array_equal(q.gauss_x, q.kronrod_x[q.gauss_col])
    assert sorted(np.concatenate([q.gauss_col, q.kronrod_col])) == list(range(15))
    # the Lagrange bases sum to 1 at every fine point; the fine rule integrates degree 47 exactly
    np.testing.assert_allclose(q.gauss_lag.sum(axis=0), 1.0, atol=1e-12)
    np.testing.assert_allclose(q.kronrod_lag.sum(axis=0), 1.0, atol=1e-10)
    assert np.sum(q.fine_w * q.fine_y ** 20) == pytest.approx(1 / 21, rel=1e-13)
    # the Legendre tail vanishes on polynomials of degree < 5 and measures P_5, P_6
    for k in range(5):
        np.testing.assert_allclose(q.tail @ q.gauss_x ** k, 0.0, atol=1e-12)
    for j, row in ((5, 0), (6, 1)):
        p = np.polynomial.legendre.Legendre.basis(j)(2 * q.gauss_x - 1)
        assert q.tail[row] @ p == pytest.approx(1.0, rel=1e-12)
    assert q.u_stop == pytest.approx(-math.log(1e-3), rel=1e-15)
    assert pack.quadrature(pack_quality().__class__(**{**pack_quality().__dict__, "cutoff": 0.0})).u_stop == np.inf
