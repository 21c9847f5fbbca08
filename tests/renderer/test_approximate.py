"""The approximate multiple-scattering mode (renderer.approximate, kernels.single.octave_phase): octaves
reduce to single scattering, keep the white furnace, brighten what single scattering leaves dark, and
measure their own error against the unbiased estimator."""
import textwrap
from dataclasses import replace

import numpy as np
import pytest

from cloudmeta.errors import SceneError
from cloudmeta.renderer import render, render_frame
from cloudmeta.renderer.pack import octave_table
from cloudmeta.scene.atmosphere import sky_mean
from cloudmeta.scene import load_scene

BALLS = """[{center: [0, 0, 0], radius: 1.6}, {center: [0.9, 0.2, 0.3], radius: 1.2},
                     {center: [-0.8, -0.1, 0.2], radius: 1.3}]"""


def cloud(tmp_path, render_block="{quality: draft}", lights=None, albedo=0.95, background="[0.2, 0.3, 0.5]",
          extra="", size=12):
    lights = lights or "[{type: directional, direction: [0.4, -0.6, 0.5], irradiance: 8.0}]"
    p = tmp_path / "s.yaml"
    p.write_text(textwrap.dedent(f"""
        image: {{width: {size}, height: {size}}}
        camera: {{position: [0, -9, 0.3], look_at: [0, 0, 0.2], up: [0, 0, 1], fov: 30}}
        background: {background}
        lights: {lights}
        render: {render_block}
        {extra}
        media:
          - kernel: wyvill6
            threshold: 0.4
            density: {{mode: field, scale: 3.0}}
            albedo: {albedo}
            phase: {{type: hg, g: 0.6}}
            balls: {BALLS}
        """))
    return load_scene(p)


def test_one_octave_is_single_scattering_with_the_background_as_ambient(tmp_path):
    approx = render(cloud(tmp_path, "{quality: draft, scattering: approximate, octaves: {count: 1}}"),
                    progress=False)
    single = render(cloud(tmp_path, extra="ambient: [0.2, 0.3, 0.5]"), progress=False)
    np.testing.assert_array_equal(approx, single)


def test_octaves_brighten_the_cloud_and_leave_the_background(tmp_path):
    single = render(cloud(tmp_path, extra="ambient: [0.2, 0.3, 0.5]"), progress=False)
    approx = render(cloud(tmp_path, "{quality: draft, scattering: approximate}"), progress=False)
    inside = single[..., 3] > 0.5
    outside = single[..., 3] == 0.0
    assert inside.sum() > 10 and outside.sum() > 10
    assert np.all(approx[inside, :3] > single[inside, :3])
    np.testing.assert_array_equal(approx[outside], single[outside])


def test_white_furnace(tmp_path):
    """Albedo 1, no lights, a uniform environment: every order together gives the environment back; the
    approximate mode's ambient term (the environment's mean) does so exactly, up to the quadrature."""
    img = render(cloud(tmp_path, "{quality: fine, scattering: approximate}", lights="[]", albedo=1.0,
                       background="[0.5, 0.7, 1.0]"), progress=False)
    np.testing.assert_allclose(img[..., :3], np.broadcast_to([0.5, 0.7, 1.0], img[..., :3].shape), rtol=2e-3)


def test_octave_table_and_the_environments_mean():
    np.testing.assert_allclose(octave_table(3, 0.5, 0.25, 0.8), [[1, 1, 1], [0.5, 0.25, 0.8], [0.25, 0.0625, 0.64]])
    table = np.zeros((181, 3))
    table[91:] = 1.0  # 1 above the horizon, 0 below: the mean over the sphere is about 1/2
    assert sky_mean(table)[0] == pytest.approx(0.5, abs=0.01)
    np.testing.assert_array_equal(sky_mean(np.array([[0.1, 0.2, 0.3]])), [0.1, 0.2, 0.3])


def test_settings_are_validated(tmp_path):
    with pytest.raises(SceneError, match=r"render\.octaves\.a"):
        cloud(tmp_path, "{scattering: approximate, octaves: {a: 1.5}}")
    with pytest.raises(SceneError, match=r"render\.octaves\.count"):
        cloud(tmp_path, "{scattering: approximate, octaves: {count: 0}}")
    with pytest.raises(SceneError, match="render.method"):
        cloud(tmp_path, "{scattering: approximate, method: nonsense}")
    with pytest.raises(SceneError, match="ambient"):
        render(cloud(tmp_path, "{scattering: approximate}", extra="ambient: [0.1, 0.1, 0.1]"), progress=False)


def test_the_approximation_measures_its_error(tmp_path):
    """One octave without the environment's ambient is single scattering: its estimated error against the
    unbiased image is what the Monte Carlo orders add, which a render in multiple mode shows directly."""
    scene = cloud(tmp_path, "{quality: draft, scattering: approximate, octaves: {count: 1}, max_order: 8}",
                  background="[0, 0, 0]", size=8)
    result = render_frame(scene, progress=False, error=True)
    est = result.approximation
    assert est.pixels == est.cloud_pixels > 0
    multi = replace(scene, render=replace(scene.render, scattering="multiple", ms_spp=256))
    full = render(multi, progress=False)
    diff = full[..., :3].astype(np.float64) - result.image[..., :3]
    truth = np.sqrt(np.mean(diff ** 2)) / full[..., :3].mean()
    assert truth > 0.02  # the orders above 1 matter in this cloud
    assert 0.7 * truth < est.rel_rmse < 1.4 * truth


def test_cli_prints_the_approximations_measured_error(tmp_path):
    """`cloudmeta render --error` of an approximate scene prints the approximation's estimate, the same
    number render_frame gives (every random number is keyed by the pixel)."""
    import os
    import subprocess
    import sys
    from pathlib import Path
    root = Path(__file__).resolve().parents[2]
    scene = cloud(tmp_path, "{quality: draft, scattering: approximate, max_order: 8}", size=8)
    run = subprocess.run([sys.executable, "-m", "cloudmeta.cli", "render", scene.path, "-o", str(tmp_path / "a.exr"),
                          "--error", "-q"], capture_output=True, text=True, cwd=tmp_path,
                         env=dict(os.environ, PYTHONPATH=str(root)))
    assert run.returncode == 0, run.stderr
    summary = run.stdout.splitlines()[-1]  # the render's one line gives it beside the quadrature's estimate
    assert "estimated error" in summary and "against multiple scattering" in summary
    printed = float(summary.split("approximation error ")[1].split()[0])
    assert printed == pytest.approx(render_frame(scene, progress=False, error=True).approximation.rel_rmse, abs=1e-3)


def test_bit_identical_whatever_the_thread_count(tmp_path):
    import numba
    scene = cloud(tmp_path, "{quality: draft, scattering: approximate, max_order: 8}", size=10)
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = render_frame(scene, progress=False, error=True)
        numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
        two = render_frame(scene, progress=False, error=True)
    finally:
        numba.set_num_threads(before)
    np.testing.assert_array_equal(one.image, two.image)
    assert one.approximation == two.approximation
