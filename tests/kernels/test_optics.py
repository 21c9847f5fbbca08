"""Phase functions (cloudmeta.kernels.optics) against docs/model.md §4's formulas (tests/naive.py)."""
import numpy as np
import pytest

from cloudmeta.kernels import kinds
from cloudmeta.kernels import optics as ko

from tests import naive

COS = np.linspace(-1.0, 1.0, 41)
CASES = [("isotropic", kinds.ISOTROPIC, 0.0, 0.0, 1.0), ("hg", kinds.HG, 0.6, 0.0, 1.0), ("hg", kinds.HG, -0.3, 0.0, 1.0),
         ("hg", kinds.HG, 0.0, 0.0, 1.0), ("double_hg", kinds.DOUBLE_HG, 0.8, -0.4, 0.7), ("rayleigh", kinds.RAYLEIGH, 0.0, 0.0, 1.0)]


@pytest.mark.parametrize("name, kind, g1, g2, w", CASES)
def test_phase_matches_the_formula(name, kind, g1, g2, w):
    got = np.array([ko.phase(kind, g1, g2, w, c) for c in COS])
    np.testing.assert_allclose(got, naive.phase(name, COS, g1, g2, w), rtol=1e-14)


@pytest.mark.parametrize("name, kind, g1, g2, w", CASES)
def test_phase_integrates_to_one_over_the_sphere(name, kind, g1, g2, w):
    x, wt = np.polynomial.legendre.leggauss(400)
    total = 2 * np.pi * sum(wi * ko.phase(kind, g1, g2, w, xi) for xi, wi in zip(x, wt))
    assert total == pytest.approx(1.0, rel=1e-9)


def test_hg_with_g_zero_is_isotropic_and_g_sign_flips_the_lobe():
    assert ko.phase_hg(0.3, 0.0) == pytest.approx(ko.INV_4PI, rel=1e-15)
    for c in COS:
        assert ko.phase_hg(c, 0.5) == pytest.approx(ko.phase_hg(-c, -0.5), rel=1e-14)
    assert ko.phase_rayleigh(1.0) == ko.phase_rayleigh(-1.0) == pytest.approx(2 * ko.phase_rayleigh(0.0))
