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


def test_moments_are_the_length_in_each_cell_times_the_harmonics():
    """deposit_moments: the track-length estimate of the radiance's spherical-harmonic coefficients, cell by cell;
    sh_basis orthonormal on the sphere (a midpoint rule in cos and phi)."""
    from cloudmeta.kernels.fluence import SH_TERMS, deposit_moments, sh_basis
    dims = np.array([4, 3, 2], np.int64)
    grid = RadianceGrid(origin=np.zeros(3), size=1.0, dims=dims, coef=np.zeros((1, 3, SH_TERMS)),
                        towards=np.zeros((1, 3)), peak=np.zeros((1, 2)), filled=np.ones((1, SH_TERMS)))
    coef = np.zeros((24, 3, SH_TERMS))
    o = np.array([-1.0, 0.5, 0.5])
    d = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    y = np.empty(SH_TERMS)
    sh_basis(d, y)
    deposit_moments(o, d, np.inf, grid, coef, np.array([1.0, 2.0, 3.0]), y)
    np.testing.assert_allclose(coef[:, 0].sum(axis=0), 1.5 * np.sqrt(2) * y)  # as deposit's length above
    np.testing.assert_allclose(coef[4, 1], 2 * 0.5 * np.sqrt(2) * y)  # cell (0, 1, 0)
    assert np.all(coef[12:] == 0)
    n = 200
    cos = -1.0 + (np.arange(n) + 0.5) * 2.0 / n
    phi = (np.arange(2 * n) + 0.5) * np.pi / n
    c, p = np.meshgrid(cos, phi, indexing="ij")
    s = np.sqrt(1.0 - c * c)
    basis = np.empty((c.size, SH_TERMS))
    for k, w in enumerate(np.stack([s * np.cos(p), s * np.sin(p), c], -1).reshape(-1, 3)):
        sh_basis(w, y)
        basis[k] = y
    gram = basis.T @ basis * (2.0 / n) * (np.pi / n)
    np.testing.assert_allclose(gram, np.eye(SH_TERMS), atol=1e-3)  # the midpoint rule: O(1 / n^2)


def test_cached_light_is_the_phase_convolution_of_the_harmonics():
    """cached_light: for a radiance field in the span of the harmonics (here (a + 3 b . w + c (w_z^2 - 1/3)) / 4 pi,
    the same in every cell), the phase function's convolution int p(d . u) L(-u) du against a quadrature over the
    sphere; trilinear between cells (a cell twice as bright on one side gives the mean midway)."""
    from cloudmeta.kernels.fluence import SH_DEGREE, SH_TERMS, cached_light, sh_basis
    from cloudmeta.kernels.records import FluenceCache
    from cloudmeta.renderer.fluence import legendre_moments
    n = 400
    cos = -1.0 + (np.arange(n) + 0.5) * 2.0 / n
    phi = (np.arange(2 * n) + 0.5) * np.pi / n
    c, p = np.meshgrid(cos, phi, indexing="ij")
    s = np.sqrt(1.0 - c * c)
    u = np.stack([s * np.cos(p), s * np.sin(p), c], -1).reshape(-1, 3)
    da = (2.0 / n) * (np.pi / n)
    b = np.array([0.1, -0.2, 0.15])

    def radiance(w):
        return (1.0 + 3.0 * w @ b + 0.6 * (w[..., 2] ** 2 - 1.0 / 3.0)) / (4 * np.pi)
    y = np.empty(SH_TERMS)
    basis = np.empty((len(u), SH_TERMS))
    for k, w in enumerate(u):
        sh_basis(w, y)
        basis[k] = y
    coefficients = basis.T @ radiance(u) * da  # c_j = int L Y_j
    row = np.array([1, 0.7, 0, 0], np.float64)  # Henyey-Greenstein, g = 0.7
    k_l = legendre_moments(row)
    np.testing.assert_allclose(k_l, 0.7 ** np.arange(4), rtol=1e-6)
    moments = np.zeros((2, 3, SH_TERMS))
    moments[0, :] = coefficients
    moments[1, :] = 2 * coefficients
    cache = FluenceCache(origin=np.zeros(3), size=1.0, dims=np.array([2, 1, 1], np.int64), moments=moments,
                         phase_moments=((-1.0) ** np.array(SH_DEGREE) * k_l[list(SH_DEGREE)])[None, :], order=3)
    for d in (np.array([0.0, 0.0, 1.0]), np.array([0.6, 0.0, -0.8]), np.array([0.0, 1.0, 0.0])):
        ph = np.array([phase(1, 0.7, 0.0, 0.0, float(x)) for x in u @ d])
        want = float(np.sum(ph * radiance(-u)) * da)
        got = cached_light(cache, np.array([0.5, 0.5, 0.5]), d, 0, y)  # the first cell's centre
        np.testing.assert_allclose(got, (want,) * 3, rtol=2e-3)
        midway = cached_light(cache, np.array([1.0, 0.5, 0.5]), d, 0, y)
        np.testing.assert_allclose(midway, (1.5 * want,) * 3, rtol=2e-3)
