"""kernels.fluence: the track-length deposit of the light scattered towards the camera."""
from collections import namedtuple

import numpy as np

from cloudmeta.kernels.fluence import deposit
from cloudmeta.kernels.optics import phase
from cloudmeta.kernels.records import RadianceGrid
from cloudmeta.kernels.tracking import alloc_track_work


#: the only field of records.Media that deposit reads: each medium's phase row (kind, g1, g2, w)
_Media = namedtuple("_Media", ["phase"])


def test_deposit_is_the_length_in_each_cell_times_the_phase_towards_the_camera():
    dims = np.array([4, 3, 2], np.int64)
    towards = np.zeros((24, 3))
    towards[:, 2] = 1.0  # the camera straight up from every cell
    grid = RadianceGrid(origin=np.zeros(3), size=1.0, dims=dims, coef=np.zeros((24, 3, 2)), towards=towards)
    coef = np.zeros((24, 3, 2))
    o = np.array([-1.0, 0.5, 0.5])
    d = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    med = _Media(np.array([(1, 0.6, 0, 0), (0, 0, 0, 0)], np.float64))
    deposit(o, d, np.inf, grid, coef, np.array([1.0, 2.0, 3.0]), med, alloc_track_work(1))
    # the ray enters at x = 0 (y = 1.5) and leaves at y = 3 (x = 2.5): length 1.5 sqrt(2) in the box, at 90
    # degrees to the camera direction
    p_hg = phase(1, 0.6, 0.0, 0.0, 0.0)
    np.testing.assert_allclose(coef[:, 0, 0].sum(), 1.5 * np.sqrt(2) * p_hg)
    np.testing.assert_allclose(coef[:, 0, 1].sum(), 1.5 * np.sqrt(2) / (4 * np.pi))
    np.testing.assert_allclose(coef[:, 2], 3 * coef[:, 0])
    assert np.all(coef[12:] == 0)  # only the layer z in [0, 1]
    np.testing.assert_allclose(coef[0 + 4 * 1, 0, 1], 0.5 * np.sqrt(2) / (4 * np.pi))  # cell (0, 1, 0): x 0 .. 0.5
    coef[:] = 0
    # t_max: the ray enters the box at t = sqrt(2) and stops 1.0 further on
    deposit(o, d, np.sqrt(2) + 1.0, grid, coef, np.array([1.0, 2.0, 3.0]), med, alloc_track_work(1))
    np.testing.assert_allclose(coef[:, 0, 1].sum(), 1.0 / (4 * np.pi))
