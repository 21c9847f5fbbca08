"""validation/peers/mitsuba_peer.py's pure-Python helpers (no Mitsuba needed): the voxel grid Mitsuba reads holds
cloudmeta's own sigma_t at the voxel centres, in Mitsuba's layout, and the conventions it converts."""
import math
import sys

import numpy as np
import pytest

import cloudmeta as cm
from cloudmeta.api.viewer import sigma_t
from validation.peers import mitsuba_peer as mp

SCENE = """
image: {width: 8, height: 6, spp: 1}
camera: {position: [0, -10, 0], look_at: [0, 0, 0], up: [0, 0, 1], fov: 30}
background: [0.2, 0.3, 0.6]
ambient: [0.1, 0.1, 0.1]
lights:
  - {type: directional, direction: [0.6, -0.8, 0.0], irradiance: 2.0}
media:
  - name: puff
    kernel: wyvill6
    threshold: 0.4
    density: {mode: field, scale: 3.0}
    albedo: 0.9
    phase: {type: hg, g: 0.5}
    balls:
      - {center: [0, 0, 0], radius: 1.5, weight: 1.0}
      - {center: [1.1, 0.2, 0.3], radii: [1.2, 0.7, 0.6], rotation: [0, 20, 40], weight: 0.9}
"""


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    path = tmp_path_factory.mktemp("mitsuba") / "puff.yaml"
    path.write_text(SCENE)
    return cm.load_scene(path)


def test_voxel_geometry_covers_the_box_with_cubic_voxels():
    lo, hi = np.array([-1.0, 0.0, 2.0]), np.array([3.0, 1.0, 2.5])
    origin, h, dims = mp.voxel_geometry(lo, hi, 16)
    assert h == pytest.approx(0.25)
    assert dims.tolist() == [16, 4, 2]
    assert np.all(origin <= lo + 1e-12) and np.all(origin + dims * h >= hi - 1e-12)
    np.testing.assert_allclose(origin + 0.5 * dims * h, 0.5 * (lo + hi))


def test_voxel_centres_order_is_z_y_x():
    origin, h, dims = np.zeros(3), 0.5, np.array([4, 3, 2])
    c = mp.voxel_centres(origin, h, dims)
    assert c.shape == (2, 3, 4, 3)
    np.testing.assert_allclose(c[1, 2, 3], [3.5 * h, 2.5 * h, 1.5 * h])


def test_voxelise_is_cloudmeta_sigma_t_at_the_centres(scene):
    sigma, origin, h, dims = mp.voxelise(scene, 20)
    assert sigma.dtype == np.float32 and sigma.shape == (dims[2], dims[1], dims[0])
    centres = mp.voxel_centres(origin, h, dims).reshape(-1, 3)
    medium = scene.media[0]
    expected = sigma_t(medium, cm.field(medium.blob, centres)).reshape(sigma.shape)
    np.testing.assert_allclose(sigma, expected, rtol=1e-6, atol=1e-6)
    assert sigma.max() > medium.density.scale * medium.blob.threshold  # the grid does meet the inside
    assert np.count_nonzero(sigma) > 0.05 * sigma.size
    # the box holds every ball's support: the outermost voxels are outside the medium
    assert sigma[0].max() == 0 and sigma[-1].max() == 0 and sigma[:, :, 0].max() == 0


def test_light_direction_is_the_way_light_travels():
    assert mp.mitsuba_light_direction(np.array([0.6, -0.8, 0.0])) == [-0.6, 0.8, -0.0]


def test_multiple_scene_drops_ambient(scene):
    s = mp.multiple_scene(scene, 4, 32, 500)
    assert s.ambient is None and s.image.spp == 4
    assert (s.render.scattering, s.render.ms_spp, s.render.max_order) == ("multiple", 32, 500)
    assert scene.ambient is not None  # the input scene is untouched


def test_noise_of_seeds_is_per_image_noise():
    rng = np.random.default_rng(3)
    a = 1.0 + 0.1 * rng.standard_normal((64, 64, 3))
    b = 1.0 + 0.1 * rng.standard_normal((64, 64, 3))
    assert mp.noise_of_seeds([a, b]) == pytest.approx(0.1, rel=0.03)
    assert mp.noise_of_seeds([a, b]) == pytest.approx(np.sqrt(np.mean((a - b) ** 2) / 2.0), rel=1e-12)
    c = 1.0 + 0.1 * rng.standard_normal((64, 64, 3))
    assert mp.noise_of_seeds([a, b, c]) == pytest.approx(0.1, rel=0.03)
    assert mp.rel_rmse(a, a, 1.0) == 0.0
    assert math.isclose(mp.rel_rmse(a, a + 0.5, 2.0), 0.25)


def test_skips_cleanly_without_mitsuba(monkeypatch, capsys):
    # None in sys.modules makes `import mitsuba` raise ImportError, as on a machine without it (CI)
    monkeypatch.setitem(sys.modules, "mitsuba", None)
    monkeypatch.setitem(sys.modules, "drjit", None)
    assert mp.main([]) == dict(passed=True, skipped=True)
    out = capsys.readouterr().out.strip().splitlines()
    assert out == [mp.INSTALL] and "pip install mitsuba==3.8.0" in out[0]


def test_block_means():
    img = np.arange(4 * 6 * 1, dtype=np.float64).reshape(4, 6, 1)
    m = mp.block_means(img, 2)
    assert m.shape == (2, 3, 1)
    assert m[0, 0, 0] == np.mean([0, 1, 6, 7]) and m[1, 2, 0] == np.mean([16, 17, 22, 23])


def test_agreement_sees_a_bias_the_noise_hides_per_pixel():
    rng = np.random.default_rng(5)
    truth = np.ones((32, 32, 3))
    se = np.full_like(truth, 0.05)
    a = truth + 0.05 * rng.standard_normal(truth.shape)
    b = 1.01 * truth + 0.05 * rng.standard_normal(truth.shape)  # 1 % bias under 7 % noise per pixel
    r = mp.agreement(a, se, b, se)
    assert r["rel_mean"] == pytest.approx(0.01, abs=4 * r["se_rel_mean"])
    assert r["block_noise_rel"] == pytest.approx(r["noise_rel"] / mp.BLOCK)
    assert r["block_bias_rel"] == pytest.approx(0.01, abs=0.005)


def test_calibrate_is_linear_and_never_runs_away():
    n, per, fixed = mp.calibrate(lambda k: 1.0 + 0.5 * k, 11.0, 4, 10 ** 6)
    assert (n, per, fixed) == (20, 0.5, 1.0)
    # a flat clock (noise, or all fixed cost) must not give the cap
    n, _, _ = mp.calibrate(lambda k: 2.0, 10.0, 4, 10 ** 6)
    assert n < 600  # ~ 8 x budget / (mean cost at 4 start), far below the cap
    # cheaper per sample at scale (cloudmeta's paths against its camera rays): the check at the first count
    # moves the count towards the budget

    def cost(k):
        return 1.0 + 0.5 * k if k <= 16 else 5.0 + 0.25 * (k - 8)
    n, _, _ = mp.calibrate(cost, 11.0, 4, 10 ** 6)
    assert n > 20 and abs(cost(n) - 11.0) < abs(cost(20) - 11.0)


def test_shared_comparison_skips_cleanly_without_mitsuba(monkeypatch, capsys):
    from validation.peers import mitsuba_shared as ms
    monkeypatch.setitem(sys.modules, "mitsuba", None)
    monkeypatch.setitem(sys.modules, "drjit", None)
    assert ms.main([]) == dict(passed=True, skipped=True)
    assert capsys.readouterr().out.strip().splitlines() == [mp.INSTALL]


def test_shared_total_error_subtracts_the_references_noise_only():
    # a render 5 % off a truth of scattered light 1 over a background 1, against a reference of two noisy halves:
    # the reference's noise is subtracted, the render's own error (bias and noise alike) is kept
    from validation.peers import mitsuba_shared as ms
    rng = np.random.default_rng(3)
    truth = 2.0 + 0.3 * rng.standard_normal((96, 96, 3))
    bt = np.ones_like(truth)
    halves = [truth + 0.1 * rng.standard_normal(truth.shape) for _ in range(2)]
    u = 0.5 * (halves[0] + halves[1])
    var = (halves[0] - halves[1]) ** 2 / 4.0
    scattered = float(np.mean(truth - bt))
    biased = [truth + 0.05 * scattered for _ in range(3)]
    assert ms.total_error(biased, u, var, bt) == pytest.approx(0.05, rel=0.05)
    noisy = [truth + 0.03 * scattered * rng.standard_normal(truth.shape) for _ in range(4)]
    assert ms.total_error(noisy, u, var, bt) == pytest.approx(0.03, rel=0.1)
