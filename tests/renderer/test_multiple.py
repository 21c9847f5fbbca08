"""Multiple scattering (cloudmeta.multiple, kernels.multiple, kernels.sampling): the sampling routines
against their densities, the white furnace, max_order 1, determinism across threads, the scene keys."""
from dataclasses import replace

import numba
import numpy as np
import pytest

import cloudmeta as cm
from cloudmeta.errors import SceneError
from cloudmeta.kernels.bernstein import bernstein_cumulative
from cloudmeta.kernels.kinds import DOUBLE_HG, HG, ISOTROPIC, RAYLEIGH
from cloudmeta.kernels.optics import phase
from cloudmeta.kernels.sampling import (SOBOL_V, _sobol32, free_flight, owen_scramble, sample_phase_cos, sobol4, turn,
                                        uniform)
from cloudmeta.renderer.multiple import render_multiple

FURNACE = """
image: {width: 8, height: 8, spp: 1}
camera: {position: [0, -8, 0], look_at: [0, 0, 0], up: [0, 0, 1], fov: 20}
background: [0.5, 0.7, 1.0]
media:
  - name: puff
    kernel: wyvill6
    threshold: 0.3
    density: {mode: field, scale: 4.0}
    albedo: 1.0
    phase: {type: hg, g: 0.6}
    balls:
      - {center: [0, 0, 0], radius: 1.5, weight: 1.0}
      - {center: [0.8, 0.3, 0.4], radius: 1.0, weight: 0.8}
render: {scattering: multiple, max_order: 100000, ms_spp: 1024}
"""

LIT = """
image: {width: 6, height: 6, spp: 1}
camera: {position: [0, -8, 0], look_at: [0, 0, 0], up: [0, 0, 1], fov: 30}
lights:
  - {type: directional, direction: [0.3, -0.5, 0.8], irradiance: 3.0}
  - {type: point, position: [2, -2, 3], intensity: 10.0}
media:
  - name: puff
    kernel: wyvill6
    threshold: 0.3
    density: {mode: field, scale: 3.0}
    albedo: 0.9
    phase: {type: double_hg, g1: 0.7, g2: -0.3, w: 0.8}
    balls:
      - {center: [0, 0, 0], radius: 1.5, weight: 1.0}
  - name: haze
    kernel: murakami4
    threshold: 0.2
    density: {mode: uniform, scale: 0.5}
    albedo: 1.0
    phase: {type: rayleigh}
    balls:
      - {center: [0.5, 0, 0.5], radius: 1.2, weight: 1.0}
surfaces:
  - {name: ground, kernel: wyvill6, threshold: 0.5, color: [0.6, 0.6, 0.6],
     balls: [{center: [0, 0, -6], radius: 5.0, weight: 1.0}]}
render: {scattering: multiple, max_order: 16, ms_spp: 8}
"""


def _scene(tmp_path, text, name="scene.yaml"):
    path = tmp_path / name
    path.write_text(text)
    return cm.load_scene(path)


# ------------------------------------------------------------------------------------------ sampling

def _moments(kind, g1=0.0, g2=0.0, w=1.0, n=20000):
    """E[cos] and E[cos^2] of the sampler on a stratified grid of u (the lobe picked by a second grid)."""
    u = (np.arange(n) + 0.5) / n
    lobe = ((np.arange(n) * 7919) % n + 0.5) / n
    mu = np.array([sample_phase_cos(kind, g1, g2, w, a, b) for a, b in zip(lobe, u)])
    return mu.mean(), (mu * mu).mean()


def _phase_moments(kind, g1=0.0, g2=0.0, w=1.0):
    """The same moments of the phase function itself, integrated over the sphere (2 pi d mu)."""
    x, wt = np.polynomial.legendre.leggauss(400)
    p = np.array([phase(kind, g1, g2, w, m) for m in x]) * 2 * np.pi
    return (wt * p).sum(), (wt * p * x).sum(), (wt * p * x * x).sum()


@pytest.mark.parametrize("kind,g1,g2,w", [(ISOTROPIC, 0, 0, 1), (HG, 0.6, 0, 1), (HG, -0.3, 0, 1), (HG, 0.95, 0, 1),
                                          (DOUBLE_HG, 0.8, -0.4, 0.7), (RAYLEIGH, 0, 0, 1)])
def test_phase_sampling_matches_the_phase_function(kind, g1, g2, w):
    m1, m2 = _moments(kind, g1, g2, w)
    norm, p1, p2 = _phase_moments(kind, g1, g2, w)
    assert norm == pytest.approx(1.0, abs=1e-6)
    assert m1 == pytest.approx(p1, abs=2e-3)
    assert m2 == pytest.approx(p2, abs=2e-3)


def test_phase_sampling_histogram_hg():
    """The sampled cos theta of HG(0.7) in 20 bins against the CDF of the phase function."""
    g = 0.7
    n = 40000
    rng = np.random.default_rng(1)
    mu = np.array([sample_phase_cos(HG, g, 0.0, 1.0, 0.0, u) for u in rng.random(n)])
    edges = np.linspace(-1, 1, 21)
    counts, _ = np.histogram(mu, edges)
    x, wt = np.polynomial.legendre.leggauss(64)
    expected = []
    for a, b in zip(edges[:-1], edges[1:]):
        m = 0.5 * (a + b) + 0.5 * (b - a) * x
        expected.append(0.5 * (b - a) * (wt * np.array([phase(HG, g, 0, 1, v) for v in m])).sum() * 2 * np.pi)
    expected = n * np.array(expected)
    chi2 = ((counts - expected) ** 2 / expected).sum()
    assert chi2 < 45  # 19 degrees of freedom: p ~ 1e-3


def test_turn_keeps_the_angle_and_unit_length():
    rng = np.random.default_rng(2)
    out = np.empty(3)
    for _ in range(200):
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        cos_t = rng.uniform(-1, 1)
        turn(d, cos_t, rng.random(), out)
        assert np.linalg.norm(out) == pytest.approx(1.0, abs=1e-12)
        assert out @ d == pytest.approx(cos_t, abs=1e-10)
    turn(np.array([0.0, 0.0, -1.0]), 0.3, 0.2, out)  # the frame's singular side
    assert out @ np.array([0.0, 0.0, -1.0]) == pytest.approx(0.3, abs=1e-12)


def test_free_flight_inverts_the_exact_optical_depth():
    rng = np.random.default_rng(3)
    for _ in range(200):
        c = rng.uniform(0.0, 3.0, 7)
        if rng.random() < 0.3:
            c[rng.integers(7)] = 0.0  # zero density at an end or inside: still monotone
        w = rng.uniform(0.01, 5.0)
        total = w * bernstein_cumulative(c, 1.0)
        for frac in (0.0, 1e-9, rng.random(), 1.0 - 1e-9, 1.0):
            target = frac * total
            s = free_flight(c, w, target)
            assert 0.0 <= s <= 1.0
            assert w * bernstein_cumulative(c, s) == pytest.approx(target, abs=1e-12 * max(total, 1))


def test_uniform_stream_is_keyed_and_uniform():
    a = uniform(0, 5, 3, 2, 1)
    assert a == uniform(0, 5, 3, 2, 1)
    keys = [(0, 5, 3, 2, 2), (0, 5, 3, 3, 1), (0, 5, 4, 2, 1), (0, 6, 3, 2, 1), (1, 5, 3, 2, 1)]
    assert all(uniform(*k) != a for k in keys)
    x = np.array([uniform(0, p, s, 0, 0) for p in range(100) for s in range(100)])
    assert x.min() >= 0.0 and x.max() < 1.0
    assert x.mean() == pytest.approx(0.5, abs=0.01)
    assert np.corrcoef(x[:-1], x[1:])[0, 1] == pytest.approx(0.0, abs=0.03)


def _sobol_unscrambled(n):
    """Sobol's first four dimensions at indices 0 .. n - 1, straight from the direction numbers."""
    out = np.zeros((n, 4))
    for i in range(n):
        for d in range(4):
            v, k, j = 0, 0, i
            while j:
                if j & 1:
                    v ^= int(SOBOL_V[d, k])
                j >>= 1
                k += 1
            out[i, d] = v / 2.0 ** 32
    return out


def test_sobol_direction_numbers_match_scipy():
    """The same point sets as scipy's Sobol (Joe-Kuo numbers); scipy enumerates them in Gray-code order, so
    every aligned block of 2^m points is compared as a set."""
    qmc = pytest.importorskip("scipy.stats.qmc")
    ref = qmc.Sobol(4, scramble=False).random(1024)
    mine = _sobol_unscrambled(1024)
    for m in (4, 7, 10):
        n = 2 ** m
        assert np.array_equal(np.sort(mine[:n], axis=0), np.sort(ref[:n], axis=0))
        assert np.array_equal(mine[:n][np.lexsort(mine[:n].T)], ref[:n][np.lexsort(ref[:n].T)])


def test_sobol_byte_tables_match_the_direction_numbers():
    """The kernel's Sobol point (four byte lookups) is the XOR of the direction numbers over the index's set
    bits, for indices that use all 32 bits (the paths' shuffled indices do)."""
    rng = np.random.default_rng(11)
    for index in rng.integers(0, 2 ** 32, 200, dtype=np.uint64):
        for d in range(4):
            v = 0
            for k in range(32):
                if int(index) >> k & 1:
                    v ^= int(SOBOL_V[d, k])
            assert int(_sobol32(np.uint64(index), d)) == v


def test_owen_scramble_is_a_nested_permutation():
    """Owen scrambling permutes each binary digit as a function of the digits above it: 256 points, one per
    stratum of width 2^-8, stay one per stratum, and points that share their leading digit still share one."""
    rng = np.random.default_rng(5)
    for seed in rng.integers(0, 2 ** 32, 4):
        x = np.arange(256, dtype=np.uint64) << np.uint64(24)  # 256 equal strata of [0, 1)
        y = np.array([owen_scramble(v, np.uint64(seed)) for v in x], dtype=np.uint64)
        assert len(set((y >> np.uint64(24)).tolist())) == 256  # still one point per stratum
        # values sharing their top k digits still share them after scrambling
        top = y[:128] >> np.uint64(31)
        assert len(set(top.tolist())) == 1


def test_sobol4_is_a_scrambled_net_per_pixel_and_block():
    """The first 2^m paths of a pixel's block: one point in each of 2^m equal slices of every dimension and
    in each 16 x 16 cell of dimensions 0 and 1 (a (0, 2)-net); other pixels and blocks differ."""
    pts = np.array([sobol4(3, 17, p, 2) for p in range(256)])
    assert pts.min() >= 0.0 and pts.max() < 1.0
    for d in range(4):
        assert np.all(np.histogram(pts[:, d], bins=256, range=(0, 1))[0] == 1)
    cells = np.histogram2d(pts[:, 0], pts[:, 1], bins=16, range=[[0, 1], [0, 1]])[0]
    assert np.all(cells == 1)
    assert sobol4(3, 17, 5, 2) == sobol4(3, 17, 5, 2)
    for key in [(4, 17, 5, 2), (3, 18, 5, 2), (3, 17, 5, 3)]:
        assert sobol4(*key) != sobol4(3, 17, 5, 2)
    # two blocks of one pixel are not paired point for point
    other = np.array([sobol4(3, 17, p, 3) for p in range(256)])
    assert abs(np.corrcoef(pts[:, 0], other[:, 0])[0, 1]) < 0.2


# ------------------------------------------------------------------------------------------ renders

def test_white_furnace(tmp_path):
    """Albedo 1, heterogeneous density, a uniform environment, no lights: every pixel shows exactly the
    environment, within the estimate's own standard error."""
    scene = _scene(tmp_path, FURNACE)
    image = cm.render(scene, progress=False).astype(np.float64)
    bg = np.array(scene.background)
    for track_from in (2, 4, 10 ** 6):  # tracked from vertex 2 (the default), from 4, never
        furnace = replace(scene, render=replace(scene.render, track_from=track_from))
        image = cm.render(furnace, progress=False).astype(np.float64)
        ms, err = render_multiple(furnace)
        inside = ms[..., 0] > 0  # the pixels whose camera ray meets the medium
        assert inside.sum() >= 16
        mean = image[..., :3][inside].mean(axis=0)
        assert np.all(np.abs(mean / bg - 1.0) < 0.01)
        # tracked, with albedo 1, a path's estimate is the same for every path of its camera ray (the
        # escape sees bg, roulette never plays): err is then 0 and the float32 image rounds to bg
        z = (image[..., :3][inside] - bg) / np.sqrt(err[inside] ** 2 + (4 * 2.0 ** -24 * bg) ** 2)
        assert np.mean(np.abs(z) < 3.0) >= 0.97
        assert np.abs(z).max() < 5.0
    outside = image[..., :3][~inside]  # the camera ray misses the medium: the background, exactly (float32)
    np.testing.assert_array_equal(outside, np.broadcast_to(bg.astype(np.float32), outside.shape))


def test_max_order_one_is_single_scattering(tmp_path):
    """Without an environment the Monte Carlo part of max_order 1 is exactly zero: the image is the
    single-scattering image at the same (uncalibrated: multiple scattering is not calibrated) settings bit for
    bit."""
    scene = _scene(tmp_path, LIT)
    single = cm.render(replace(scene, render=replace(scene.render, scattering="single", calibrate=False)),
                       progress=False)
    one = replace(scene, render=replace(scene.render, max_order=1))
    mean, err = render_multiple(one)
    assert np.all(mean == 0.0) and np.all(err == 0.0)
    np.testing.assert_array_equal(cm.render(one, progress=False), single)
    multiple = cm.render(scene, progress=False)
    assert np.all(multiple[..., :3] >= single[..., :3])
    assert multiple[..., :3].sum() > single[..., :3].sum() * 1.01  # orders >= 2 add light


def test_bit_identical_across_threads(tmp_path):
    scene = _scene(tmp_path, LIT)
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = render_multiple(scene, seed=3)
        numba.set_num_threads(max(2, before))
        many = render_multiple(scene, seed=3)
    finally:
        numba.set_num_threads(before)
    np.testing.assert_array_equal(one[0], many[0])
    np.testing.assert_array_equal(one[1], many[1])
    other = render_multiple(scene, seed=4)
    assert not np.array_equal(one[0], other[0])


def test_scene_keys(tmp_path):
    scene = _scene(tmp_path, LIT)
    assert (scene.render.scattering, scene.render.max_order, scene.render.ms_spp) == ("multiple", 16, 8)
    plain = _scene(tmp_path, LIT.replace("render: {scattering: multiple, max_order: 16, ms_spp: 8}", ""), "p.yaml")
    assert (plain.render.scattering, plain.render.max_order, plain.render.ms_spp) == ("single", 64, None)
    auto = _scene(tmp_path, LIT.replace("ms_spp: 8", "ms_spp: auto"), "a.yaml")
    assert auto.render.ms_spp is None
    assert plain.render.track_from == 2
    for bad, key in (("scattering: many", "render.scattering"), ("max_order: 0", "render.max_order"),
                     ("ms_spp: 1.5", "render.ms_spp"), ("ms_spp: many", "render.ms_spp: .*or auto"),
                     ("track_from: 1", "render.track_from")):
        text = LIT.replace("render: {scattering: multiple, max_order: 16, ms_spp: 8}", f"render: {{{bad}}}")
        with pytest.raises(SceneError, match=key):
            _scene(tmp_path, text, "bad.yaml")


def test_tracked_and_exact_flights_agree(tmp_path):
    """The lit scene (a directional light through the shadow-map control variate, a point light through ratio
    tracking, two media, a surface): tracked from vertex 2, from 3 and never, 512 paths per pixel; the image
    means agree within 3 standard errors, and no pixel differs by more than 4.5."""
    scene = _scene(tmp_path, LIT)
    runs = {}
    for track_from in (2, 3, 10 ** 6):
        tracked = replace(scene, render=replace(scene.render, track_from=track_from, max_order=64))
        runs[track_from] = render_multiple(tracked, paths=512, seed=1)
    exact_mean, exact_err = runs[10 ** 6]
    lit = exact_err[..., 0] > 0
    for track_from in (2, 3):
        mean, err = runs[track_from]
        se = np.sqrt(np.sum(err[lit] ** 2) + np.sum(exact_err[lit] ** 2)) / lit.sum()
        assert abs(mean[lit].mean() - exact_mean[lit].mean()) < 3 * se
        z = (mean - exact_mean)[lit] / np.sqrt(err[lit] ** 2 + exact_err[lit] ** 2)
        assert np.abs(z).max() < 4.5


def test_ambient_is_refused_in_multiple_mode(tmp_path):
    scene = _scene(tmp_path, "ambient: [0.1, 0.1, 0.1]\n" + LIT)
    with pytest.raises(SceneError, match="ambient"):
        cm.render(scene, progress=False)
    with pytest.raises(SceneError, match="ambient"):
        render_multiple(scene)


def test_slab_against_adding_doubling(tmp_path):
    """One slab case of validation/accuracy/multiple_scattering.py (tau 2, albedo 0.8, g 0; reflected and
    transmitted radiance at nu ~ 0.6) within 1 % or 3 standard errors of iadpython."""
    pytest.importorskip("iadpython")  # a validation-only dependency (the dev extra)
    from validation.accuracy import multiple_scattering as ms
    rows = ms.slab(tmp_path, quick=True)
    assert len(rows) == 2
    for r in rows:
        assert abs(r["rel"]) < 0.01 or abs(r["z"]) < 3, r
        assert abs(r["rel"]) < 0.03, r


def test_tile_equals_the_same_pixels_of_the_frame(tmp_path):
    """rows / columns: the Monte Carlo part of a tile is the same pixels of the whole frame (the random
    stream is keyed by the pixel), and so is the rendered tile."""
    scene = _scene(tmp_path, LIT)
    mean, err = render_multiple(scene, seed=2)
    tile, tile_err = render_multiple(scene, seed=2, rows=(1, 4), columns=(2, 5))
    np.testing.assert_array_equal(tile, mean[1:4, 2:5])
    np.testing.assert_array_equal(tile_err, err[1:4, 2:5])
    whole = cm.render(scene, progress=False, seed=2)
    np.testing.assert_array_equal(cm.render(scene, progress=False, seed=2, rows=(1, 4), columns=(2, 5)),
                                  whole[1:4, 2:5])


# ------------------------------------------------------------------------------------------ planned paths

PLANNED = LIT.replace("image: {width: 6, height: 6, spp: 1}", "image: {width: 20, height: 18, spp: 1}").replace(
    "render: {scattering: multiple, max_order: 16, ms_spp: 8}", "render: {scattering: multiple, max_order: 16, quality: draft}")


def test_planned_paths_meet_their_target_and_tiles_agree(tmp_path):
    """ms_spp auto: a pilot over the frame plans paths per 16 x 16 block so that the paths' estimated relative
    RMSE against the scattered light meets the preset's target (draft: 10 %); the estimate the render reports is
    within the target, the plan gives the blocks that hold the cloud more paths than the empty ones, and a tile
    or one thread gives the same pixels as the whole frame on all threads (one plan per frame)."""
    from cloudmeta.renderer.frame import render_frame
    from cloudmeta.renderer.multiple import BLOCK, MIN_PATHS
    scene = _scene(tmp_path, PLANNED)
    result = render_frame(scene, progress=False, seed=3)
    plan = result.plan
    assert plan is not None and plan.target == 0.10 and result.settings.target == 0.10
    assert plan.paths.shape == (2, 2) and plan.paths.min() >= MIN_PATHS
    assert plan.paths.max() > MIN_PATHS  # the cloud's blocks need more than the floor
    assert 0.0 < result.estimated <= 0.10
    assert plan.predicted <= 0.10
    before = numba.get_num_threads()
    try:  # one thread: the same plan, the same pixels
        numba.set_num_threads(1)
        np.testing.assert_array_equal(render_frame(scene, progress=False, seed=3).image, result.image)
    finally:
        numba.set_num_threads(before)
    tile = render_frame(scene, progress=False, seed=3, rows=(BLOCK - 3, 18), columns=(2, 19))
    np.testing.assert_array_equal(tile.image, result.image[BLOCK - 3:18, 2:19])
    np.testing.assert_array_equal(tile.plan.paths, plan.paths)
    # an explicit count is no plan, and render_multiple plans alone to the preset's target
    fixed = render_frame(replace(scene, render=replace(scene.render, ms_spp=8)), progress=False, seed=3)
    assert fixed.plan is None and fixed.settings.paths == 8
    mean, err = render_multiple(scene, seed=3, plan=plan)
    np.testing.assert_array_equal(mean, render_multiple(scene, seed=3, plan=plan, rows=(0, 18))[0])


def test_plan_spends_paths_where_the_variance_is():
    """The allocation plan_paths and the top-up use (allocation_rate, paths_at_rate): the sum of variances
    allowed exactly, each block's count in proportion to its RMS per-path standard deviation, and no other
    allocation of as many paths does better."""
    from cloudmeta.renderer.multiple import allocation_rate, paths_at_rate
    total = np.array([[4.0, 1.0], [0.0, 16.0]])
    size = np.full((2, 2), 3.0)
    n = paths_at_rate(allocation_rate(total, size, 2.0), total, size)
    used = lambda m: (total / np.where(m > 0, m, 1.0)).sum()  # noqa: E731
    assert np.isclose(used(n), 2.0)
    assert np.isclose(n[1, 1], 2 * n[0, 0]) and np.isclose(n[0, 0], 2 * n[0, 1]) and n[1, 0] == 0.0
    uniform = np.where(total > 0, (n * size).sum() / (size[total > 0]).sum(), 0.0)
    assert used(uniform) > used(n)


def test_plan_is_the_allocation_of_the_pilots_variance(tmp_path):
    """plan_paths on a frame: its counts are the allocation (times the margin, at least MIN_PATHS) of the per-path
    variance its pilot measured, and the error it predicts is the target over the margin where no floor binds."""
    from cloudmeta.renderer import multiple as rm
    from cloudmeta.renderer.pack import pack_scene
    scene = _scene(tmp_path, PLANNED)
    packed = pack_scene(scene, 3)
    plan = rm.plan_paths(scene, packed, 0.10, 0.0, seed=3)
    h, w = scene.image.height, scene.image.width
    mean, stderr = rm._paths_over(scene, packed, ((0, h), (0, w)), lambda r, c: rm.PILOT_PATHS,
                                  (3 + rm.PILOT_STREAM) % (1 << 62), False)
    total, size = rm._block_sums(stderr * stderr * rm.PILOT_PATHS)
    rate = rm.MARGIN ** 2 * rm.allocation_rate(total, size, (0.10 * mean.mean()) ** 2 * h * w * 3)
    assert plan.scale == pytest.approx(rate, rel=1e-12)
    np.testing.assert_array_equal(plan.paths, np.maximum(np.ceil(rm.paths_at_rate(rate, total, size)), rm.MIN_PATHS))
    assert plan.predicted <= 0.10 / rm.MARGIN * (1 + 1e-9)
