"""Balls at load (cloudmeta.scene.balls) and the length tolerances are relative to (scene.blob.length_scale):
identical balls merged exactly, and far-away geometry that loosens no tolerance of the rest (issue #27)."""
import numpy as np
import pytest

import cloudmeta as cm
from cloudmeta.scene.balls import merge_identical
from cloudmeta.scene.blob import FAR_GAP, length_scale


def test_merge_identical_sums_weights_in_order_of_first_appearance():
    b = np.array([[0, 0, 0, 1, 1, 1, 0, 0, 0, 1.0], [1, 0, 0, 1, 1, 1, 0, 0, 0, 2.0],
                  [0, 0, 0, 1, 1, 1, 0, 0, 0, 0.5], [1, 0, 0, 1, 1, 1, 0, 0, 0, -1.0],
                  [0, 0, 0, 1, 1, 1, 0, 0, 30, 4.0]])  # the last is rotated: another ball
    merged, first = merge_identical(b)
    np.testing.assert_array_equal(first, [0, 1, 4])
    np.testing.assert_array_equal(merged[:, 9], [1.5, 1.0, 4.0])
    np.testing.assert_array_equal(merged[:, :9], b[[0, 1, 4], :9])
    distinct = b[[0, 1, 4]]
    same, first = merge_identical(distinct)
    assert same is distinct and list(first) == [0, 1, 2]  # nothing to merge: the input as it is


def write_scene(folder, csv_rows):
    (folder / "balls.csv").write_text("x,y,z,radius,weight\n" + "".join(f"{r}\n" for r in csv_rows))
    (folder / "s.yaml").write_text(
        "image: {width: 12, height: 10}\n"
        "camera: {position: [0, -8, 0], look_at: [0, 0, 0], up: [0, 0, 1], fov: 40}\n"
        "background: [0.2, 0.3, 0.5]\n"
        "lights: [{type: directional, direction: [0.3, -0.5, 0.8], irradiance: 3.0}]\n"
        "media: [{density: {scale: 2.0}, albedo: 0.9, phase: {type: hg, g: 0.5}, balls_file: balls.csv}]\n")
    return folder / "s.yaml"


def test_identical_lines_load_as_one_ball_and_render_the_same(tmp_path):
    rows = ["0,0,0,1.5,0.25"] * 4 + ["0.8,0.2,0.3,1.0,1"]
    merged = cm.load_scene(write_scene(tmp_path, rows))
    assert len(merged.media[0].blob) == 2 and merged.merged_balls == 3
    np.testing.assert_array_equal(merged.media[0].blob.weights, [1.0, 1.0])
    single = cm.load_scene(write_scene(tmp_path, ["0,0,0,1.5,1", "0.8,0.2,0.3,1.0,1"]))
    assert single.merged_balls == 0
    a, b = cm.render(merged, progress=False), cm.render(single, progress=False)
    np.testing.assert_array_equal(a, b)  # weights 4 x 0.25 sum to 1 exactly: the same scene


def test_many_identical_lines_are_one_ball(tmp_path):
    scene = cm.load_scene(write_scene(tmp_path, ["0,0,0,1.5,5e-6"] * 200_000))
    assert len(scene.media[0].blob) == 1 and scene.merged_balls == 199_999
    assert scene.media[0].blob.weights[0] == pytest.approx(1.0, rel=1e-9)


def test_length_scale_is_the_diagonal_without_far_gaps_and_the_group_with_them():
    rng = np.random.default_rng(3)
    centres = rng.uniform(-3, 3, (200, 3))
    bounds = np.concatenate([centres - 1, centres + 1], axis=1)
    lo, hi = bounds[:, :3].min(axis=0), bounds[:, 3:].max(axis=0)
    assert length_scale(bounds) == float(np.linalg.norm(hi - lo))  # bit for bit
    for far in (1e3, 1e4, 1e5, 1e6):
        stray = np.array([[far - 1, 0, -1, far + 1, 2, 1]])
        assert length_scale(np.concatenate([bounds, stray])) == length_scale(bounds)
    # a gap narrower than FAR_GAP x the groups keeps them one group
    near = np.array([[10.0, -1, -1, 12.0, 1, 1]])
    both = np.concatenate([bounds, near])
    assert length_scale(both) == float(np.linalg.norm(both[:, 3:].max(axis=0) - both[:, :3].min(axis=0)))
    assert FAR_GAP == 10.0
