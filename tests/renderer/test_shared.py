"""The approximate mode's shared method (renderer.shared, docs/approximate.md): the depth weights against
quadrature, the white furnace exactly, every pixel's own tails against the unbiased estimator, tiles and
threads bit-identical, the settings validated."""
import textwrap

import numba
import numpy as np
import pytest

from cloudmeta.errors import SceneError
from cloudmeta.renderer import render, render_frame
from cloudmeta.renderer.shared import (MIN_TAILS, NOISE_SHARE, TAUS, TailPlan, depth_weights, node_weights,
                                      tails_per_node)
from cloudmeta.scene import load_scene
from tests.renderer.test_approximate import cloud


def test_depth_weights_against_quadrature():
    """The integral over [0, U] of e^-tau times each node's hat function, closed form, against the trapezoid
    rule; the hats sum to 1, so the weights sum to 1 - e^-U."""
    depths = np.array([0.0, 0.01, 0.02, 0.3, 1.0, 4.5, 9.0, 12.0, np.inf])
    got = depth_weights(depths)
    for u, row in zip(depths, got):
        t = np.linspace(0.0, min(u, 60.0), 400001)
        hats = np.stack([np.interp(t, TAUS, np.eye(len(TAUS))[a]) for a in range(len(TAUS))])
        np.testing.assert_allclose(row, np.trapezoid(np.exp(-t) * hats, t, axis=1), atol=1e-8)
        assert row.sum() == pytest.approx(-np.expm1(-min(u, 60.0)), rel=1e-12)
    np.testing.assert_allclose(node_weights(), got[-1])
    per = tails_per_node(1000)
    assert per.min() >= 2 and abs(per.sum() - 1000) <= len(TAUS) and per[0] < per[1]


def shared_cloud(tmp_path, shared="{stride: 4, tails: 64}", max_order=16, **kw):
    return cloud(tmp_path, f"{{quality: draft, scattering: approximate, method: shared, max_order: {max_order}, "
                 f"shared: {shared}}}", **kw)


def test_white_furnace(tmp_path):
    """Albedo 1, no lights, a uniform environment: every tail sees the environment, so each node's light is
    the environment and a pixel's is the environment times its alpha; with the background seen through the
    media, exactly the environment (no path is cut short by max_order). With the cache of the deep orders, the
    environment within its photons' noise."""
    s = shared_cloud(tmp_path, "{stride: 4, tails: 64, cache: 0}", lights="[]", albedo=1.0,
                     background="[0.5, 0.7, 1.0]", size=16, max_order=100000)
    img = render(s, progress=False)
    assert np.count_nonzero(img[..., 3] > 0.5) > 20
    np.testing.assert_allclose(img[..., :3], np.broadcast_to([0.5, 0.7, 1.0], img[..., :3].shape), rtol=1e-5)
    cached = render(shared_cloud(tmp_path, "{stride: 4, tails: 64, cache: 3}", lights="[]", albedo=1.0,
                                 background="[0.5, 0.7, 1.0]", size=16, max_order=100000), progress=False)
    inside = img[..., 3] > 0.5
    np.testing.assert_allclose(cached[inside, :3].mean(axis=0), [0.5, 0.7, 1.0], rtol=0.02)
    assert not np.array_equal(cached, img)


@pytest.mark.parametrize("cache", [0, 5])
def test_own_tails_against_the_unbiased_estimator(tmp_path, cache):
    """Stride 1 (every pixel its own sample ray): the only approximation left is Q piecewise linear in the
    optical depth (and, with the cache, the cached orders beyond 5); the image's multiply scattered light agrees
    with the unbiased paths' to a few per cent."""
    from dataclasses import replace
    s = shared_cloud(tmp_path, f"{{stride: 1, tails: 2048, cache: {cache}}}", size=10)
    shared = render(s, progress=False)[..., :3].astype(np.float64)
    single = render(replace(s, render=replace(s.render, scattering="single")), progress=False).astype(np.float64)
    multi = render(replace(s, render=replace(s.render, scattering="multiple", ms_spp=2048)), progress=False)
    ms_shared, ms_paths = (shared - single[..., :3]).sum(), (multi[..., :3] - single[..., :3]).sum()
    scattered_once = (single[..., :3] - np.array([0.2, 0.3, 0.5]) * (1.0 - single[..., 3:])).sum()
    assert ms_paths > 0.5 * scattered_once  # the orders above 1 (and the sky's light) matter in this cloud
    assert ms_shared == pytest.approx(ms_paths, rel=0.03)


def test_tiles_and_threads_bit_identical(tmp_path):
    s = shared_cloud(tmp_path, "{stride: 4, tails: 32}", size=18)
    frame = render_frame(s, progress=False, error=True)
    tile = render(s, progress=False, rows=(5, 13), columns=(3, 11))
    np.testing.assert_array_equal(tile, frame.image[5:13, 3:11])
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = render_frame(s, progress=False, error=True)
    finally:
        numba.set_num_threads(before)
    np.testing.assert_array_equal(one.image, frame.image)
    np.testing.assert_array_equal(one.error, frame.error)
    assert one.approximation == frame.approximation and frame.approximation.rel_rmse > 0.0
    # the per-pixel error carries the tails' noise: more than the quadrature's alone
    octaves = render_frame(cloud(tmp_path, "{quality: draft, scattering: approximate, max_order: 16}", size=18),
                           progress=False, error=True)
    inside = frame.image[..., 3] > 0.5
    assert np.mean(frame.error[inside]) > 3.0 * np.mean(octaves.error[inside])


def test_quadrature_calibrated_to_a_share_of_the_tails_target(tmp_path, monkeypatch):
    """The shared method's exact order 1 is calibrated to SHARED_QUADRATURE of the preset's paths target, not to the
    preset's own (far tighter) target: the calibration is handed that target, and the image's quadrature error
    (against `reference`'s, the same tails) stays within half of it."""
    from dataclasses import replace
    from cloudmeta.renderer import calibrate
    from cloudmeta.renderer.quality import PRESETS, SHARED_QUADRATURE, resolve_settings
    s = shared_cloud(tmp_path, "{stride: 2, tails: 64, cache: 0}", size=24)  # the same tails at every quality
    seen = []
    real = calibrate.calibrate
    monkeypatch.setattr(calibrate, "calibrate", lambda *a: seen.append(a[-1].target) or real(*a))
    frame = render_frame(s, progress=False)
    assert frame.settings.quadrature_target == pytest.approx(SHARED_QUADRATURE * PRESETS["draft"].paths_target)
    assert seen == [frame.settings.quadrature_target] and seen[0] > 3 * PRESETS["draft"].target
    single = cloud(tmp_path, "{quality: draft}", size=24)
    assert resolve_settings(single).quadrature_target == PRESETS["draft"].target  # single scattering keeps its own
    exact = render_frame(replace(s, render=replace(s.render, quality="reference")), progress=False).image
    image = frame.image.astype(np.float64)
    scattered = (image[..., :3] - np.array([0.2, 0.3, 0.5]) * (1.0 - image[..., 3:])).mean()
    err = np.sqrt(np.mean((image[..., :3] - exact[..., :3]) ** 2)) / scattered
    assert 0.0 < err < 0.5 * frame.settings.quadrature_target


def test_planned_tails(tmp_path):
    """Without render.shared.tails the tails are planned to the preset's target from a pilot over the whole frame:
    the plan is the frame's in every tile (bit-identical tiles), it scales as 1 / target^2, and the image's noise
    (the error channels' RMS over the scattered light) comes out near the share of the target it aims at."""
    from cloudmeta.renderer.fluence import fluence_cache
    from cloudmeta.renderer.pack import pack_scene
    from cloudmeta.renderer.shared import CACHE_SEED, plan_tails
    s = shared_cloud(tmp_path, "{stride: 2}", size=24)
    frame = render_frame(s, progress=False, error=True)
    plan = frame.plan
    assert isinstance(plan, TailPlan) and plan.target == 0.10 and plan.tails > MIN_TAILS
    assert plan.cache_order == 5 and plan.deep_share >= frame.settings.shared.cache_min_share  # draft's, where it pays
    tile = render(s, progress=False, rows=(7, 19), columns=(2, 13))
    np.testing.assert_array_equal(tile, frame.image[7:19, 2:13])
    image = frame.image.astype(np.float64)
    scattered = (image[..., :3] - np.array([0.2, 0.3, 0.5]) * (1.0 - image[..., 3:])).mean()
    noise = np.sqrt(np.mean(frame.error.astype(np.float64) ** 2)) / scattered
    assert 0.3 * NOISE_SHARE * 0.10 < noise < 1.5 * NOISE_SHARE * 0.10
    assert plan.scattered_mean == pytest.approx(scattered, rel=0.2)
    packed = pack_scene(s, 0)
    settings = frame.settings.shared
    assert settings.cache_order == 5  # draft's cache, which the pilot's tails read too
    cache = fluence_cache(s, packed.records, 0 ^ CACHE_SEED, settings.cache_order, settings.cache_cells,
                          settings.cache_photons)
    half = plan_tails(s, packed, 2, 0.05, frame.scattered.mean, 0, 2 ** 24, cache)
    assert half.tails == pytest.approx(4 * plan.tails, rel=0.01) and half.predicted < plan.predicted
    assert plan_tails(s, packed, 2, 0.05, frame.scattered.mean, 0, 1000, cache).tails == 1000  # render's limit
    dark = shared_cloud(tmp_path, "{stride: 2}", size=24, lights="[]", background="[0, 0, 0]")
    assert plan_tails(dark, pack_scene(dark, 0), 2, 0.1, 0.0, 0, 2 ** 24).tails == MIN_TAILS  # nothing scatters


def test_cache_left_out_where_the_deep_orders_are_dim(tmp_path):
    """The preset's cache of the deep orders is built only where the orders beyond its order carry at least
    the preset's share of the light (deep_share): a dark cloud (albedo 0.3) renders bit-identically to ``cache: 0``,
    the usual one to the preset's order set by the scene (which a scene always gets)."""
    from cloudmeta.renderer.pack import pack_scene
    from cloudmeta.renderer.quality import PRESETS
    from cloudmeta.renderer.shared import deep_share
    images = {}
    for albedo in (0.3, 0.95):
        scenes = {key: shared_cloud(tmp_path, f"{{stride: 4, tails: 64{key}}}", albedo=albedo, size=16)
                  for key in ("", ", cache: 0", ", cache: 5")}
        packed = pack_scene(scenes[""], 0)
        share = deep_share(scenes[""], packed, 0, 5)
        assert (share < PRESETS["draft"].cache[3]) == (albedo < 0.5)
        assert deep_share(scenes[""], packed, 0, 16) == 0.0  # cut at max_order: nothing beyond it
        images[albedo] = {key: render(s, progress=False) for key, s in scenes.items()}
    dark, bright = images[0.3], images[0.95]
    np.testing.assert_array_equal(dark[""], dark[", cache: 0"])
    assert not np.array_equal(dark[", cache: 5"], dark[", cache: 0"])
    np.testing.assert_array_equal(bright[""], bright[", cache: 5"])


def test_verbose_says_whether_the_cache_was_built(tmp_path, capsys):
    """``-v`` prints the plan of the tails and what became of the preset's cache of the deep orders, with the share
    of the light that decided it."""
    from cloudmeta.cli import main
    for albedo, said in ((0.95, "the orders beyond 5 from the cache of the deep orders ("),
                         (0.3, "no cache of the deep orders (the orders beyond the preset's cache order carry")):
        s = shared_cloud(tmp_path, "{stride: 2}", size=16, albedo=albedo)
        assert main(["render", str(s.path), "-o", str(tmp_path / f"{albedo}.exr"), "-q", "-v"]) == 0
        out = capsys.readouterr()
        assert "tails planned to 0.1" in out.out + out.err and said in out.out + out.err


def test_edge_share():
    """The plan's share of the pilot's variance in blocks whose corners partly miss the media: by hand on 3 x 3
    lattice points (four blocks), one corner point missing."""
    from cloudmeta.renderer.shared import _edge_share
    var = np.array([[1.0, 2.0, 0.0], [1.0, 1.0, 3.0], [0.0, 1.0, 1.0]])
    hit = np.array([[True, True, False], [True, True, True], [True, True, True]])
    blocks = np.array([[5.0, 6.0], [3.0, 6.0]])  # each block's corner variances summed
    assert _edge_share(var, hit) == pytest.approx(6.0 / blocks.sum())
    assert _edge_share(var, np.ones((3, 3), bool)) == 0.0 and _edge_share(np.zeros((3, 3)), hit) == 0.0


def test_settings_are_validated(tmp_path):
    with pytest.raises(SceneError, match=r"render\.shared\.stride"):
        shared_cloud(tmp_path, "{stride: 3}")
    with pytest.raises(SceneError, match=r"render\.shared\.tails"):
        shared_cloud(tmp_path, "{tails: 1}")
    with pytest.raises(SceneError, match=r"render\.shared\.cache"):
        shared_cloud(tmp_path, "{cache: 1}")
    with pytest.raises(SceneError, match=r"render\.shared\.paths"):
        shared_cloud(tmp_path, "{paths: 8}")
    p = tmp_path / "surf.yaml"
    p.write_text(textwrap.dedent("""
        image: {width: 4, height: 4}
        camera: {position: [0, -9, 0.3], look_at: [0, 0, 0.2]}
        render: {scattering: approximate, method: shared}
        media: [{balls: [{center: [0, 0, 0], radius: 1.0}]}]
        surfaces: [{balls: [{center: [0, 2, 0], radius: 1.0}]}]
        """))
    with pytest.raises(SceneError, match=r"render\.method"):
        render(load_scene(p), progress=False)


def test_blocks_split_where_a_pixel_sees_another_depth_than_its_corners():
    """A block is split where a pixel's optical depth differs from the one bilinear between its corners by more than
    the factor e^DEPTH_SPLIT (depths below DEPTH_FLOOR count as DEPTH_FLOOR; the bilinear depths built by a loop over
    the pixels); a block that crosses the last row of the pixels passed reads only the rows before it."""
    from cloudmeta.renderer.shared import DEPTH_FLOOR, DEPTH_SPLIT, _unlike_corners
    rng = np.random.default_rng(7)
    s = 4
    br, bc = np.array([0, 0, 1]), np.array([0, 1, 0])

    def bilinear(corners):
        depth = np.zeros((2 * s, 2 * s))
        for k, d in enumerate(corners):
            for i in range(s):
                for j in range(s):
                    fr, fc = i / s, j / s
                    depth[br[k] * s + i, bc[k] * s + j] = ((1 - fr) * ((1 - fc) * d[0] + fc * d[1])
                                                           + fr * ((1 - fc) * d[2] + fc * d[3]))
        return depth

    corners = np.array([[0.5, 1.0, 2.0, 4.0], [0.3, 0.3, 0.3, 0.3], [0.001, 0.002, 0.01, 0.003]])
    depth = bilinear(corners)
    assert not _unlike_corners(depth, 0, 2 * s, 0, 2 * s, br, bc, s, corners).any()
    just_in, just_out = np.exp(0.9 * DEPTH_SPLIT), np.exp(1.1 * DEPTH_SPLIT)
    for factor, split in [(just_in, False), (just_out, True), (1 / just_out, True)]:
        moved = depth.copy()
        moved[2, 3] *= factor  # a pixel of the first block
        moved[6, 1] *= 5.0  # one of the third: five times its corners' depth, both below the floor
        assert moved[6, 1] < DEPTH_FLOOR
        assert list(_unlike_corners(moved, 0, 2 * s, 0, 2 * s, br, bc, s, corners)) == [split, False, False]
    # the third block rising steeply over its rows, cut after its first row: the rows beyond it (where the first
    # row's depth, clipped, would meet a bilinear depth up to 3 times as deep) do not count; whole, pixels 5-9
    # deep in its rows do
    steep = corners.copy()
    steep[2] = [0.2, 0.2, 4.0, 4.0]
    depth = bilinear(steep)
    assert not _unlike_corners(depth[:s + 1], 0, s + 1, 0, 2 * s, br, bc, s, steep).any()
    depth[s:, :s] = rng.uniform(5.0, 9.0, (s, s))
    assert list(_unlike_corners(depth, 0, 2 * s, 0, 2 * s, br, bc, s, steep)) == [False, False, True]
