import numpy as np
import pytest

import cloudmeta as cm
from cloudmeta.scene.blob import rotation_matrix


@pytest.mark.parametrize("kwargs,match", [
    (dict(centers=[[0, 0, 0], [1, 1, np.nan]], radii=[1, 1]), r"centers\[1, 2\]"),
    (dict(centers=[[0, 0, 0], [1, 1, 1]], radii=[1, -2]), r"radii\[1\]"),
    (dict(centers=[[0, 0, 0], [1, 1, 1]], radii=[[1, 1, 1], [1, 0, 1]]), r"radii\[1\]"),
    (dict(centers=[[0, 0, 0]], radii=[1, 2]), "radii: expected shape"),
    (dict(centers=[[0, 0]], radii=[1]), r"centers: expected shape \(N, 3\)"),
    (dict(centers=[[0, 0, 0]], radii=[1], kernel="gauss"), "kernel"),
    (dict(centers=[[0, 0, 0]], radii=[1], threshold=0.0), "threshold"),
    (dict(centers=[[0, 0, 0]], radii=[1], weights=[1, 2]), "weights"),
    (dict(centers=[[0, 0, 0]], radii=[1], rotations=[[[1, 0, 0], [0, 2, 0], [0, 0, 1]]]), r"rotations\[0\]"),
    (dict(centers=np.zeros((0, 3)), radii=[]), "at least one ball"),
])
def test_bad_blobs_name_the_argument_and_index(kwargs, match):
    with pytest.raises(cm.InputError, match=match):
        cm.Blob(**kwargs)


def test_rotation_convention_is_rz_ry_rx():
    """docs/model.md §9: Q = Rz(az) Ry(ay) Rx(ax), about the fixed x, then y, then z axes."""
    q = rotation_matrix([0, 0, 90])
    np.testing.assert_allclose(q @ [1, 0, 0], [0, 1, 0], atol=1e-15)
    q = rotation_matrix([90, 0, 90])  # x first: y -> z; then z about z stays z
    np.testing.assert_allclose(q @ [0, 1, 0], [0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(q @ [1, 0, 0], [0, 1, 0], atol=1e-15)


def test_ellipsoid_axes_are_the_columns_of_q():
    """radii are along Q's columns: the support reaches c + a * Q[:, 0]."""
    b = cm.Blob([[0, 0, 0]], [[3.0, 1.0, 0.5]], rotations=[[0, 0, 90]])
    assert cm.field(b, [[0, 2.99, 0]])[0] > 0 and cm.field(b, [[2.99, 0, 0]])[0] == 0
    lo, hi = b.bbox
    np.testing.assert_allclose(hi, [1, 3, 0.5], atol=1e-12)


# --- issue #15: every wrong type or shape is an InputError naming the argument ------------------------------

@pytest.mark.parametrize("kwargs, match", [
    (dict(centers=[[0, 0, 0]], radii=[1], kernel=["wyvill6"]), "kernel"),
    (dict(centers=[[0, 0, 0]], radii=[1], threshold=True), "threshold"),
    (dict(centers=[[0, 0, 0]], radii=[1], threshold="0.5"), "threshold"),
    (dict(centers=[[0, 0, 0]], radii=[1], kernel="blinn", blobbiness="4"), "blobbiness"),
    (dict(centers=[[0, 0, 0]], radii=[1], kernel="blinn", blobbiness=1e308), "blobbiness"),
    (dict(centers=[["0", "0", "0"]], radii=[1]), "centers: expected an array of real numbers"),
    (dict(centers=[[0, 0, 0], [1, 1]], radii=[1, 1]), "centers: expected an array of numbers, got a ragged"),
    (dict(centers=[[0, 0, 0]], radii=[1], weights=[True]), "weights: expected an array of real numbers, got bool"),
    (dict(centers=[[1e308, 0, 0]], radii=[1]), r"centers\[0\]: expected coordinates within"),
    (dict(centers=[[0, 0, 0]], radii=[1e-300]), r"radii\[0\]: expected a radius from"),
    (dict(centers=[[0, 0, 0]], radii=[1e308]), r"radii\[0\]"),
    (dict(centers=[[0, 0, 0]], radii=[1], weights=[1e308]), r"weights\[0\]: expected \|weight\|"),
    (dict(centers=[[0, 0, 0]], radii=[1], rotations=[[0, 0, 1e300]]), "rotations"),
])
def test_wrong_types_and_values_are_input_errors(kwargs, match):
    with pytest.raises(cm.InputError, match=match):
        cm.Blob(**kwargs)


def test_render_of_a_non_scene_is_an_input_error():
    with pytest.raises(cm.InputError, match="scene: expected a cloudmeta Scene"):
        cm.render(cm.Blob([[0, 0, 0]], [1.0]))


def test_inside_bbox_leaves_out_carving_balls_and_holds_the_inside():
    """A wide negative ball (the generator's base cutter) widens bbox, not inside_bbox, and every point with
    F >= T lies in inside_bbox (outside every positive ball F <= 0 < T)."""
    blob = cm.Blob([[0, 0, 1], [0.8, 0, 1.2], [0, 0, -3]], [[1.0] * 3, [0.7] * 3, [20.0, 20.0, 3.0]],
                [1.0, 0.8, -50.0])
    lo, hi = blob.inside_bbox()
    np.testing.assert_allclose(lo, [-1.0, -1.0, 0.0])
    np.testing.assert_allclose(hi, [1.5, 1.0, 2.0])
    assert np.all(blob.bbox[0] < lo) and np.all(blob.bbox[1] >= hi)
    pts = np.random.default_rng(3).uniform(blob.bbox[0], blob.bbox[1], size=(200000, 3))
    inside = pts[cm.field(blob, pts) >= blob.threshold]
    assert len(inside) > 0
    assert np.all((inside >= lo) & (inside <= hi))
    only_negative = cm.Blob([[0, 0, 0]], [1.0], [-1.0])
    np.testing.assert_array_equal(only_negative.inside_bbox(), only_negative.bbox)
