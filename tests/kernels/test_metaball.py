import numpy as np
import pytest

from cloudmeta.scene.blob import rotation_matrix
from cloudmeta.kernels import metaball as km
from tests import naive

KERNEL_IDS = {"wyvill6": km.WYVILL6, "murakami4": km.MURAKAMI4}


@pytest.mark.parametrize("kernel", ["wyvill6", "murakami4"])
@pytest.mark.parametrize("a", [1e-6, 0.1, 0.5, 0.77, 1.0])
def test_control_values_match_the_curve(kernel, a):
    out = np.empty(7)
    km.control_values(KERNEL_IDS[kernel], a, 1.3, out)
    np.testing.assert_allclose(out, naive.control_values(kernel, a, 1.3), rtol=1e-10, atol=1e-13)


def test_wyvill6_paper_numbers_with_erratum():
    """docs/model.md §2: d_3 = 8 a^2 (8a + 5) / 45; the paper's own numbers 2.31 (a = 1) and 0.4 (a = 0.5)."""
    out = np.empty(7)
    km.control_values(km.WYVILL6, 1.0, 1.0, out)
    np.testing.assert_allclose(out, [0, 0, 16 / 27, 104 / 45, 16 / 27, 0, 0], rtol=1e-15)
    assert round(out[2], 2) == 0.59 and round(out[3], 2) == 2.31
    km.control_values(km.WYVILL6, 0.5, 1.0, out)
    assert out[3] == pytest.approx(0.4, rel=1e-15)


def test_murakami4_is_eq18_elevated():
    out = np.empty(7)
    km.control_values(km.MURAKAMI4, 0.5, 1.0, out)
    deg4 = np.array([0, 0, 8 / 3 * 0.25, 0, 0])
    for s in np.linspace(0, 1, 9):
        assert naive.bernstein_eval(out, s) == pytest.approx(naive.bernstein_eval(deg4, s), abs=1e-15)


def test_sphere_chord_matches_textbook(rng):
    for _ in range(50):
        o = rng.normal(size=3) * 5
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        c = rng.normal(size=3)
        r = rng.uniform(0.5, 3)
        ref = naive.chord_sphere(o, d, c, r)
        t0, t1, a = km.chord(o, d, c, np.eye(3) / r)
        if ref is None:
            assert a <= 1e-12
        else:
            np.testing.assert_allclose([t0, t1, a], ref, rtol=1e-9, atol=1e-11)


def test_ellipsoid_chord_matches_model(rng):
    hits = 0
    for _ in range(100):
        o = rng.normal(size=3) * 5
        c = rng.normal(size=3)
        d = c + rng.normal(size=3) - o
        d /= np.linalg.norm(d)
        radii = rng.uniform(0.5, 3, 3)
        q = rotation_matrix(rng.uniform(0, 360, 3))
        ref = naive.chord_ellipsoid(o, d, c, radii, q)
        t0, t1, a = km.chord(o, d, c, naive.unit_frame(radii, q))
        if ref is None:
            assert a <= 1e-12
        else:
            hits += 1
            np.testing.assert_allclose([t0, t1, a], ref, rtol=1e-9, atol=1e-11)
            # the ends lie on the support: u = 1
            for t in (t0, t1):
                assert km.unit_distance2(o + t * d, c, naive.unit_frame(radii, q)) == pytest.approx(1.0, abs=1e-9)
    assert hits > 10


def test_chord_far_from_origin_keeps_its_precision():
    """The stable form of D keeps 1e-9 accuracy at 1e6 units, where B^2 - C loses ~6 digits."""
    c = np.array([1e6, 1e6, 0.0])
    o = c + np.array([-50.0, 0.3, 0.0])
    t0, t1, a = km.chord(o, np.array([1.0, 0, 0]), c, np.eye(3))
    # (o - c) itself carries the rounding of 1e6 + 0.3 (ulp 1.2e-10), so 1e-9 is what can be asked
    assert a == pytest.approx(1 - 0.09, rel=1e-9)
    assert t0 == pytest.approx(50 - np.sqrt(0.91), abs=1e-9)


@pytest.mark.parametrize("kernel", ["wyvill6", "murakami4", "nishimura", "blinn"])
def test_falloff_matches_model(kernel, rng):
    kid = {"wyvill6": 0, "murakami4": 1, "nishimura": 2, "blinn": 3}[kernel]
    u = np.concatenate([rng.uniform(0, 1.2, 50), [0.0, 1 / 9, 0.999999, 1.0]])
    got = np.array([km.falloff(kid, x, 4.0) for x in u])
    np.testing.assert_allclose(got, naive.falloff(kernel, u), rtol=1e-14, atol=1e-15)


# --- nishimura and blinn: piecewise degree-6 representations on the chord (issue 7, part 3) ----------

def chord_pieces(kernel, a, b=4.0, q=1.0, t0=0.0, t1=1.0, cap=4096):
    from cloudmeta.kernels.sweep import alloc_scratch
    rows = alloc_scratch(cap)
    p0, p1, pc = rows.chord_t0, rows.chord_t1, rows.chord_c
    n = km.chord_pieces(kernel, a, b, q, t0, t1, -np.inf, np.inf, p0, p1, pc, np.int64(0))
    assert n <= cap
    order = np.argsort(p0[:n])
    return p0[:n][order], p1[:n][order], pc[:n][order]


def true_curve(kernel, a, b, s):
    """q = 1: k(u(s)) on the open chord (blinn's value at the ends is its limit from inside, exp(-b))."""
    u = (1 - a) + a * (1 - 2 * s) ** 2
    if kernel == km.BLINN:
        return np.exp(-b * u)
    return naive.falloff("nishimura", u)


PIECEWISE_CASES = [(km.NISHIMURA, 4.0)] + [(km.BLINN, b) for b in (0.3, 1.0, 4.0, 9.0, 20.0)]
A_VALUES = np.concatenate([np.geomspace(1e-8, 0.5, 12), np.linspace(0.5, 1.0, 40),
                           [8 / 9 - 1e-12, 8 / 9, 8 / 9 + 1e-12, 1 - 1e-13]])


@pytest.mark.parametrize("kernel,b", PIECEWISE_CASES)
def test_pieces_match_the_kernel_within_their_bound(kernel, b):
    """Every piece's Bernstein curve is within APPROX_TOLERANCE (+ rounding) of k(u(s)) on dense samples;
    the pieces tile the chord, sharing their ends bit for bit."""
    x = np.linspace(0, 1, 97)
    worst = 0.0
    for a in A_VALUES:
        p0, p1, pc = chord_pieces(kernel, a, b)
        assert p0[0] == 0.0 and p1[-1] == 1.0
        np.testing.assert_array_equal(p0[1:], p1[:-1])
        assert np.all(p1 > p0)
        for s0, s1, c in zip(p0, p1, pc):
            err = np.abs(naive.bernstein_eval(c, x) - true_curve(kernel, a, b, s0 + (s1 - s0) * x)).max()
            worst = max(worst, err)
    assert worst <= km.APPROX_TOLERANCE + 1e-14, worst
    assert worst > 1e-2 * km.APPROX_TOLERANCE  # the bound is not wildly pessimistic either


@pytest.mark.parametrize("kernel,b", PIECEWISE_CASES)
def test_pieces_scale_with_weight_and_map_to_the_chord(kernel, b):
    """q scales the control values; pieces on [t0, t1] are the same curves at t = t0 + s (t1 - t0)."""
    a = 0.83
    s0, s1, c = chord_pieces(kernel, a, b)
    t0, t1, ct = chord_pieces(kernel, a, b, q=-1.7, t0=3.0, t1=5.5)
    np.testing.assert_allclose(ct, -1.7 * c, rtol=1e-14, atol=1e-16)
    np.testing.assert_allclose(t0, 3.0 + 2.5 * s0, rtol=0, atol=1e-14)
    np.testing.assert_allclose(t1, 3.0 + 2.5 * s1, rtol=0, atol=1e-14)
    # mirror pairs: the curve is symmetric about the chord's middle
    np.testing.assert_allclose(s0[::-1], 1 - s1, atol=1e-15)
    np.testing.assert_allclose(c[::-1, ::-1], c, rtol=1e-12, atol=1e-15)


def test_nishimura_has_an_exact_inner_piece():
    """a > 8/9: the middle, u <= 1/9, is one piece, exactly 1 - 3u (degree 2); at a = 1 the outer pieces
    are exact too (sqrt(u) = |1 - 2s|)."""
    for a in (0.9, 0.95, 1.0):
        p0, p1, pc = chord_pieces(km.NISHIMURA, a)
        v1 = np.sqrt((a - 8 / 9) / a)
        mid = np.flatnonzero((p0 < 0.5) & (p1 > 0.5))
        assert len(mid) == 1
        k = mid[0]
        assert p0[k] == pytest.approx((1 - v1) / 2, abs=1e-15) and p1[k] == pytest.approx((1 + v1) / 2, abs=1e-15)
        x = np.linspace(0, 1, 33)
        s = p0[k] + (p1[k] - p0[k]) * x
        np.testing.assert_allclose(naive.bernstein_eval(pc[k], x), 1 - 3 * (1 - 4 * a * s * (1 - s)), rtol=0, atol=2e-15)
        # the exact form of 1 - 3u on the piece, fitted independently
        np.testing.assert_allclose(pc[k], naive.fit_bernstein(lambda xx: 1 - 3 * (1 - 4 * a * (p0[k] + (p1[k] - p0[k]) * xx)
                                                                            * (1 - p0[k] - (p1[k] - p0[k]) * xx)), 6),
                                   rtol=0, atol=1e-13)
    p0, p1, pc = chord_pieces(km.NISHIMURA, 1.0)
    x = np.linspace(0, 1, 33)
    err = max(np.abs(naive.bernstein_eval(c, x) - true_curve(km.NISHIMURA, 1.0, 4.0, s0 + (s1 - s0) * x)).max()
              for s0, s1, c in zip(p0, p1, pc))
    assert err < 1e-14


def test_piece_counts_follow_the_bound():
    """Grazing chords need one piece; deep ones more (the cost of 1e-12 at degree 6)."""
    assert len(chord_pieces(km.NISHIMURA, 1e-4)[0]) == 1
    assert len(chord_pieces(km.BLINN, 1e-4, 4.0)[0]) == 1
    for kernel, b in PIECEWISE_CASES:
        counts = [len(chord_pieces(kernel, a, b)[0]) for a in (0.05, 0.3, 0.7, 1.0)]
        assert 1 <= counts[0] <= counts[1] <= counts[2] and counts[3] <= 100, (kernel, b, counts)


def test_nishimura_derivative_constant():
    """The proof's two facts: the 7th Taylor coefficient of sqrt(1 - 2xt + t^2) is (P_5(x) - P_7(x)) / 13,
    and NISHIMURA_G7 bounds its modulus on [-1, 1] (dense samples plus the Lipschitz bound 15 + 28 of
    P_5 - P_7 there)."""
    from numpy.polynomial import legendre as L
    for x in np.linspace(-1, 1, 21):
        p = [1.0, -2 * x, 1.0] + [0.0] * 6
        y = [1.0]
        for n in range(1, 8):  # y^2 = p, term by term
            y.append((p[n] - sum(y[k] * y[n - k] for k in range(1, n))) / 2)
        assert y[7] == pytest.approx((L.legval(x, [0] * 5 + [1]) - L.legval(x, [0] * 7 + [1])) / 13, abs=1e-14)
    xs = np.linspace(-1, 1, 2_000_001)
    m = np.abs(L.legval(xs, [0] * 5 + [1, 0, -1])).max() + 43 * (xs[1] - xs[0]) / 2
    assert m / 13 <= km.NISHIMURA_G7 < 1.001 * m / 13


def test_blinn_derivative_bound():
    """|f^(7)| <= f P(|phi'|) for f = exp(phi), phi quadratic with phi''/2 = -4c: the Taylor coefficients of
    exp(beta t - g t^2) from (n + 1) y_{n+1} = beta y_n - 2 g y_{n-1}."""
    for c in (0.01, 0.7, 4.0, 30.0):
        g = 4 * c
        for beta in np.linspace(-4 * c, 4 * c, 9):
            y = [1.0, beta]
            for n in range(1, 7):
                y.append((beta * y[n] - 2 * g * y[n - 1]) / (n + 1))
            x = abs(beta)
            bound = x ** 7 + 42 * g * x ** 5 + 420 * g ** 2 * x ** 3 + 840 * g ** 3 * x
            assert abs(5040 * y[7]) <= bound * (1 + 1e-12) + 1e-300


def test_chebyshev_to_bernstein_matrix():
    x = km.CHEB_NODES
    np.testing.assert_allclose(np.cos(np.pi * (2 * np.arange(7) + 1) / 14), 1 - 2 * x, atol=1e-16)
    for deg in range(7):  # reproduces every polynomial of degree <= 6
        c = np.random.default_rng(deg).normal(size=7)
        np.testing.assert_allclose(km.CHEB_TO_BERNSTEIN @ naive.bernstein_eval(c, x), c, atol=1e-13)


def test_gather_chords_counts_pieces_beyond_capacity():
    """The capacity contract holds for pieces: the count is every piece; only the first capacity rows
    are written, and they are the same as with room for all."""
    from cloudmeta.kernels.records import BlobRecord
    from cloudmeta.kernels.sweep import alloc_scratch, gather_chords
    centers = np.array([[0.0, 0.0, 0.0], [1.0, 0.2, 0.0], [2.5, -0.3, 0.1]])
    frames = np.array([np.eye(3) / r for r in (1.5, 1.0, 1.2)])
    weights = np.array([1.0, 0.8, -0.4])
    cand = np.arange(3)
    o, d = np.array([-5.0, 0.1, 0.05]), np.array([1.0, 0.0, 0.0])
    for kernel, b, per_chord in ((km.WYVILL6, 4.0, 1), (km.NISHIMURA, 4.0, None), (km.BLINN, 2.5, None)):
        big = alloc_scratch(1000)
        n = gather_chords(o, d, 0.0, np.inf, BlobRecord(centers, frames, weights, kernel, b, 0.5), cand, 3, big)
        assert (n == 3) if per_chord else (n > 6)
        small = alloc_scratch(3)
        assert gather_chords(o, d, 0.0, np.inf, BlobRecord(centers, frames, weights, kernel, b, 0.5), cand, 3,
                             small) == n
        for k in range(3):
            np.testing.assert_array_equal(small[k][:3], big[k][:3])
        if per_chord is None:  # gather_chords inlines chord_pieces: the same rows, bit for bit
            rows = alloc_scratch(n)
            p0, p1, pc = rows.chord_t0, rows.chord_t1, rows.chord_c
            m = 0
            for i in range(3):
                t0, t1, a = km.chord(o, d, centers[i], frames[i])
                m = km.chord_pieces(kernel, min(a, 1.0), b, weights[i], t0, t1, 0.0, np.inf, p0, p1, pc, np.int64(m))
            assert m == n
            np.testing.assert_array_equal(big[0][:n], p0)
            np.testing.assert_array_equal(big[1][:n], p1)
            np.testing.assert_array_equal(big[2][:n], pc)
        # tmin / tmax leave out the pieces that lie outside
        m = gather_chords(o, d, 5.0, 6.0, BlobRecord(centers, frames, weights, kernel, b, 0.5), cand, 3, big)
        assert 1 <= m <= n
        assert np.all((big[1][:m] > 5.0) & (big[0][:m] < 6.0))
