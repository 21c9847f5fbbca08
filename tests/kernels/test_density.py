"""Density modes (cloudmeta.kernels.density): rho(F) of each mode, its mean over a piece and its integral
from the integral of F, all as docs/model.md §4 states them, and affine in F as the kernels assume."""
import numpy as np
import pytest

from cloudmeta.kernels import density as kd
from cloudmeta.kernels.kinds import DENSITY_EXCESS, DENSITY_FIELD, DENSITY_MODES, DENSITY_UNIFORM


def test_density_modes_follow_the_model():
    c = np.array([0.5, 0.9, 1.4, 1.1, 0.8, 0.6, 0.5])
    t = 0.5
    assert kd.density_mean(c, DENSITY_FIELD, t) == pytest.approx(c.mean(), rel=1e-15)
    assert kd.density_mean(c, DENSITY_EXCESS, t) == pytest.approx(c.mean() - t, rel=1e-15)
    assert kd.density_mean(c, DENSITY_UNIFORM, t) == 1.0
    for f in (0.5, 0.7, 2.0):
        assert kd.rho_value(f, DENSITY_FIELD, t) == f
        assert kd.rho_value(f, DENSITY_EXCESS, t) == f - t
        assert kd.rho_value(f, DENSITY_UNIFORM, t) == 1.0


@pytest.mark.parametrize("mode", list(DENSITY_MODES.values()))
def test_every_mode_is_affine_in_the_field(mode):
    """rho(a F1 + (1 - a) F2) = a rho(F1) + (1 - a) rho(F2), and the integral of rho over inside parts of
    total length L with int F = I is rho_integral(I, L): what the shadow rays and piece means rely on."""
    rng = np.random.default_rng(7)
    t = 0.4
    for _ in range(50):
        f1, f2, a = rng.uniform(t, 3.0), rng.uniform(t, 3.0), rng.uniform()
        mixed = kd.rho_value(a * f1 + (1 - a) * f2, mode, t)
        assert mixed == pytest.approx(a * kd.rho_value(f1, mode, t) + (1 - a) * kd.rho_value(f2, mode, t), rel=1e-14)
    # a piece of length 2 where F goes linearly from 1 to 2: int F = 3, int rho by midpoint rule (exact)
    x = np.linspace(0.0, 2.0, 20001)
    f = 1.0 + x / 2.0
    rho = np.array([kd.rho_value(v, mode, t) for v in f])
    assert kd.rho_integral(3.0, 2.0, mode, t) == pytest.approx(np.trapezoid(rho, x), rel=1e-9)


def test_inspect_evaluates_the_same_formula_on_arrays():
    f = np.array([0.5, 0.7, 2.0])
    np.testing.assert_array_equal(kd.rho_value.py_func(f, DENSITY_EXCESS, 0.5), f - 0.5)
