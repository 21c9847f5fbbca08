"""kernels.fluence: the track-length deposit of the light scattered towards the camera."""
from collections import namedtuple

import numpy as np

from cloudmeta.kernels.fluence import deposit
from cloudmeta.kernels.optics import phase
from cloudmeta.kernels.records import RadianceGrid


#: the only field of records.Media that deposit reads: each medium's phase row (kind, g1, g2, w)
_Media = namedtuple("_Media", ["phase"])


def test_deposit_is_the_length_in_each_cell_times_the_phase_towards_the_camera():
    dims = np.array([4, 3, 2], np.int64)
    towards = np.zeros((24, 3))
    towards[:, 2] = 1.0  # the camera straight up from every cell
    grid = RadianceGrid(origin=np.zeros(3), size=1.0, dims=dims, coef=np.zeros((24, 3, 2)), towards=towards,
                        peak=np.array([[1.0, 0.0], [1.0, 0.0]]), filled=np.ones((24, 2)))  # no peak split off
    coef = np.zeros((24, 3, 2))
    o = np.array([-1.0, 0.5, 0.5])
    d = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    med = _Media(np.array([(1, 0.6, 0, 0), (0, 0, 0, 0)], np.float64))
    deposit(o, d, np.inf, grid, coef, np.array([1.0, 2.0, 3.0]), med)
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
    deposit(o, d, np.sqrt(2) + 1.0, grid, coef, np.array([1.0, 2.0, 3.0]), med)
    np.testing.assert_allclose(coef[:, 0, 1].sum(), 1.0 / (4 * np.pi))


def test_deposit_clamps_the_forward_peak_that_the_camera_ray_carries():
    """Inside the cone cos theta > cos_c the deposited phase function is p clamped to p_c: the peak above p_c is
    the camera ray's (docs/approximate.md, the delta split); outside the cone p as it is."""
    dims = np.array([1, 1, 1], np.int64)
    towards = np.array([[1.0, 0.0, 0.0]])
    cos_c, p_c = np.cos(np.radians(10.0)), phase(1, 0.9, 0.0, 0.0, np.cos(np.radians(10.0)))
    grid = RadianceGrid(origin=np.zeros(3), size=1.0, dims=dims, coef=np.zeros((1, 3, 1)), towards=towards,
                        peak=np.array([[cos_c, p_c]]), filled=np.ones((1, 1)))
    med = _Media(np.array([(1, 0.9, 0, 0)], np.float64))
    for angle, expected in [(0.0, p_c), (5.0, p_c), (30.0, phase(1, 0.9, 0.0, 0.0, np.cos(np.radians(30.0))))]:
        coef = np.zeros((1, 3, 1))
        a = np.radians(angle)
        d = np.array([np.cos(a), np.sin(a), 0.0])
        deposit(np.array([0.5, 0.5, 0.5]), d, 0.1, grid, coef, np.ones(3), med)
        np.testing.assert_allclose(coef[0, 0, 0], 0.1 * expected, rtol=1e-12)
