"""Light-space shadow maps (render: {shadows: map | hybrid}): exact in depth along texel rays, close to exact
shadows across them, and the same map whether or not the single tracing pass overflows; the hybrid keeps
the map only where its own error estimate allows, and counts what it did."""
import sys
from dataclasses import replace
from pathlib import Path

import numba
import numpy as np

import cloudmeta as cm
from cloudmeta.kernels.shadowmap import map_optical_depth, volume_optical_depth
from cloudmeta.renderer.frame import render_frame

ROOT = Path(__file__).resolve().parents[2]
pack_module = sys.modules["cloudmeta.renderer.pack"]


def cumulus(size=40, **settings):
    s = cm.load_scene(ROOT / "scenes" / "cumulus.yaml", width=size, height=size)
    return replace(s, render=replace(s.render, **settings))


def cumulus_map(resolution):
    s = cumulus()
    med = pack_module.pack_media(s.media)
    lo, hi = pack_module.media_bbox(s)
    return s, pack_module.build_shadow_maps(s.lights, med, lo, hi, resolution, 1e-8)


def test_map_is_exact_in_depth_on_texel_rays():
    """At a texel centre the bilinear weights pick one texel: the map's optical depth towards the light
    is the engine's exact optical depth from that point, at any depth along the texel's ray."""
    s, maps = cumulus_map(48)
    map_of, geo, res, base, start, t0, t1, c, cum, reach = maps
    g = geo[map_of[0]]
    origin, e1, e2, ray, size = g[:3], g[3:6], g[6:9], g[9:12], g[12]
    blob, m = s.media[0].blob, s.media[0]
    rng = np.random.default_rng(3)
    points = []
    for _ in range(200):
        i, j = rng.integers(0, 48, 2)
        depth = rng.uniform(0.0, 2.02 * 0.5 * np.linalg.norm(blob.bbox[1] - blob.bbox[0]))
        points.append(origin + (i + 0.5) * size * e1 + (j + 0.5) * size * e2 + depth * ray)
    points = np.array(points)
    got = np.array([map_optical_depth(p, maps, map_of[0]) for p in points])
    exact = cm.optical_depth(blob, points, np.broadcast_to(-ray, points.shape).copy(), density=m.density.mode,
                             scale=m.density.scale)
    assert np.count_nonzero(exact > 0.1) > 20  # the points do sample the cloud's shadow
    np.testing.assert_allclose(got[:, 0], exact, rtol=1e-10, atol=1e-10)


def test_bilinear_lookup_lies_within_its_texels_bounds():
    """Between texel rays the bilinear depth lies between the least and greatest of its four texels."""
    s, maps = cumulus_map(96)
    g = maps.geo[maps.map_of[0]]
    origin, e1, e2, ray, size = g[:3], g[3:6], g[6:9], g[9:12], g[12]
    rng = np.random.default_rng(5)
    u = rng.uniform(10, 86, (400, 2))
    depth = rng.uniform(0.0, np.linalg.norm(s.media[0].blob.bbox[1] - s.media[0].blob.bbox[0]), 400)
    points = origin + u[:, :1] * size * e1 + u[:, 1:] * size * e2 + depth[:, None] * ray
    bil = np.array([map_optical_depth(p, maps, maps.map_of[0]) for p in points])
    assert np.count_nonzero(bil[:, 2] > bil[:, 1]) > 50  # the points do sample the shadow's edges
    assert np.all((bil[:, 1] <= bil[:, 0] + 1e-12) & (bil[:, 0] <= bil[:, 2] + 1e-12))


def volume_points(maps, n, seed):
    g = maps.geo[maps.map_of[0]]
    origin, e1, e2, ray = g[:3], g[3:6], g[6:9], g[9:12]
    side = g[12] * maps.res[maps.map_of[0]]
    rng = np.random.default_rng(seed)
    u = rng.uniform(0.2, 0.8, (n, 3)) * side
    return origin + u[:, :1] * e1 + u[:, 1:2] * e2 + u[:, 2:] * ray


def test_volume_on_the_maps_texels_is_the_map_on_its_lattice():
    """A light volume at the map's resolution holds the map's exact depths at texel centres every texel size
    along the light; between them it is trilinear, and its lo / hi are the four columns' extremes."""
    _, maps = cumulus_map(48)
    vols = pack_module.build_light_volumes(maps, 48)
    g = vols.geo[0]
    np.testing.assert_array_equal(g, maps.geo[0])
    origin, e1, e2, ray, size = g[:3], g[3:6], g[6:9], g[9:12], g[12]
    rng = np.random.default_rng(4)
    ijk = np.column_stack([rng.integers(10, 38, (300, 2)), rng.integers(0, 49, 300)])
    points = origin + (ijk[:, :1] + 0.5) * size * e1 + (ijk[:, 1:2] + 0.5) * size * e2 + ijk[:, 2:] * size * ray
    on_map = np.array([map_optical_depth(p, maps, 0)[0] for p in points])
    on_volume = np.array([volume_optical_depth(p, vols, 0) for p in points])
    assert np.count_nonzero(on_map > 0.1) > 50
    np.testing.assert_allclose(on_volume[:, 0], on_map, rtol=1e-6, atol=1e-6)  # float32 storage
    points = volume_points(maps, 500, 6)
    on_map = np.array([map_optical_depth(p, maps, 0)[0] for p in points])
    on_volume = np.array([volume_optical_depth(p, vols, 0) for p in points])
    assert np.all((on_volume[:, 1] <= on_volume[:, 0] + 1e-6) & (on_volume[:, 0] <= on_volume[:, 2] + 1e-6))
    inside = on_map > 0.05
    assert np.count_nonzero(inside) > 50
    # the depth is only interpolated along the light as well: close to the map's, not equal
    assert np.median(np.abs(on_volume[inside, 0] - on_map[inside]) / on_map[inside]) < 0.05


def test_coarser_volume_reads_the_map_bilinearly():
    _, maps = cumulus_map(64)
    vols = pack_module.build_light_volumes(maps, 32)
    assert vols.res[0] == 32 and vols.depth_n[0] == 34
    np.testing.assert_allclose(vols.geo[0, 12], 2 * maps.geo[0, 12])
    points = volume_points(maps, 400, 7)
    on_map = np.array([map_optical_depth(p, maps, 0)[0] for p in points])
    on_volume = np.array([volume_optical_depth(p, vols, 0)[0] for p in points])
    inside = on_map > 0.05
    assert np.count_nonzero(inside) > 50
    assert np.median(np.abs(on_volume[inside] - on_map[inside]) / on_map[inside]) < 0.15


def test_single_pass_overflow_gives_the_same_map(monkeypatch):
    _, once = cumulus_map(40)
    monkeypatch.setattr(pack_module, "MAP_PIECES_PER_TEXEL", 0)  # every chunk overflows: a second pass
    _, twice = cumulus_map(40)
    for a, b in zip(once, twice):
        np.testing.assert_array_equal(a, b)


def test_map_shadows_close_to_exact_shadows():
    """Measured against exact shadows at 40 x 40: relative RMSE 1.3e-3 (map 128), 4.0e-4 (256), 2.6e-4 (384)."""
    exact = cm.render(cumulus(), progress=False)
    mapped = cm.render(cumulus(shadows="map", shadow_map=384), progress=False)
    err = np.sqrt(np.mean((mapped[..., :3] - exact[..., :3]) ** 2)) / np.sqrt(np.mean(exact[..., :3] ** 2))
    assert 0 < err < 1e-3


def scattered_rel_rmse(img, ref, background):
    scattered = ref[..., :3] - np.asarray(background) * (1.0 - ref[..., 3:4])
    return np.sqrt(np.mean((img[..., :3] - ref[..., :3]) ** 2)) / scattered.mean()


def test_hybrid_shadows_keep_the_quality_and_count_their_work():
    """shadows: hybrid against exact shadow rays at 48 x 48, default's own settings (not calibrated: each mode's
    calibration may choose its own level, and the quadrature's difference would then count too): within a tenth
    of the target relative to the scattered light; part of the nodes take the map, the rest an exact ray,
    and the counters add up: per pixel, lookups = nodes (one directional light), trusted + exact = lookups."""
    exact = render_frame(cumulus(48, quality="default", calibrate=False), progress=False)
    hybrid = render_frame(cumulus(48, quality="default", shadows="hybrid", calibrate=False), progress=False)
    plain = render_frame(cumulus(48, quality="default", shadows="map", calibrate=False), progress=False)
    bg = cumulus().background
    err = scattered_rel_rmse(np.float64(hybrid.image), np.float64(exact.image), bg)
    err_map = scattered_rel_rmse(np.float64(plain.image), np.float64(exact.image), bg)
    assert 0 < err < 1e-4 and err < err_map
    ce, ch = exact.cost(), hybrid.cost()
    assert ce["media_pixels"] == ch["media_pixels"] > 100
    assert ce["exact_rays"] == ce["nodes"] > 20 and ce["lookups"] == ce["trusted"] == 0
    n = hybrid.counts
    np.testing.assert_array_equal(n[..., 2], n[..., 0])
    np.testing.assert_array_equal(n[..., 3] + n[..., 1], n[..., 2])
    assert 0.1 * ch["nodes"] < ch["trusted"] < ch["nodes"]  # 18 % at default's own settings
    # shadows: map trusts every lookup
    np.testing.assert_array_equal(plain.counts[..., 3], plain.counts[..., 2])
    assert plain.cost()["exact_rays"] == 0


def test_hybrid_shadows_same_whatever_the_thread_count():
    s = cumulus(24, quality="default", shadows="hybrid")
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = render_frame(s, progress=False)
        numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
        two = render_frame(s, progress=False)
    finally:
        numba.set_num_threads(before)
    np.testing.assert_array_equal(one.image, two.image)
    np.testing.assert_array_equal(one.counts, two.counts)
