import numpy as np
import pytest

import cloudmeta as cm
from cloudmeta.blob import rotation_matrix


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
    """MODEL.md §9: Q = Rz(az) Ry(ay) Rx(ax), about the fixed x, then y, then z axes."""
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
