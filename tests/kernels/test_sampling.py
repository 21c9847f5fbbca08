"""The one Newton inversion of an optical depth (sampling.invert_depth), in both of its bracket modes."""
import numpy as np
import pytest

from cloudmeta.kernels.sampling import free_flight, invert_depth
from cloudmeta.kernels.single import _depth_to_s


def _depth(S, w, s):
    """w * int_0^s of the Bernstein polynomial with control values S, by Gauss-Legendre."""
    n = S.shape[0] - 1
    x, wt = np.polynomial.legendre.leggauss(16)
    t = 0.5 * s * (x + 1.0)
    from math import comb
    values = sum(S[i] * comb(n, i) * t ** i * (1.0 - t) ** (n - i) for i in range(n + 1))
    return w * 0.5 * s * float(np.dot(wt, values))


@pytest.mark.parametrize("open_bracket", [True, False])
def test_invert_depth_reaches_the_target_inside_its_bracket(open_bracket):
    rng = np.random.default_rng(7)
    for _ in range(20):
        S = rng.uniform(0.0, 3.0, 7)
        w = rng.uniform(0.1, 2.0)
        lo = rng.uniform(0.0, 0.5)
        target = rng.uniform(_depth(S, w, lo), _depth(S, w, 1.0))
        s = invert_depth(S, w, target, lo, 0.5 * (lo + 1.0), 1e-15, np.int64(100), np.bool_(open_bracket))
        assert lo <= s <= 1.0
        assert _depth(S, w, s) == pytest.approx(target, rel=1e-11, abs=1e-13)


def test_free_flight_and_the_quadrature_nodes_share_it():
    S = np.array([0.5, 1.5, 2.5, 0.2, 0.0, 1.0, 3.0])
    w = 1.3
    target = 0.4 * _depth(S, w, 1.0)
    s_flight = free_flight(S, w, target)
    s_node = _depth_to_s(S, w, target, 0.0, 0.0)
    assert _depth(S, w, s_flight) == pytest.approx(target, rel=1e-12)
    assert _depth(S, w, s_node) == pytest.approx(target, rel=1e-12)
    assert s_flight == pytest.approx(s_node, rel=1e-12)
