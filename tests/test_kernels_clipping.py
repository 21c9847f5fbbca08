import numpy as np
import pytest
from numpy.polynomial import polynomial as P

from cloudmeta.kernels import clipping as kc
from tests import naive


def bernstein_from_roots(roots, scale=1.0):
    """Control values of scale * prod (s - r) (padded to degree 6 by a positive factor)."""
    poly = np.array([scale])
    for r in roots:
        poly = P.polymul(poly, [-r, 1.0])
    while len(poly) < 7:
        poly = P.polymul(poly, [1.0, 0.5])  # (1 + s/2) > 0 on [0, 1]
    return naive.fit_bernstein(lambda s: P.polyval(s, poly), 6)


def clip(g, tol=1e-12, eps=0.0):
    st = (np.empty(kc.STACK_DEPTH), np.empty(kc.STACK_DEPTH), np.empty((kc.STACK_DEPTH, 7)))
    roots, rising = np.empty(16), np.empty(16, np.bool_)
    n = kc.clip_roots(np.asarray(g, float), tol, eps, *st, np.empty((2, 7)), roots, rising)
    return roots[:n].copy(), rising[:n].copy()


@pytest.mark.parametrize("roots", [[0.3], [0.1, 0.7], [0.05, 0.5, 0.95], [0.2, 0.21], [0.1, 0.3, 0.5, 0.7, 0.9]])
def test_simple_roots_in_order(roots):
    got, rising = clip(bernstein_from_roots(roots))
    np.testing.assert_allclose(got, roots, atol=1e-11)
    assert np.all(np.diff(got) > 0)
    # classes alternate, and the first crossing of prod(s - r) * positive is rising iff len is odd... check directly
    for r, up in zip(got, rising):
        g = bernstein_from_roots(roots)
        assert (naive.bernstein_eval(g, min(r + 1e-6, 1)) >= 0) == up


def test_root_free_interval_is_rejected_by_the_hull():
    assert len(clip([0.2, 0.5, 0.1, 0.9, 0.3, 0.4, 0.2])[0]) == 0
    assert len(clip([-0.2, -0.5, -0.1, -0.9, -0.3, -0.4, -0.2])[0]) == 0


def test_double_root_is_a_touch_not_a_crossing():
    assert len(clip(bernstein_from_roots([0.4, 0.4]))[0]) == 0
    got, _ = clip(bernstein_from_roots([0.4, 0.4, 0.8]))
    np.testing.assert_allclose(got, [0.8], atol=1e-11)


def test_triple_root_is_one_crossing():
    got, _ = clip(bernstein_from_roots([0.6, 0.6, 0.6]), tol=1e-10)
    assert len(got) == 1 and abs(got[0] - 0.6) < 1e-4  # a triple root is conditioned as eps^(1/3)


def test_touch_lifted_by_noise_is_dropped():
    """g = (s - 0.4)^2 (1 + s) - 1e-14: two crossings 1.7e-7 apart whose |g| stays below the noise level."""
    g = naive.fit_bernstein(lambda s: (s - 0.4) ** 2 * (1 + s) - 1e-14, 6)
    assert len(clip(g, tol=1e-12, eps=1e-13)[0]) == 0
    assert len(clip(g, tol=1e-12, eps=0.0)[0]) == 2  # without the noise level they are kept


def test_roots_at_the_ends():
    g = bernstein_from_roots([0.0, 0.5])
    g[0] = 0.0  # exactly: g(0) = 0 belongs to the class g >= 0, so the class changes at s = 0
    got, rising = clip(g)
    assert len(got) == 2 and not rising[0] and rising[1]
    assert got[0] == pytest.approx(0.0, abs=1e-12) and got[-1] == pytest.approx(0.5, abs=1e-12)


def test_random_polynomials_match_numpy_roots(rng):
    for _ in range(200):
        g = rng.normal(size=7)
        got, _ = clip(g, tol=1e-13)
        power = naive.fit_bernstein  # noqa: F841 (documentation: power form below is independent)
        # power form of the Bernstein polynomial by the textbook basis
        poly = np.zeros(7)
        for i in range(7):
            basis = np.array([1.0])
            for _k in range(i):
                basis = P.polymul(basis, [0, 1])
            for _k in range(6 - i):
                basis = P.polymul(basis, [1, -1])
            poly = P.polyadd(poly, g[i] * __import__("math").comb(6, i) * basis)
        ref = [x for x in naive._real_roots_in(poly, 1.0)]
        ref = [x for x in ref if (P.polyval(max(x - 1e-7, 0), poly) >= 0) != (P.polyval(min(x + 1e-7, 1), poly) >= 0)]
        np.testing.assert_allclose(got, ref, atol=1e-9)


def test_hull_crossing_matches_all_pairs(rng):
    hull = np.empty(7)
    cases = [rng.normal(size=7) for _ in range(3000)]
    cases += [np.round(rng.normal(size=7)) for _ in range(500)]  # zeros and collinear points
    cases += [np.array([0, 0, 0.59, 2.31, 0.59, 0, 0]) - t for t in (-0.2, 0.5, 1.2)]
    for c in cases:
        got = kc.hull_crossing(c, hull)
        ref = naive.hull_crossing(c)
        if ref is None:
            assert got[0] > got[1], c
        else:
            np.testing.assert_allclose(got, ref, atol=1e-14, err_msg=str(c))
