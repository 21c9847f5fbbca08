"""kernels.fluence: the spherical harmonics, the track-length deposit and the photons' emission."""
import numpy as np

from cloudmeta.kernels.fluence import deposit, sh_basis
from cloudmeta.kernels.records import RadianceGrid
from cloudmeta.kernels.tracking import alloc_track_work


def _sphere(n=200):
    mu, wmu = np.polynomial.legendre.leggauss(n)
    phi = (np.arange(2 * n) + 0.5) * np.pi / n
    m, p = np.meshgrid(mu, phi, indexing="ij")
    s = np.sqrt(1 - m ** 2)
    dirs = np.stack([s * np.cos(p), s * np.sin(p), m], -1).reshape(-1, 3)
    weights = (wmu[:, None] * np.full(phi.shape, np.pi / n)[None, :]).ravel()
    return dirs, weights


def test_harmonics_are_orthonormal():
    dirs, weights = _sphere()
    y = np.empty(9)
    basis = np.empty((len(dirs), 9))
    for i, d in enumerate(dirs):
        sh_basis(d, y)
        basis[i] = y
    gram = (basis * weights[:, None]).T @ basis
    np.testing.assert_allclose(gram, np.eye(9), atol=1e-10)


def test_deposit_is_the_length_in_each_cell():
    grid = RadianceGrid(origin=np.zeros(3), size=1.0, dims=np.array([4, 3, 2], np.int64), coef=np.zeros((24, 3, 9)),
                        moments=np.ones((1, 3)))
    coef = np.zeros((24, 3, 9))
    o = np.array([-1.0, 0.5, 0.5])
    d = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    y = np.arange(1.0, 10.0)
    deposit(o, d, np.inf, grid, coef, np.array([1.0, 2.0, 3.0]), y, alloc_track_work(1))
    # the ray enters at x = 0 (y = 1.5) and leaves at y = 3 (x = 2.5): length 1.5 sqrt(2) in the box
    np.testing.assert_allclose(coef[:, 0, 0].sum(), 1.5 * np.sqrt(2))
    np.testing.assert_allclose(coef[:, 2, 4], 3 * 5 * coef[:, 0, 0])
    # only cells of the layer z in [0, 1] (k = 0), and the cell (0, 1, 0) has the chord from x = 0 to 0.5
    assert np.all(coef[12:] == 0)
    np.testing.assert_allclose(coef[0 + 4 * 1, 0, 0], 0.5 * np.sqrt(2))
    half = coef.copy()
    coef[:] = 0
    # t_max: the ray enters the box at t = sqrt(2) and stops 1.0 further on
    deposit(o, d, np.sqrt(2) + 1.0, grid, coef, np.array([1.0, 2.0, 3.0]), y, alloc_track_work(1))
    np.testing.assert_allclose(coef[:, 0, 0].sum(), 1.0)
    assert np.all(coef <= half + 1e-15)
