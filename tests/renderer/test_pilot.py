"""renderer.pilot: the frame's scattered-light scale that the quadrature's tolerance is relative to (issue
#23), and the closed-form in-scattering of a scene lit by ambient light alone."""
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import cloudmeta as cm
from cloudmeta.renderer import render_frame
from cloudmeta.renderer.pack import pack_scene
from cloudmeta.errors import SceneError
from cloudmeta.kernels.lighting import COUNT_KRONROD, COUNT_STEPS, N_COUNTS
from cloudmeta.renderer import calibrate as pilot
from cloudmeta.scene.vocabulary import ShadowMode
from cloudmeta.renderer.calibrate import (CALIBRATION_RAYS, MAX_LEVEL, MIN_SIDE, MIN_TRUSTED, SHARE, STRIDE,
                                      calibrated_level, calibration_size, light_scale, pilot_size)

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("size, expected", [((512, 512), (32, 32)), ((64, 48), (22, 16)), ((4, 3), (4, 3)),
                                            ((1920, 1080), (120, 68)), ((100, 20), (100, 20))])
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


# ---- calibration (issue #23: the preset's target checked on the frame) ----------------------------------

def test_calibration_grid_keeps_4096_rays_or_the_whole_frame():
    assert calibration_size(512, 512) == (64, 64)
    assert calibration_size(64, 48) == (64, 48)  # fewer pixels than CALIBRATION_RAYS: every one
    w, h = calibration_size(1920, 1080)
    assert CALIBRATION_RAYS <= w * h <= 1.2 * CALIBRATION_RAYS and abs(w / h - 1920 / 1080) < 0.05


@pytest.mark.parametrize("per_level, expected", [
    # between 1 and 2: aimed at 0.9 x half
    (lambda lv: 1.4e-4 * 3.0 ** lv, math.log(0.45e-3 / 4.2e-4) / math.log(3.0) + 1.0),
    (lambda lv: 6e-4 * 3.0 ** lv, math.log(0.45e-3 / 6e-4) / math.log(3.0)),  # level 0 above half: finer
    (lambda lv: 1.4e-3 * 3.0 ** lv, -1.0),  # level 0 3x above the limit: the reference, whose own error passes
    (lambda lv: 2e-3 * 3.0 ** lv, -2.0),    # level 0 4x above: the reference's own error too, one step finer still
    (lambda lv: 1.3e-3 * 1.2 ** lv, -2.0),  # an error that grows slowly: the reference seen through at most 1.5x
    (lambda lv: 1e-5 * 3.0 ** lv, 3.0),     # every level passes: MAX_LEVEL
    (lambda lv: 0.0, 3.0),                  # no error at all (a closed form)
    (lambda lv: 3e-4 * 3.0 ** lv, math.log(0.45e-3 / 3e-4) / math.log(3.0)),  # between 0 and 1
])
def test_calibrated_level_is_the_coarsest_within_half_the_target(per_level, expected):
    calls = []

    def error_at(level):
        calls.append(level)
        return per_level(level)
    level, measured = calibrated_level(error_at, 1e-3)
    assert level == pytest.approx(expected, abs=1e-9)
    if level > 0.0:
        assert measured == pytest.approx(per_level(level)) and measured <= SHARE * 1e-3 * (1 + 1e-12)
    assert calls[0] == 1.0  # level 1 first: most scenes pass there, and level 0's render is spared
    assert max(calls) <= MAX_LEVEL


def test_a_finer_level_that_fails_is_tried_again_with_the_growth_it_measured():
    """Below level 0 the first try is aimed with the growth measured between levels 0 and 1; where the error falls
    more slowly than that, the growth is refitted from level 0 and the try, and a second try is aimed with it."""
    calls = []

    def error_at(level):
        calls.append(level)
        return {1.0: 2e-3, 0.0: 8e-4}.get(level, 5.2e-4 if level > -0.7 else 3e-4)
    level, measured = calibrated_level(error_at, 1e-3)
    first = math.log(0.45e-3 / 8e-4) / math.log(2.5)
    second = first + math.log(0.45e-3 / 5.2e-4) / math.log((8e-4 / 5.2e-4) ** (1.0 / -first))
    assert calls == pytest.approx([1.0, 0.0, first, second])
    assert (level, measured) == (pytest.approx(second), 3e-4)


def test_where_level_one_fails_the_first_try_is_aimed_with_the_ladders_growth():
    """Level 1 measures above the limit: the next try is aimed at AIM of the limit as if the error grew GROWTH times
    a step. Where it passes, level 0 is never rendered, and the search goes on between it and level 1; where it
    fails, level 0 is rendered and the search runs between level 0 and the try."""
    limit = SHARE * 1e-3
    calls = []

    def error_at(level):
        calls.append(level)
        return 0.15 * limit * 9.0 ** level  # 9x a step: the try aimed with 3x passes well below the limit
    level, measured = calibrated_level(error_at, 1e-3)
    aimed = 1.0 - math.log(1.35 / pilot.AIM) / math.log(pilot.GROWTH)
    second = aimed + (1.0 - aimed) * math.log(pilot.AIM / (0.15 * 9.0 ** aimed)) / math.log(1.35 / (0.15 * 9.0 ** aimed))
    assert pilot.GROWTH == 3.0 and calls == pytest.approx([1.0, aimed, second])
    assert 1.0 - aimed > pilot.NARROW  # so the second aims at AIM; the third, at NARROW_AIM, would gain too little
    assert level == pytest.approx(second) and measured == pytest.approx(pilot.AIM * limit)

    calls.clear()
    slow = {1.0: 1.2 * limit, 0.0: 0.5 * limit}  # grows 2.4x a step: the try aimed with 3x lands above the limit
    level, measured = calibrated_level(lambda lv: calls.append(lv) or slow.get(lv, 1.05 * limit), 1e-3)
    assert calls[:3] == pytest.approx([1.0, 1.0 - math.log(1.2 / pilot.AIM) / math.log(3.0), 0.0])
    assert (level, measured) == (0.0, 0.5 * limit)  # every try between them failed


def test_a_try_between_close_levels_aims_nearer_the_limit_where_it_is_worth_its_render():
    """Between two levels at most NARROW apart the try aims at NARROW_AIM of the limit; a ``worth`` that refuses it
    keeps the level that passed."""
    limit = SHARE * 1e-3
    aimed = 1.0 - math.log(1.002 / pilot.AIM) / math.log(pilot.GROWTH)
    e = {1.0: 1.002 * limit, aimed: 0.87 * limit}
    tried = []
    level, measured = calibrated_level(lambda lv: tried.append(lv) or e.get(lv, 0.94 * limit), 1e-3)
    narrow = aimed + (1.0 - aimed) * math.log(pilot.NARROW_AIM / 0.87) / math.log(1.002 / 0.87)
    assert 1.0 - aimed <= pilot.NARROW and tried[:3] == pytest.approx([1.0, aimed, narrow])
    assert (level, measured) == (pytest.approx(narrow), 0.94 * limit)
    asked = []
    level, measured = calibrated_level(lambda lv: e.get(lv, 0.94 * limit), 1e-3,
                                       worth=lambda passed, failed, lv: asked.append((passed, failed, lv)) or False)
    assert asked == [(aimed, 1.0, pytest.approx(narrow))] and (level, measured) == (aimed, 0.87 * limit)


def test_kronrod_share_counts_the_steps_that_took_the_kronrod_nodes():
    counts = np.zeros((2, 3, N_COUNTS))
    counts[0, 0, COUNT_STEPS], counts[0, 0, COUNT_KRONROD] = 4.0, 1.0
    counts[1, 2, COUNT_STEPS], counts[1, 2, COUNT_KRONROD] = 4.0, 2.0
    assert pilot.kronrod_share(counts) == pytest.approx(3.0 / 8.0)
    assert pilot.kronrod_share(np.zeros((1, 1, N_COUNTS))) == 0.0


def test_the_shorter_ladder_is_searched_where_the_references_steps_took_the_kronrod_nodes(monkeypatch):
    """The bank's calibration reference (64 x 48) sends more than KRONROD_SHARE of its steps to the Kronrod nodes, the
    cumulus's fewer: the bank's search runs on the shorter ladder (steps SHORTER_TAU as thick, SHORTER_LEVEL coarser),
    its measured error passes, and its true error against a render at ``reference`` stays within the target; with
    the threshold out of reach it stays on the ladder."""
    def dark(name):
        s = cm.load_scene(ROOT / "scenes" / f"{name}.yaml", width=64, height=48)
        return replace(s, background=np.zeros(3), ambient=None)
    assert not render_frame(dark("cumulus"), progress=False).scattered.shorter
    s = dark("dense_1000")
    result = render_frame(s, progress=False)
    assert result.scattered.shorter
    assert result.scattered.predicted <= SHARE * 1e-3
    ref = np.asarray(render_frame(replace(s, render=replace(s.render, quality="reference")), progress=False).image,
                     np.float64)[..., :3]
    img = np.asarray(result.image, np.float64)[..., :3]
    assert np.sqrt(np.mean((img - ref) ** 2)) / ref.mean() <= 1e-3
    monkeypatch.setattr(pilot, "KRONROD_SHARE", 2.0)  # never
    assert not render_frame(s, progress=False).scattered.shorter


def test_an_interpolated_level_that_fails_falls_back_to_the_last_whole_step():
    steps = {1.0: 4e-4, 2.0: 2e-3}
    level, measured = calibrated_level(lambda lv: steps.get(lv, 9e-4), 1e-3)
    assert (level, measured) == (1.0, 4e-4)


def test_calibration_keeps_the_target_and_turns_off_where_the_settings_are_the_users():
    """The shipped cumulus at 64 x 48: calibrated, its error against a render at ``reference`` is at most half the
    preset's target (its calibration grid is the whole frame); with render.calibrate false, an explicit
    tolerance or render.error, the frame takes the preset's own settings."""
    s = cm.load_scene(ROOT / "scenes" / "cumulus.yaml", width=64, height=48)
    s = replace(s, background=np.zeros(3), ambient=None)  # the image is the scattered light alone
    calibrated = render_frame(s, progress=False)
    assert calibrated.scattered.level is not None and calibrated.scattered.level > 0.0
    assert calibrated.scattered.rays == 64 * 48
    ref = np.asarray(render_frame(replace(s, render=replace(s.render, quality="reference")),
                                  progress=False).image, np.float64)[..., :3]
    img = np.asarray(calibrated.image, np.float64)[..., :3]
    true = np.sqrt(np.mean((img - ref) ** 2)) / ref.mean()
    assert true <= 0.5e-3 * 1.2  # SHARE of default's 1e-3; within float32 output and the reference's own error
    assert calibrated.scattered.predicted == pytest.approx(true, rel=0.3)
    plain = render_frame(replace(s, render=replace(s.render, calibrate=False)), progress=False)
    assert plain.scattered.level is None
    assert plain.cost()["nodes"] > 1.2 * calibrated.cost()["nodes"]  # 1.27x here (steps grow with depth at both)
    for off in (dict(tolerance=1e-3), dict(error=1e-3), dict(scattering="multiple", ms_spp=1)):
        assert render_frame(replace(s, render=replace(s.render, **off)), progress=False).scattered.level is None


def test_render_calibrate_is_a_yaml_flag(tmp_path):
    text = (ROOT / "scenes" / "cumulus.yaml").read_text().replace("cumulus.csv", str(ROOT / "scenes" / "cumulus.csv"))
    for value, expected in (("false", False), ("true", True)):
        f = tmp_path / f"s_{value}.yaml"
        f.write_text(text.replace("render: {", f"render: {{calibrate: {value}, ", 1))
        assert cm.load_scene(f).render.calibrate is expected
    assert cm.load_scene(ROOT / "scenes" / "cumulus.yaml").render.calibrate is True
    bad = tmp_path / "bad.yaml"
    bad.write_text(text.replace("render: {", "render: {calibrate: 1, ", 1))
    with pytest.raises(SceneError, match="render.calibrate"):
        cm.load_scene(bad)


@pytest.mark.parametrize("path, size, keeps_maps", [("cumulus.yaml", (48, 40), True),
                                                     ("dense_1000.yaml", (40, 24), False)])
def test_hybrid_shadows_trace_exact_rays_where_the_calibration_trusted_few_lookups(path, size, keeps_maps):
    """shadows: hybrid, calibrated: the cumulus trusts about half its map lookups and keeps the maps; the
    1,200-ball bank, lit from behind, trusts almost none, and its frame traces exact shadow rays alone."""
    s = cm.load_scene(ROOT / "scenes" / path, width=size[0], height=size[1])
    r = render_frame(replace(s, render=replace(s.render, shadows="hybrid")), progress=False)
    cost = r.cost()
    assert (r.scattered.trusted >= MIN_TRUSTED) is keeps_maps
    if keeps_maps:
        assert cost["trusted"] > 0.2 * cost["nodes"]
    else:
        assert cost["lookups"] == 0.0 and cost["exact_rays"] == cost["nodes"]


def test_hybrid_calibration_measures_against_a_reference_with_exact_shadow_rays(monkeypatch):
    """shadows: hybrid: the calibration's reference (one step below the start) traces exact shadow rays, so a
    map's error counts in full in each level's measure; the levels themselves keep the maps."""
    from cloudmeta.renderer import calibrate as pilot
    seen = []
    original = pilot.pilot_render

    def recording(scene, packed, quality, size=None):
        seen.append((quality.shadows, quality.tolerance, size is not None))
        return original(scene, packed, quality, size)

    monkeypatch.setattr(pilot, "pilot_render", recording)
    s = cm.load_scene(ROOT / "scenes" / "cumulus.yaml", width=48, height=40)
    r = render_frame(replace(s, render=replace(s.render, shadows="hybrid")), progress=False)
    grid = [(share, tol) for share, tol, on_grid in seen if on_grid]
    reference = min(grid, key=lambda st: st[1])  # the finest tolerance: level -1
    assert reference[0] == ShadowMode.EXACT
    assert all(mode == ShadowMode.HYBRID for mode, tol in grid if tol > reference[1])
    assert r.scattered.trusted >= MIN_TRUSTED
    seen.clear()  # shadows: map interpolates everywhere, the reference too: the calibration scales the quadrature
    render_frame(replace(s, render=replace(s.render, shadows="map")), progress=False)
    assert seen and all(mode == ShadowMode.MAP for mode, _, on_grid in seen if on_grid)


def test_hybrid_calibration_that_turns_to_exact_rays_chooses_the_exact_level(monkeypatch):
    """shadows: hybrid: where a level's grid trusts fewer than MIN_TRUSTED of its lookups the frame traces exact
    rays, so the search starts again with exact rays: the level is then the one exact shadows get, not one chosen
    by the error of lookups the frame refuses (every grid 'trusts too few' here: MIN_TRUSTED above 1). The frame then
    runs the kernel compiled for exact shadows: its records hold no maps (pack.without_maps)."""
    from cloudmeta.renderer import frame as frame_module
    monkeypatch.setattr(pilot, "MIN_TRUSTED", 1.01)
    maps = []
    original = frame_module.render_single

    def recording(scene, packed, *args):
        maps.append(packed.records.lights.maps)
        return original(scene, packed, *args)
    monkeypatch.setattr(frame_module, "render_single", recording)
    s = cm.load_scene(ROOT / "scenes" / "cumulus.yaml", width=48, height=40)
    exact = render_frame(s, progress=False)
    hybrid = render_frame(replace(s, render=replace(s.render, shadows="hybrid")), progress=False)
    assert maps == [None, None]
    assert hybrid.scattered.level == exact.scattered.level
    assert 0.0 < hybrid.scattered.trusted < 1.01
    assert hybrid.cost()["lookups"] == 0.0
    np.testing.assert_array_equal(hybrid.image, exact.image)
