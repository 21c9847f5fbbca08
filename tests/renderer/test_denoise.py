"""Denoised multiple scattering (renderer.denoise): what is filtered, the auxiliary images, the refusals,
the CLI's raw channels."""
from dataclasses import replace

import numpy as np
import OpenEXR
import pytest

import cloudmeta as cm
from cloudmeta.cli import main
from cloudmeta.errors import InputError
from cloudmeta.renderer.denoise import aux_images
from cloudmeta.renderer.frame import render_frame
from cloudmeta.renderer.pack import pack_scene, pixel_directions

#: one ball seen from the front, lit from the side, under a blue sky: multiple scattering, no ambient
BALL = """
image: {width: 32, height: 32, spp: 1}
camera: {position: [0, -6, 0], look_at: [0, 0, 0], up: [0, 0, 1], fov: 30}
background: [0.3, 0.4, 0.6]
lights:
  - {type: directional, direction: [0.6, -0.3, 0.74], irradiance: 3.0}
media:
  - name: puff
    kernel: wyvill6
    threshold: 0.3
    density: {mode: field, scale: 4.0}
    albedo: 0.9
    phase: {type: hg, g: 0.6}
    balls:
      - {center: [0.1, 0, 0.05], radius: 1.5, weight: 1.0}
render: {scattering: multiple, max_order: 8, ms_spp: 8}
"""


@pytest.fixture
def ball(tmp_path):
    path = tmp_path / "ball.yaml"
    path.write_text(BALL)
    return cm.load_scene(path)


def test_denoise_filters_the_paths_alone_and_keeps_the_raw_image(ball):
    plain = render_frame(ball, progress=False)
    den = render_frame(ball, progress=False, denoise=True)
    assert plain.raw is None
    np.testing.assert_array_equal(den.raw, plain.image)  # raw: the render without denoising, bit for bit
    np.testing.assert_array_equal(den.image[..., 3], plain.image[..., 3])  # alpha is not filtered
    np.testing.assert_array_equal(den.depth, plain.depth)
    assert np.abs(den.image[..., :3] - plain.image[..., :3]).max() > 1e-4
    # the deterministic part is not filtered: where no path contributes (the sky beside the ball) nothing moves
    sky = plain.image[..., 3] == 0.0
    assert sky.sum() > 100
    np.testing.assert_allclose(den.image[sky, :3], plain.image[sky, :3], atol=1e-6)
    again = render_frame(ball, progress=False, denoise=True)
    np.testing.assert_array_equal(again.image, den.image)


def test_denoised_image_is_closer_to_the_converged_one(ball):
    """At 8 paths per pixel the denoised image is nearer a 512-path render (another seed) than the raw one
    (docs/multiple_scattering.md: at 64 paths it can lose, on thin wisps and under a low sun)."""
    converged = render_frame(replace(ball, render=replace(ball.render, ms_spp=512)), progress=False, seed=7)
    den = render_frame(ball, progress=False, denoise=True)
    cloud = converged.image[..., 3] > 0.0
    err_raw = np.sqrt(np.mean((den.raw[cloud, :3] - converged.image[cloud, :3]) ** 2))
    err_den = np.sqrt(np.mean((den.image[cloud, :3] - converged.image[cloud, :3]) ** 2))
    assert err_den < 0.55 * err_raw  # measured 0.39x


def test_aux_images_are_the_albedo_and_the_outward_normal_at_the_first_entry(ball):
    p = pack_scene(ball, 0)
    h, w = ball.image.height, ball.image.width
    albedo, normal = aux_images(ball, p, ((0, h), (0, w)))
    hit = albedo[..., 0] > 0.0
    assert 50 < hit.sum() < h * w
    np.testing.assert_array_equal(albedo[hit], np.float32(0.9))
    assert np.all(normal[~hit] == 0.0) and np.all(albedo[~hit] == 0.0)
    np.testing.assert_allclose(np.linalg.norm(normal[hit], axis=1), 1.0, atol=1e-5)
    # a sphere: the entry point c + r n lies on the camera ray o + t d for one iso radius r on every pixel,
    # so (c - o) x d = -r (n x d)
    rows, cols = np.nonzero(hit)
    d = pixel_directions(p.camera, rows, cols)
    n = normal[hit].astype(np.float64)
    c = np.array([0.1, 0.0, 0.05]) - np.array([0.0, -6.0, 0.0])
    lhs = np.cross(c[None, :], d)
    rhs = -np.cross(n, d)
    r = np.linalg.norm(lhs, axis=1) / np.linalg.norm(rhs, axis=1)
    off_axis = np.linalg.norm(lhs, axis=1) > 0.2
    assert off_axis.sum() > 20
    np.testing.assert_allclose(lhs[off_axis], r[off_axis, None] * rhs[off_axis], atol=2e-4)
    np.testing.assert_allclose(r[off_axis], np.median(r[off_axis]), rtol=1e-3)
    assert np.all(np.einsum("ij,ij->i", n, d) < 0.0)  # facing the camera


def test_denoise_is_refused_where_it_cannot_apply(ball):
    single = replace(ball, render=replace(ball.render, scattering="single"))
    with pytest.raises(InputError, match="denoise: only a multiple-scattering render"):
        render_frame(single, progress=False, denoise=True)
    with pytest.raises(InputError, match="denoise: a whole frame only"):
        render_frame(ball, progress=False, denoise=True, rows=(0, 8))
    with pytest.raises(InputError, match="denoise: expected True or False"):
        render_frame(ball, progress=False, denoise="yes")


def test_cli_denoise_writes_the_raw_image_beside_the_denoised_one(ball, tmp_path, capsys):
    exr = tmp_path / "d.exr"
    assert main(["render", str(ball.path), "-o", str(exr), "--denoise", "-q"]) == 0
    with OpenEXR.File(str(exr), separate_channels=True) as f:
        ch = f.channels()
        image = np.stack([ch[c].pixels for c in "RGBA"], axis=-1)
        raw = np.stack([ch[f"raw.{c}"].pixels for c in "RGBA"], axis=-1)
    plain = render_frame(ball, progress=False)
    np.testing.assert_array_equal(raw, plain.image)
    assert np.abs(image - raw).max() > 1e-4
    assert "multiple scattering, denoised, quality default" in capsys.readouterr().out
    assert main(["render", str(ball.path), "-o", str(exr), "--denoise", "-q", "-v"]) == 0
    assert "the image before it is in the EXR's channels raw.R/G/B/A" in capsys.readouterr().out


def test_cli_denoise_refuses_a_single_scattering_scene(tmp_path, capsys):
    path = tmp_path / "s.yaml"
    path.write_text(BALL.replace("render: {scattering: multiple, max_order: 8, ms_spp: 8}", ""))
    assert main(["render", str(path), "-o", str(tmp_path / "s.exr"), "--denoise", "-q"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "denoise: only a multiple-scattering render" in err[0]
    assert not (tmp_path / "s.exr").exists()


def test_cli_denoise_refuses_a_sequence(ball, tmp_path, capsys):
    assert main(["render", str(ball.path), "-o", str(tmp_path / "f.exr"), "--frames", "0:1", "--denoise",
                 "-q"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "--denoise: only for a single image" in err[0]
    assert not list(tmp_path.glob("f*.exr"))
