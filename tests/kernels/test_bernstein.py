import numpy as np
import pytest

from cloudmeta.kernels import bernstein as kb
from tests import naive


@pytest.mark.parametrize("s0,s1", [(0.0, 1.0), (0.0, 0.3), (0.25, 1.0), (0.1, 0.9), (0.4624, 0.4625), (0.7, 0.71)])
def test_subdivide_matches_naive(rng, s0, s1):
    for _ in range(5):
        c = rng.normal(size=7)
        out = np.empty(7)
        kb.subdivide(c, s0, s1, out)
        np.testing.assert_allclose(out, naive.subdivide(c, s0, s1), rtol=0, atol=1e-12)


def test_eval_matches_basis_sum(rng):
    c = rng.normal(size=7)
    for s in (0.0, 0.2, 0.5, 0.999, 1.0):
        assert kb.bernstein_eval(c, s) == pytest.approx(naive.bernstein_eval(c, s), abs=1e-14)


def test_elevate_keeps_the_curve(rng):
    c = rng.normal(size=5)
    out = np.empty(6)
    kb.elevate(c, out)
    for s in np.linspace(0, 1, 11):
        assert naive.bernstein_eval(out, s) == pytest.approx(naive.bernstein_eval(c, s), abs=1e-14)


def test_mean_is_the_integral(rng):
    c = rng.normal(size=7)
    from scipy.integrate import quad
    ref = quad(lambda s: naive.bernstein_eval(c, s), 0, 1, epsabs=0, epsrel=1e-13)[0]
    assert kb.bernstein_mean(c) == pytest.approx(ref, rel=1e-13)


def test_integral_and_cumulative_over_subintervals(rng):
    from scipy.integrate import quad
    c = rng.normal(size=7)
    work = np.empty(8)
    for s0, s1 in ((0.0, 0.37), (0.2, 0.9), (0.5, 1.0)):
        ref = quad(lambda s: naive.bernstein_eval(c, s), s0, s1, epsabs=0, epsrel=1e-13)[0]
        assert kb.bernstein_integral(c, s0, s1, work) == pytest.approx(ref, rel=1e-12)
        cum = kb.bernstein_cumulative(c, s1) - kb.bernstein_cumulative(c, s0)
        assert cum == pytest.approx(ref, rel=1e-12)
