"""Renderer checks against closed forms (issue 3), at the tightest quadrature setting."""
import math
import textwrap

import numba
import numpy as np
import pytest

from cloudmeta.renderer import render
from cloudmeta.scene import load_scene

R = 1.0       # radius of the inside region: a wyvill6 ball of radius 2R at T = 0.5
SIGMA = 0.8   # uniform sigma_t


def scene_file(tmp_path, body, name="s.yaml"):
    p = tmp_path / name
    p.write_text(textwrap.dedent(body))
    return p


def one_ball(tmp_path, lights="[]", albedo=1.0, phase="{type: isotropic}", background="[1, 1, 1]",
             camera="{position: [0, -6, 0], look_at: [0, 0, 0], up: [0, 0, 1], fov: 1}", quality="reference",
             size=1, extra=""):
    return load_scene(scene_file(tmp_path, f"""
        image: {{width: {size}, height: {size}}}
        camera: {camera}
        background: {background}
        lights: {lights}
        render: {{quality: {quality}}}
        {extra}
        media:
          - kernel: wyvill6
            threshold: 0.5
            density: {{mode: uniform, scale: {SIGMA}}}
            albedo: {albedo}
            phase: {phase}
            balls: [{{center: [0, 0, 0], radius: {2 * R}}}]
        """))


def test_transmittance_through_the_centre(tmp_path):
    img = render(one_ball(tmp_path), progress=False)
    expected = math.exp(-2 * R * SIGMA)
    np.testing.assert_allclose(img[0, 0, :3], expected, rtol=1e-6)
    assert img[0, 0, 3] == pytest.approx(1 - expected, rel=1e-6)


def test_single_scattering_lit_from_behind_the_camera(tmp_path):
    """Light along -d (from behind the camera): the shadow ray retraces the view ray, so a point at depth
    x into the ball sees exp(-2 sigma x) in all: L = E / (8 pi) (1 - exp(-4 sigma R))."""
    E = 2.5
    s = one_ball(tmp_path, lights=f"[{{type: directional, direction: [0, -1, 0], irradiance: {E}}}]",
                 background="[0, 0, 0]")
    img = render(s, progress=False)
    expected = E / (8 * math.pi) * (1 - math.exp(-4 * SIGMA * R))
    np.testing.assert_allclose(img[0, 0, :3], expected, rtol=1e-6)


def test_single_scattering_lit_from_behind_the_ball(tmp_path):
    """Light along d: every point sees exp(-2 sigma R) in all, so L = E / (4 pi) sigma 2R exp(-2 sigma R)."""
    E = 2.5
    s = one_ball(tmp_path, lights=f"[{{type: directional, direction: [0, 1, 0], irradiance: {E}}}]",
                 background="[0, 0, 0]")
    img = render(s, progress=False)
    expected = E / (4 * math.pi) * SIGMA * 2 * R * math.exp(-2 * SIGMA * R)
    np.testing.assert_allclose(img[0, 0, :3], expected, rtol=1e-6)


def test_ambient_term_is_albedo_times_one_minus_transmittance(tmp_path):
    s = one_ball(tmp_path, background="[0, 0, 0]", extra="ambient: [0.2, 0.3, 0.4]", albedo=0.7)
    img = render(s, progress=False)
    expected = 0.7 * (1 - math.exp(-2 * R * SIGMA)) * np.array([0.2, 0.3, 0.4])
    np.testing.assert_allclose(img[0, 0, :3], expected, rtol=1e-6)  # float32 image


def test_albedo_zero_scatters_nothing(tmp_path):
    s = one_ball(tmp_path, albedo=0.0, lights="[{type: directional, direction: [0, -1, 0], irradiance: 5}]",
                 extra="ambient: [1, 1, 1]", background="[0.5, 0.5, 0.5]")
    img = render(s, progress=False)
    np.testing.assert_allclose(img[0, 0, :3], 0.5 * math.exp(-2 * R * SIGMA), rtol=1e-7)


def test_point_light_inverse_square(tmp_path):
    """An optically thin ball lit by a point light far away matches the directional light with E = I / d^2."""
    far = 1000.0
    a = one_ball(tmp_path, lights=f"[{{type: point, position: [0, -{far}, 0], intensity: {far * far}}}]",
                 background="[0, 0, 0]")
    b = one_ball(tmp_path, lights="[{type: directional, direction: [0, -1, 0], irradiance: 1}]",
                 background="[0, 0, 0]")
    np.testing.assert_allclose(render(a, progress=False), render(b, progress=False), rtol=1e-2)


def test_escaping_rays_show_the_background(tmp_path):
    s = one_ball(tmp_path, size=8, camera="{position: [0, -6, 0], look_at: [0, 0, 5], up: [0, 0, 1], fov: 5}",
                 background="[0.1, 0.2, 0.3]")
    img = render(s, progress=False)
    np.testing.assert_array_equal(img[..., :3], np.broadcast_to(np.float32([0.1, 0.2, 0.3]), (8, 8, 3)))
    assert np.all(img[..., 3] == 0)


def test_same_image_whatever_the_thread_count(tmp_path):
    s = one_ball(tmp_path, size=24, quality="default", albedo=0.9, phase="{type: hg, g: 0.6}",
                 camera="{position: [0, -6, 1], look_at: [0, 0, 0], up: [0, 0, 1], fov: 30}",
                 lights="[{type: directional, direction: [0.3, -0.5, 0.8], irradiance: 3}]")
    s = load_scene(s.path, spp=4)
    numba.set_num_threads(1)
    try:
        one = render(s, progress=False)
    finally:
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    two = render(s, progress=False)
    np.testing.assert_array_equal(one, two)
    assert one[..., 3].max() > 0.5  # the ball is in the picture


def test_phase_functions_integrate_to_one():
    from scipy.integrate import quad
    from cloudmeta.kernels.kinds import DOUBLE_HG, HG, ISOTROPIC, RAYLEIGH
    from cloudmeta.kernels.optics import phase
    for kind, g1, g2, w in ((ISOTROPIC, 0, 0, 1), (HG, 0.6, 0, 1), (HG, -0.3, 0, 1), (DOUBLE_HG, 0.8, -0.4, 0.7),
                            (RAYLEIGH, 0, 0, 1)):
        total = 2 * math.pi * quad(lambda c: phase(kind, g1, g2, w, c), -1, 1, epsabs=0, epsrel=1e-12)[0]
        assert total == pytest.approx(1.0, rel=1e-10)
    # g > 0 brightens clouds seen against the light: cos = l . d = 1 is forward
    assert phase(HG, 0.6, 0, 1, 1.0) > phase(HG, 0.6, 0, 1, -1.0)


@pytest.mark.parametrize("h", [0.3, 0.02])
def test_point_light_inside_a_ball_matches_quadrature(tmp_path, h):
    """A point light at the centre of a uniform ball, the view ray passing at distance h from it: the
    1/r^2 peak is sharp for small h. Reference: scipy quad of the single-scattering integral."""
    from scipy.integrate import quad
    I = 3.0
    s = one_ball(tmp_path, lights=f"[{{type: point, position: [0, 0, 0], intensity: {I}}}]",
                 background="[0, 0, 0]", camera=f"{{position: [0, -6, {h}], look_at: [0, 0, {h}], up: [0, 0, 1], fov: 1}}")
    img = render(s, progress=False)
    half = math.sqrt(R * R - h * h)

    def integrand(x):  # x: position along the chord from its middle; the light is at distance r
        r2 = h * h + x * x
        return math.exp(-SIGMA * (x + half)) * SIGMA / (4 * math.pi) * I * math.exp(-SIGMA * math.sqrt(r2)) / r2

    ref = quad(integrand, -half, half, points=[0.0], epsabs=0, epsrel=1e-12, limit=400)[0]
    np.testing.assert_allclose(img[0, 0, :3], ref, rtol=1e-6)


@pytest.mark.parametrize("quality", ["default", "reference"])
def test_a_stray_ball_far_away_changes_nothing_near_the_cloud(quality):
    """Issue #27: tolerances follow the geometry a ray meets (Scene.length_scale), not the scene's diagonal:
    a ball 1e3-1e6 away, out of view and off every shadow ray, leaves the cloud's pixels as they were."""
    from dataclasses import replace
    from pathlib import Path

    import cloudmeta as cm
    root = Path(__file__).resolve().parents[2]
    base = cm.load_scene(root / "scenes" / "cumulus.yaml", width=20, height=20)
    base = replace(base, render=replace(base.render, quality=quality))
    ref = render(base, progress=False)
    medium = base.media[0]
    for far in (1e3, 1e5, 1e6):
        blob = cm.Blob(np.concatenate([medium.blob.centers, [[0.0, far, -far / 2]]]),
                       np.concatenate([medium.blob.radii, [[1.0, 1.0, 1.0]]]),
                       np.concatenate([medium.blob.weights, [1.0]]), medium.blob.kernel, medium.blob.threshold,
                       rotations=np.concatenate([medium.blob.rotations, np.eye(3)[None]]))
        stray = replace(base, media=(replace(medium, blob=blob),))
        assert np.linalg.norm(np.subtract(*stray.bbox())) > far  # the diagonal grew; the length did not
        assert stray.length_scale() == base.length_scale()
        img = render(stray, progress=False)
        assert np.max(np.abs(img - ref)) <= 1e-9 * np.max(np.abs(ref))
