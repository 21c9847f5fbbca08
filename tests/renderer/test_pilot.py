"""renderer.pilot: the frame's scattered-light scale that the quadrature's tolerance is relative to (issue
#23), and the closed-form in-scattering of a scene lit by ambient light alone."""
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import cloudmeta as cm
from cloudmeta.renderer import render_frame
from cloudmeta.renderer.pack import pack_scene
from cloudmeta.renderer.pilot import MIN_SIDE, STRIDE, light_scale, pilot_size

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("size, expected", [((512, 512), (64, 64)), ((64, 48), (22, 16)), ((4, 3), (4, 3)),
                                            ((1920, 1080), (240, 135)), ((100, 20), (100, 20))])
def test_pilot_grid_keeps_the_aspect_and_a_minimum_side(size, expected):
    assert pilot_size(*size) == expected
    w, h = pilot_size(*size)
    assert min(w, h) >= min(MIN_SIDE, *size) and w >= size[0] // STRIDE


def test_scale_is_the_rms_of_the_scattered_light_at_draft_on_the_pilot_grid():
    """Its independent twin: the same grid rendered through the public API at draft, with a black
    background, so that every pixel is scattered light alone."""
    s = cm.load_scene(ROOT / "scenes" / "cumulus.yaml", width=48, height=40)
    got = light_scale(s, pack_scene(s, 0))
    w, h = pilot_size(48, 40)
    twin = cm.load_scene(ROOT / "scenes" / "cumulus.yaml", width=w, height=h)
    twin = replace(twin, background=np.zeros(3), render=replace(twin.render, quality="draft"))
    img = np.asarray(render_frame(twin, progress=False).image, np.float64)[..., :3]
    # the twin's own quadrature is relative to its own pilot: equal to the draft per-ray rule within its target
    assert got.mean == pytest.approx(img.mean(), rel=3e-3)
    assert got.scale == pytest.approx(np.sqrt(np.mean(img.sum(-1) ** 2)), rel=3e-3)
    assert (got.width, got.height) == (w, h) and got.mean > 0


def test_a_frame_without_scattered_light_has_scale_zero():
    s = cm.load_scene(ROOT / "scenes" / "cumulus.yaml", width=16, height=12)
    dark = replace(s, lights=(), ambient=None)
    assert light_scale(dark, pack_scene(dark, 0)).scale == 0.0


def test_a_tile_gets_the_frames_scale_and_its_pixels():
    s = cm.load_scene(ROOT / "scenes" / "cumulus.yaml", width=40, height=30)
    whole = render_frame(s, progress=False)
    tile = render_frame(s, progress=False, rows=(10, 20), columns=(5, 30))
    assert tile.scattered == whole.scattered
    assert np.array_equal(tile.image, whole.image[10:20, 5:30])


def test_ambient_light_alone_is_integrated_in_closed_form():
    """No lights and one albedo: J = albedo * ambient everywhere in the medium, so a pixel is
    albedo * ambient * (1 - T) + background * T, exactly, at any quality."""
    s = cm.load_scene(ROOT / "scenes" / "cumulus.yaml", width=24, height=18)
    s = replace(s, lights=(), ambient=np.array([0.2, 0.3, 0.5]))
    albedo = s.media[0].albedo
    for quality in ("draft", "fine"):
        img = np.asarray(cm.render(replace(s, render=replace(s.render, quality=quality)), progress=False),
                         np.float64)
        alpha = img[..., 3:4]
        expected = albedo * s.ambient * alpha + np.asarray(s.background) * (1.0 - alpha)
        assert alpha.max() > 0.9
        assert np.abs(img[..., :3] - expected).max() < 1e-5  # float32 output
