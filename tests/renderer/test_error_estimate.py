"""render(..., error=True): the per-pixel error estimate, its EXR channels and the CLI's summary."""
import os
from dataclasses import replace
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import cloudmeta as cm
from cloudmeta.api.io import read_exr, write_exr
from cloudmeta.kernels.camera import background_radiance, camera_ray
from cloudmeta.renderer.estimate import (MAX_ANGLE, background_seen, coarser_quality, estimated_rel_rmse, finer_quality,
                                         frame_scattered_mean, scaled_quality)
from cloudmeta.renderer.pack import pack_scene
from cloudmeta.renderer import render
from cloudmeta.renderer.quality import resolve_quality
from validation.references import suite as S

ROOT = Path(__file__).resolve().parents[2]
SUITE = ROOT / "scenes" / "suite"
REFERENCES = ROOT / "validation" / "reference_images" / "suite"


def test_estimate_leaves_the_image_unchanged_and_is_the_difference_to_a_coarser_render():
    s = cm.load_scene(ROOT / "scenes" / "cumulus.yaml", width=12, height=10)
    plain = render(s, progress=False)
    img, err = render(s, progress=False, error=True)
    assert np.array_equal(plain, img)
    assert err.shape == (10, 12, 3) and err.dtype == np.float32
    assert np.all(err >= 0) and np.all(np.isfinite(err))
    assert err.max() > 0  # the cumulus's in-scattering is not exact at the default preset
    # depth and error together: (image, depth, error)
    img2, depth, err2 = render(s, progress=False, depth=True, error=True)
    assert np.array_equal(img2, img) and np.array_equal(err2, err) and depth.shape == (10, 12)


def test_coarser_quality_scales_every_quadrature_setting():
    s = cm.load_scene(ROOT / "scenes" / "cumulus.yaml")
    q = resolve_quality(s.render, 10.0)
    c = coarser_quality(q)
    assert (c.tolerance, c.max_tau, c.max_length, c.max_angle) == (3 * q.tolerance, 2 * q.max_tau,
                                                                     2 * q.max_length, 2 * q.max_angle)
    assert (c.cutoff, c.tol_t) == (3 * q.cutoff, q.tol_t)
    # the widest angle stays within the scene's own limit (1.6 radians): a point light's 1 / r^2 is lost beyond it
    wide = coarser_quality(replace(q, max_angle=1.2, cutoff=0.3))
    assert (wide.max_angle, wide.cutoff) == (MAX_ANGLE, 0.5) and MAX_ANGLE == 1.6
    # the calibration's levels keep it within half that, so that the estimate's second render is coarser in every
    # setting (at MAX_ANGLE in both, cumulus_point_inside's estimate came out 0.6x its true error)
    high = scaled_quality(q, 5.0)
    assert high.max_angle == MAX_ANGLE / 2 and coarser_quality(high).max_angle == MAX_ANGLE


def test_estimated_rel_rmse_is_the_presets_measure():
    img = np.ones((2, 2, 4))
    err = np.full((2, 2, 3), 0.01)
    # relative to the mean scattered radiance (the pilot's), and to the image's RMS where the pilot saw none
    assert estimated_rel_rmse(img, err, 0.02) == pytest.approx(0.5, rel=1e-12)
    assert estimated_rel_rmse(img, err) == pytest.approx(0.01, rel=1e-12)
    assert estimated_rel_rmse(np.zeros((2, 2, 4)), err) == 0.0


@pytest.mark.parametrize("name", ["deck_grazing", "cumulus_front", "wisps_front", "deck_point_inside"])
def test_estimate_brackets_the_true_error_on_suite_scenes(name):
    """Against the committed converged references (validation/reference_images/suite): the image-level estimate
    between half and 10x the true relative RMSE (issue #11), at the default preset, both relative to the
    mean scattered radiance (issue #23). deck_point_inside's lamp is a bright spot the pilot's 22 x 16 rays
    missed: over the pilot's mean its estimate was 67x the truth; the calibration's reference measures the mean."""
    from cloudmeta.renderer import render_frame
    ref = np.load(REFERENCES / f"{name}.npy")
    s = cm.load_scene(SUITE / f"{name}.yaml")
    result = render_frame(s, progress=False, error=True)
    true = S.rel_rmse_scattered(result.image, ref, s.background)
    assert 0.5 * true <= result.estimated <= 10 * true
    assert result.estimated == pytest.approx(estimated_rel_rmse(result.image, result.error, frame_norm(s, result)),
                                             rel=1e-6)  # (float32 outputs)


def frame_norm(scene, result):
    """The estimate's denominator for a whole frame (renderer.estimate.frame_scattered_mean)."""
    packed = pack_scene(scene, 0)
    window = ((0, scene.image.height), (0, scene.image.width))
    return frame_scattered_mean(result.image, result.depth, packed.camera, packed.records.background, window,
                                result.scattered.mean)


def test_the_estimates_denominator_is_the_frames_own_scattered_light():
    """The image less the background seen through the media (the sky per pixel, as the kernels see it along the
    pixel's centre ray); where a pixel hits a surface, at least the sampled mean, the surface pixels counted as 0."""
    s = cm.load_scene(ROOT / "scenes" / "generated_cumulus.yaml", width=7, height=5)
    packed = pack_scene(s, 0)
    camera, sky = packed.camera, packed.records.background
    assert sky.shape[0] > 1
    window = ((1, 4), (2, 7))
    seen = background_seen(camera, sky, window)
    d = np.empty(3)
    for i in range(1, 4):
        for j in range(2, 7):
            camera_ray(camera, i, j, 0, 1, d)
            assert np.allclose(seen[i - 1, j - 2], background_radiance(sky, d), rtol=1e-12, atol=0)
    image = np.zeros((3, 5, 4))
    image[..., :3] = seen * 0.25 + 0.1  # 0.1 of scattered light everywhere, the sky seen through 0.25
    image[..., 3] = 0.75
    nearest = np.full((3, 5), np.inf)
    assert frame_scattered_mean(image, nearest, camera, sky, window, 5.0) == pytest.approx(0.1, rel=1e-12)
    nearest[0, :] = 2.0  # a surface in the first row: its pixels count 0, and the sampled mean is a floor
    assert frame_scattered_mean(image, nearest, camera, sky, window, 0.0) == pytest.approx(0.1 * 2 / 3, rel=1e-12)
    assert frame_scattered_mean(image, nearest, camera, sky, window, 5.0) == 5.0


def test_exr_error_channels_round_trip(tmp_path):
    img = np.random.default_rng(1).random((3, 4, 4)).astype(np.float32)
    err = np.random.default_rng(2).random((3, 4, 3)).astype(np.float32)
    write_exr(img, tmp_path / "e.exr", error=err)
    back, header = read_exr(tmp_path / "e.exr")
    assert back.shape == (3, 4, 7)
    assert np.array_equal(back[..., :4], img)
    assert np.array_equal(back[..., 4:], err[..., ::-1])  # extra channels in name order: error.B, .G, .R


def test_cli_writes_the_estimate_and_prints_its_rel_rmse(tmp_path):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    out = tmp_path / "c.exr"
    run = subprocess.run([sys.executable, "-m", "cloudmeta.cli", "render", str(ROOT / "scenes" / "cumulus.yaml"),
                          "--width", "8", "--height", "6", "-o", str(out), "--error", "-q", "-v"],
                         capture_output=True, text=True, env=env, cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    assert "estimated relative RMSE" in run.stdout  # -v: the estimate's line, with the channels it wrote
    back, _ = read_exr(out)
    assert back.shape == (6, 8, 7)
    s = cm.load_scene(ROOT / "scenes" / "cumulus.yaml", width=8, height=6)
    img, err = render(s, progress=False, error=True)
    assert np.array_equal(back[..., 4:], err[..., ::-1])
    reported = float(run.stdout.split("estimated relative RMSE ")[1].split()[0])
    from cloudmeta.renderer import render_frame
    result = render_frame(s, progress=False, error=True)
    assert reported == pytest.approx(result.estimated, rel=1e-2)
    # the summary gives the same estimate against the preset's target
    summary = float(run.stdout.splitlines()[-1].split("estimated error ")[1].split()[0])
    assert summary == pytest.approx(result.estimated, rel=1e-1) and "(target 1.0e-03)" in run.stdout.splitlines()[-1]
    # the calibration's line: the level it chose on default's ladder and the error it measured on its rays
    line = [ln for ln in run.stdout.splitlines() if "quadrature calibrated for quality default" in ln]
    assert len(line) == 1 and f"on its {8 * 6} rays" in line[0]
    assert f"{abs(result.scattered.level):.2f} steps" in line[0] or result.scattered.level == 0.0


def test_cli_refuses_the_estimate_for_sequences(tmp_path):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    run = subprocess.run([sys.executable, "-m", "cloudmeta.cli", "render", str(ROOT / "scenes" / "cumulus.yaml"),
                          "--frames", "2", "--error"], capture_output=True, text=True, env=env, cwd=tmp_path)
    assert run.returncode == 2
    assert run.stderr.strip().count("\n") == 0 and "--error" in run.stderr
    assert list(tmp_path.iterdir()) == []


def test_error_target_refines_until_the_estimate_meets_it():
    """render.error: a target relative RMSE. On the suite's grazing deck, a target of 1e-4 (10x below the
    default's) refines the settings; the estimate and the true error both end below it."""
    from dataclasses import replace
    from cloudmeta.renderer import render_frame
    ref = np.load(REFERENCES / "deck_grazing.npy")
    s = cm.load_scene(SUITE / "deck_grazing.yaml")
    s = replace(s, render=replace(s.render, error=1e-4))
    result = render_frame(s, progress=False, error=True)
    assert result.estimated <= 1e-4
    assert S.rel_rmse_scattered(result.image, ref, s.background) <= 1e-4
    # a target the preset meets already changes nothing (render.error is not calibrated: the preset's own settings)
    loose = replace(s, render=replace(s.render, error=0.5))
    plain = render(replace(s, render=replace(s.render, error=None, calibrate=False)), progress=False)
    assert np.array_equal(render(loose, progress=False), plain)


def test_finer_undoes_coarser():
    s = cm.load_scene(ROOT / "scenes" / "cumulus.yaml")
    q = resolve_quality(s.render, 10.0)
    f = finer_quality(coarser_quality(q))
    for key in ("tolerance", "max_tau", "max_length", "max_angle", "cutoff"):
        assert getattr(f, key) == pytest.approx(getattr(q, key), rel=1e-15)


@pytest.mark.parametrize("value", ["0", "1e-9", "0.9", "-1", "nan", "'a'"])
def test_error_target_is_validated(tmp_path, value):
    text = (ROOT / "scenes" / "cumulus.yaml").read_text().replace("render: {", f"render: {{error: {value}, ", 1)
    assert "error:" in text
    p = tmp_path / "s.yaml"
    p.write_text(text)
    (tmp_path / "cumulus.csv").write_text((ROOT / "scenes" / "cumulus.csv").read_text())
    with pytest.raises(cm.SceneError, match=r"render\.error"):
        cm.load_scene(p)


def test_multiple_scattering_adds_its_standard_error_in_quadrature():
    from dataclasses import replace
    from cloudmeta.renderer.multiple import render_multiple
    s = cm.load_scene(ROOT / "scenes" / "cumulus.yaml", width=6, height=5)
    single = replace(s, ambient=None)
    multi = replace(single, render=replace(single.render, scattering="multiple", ms_spp=3, max_order=4))
    img, err = render(multi, progress=False, error=True)
    _, quad_err = render(single, progress=False, error=True)
    _, stderr = render_multiple(multi)
    assert np.all(np.isfinite(stderr)) and stderr.max() > 0
    expect = np.sqrt(quad_err.astype(np.float64) ** 2 + stderr ** 2)
    assert np.allclose(err, expect, rtol=1e-6, atol=0)


def test_estimated_rel_rmse_includes_the_monte_carlo_standard_error():
    """With multiple scattering the returned error holds the paths' standard error too; the estimated
    relative RMSE is of that error, not of the quadrature's part alone."""
    from dataclasses import replace
    from cloudmeta.renderer import render_frame
    s = cm.load_scene(ROOT / "scenes" / "cumulus.yaml", width=8, height=6)
    s = replace(s, ambient=None, render=replace(s.render, scattering="multiple", ms_spp=4, max_order=3))
    result = render_frame(s, progress=False, error=True)
    assert result.estimated == pytest.approx(estimated_rel_rmse(result.image, result.error, frame_norm(s, result)),
                                             rel=1e-6)
    single = render_frame(replace(s, render=replace(s.render, scattering="single")), progress=False, error=True)
    assert result.estimated > single.estimated
