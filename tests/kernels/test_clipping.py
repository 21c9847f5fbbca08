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
    n = kc.clip_roots(np.asarray(g, float), tol, eps, *st, roots, rising)
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


def reference_roots(g):
    """Sign-changing roots in [0, 1] from numpy on the power form (by the textbook basis)."""
    poly = np.zeros(7)
    for i in range(7):
        basis = np.array([1.0])
        for _k in range(i):
            basis = P.polymul(basis, [0, 1])
        for _k in range(6 - i):
            basis = P.polymul(basis, [1, -1])
        poly = P.polyadd(poly, g[i] * __import__("math").comb(6, i) * basis)
    ref = [x for x in naive._real_roots_in(poly, 1.0)]
    return [x for x in ref if (P.polyval(max(x - 1e-7, 0), poly) >= 0) != (P.polyval(min(x + 1e-7, 1), poly) >= 0)]


def test_random_polynomials_match_numpy_roots(rng):
    for _ in range(200):
        g = rng.normal(size=7)
        got, _ = clip(g, tol=1e-13)
        np.testing.assert_allclose(got, reference_roots(g), atol=1e-9)


def test_many_random_polynomials_at_several_tolerances(rng):
    """2000 curves: no root lost or invented, whatever the tolerance (the convergence test and the
    polish differ between them)."""
    for k in range(2000):
        g = rng.normal(size=7)
        ref = reference_roots(g)
        for tol in (1e-13, 1e-9, 1e-3):
            got, rising = clip(g, tol=tol)
            assert len(got) == len(ref), (g, tol, got, ref)
            np.testing.assert_allclose(got, ref, atol=max(tol, 1e-9), err_msg=str((g, tol)))
            if tol < 1e-12:  # the roots are accurate enough to check the sign just past them
                for r, up in zip(got, rising):
                    assert (naive.bernstein_eval(g, min(r + 1e-6, 1.0)) >= 0) == up or abs(r - 1.0) < 1e-6


@pytest.mark.parametrize("g, roots", [
    # the hull's range collapsed by rounding to smin > smax next to a root
    ([0.07255864, -0.24408764, -0.47005357, 0.47223067, -0.0651318, -0.04407952, 2.00520671],
     [0.0399889519, 0.4689632413]),
    # a root 1e-9 inside the end of a converging interval, shaved off by rounding without FAT
    ([-1.07141261, -0.85976859, -1.20351297, -1.85846639, 1.40565943, 0.61722592, -0.20850242],
     [0.6436165203, 0.9564923259]),
    ([0.39348942, 0.58371835, 0.63461297, -0.58001189, -0.61499441, 0.50735428, -0.0007259],
     [0.4542904512, 0.7916096186, 0.9997614155]),
])
def test_roots_at_the_ends_of_clipped_intervals_survive_rounding(g, roots):
    got, _ = clip(g, tol=1e-13)
    np.testing.assert_allclose(got, reference_roots(np.array(g)), atol=1e-9)
    np.testing.assert_allclose(got, roots, atol=1e-9)


@pytest.mark.parametrize("touch, root", [(0.3, 0.8), (0.8, 0.3), (0.45, 0.55)])
def test_touch_and_root_in_the_two_lanes(touch, root):
    """A noisy touch (two crossings 2e-7 apart) and a simple root: whichever of the two lanes clip_roots
    finds them in, the touch's pair cancels and the root stays, in order."""
    g = naive.fit_bernstein(lambda s: ((s - touch) ** 2 - 1e-14) * (s - root) * (1 + s), 6)
    got, rising = clip(g, tol=1e-12, eps=1e-12)
    np.testing.assert_allclose(got, [root], atol=1e-11)
    assert rising[0] == (naive.bernstein_eval(g, root + 1e-3) >= 0)
    got, _ = clip(g, tol=1e-12, eps=0.0)  # without the noise level: all three crossings
    assert len(got) == 3 and np.all(np.diff(got) > 0)
    np.testing.assert_allclose(got, sorted([touch - 1e-7, touch + 1e-7, root]), atol=1e-9)


def test_subdivide7_matches_the_textbook(rng):
    for _ in range(300):
        c = rng.normal(size=7)
        s0 = rng.uniform(0, 1)
        s1 = s0 + rng.uniform(0, 1 - s0)
        got = np.array(kc._subdivide7(*c, s0, s1))
        np.testing.assert_allclose(got, naive.subdivide(c, s0, s1), atol=1e-12 * np.abs(c).max())
    c = rng.normal(size=7)
    np.testing.assert_allclose(kc._subdivide7(*c, 0.0, 1.0), c, rtol=0, atol=1e-15 * np.abs(c).max())


def test_hull_walk_hops_over_vertices_on_the_near_side():
    """Convex polygons whose lower hull runs through several positive vertices before it crosses 0."""
    hull = np.empty(7)
    for c in ([1, 0.5, 0.2, 0.1, 0.05, -0.1, -0.5], [1, 0.1, 0.1, 0.1, 0.1, 0.1, -0.01],
              [-1, -0.5, -0.2, -0.1, -0.05, 0.1, 0.5], [0.5, 0.2, 0.08, 0.02, 0.01, 0.005, -1e-3]):
        c = np.array(c, float)
        np.testing.assert_allclose(kc.hull_crossing(c, hull), naive.hull_crossing(c), atol=1e-14)
        np.testing.assert_allclose(kc.hull_crossing(c[::-1].copy(), hull),
                                   1 - np.array(naive.hull_crossing(c))[::-1], atol=1e-14)


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
