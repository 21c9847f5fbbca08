"""One metaball on a ray: its chord, its Bernstein control values, and its falloff and gradient at a point.

docs/model.md §1-2. A ball is a centre c and a frame M = S^-1 Q^T with u(x) = |M (x - c)|^2.

On its chord, s in [0, 1], u(s) = 1 - 4 a s (1 - s) = (1 - a) + a v^2 with v = 1 - 2 s, and the ball's
field is q k(u(s)). ``wyvill6`` and ``murakami4`` are exactly one degree-6 Bernstein polynomial per chord
(``control_values``). ``nishimura`` and ``blinn`` are not polynomials in s: ``chord_pieces`` cuts their
chord into PIECES [s_a, s_b], each a degree-6 Bernstein polynomial in the piece's own parameter, so that
compositing, clipping and the exact integrals downstream apply unchanged (a piece is to them one more
chord).

Value tolerance
---------------
Every piece differs from q k(u(s)) by at most ``APPROX_TOLERANCE`` |q| = 1e-12 |q| anywhere on the piece
(plus the rounding of the conversion below, a few 1e-15 |q|); where pieces of several balls overlap, the
field's error is at most 1e-12 sum |q_i|. This is the simple translation of docs/model.md §3's root tolerance
(1e-9 of the scene's diagonal, on t): a value error delta moves a crossing by delta / |dF/dt|, so roots
stay within 1e-9 of those of the exact field wherever |dF/dt| >= 1e-3 sum |q_i| per unit length, and
tau is off by at most 1e-12 sum |q_i| per unit of inside length. What no value tolerance buys: a ray
that touches the isosurface within delta (|F - T| <= 1e-12 sum |q_i| at a tangency) may gain or lose a
segment of length up to 2 sqrt(2 delta / |F''|), as the exact kernels do at their rounding level.

Pieces
------
Each piece is the degree-6 interpolant of q k(u(s)) at the 7 Chebyshev points of the piece (the roots
of T_7 mapped to [s_a, s_b], ``CHEB_NODES``); its control values are ``CHEB_TO_BERNSTEIN`` (the inverse
of the 7 x 7 matrix of the Bernstein basis at those points, a constant) times the 7 values. On a piece of
width h, Chebyshev's remainder bounds the error by max |f^(7)| / 7! * (h/2)^7 / 2^6. With these
derivative bounds (f = k(u(s)), q = 1):

- ``nishimura``, u >= 1/9: f = 3/2 (1 + u) - 3 sqrt(u). The first part has degree 2 and is interpolated
  exactly, so the error is 3 times that of g(s) = sqrt(u(s)) = sqrt(a) sqrt(v^2 + D^2), D^2 = (1 - a) / a.
  From the generating function sqrt(1 - 2 x t + t^2) = sum_n C_n(x) t^n (Gegenbauer, lambda = -1/2),
  C_n = (P_{n-2} - P_n) / (2n - 1), d^7/dv^7 sqrt(v^2 + D^2) = 7! C_7(-v / r) / r^6 exactly, with
  r = sqrt(v^2 + D^2) = sqrt(u / a). |C_7| <= G7 = max over [-1, 1] of |P_5 - P_7| / 13 = 0.62143532... / 13
  (``NISHIMURA_G7`` = 0.6215 / 13, checked in the tests), and also |C_7(x)| <= 1 - |x| (C_7' = -P_6,
  C_7(+-1) = 0), which is (1 - a) / (sqrt(u) (sqrt(u) + sqrt(a) |v|)) and is the smaller one near a = 1.
  So |g^(7)| <= 2^7 7! G a^3.5 / u^3 with G the lesser of the two, and a piece's error is at most
  6 G a^3.5 (h/2)^7 / u^3, G and u taken at the piece's end nearer s = 1/2 (where both are worst).
  With a > 8/9 the middle of the chord, u <= 1/9 (s in [s_1, 1 - s_1], v_1 = sqrt((a - 8/9) / a)), has
  k = 1 - 3u, exactly degree 2: one exact piece (``nishimura_inner_values``); the outer parts [0, s_1] and
  [1 - s_1, 1] are cut as above (the paper's three parts, the outer two subdivided). At a = 1 the outer
  parts are exact too (sqrt(u) = |v|) and take one piece each.
- ``blinn``: f = exp(phi(s)), phi = -b u(s) = -b + 4 c s (1 - s), c = a b. phi is quadratic, so
  f(s + t) = f(s) exp(phi'(s) t - 4 c t^2), and the Taylor coefficient of t^7, bounded term by term,
  gives |f^(7)(s)| <= f(s) P(|phi'(s)|), P(x) = x^7 + 42 (4c) x^5 + 420 (4c)^2 x^3 + 840 (4c)^3 x, with
  |phi'| = 4 c |1 - 2 s|. On a piece in [alpha, 1 - alpha], alpha <= 1/2, f <= f(min(s_b, 1/2)) and
  |phi'| <= 4 c (1 - 2 alpha): the error is at most f(min(s_b, 1/2)) P(4 c (1 - 2 alpha)) (h/2)^7 / (7! 2^6).
  The jump exp(-b) at u = 1 stays where it is: the first and last pieces begin and end at the chord's
  ends, so the field steps there exactly.

The pieces are cut greedily from both chord ends towards the middle, each as wide as its bound allows
(``piece_cut``), in mirror pairs (u is symmetric about s = 1/2; the mirror's control values are the same,
reversed), closed by one middle piece [alpha, 1 - alpha] as soon as its bound allows it (or by the exact
inner piece of ``nishimura``). Every piece meets the tolerance by the bound, not by sampling; the tests
sample them anyway (observed errors 0.67 of the bound for blinn, 0.94 for nishimura). Pieces per chord at
1e-12: nishimura 1 (a < 0.01) to 37 (a near 8/9), about 19 on average over a uniform in (0, 1];
blinn b = 4: 1 to 50 (a = 1), about 27 on average; b = 1: at most 23; b >= 16: at most about 110 at
any b (the tails below 1e-12 |q| take one piece).
"""
import math

import numpy as np
from numba import njit

from .config import NJIT, NJIT_INLINE
from .bernstein import store_curve
from .kinds import BLINN, MURAKAMI4, NISHIMURA, WYVILL6


#: the largest error of a piece of ``nishimura`` or ``blinn``, relative to |q| (see the module docstring)
APPROX_TOLERANCE = 1e-12
#: an upper bound of max over [-1, 1] of |C_7^(-1/2)| = |P_5 - P_7| / 13 (0.62143532... / 13)
NISHIMURA_G7 = 0.6215 / 13.0
#: the 7 Chebyshev points (roots of T_7) mapped to [0, 1], increasing
CHEB_NODES = 0.5 - 0.5 * np.cos(np.pi * (2.0 * np.arange(7) + 1.0) / 14.0)
#: Bernstein control values of the degree-6 interpolant = CHEB_TO_BERNSTEIN @ (values at CHEB_NODES)
CHEB_TO_BERNSTEIN = np.linalg.inv(np.array([[math.comb(6, i) * x ** i * (1.0 - x) ** (6 - i) for i in range(7)]
                                            for x in CHEB_NODES]))
#: 7! 2^6: Chebyshev's remainder on a piece of width h is max |f^(7)| (h/2)^7 / (7! 2^6)
_REMAINDER = 5040.0 * 64.0
_SEVENTH = 1.0 / 7.0


@njit(**NJIT_INLINE)
def _apply_frame(frame, x, y, z):
    """M v for the frame M = S^-1 Q^T of a ball and v = (x, y, z)."""
    return (frame[0, 0] * x + frame[0, 1] * y + frame[0, 2] * z,
            frame[1, 0] * x + frame[1, 1] * y + frame[1, 2] * z,
            frame[2, 0] * x + frame[2, 1] * y + frame[2, 2] * z)


@njit(**NJIT_INLINE)
def to_unit_frame(x, center, frame):
    """x in the ball's unit frame, M (x - c), where u(x) = |M (x - c)|^2 (docs/model.md §1)."""
    return _apply_frame(frame, x[0] - center[0], x[1] - center[1], x[2] - center[2])


@njit(**NJIT_INLINE)
def ball_field(x, center, frame, q, kernel, blobbiness):
    """q k(u(x)), one ball's share of the field F at x (0 outside its support)."""
    u = unit_distance2(x, center, frame)
    if u < 1.0:
        return q * falloff(kernel, u, blobbiness)
    return 0.0


@njit(**NJIT_INLINE)
def field_sum(x, blob, items, lo, hi):
    """F(x) over the balls items[lo:hi] of blob (a records.BlobRecord), added in that order."""
    acc = 0.0
    for m in range(lo, hi):
        i = items[m]
        acc += ball_field(x, blob.centers[i], blob.frames[i], blob.weights[i], blob.kernel, blob.blobbiness)
    return acc


@njit(**NJIT_INLINE)
def gradient_sum(x, blob, items, lo, hi):
    """grad F(x) over the balls items[lo:hi] of blob (a records.BlobRecord), added in that order."""
    gx = 0.0
    gy = 0.0
    gz = 0.0
    for m in range(lo, hi):
        i = items[m]
        ax, ay, az = ball_gradient(x, blob.centers[i], blob.frames[i], blob.weights[i], blob.kernel, blob.blobbiness)
        gx += ax
        gy += ay
        gz += az
    return gx, gy, gz


@njit(**NJIT)
def chord(o, d, center, frame):
    """The ray's chord through the ball's support u < 1: returns (t0, t1, a), a = 1 - min u on the line.

    a <= 0 means the line misses (or only touches) the support. In the unit frame o' = M (o - c),
    d' = M d, u(t) = A t^2 + 2 (o'.d') t + |o'|^2 with A = |d'|^2. a is computed as 1 - |o' + t_m d'|^2 at
    the closest point t_m rather than as B^2 - A C, which cancels catastrophically far from the ball.
    """
    px, py, pz = to_unit_frame(o, center, frame)
    dx, dy, dz = _apply_frame(frame, d[0], d[1], d[2])
    A = dx * dx + dy * dy + dz * dz
    tm = -(px * dx + py * dy + pz * dz) / A
    qx = px + tm * dx
    qy = py + tm * dy
    qz = pz + tm * dz
    a = 1.0 - (qx * qx + qy * qy + qz * qz)
    if a <= 0.0:
        return tm, tm, a
    h = math.sqrt(a / A)
    return tm - h, tm + h, a


@njit(**NJIT)
def control_values(kernel, a, q, out):
    """Degree-6 Bernstein control values of q k(u(s)) on the chord, u(s) = 1 - 4 a s (1 - s) (eq. 11).

    wyvill6: exact, with the erratum of docs/model.md §2.2 (d_3 = 8 a^2 (8a + 5) / 45, the paper drops the 8).
    murakami4: exactly (0, 0, 8/3 a^2, 0, 0) at degree 4 (eq. 18), elevated twice to degree 6.
    nishimura and blinn are not one polynomial per chord: see ``chord_pieces``.
    """
    for i in range(7):
        out[i] = 0.0
    a2 = a * a
    if kernel == WYVILL6:
        e = q * 16.0 / 27.0 * a2
        out[2] = e
        out[3] = q * 8.0 * a2 * (8.0 * a + 5.0) / 45.0
        out[4] = e
    else:  # MURAKAMI4: m = 8/3 a^2 at degree 4; elevated 4 -> 5 -> 6 it becomes (2/5, 3/5, 2/5) m
        m = q * 8.0 / 3.0 * a2
        out[2] = 0.4 * m
        out[3] = 0.6 * m
        out[4] = 0.4 * m


@njit(**NJIT)
def falloff(kernel, u, blobbiness):
    """k(u) of docs/model.md §1 (0 for u >= 1)."""
    if u >= 1.0:
        return 0.0
    if kernel == WYVILL6:
        v = 1.0 - u
        return v * v * (1.0 - 4.0 * u / 9.0)
    if kernel == MURAKAMI4:
        v = 1.0 - u
        return v * v
    if kernel == NISHIMURA:
        if u <= 1.0 / 9.0:
            return 1.0 - 3.0 * u
        v = 1.0 - math.sqrt(u)
        return 1.5 * v * v
    return math.exp(-blobbiness * u)


@njit(**NJIT)
def falloff_slope(kernel, u, blobbiness):
    """k'(u) for u < 1 (0 for u >= 1; blinn's jump at u = 1 has no slope to give)."""
    if u >= 1.0:
        return 0.0
    if kernel == WYVILL6:  # d/du (1-u)^2 (1 - 4u/9) = -(1-u) (22/9 - 12/9 u)
        return -(1.0 - u) * (22.0 - 12.0 * u) / 9.0
    if kernel == MURAKAMI4:
        return -2.0 * (1.0 - u)
    if kernel == NISHIMURA:
        if u <= 1.0 / 9.0:
            return -3.0
        r = math.sqrt(u)
        return -1.5 * (1.0 - r) / r
    return -blobbiness * math.exp(-blobbiness * u)


@njit(**NJIT)
def ball_gradient(x, center, frame, q, kernel, blobbiness):
    """grad of q k(u(x)): q k'(u) grad u, grad u = 2 M^T M (x - c). Returns its three components."""
    px, py, pz = to_unit_frame(x, center, frame)
    u = px * px + py * py + pz * pz
    if u >= 1.0:
        return 0.0, 0.0, 0.0
    f = 2.0 * q * falloff_slope(kernel, u, blobbiness)
    return (f * (frame[0, 0] * px + frame[1, 0] * py + frame[2, 0] * pz),
            f * (frame[0, 1] * px + frame[1, 1] * py + frame[2, 1] * pz),
            f * (frame[0, 2] * px + frame[1, 2] * py + frame[2, 2] * pz))


@njit(**NJIT)
def unit_distance2(x, center, frame):
    """u(x) = |M (x - c)|^2."""
    px, py, pz = to_unit_frame(x, center, frame)
    return px * px + py * py + pz * pz


# --- nishimura and blinn: pieces of degree-6 Bernstein polynomials on the chord (module docstring) ------

@njit(**NJIT_INLINE)
def is_piecewise(kernel):
    """True for the kernels that ``chord_pieces`` represents (nishimura, blinn)."""
    return kernel == NISHIMURA or kernel == BLINN


@njit(**NJIT_INLINE)
def _chord_u(a, s):
    """u(s) = (1 - a) + a (1 - 2s)^2, accurate where u is small (the middle of a deep chord)."""
    v = 1.0 - 2.0 * s
    return (1.0 - a) + a * v * v


@njit(**NJIT_INLINE)
def _piece_value(kernel, a, b, s):
    """k(u(s)) for blinn, or for nishimura's outer part (u >= 1/9)."""
    if kernel == NISHIMURA:
        m = 4.0 * a * s * (1.0 - s)  # 1 - u
        r = m / (1.0 + math.sqrt(_chord_u(a, s)))  # 1 - sqrt(u), without cancellation for small a
        return 1.5 * r * r
    return math.exp(-b * _chord_u(a, s))


@njit(**NJIT_INLINE)
def _error_factor(kernel, a, b, alpha, s_far):
    """E such that any piece [alpha, beta], alpha <= beta <= s_far, beta <= 1 - alpha, interpolates
    k(u(s)) within E (h/2)^7, h = beta - alpha (the bounds of the module docstring)."""
    s = min(s_far, 0.5)
    if kernel == NISHIMURA:
        u = _chord_u(a, s)
        su = math.sqrt(u)
        sa = math.sqrt(a)
        g7 = min(NISHIMURA_G7, (1.0 - a) / (su * (su + sa * abs(1.0 - 2.0 * s))))
        return 6.0 * g7 * a * a * a * sa / (u * u * u)
    c4 = 4.0 * a * b
    x = c4 * (1.0 - 2.0 * alpha)
    x2 = x * x
    p = x * (x2 * (x2 * (x2 + 42.0 * c4) + 420.0 * c4 * c4) + 840.0 * c4 * c4 * c4)
    if p == np.inf:
        return np.inf
    return math.exp(-b * _chord_u(a, s)) * p / _REMAINDER


@njit(**NJIT_INLINE)
def _width(e):
    """The widest h with e (h/2)^7 <= APPROX_TOLERANCE."""
    if e <= 0.0:
        return 1.0
    return 2.0 * (APPROX_TOLERANCE / e) ** _SEVENTH


@njit(**NJIT_INLINE)
def piece_cut(kernel, a, b, alpha, s_stop):
    """The end of a piece from alpha that the bound proves within tolerance, at most s_stop
    (alpha < s_stop <= 1/2).

    h_0 from the values at alpha, then h_1 from those at min(alpha + h_0, s_stop), which are no better
    than anywhere on [alpha, alpha + h_1] (h_1 <= h_0; f grows and u shrinks towards the middle): h_1 is
    proven. For blinn, whose values can grow by many orders over h_0 when b is large, h_1 is then
    widened by Newton's method on L(h) = log(bound(alpha, alpha + h) / tolerance), which is increasing
    and concave in h: from a point with L <= 0 each Newton step stays at or below the root (the tangent
    lies above a concave function), and the result is checked against the bound itself."""
    h0 = _width(_error_factor(kernel, a, b, alpha, alpha))
    h = _width(_error_factor(kernel, a, b, alpha, min(alpha + h0, s_stop)))
    if kernel == BLINN and alpha + h < s_stop:
        c4 = 4.0 * a * b
        x = c4 * (1.0 - 2.0 * alpha)
        x2 = x * x
        p = x * (x2 * (x2 * (x2 + 42.0 * c4) + 420.0 * c4 * c4) + 840.0 * c4 * c4 * c4)
        if 0.0 < p < np.inf:
            lp = math.log(p / (_REMAINDER * APPROX_TOLERANCE))
            g = h
            for _ in range(20):
                v = max(1.0 - 2.0 * (alpha + g), 0.0)
                step = (lp - b * ((1.0 - a) + a * v * v) + 7.0 * math.log(0.5 * g)) / (c4 * v + 7.0 / g)
                g -= step
                if abs(step) <= 1e-6 * g:
                    break
            end = min(alpha + g, s_stop)
            hg = 0.5 * (end - alpha)
            hg2 = hg * hg
            if end > alpha + h and _error_factor(kernel, a, b, alpha, end) * (hg2 * hg2 * hg2 * hg) <= APPROX_TOLERANCE:
                return end
    return min(alpha + h, s_stop)


@njit(**NJIT_INLINE)
def middle_fits(kernel, a, b, alpha):
    """Whether the symmetric middle piece [alpha, 1 - alpha] is within tolerance."""
    h = 0.5 * (1.0 - 2.0 * alpha)
    h2 = h * h
    return _error_factor(kernel, a, b, alpha, 0.5) * (h2 * h2 * h2 * h) <= APPROX_TOLERANCE


@njit(**NJIT_INLINE)
def piece_values(kernel, a, b, q, s0, s1):
    """The 7 control values of the degree-6 interpolant of q k(u(s)) at the Chebyshev points of [s0, s1]
    (those of the mirror piece [1 - s1, 1 - s0] are the same, reversed)."""
    h = s1 - s0
    x = CHEB_NODES
    f0 = q * _piece_value(kernel, a, b, s0 + h * x[0])
    f1 = q * _piece_value(kernel, a, b, s0 + h * x[1])
    f2 = q * _piece_value(kernel, a, b, s0 + h * x[2])
    f3 = q * _piece_value(kernel, a, b, s0 + h * x[3])
    f4 = q * _piece_value(kernel, a, b, s0 + h * x[4])
    f5 = q * _piece_value(kernel, a, b, s0 + h * x[5])
    f6 = q * _piece_value(kernel, a, b, s0 + h * x[6])
    m = CHEB_TO_BERNSTEIN
    return ((m[0, 0] * f0 + m[0, 1] * f1 + m[0, 2] * f2 + m[0, 3] * f3 + m[0, 4] * f4 + m[0, 5] * f5 + m[0, 6] * f6),
            (m[1, 0] * f0 + m[1, 1] * f1 + m[1, 2] * f2 + m[1, 3] * f3 + m[1, 4] * f4 + m[1, 5] * f5 + m[1, 6] * f6),
            (m[2, 0] * f0 + m[2, 1] * f1 + m[2, 2] * f2 + m[2, 3] * f3 + m[2, 4] * f4 + m[2, 5] * f5 + m[2, 6] * f6),
            (m[3, 0] * f0 + m[3, 1] * f1 + m[3, 2] * f2 + m[3, 3] * f3 + m[3, 4] * f4 + m[3, 5] * f5 + m[3, 6] * f6),
            (m[4, 0] * f0 + m[4, 1] * f1 + m[4, 2] * f2 + m[4, 3] * f3 + m[4, 4] * f4 + m[4, 5] * f5 + m[4, 6] * f6),
            (m[5, 0] * f0 + m[5, 1] * f1 + m[5, 2] * f2 + m[5, 3] * f3 + m[5, 4] * f4 + m[5, 5] * f5 + m[5, 6] * f6),
            (m[6, 0] * f0 + m[6, 1] * f1 + m[6, 2] * f2 + m[6, 3] * f3 + m[6, 4] * f4 + m[6, 5] * f5 + m[6, 6] * f6))


@njit(**NJIT_INLINE)
def nishimura_inner_values(a, q):
    """Exact control values of q (1 - 3u) on the middle of a chord with a > 8/9, s in [s_1, 1 - s_1]:
    in the piece's parameter x, 1 - 3u = 2/3 + 3 (a - 8/9) (1 - (1 - 2x)^2), and (1 - 2x)^2 raised to
    degree 6 has control values (1, 1/3, -1/15, -1/5, -1/15, 1/3, 1)."""
    e = 3.0 * (a - 8.0 / 9.0)
    c0 = q * (2.0 / 3.0)
    c1 = q * (2.0 / 3.0 + e * (2.0 / 3.0))
    c2 = q * (2.0 / 3.0 + e * (16.0 / 15.0))
    c3 = q * (2.0 / 3.0 + e * 1.2)
    return c0, c1, c2, c3, c2, c1, c0


#: what ``next_piece`` found: a mirror pair, the interpolated middle piece, nishimura's exact inner
#: piece, or nothing more (the pairs met at s = 1/2)
PAIR = 0
MIDDLE = 1
INNER = 2
DONE = 3


@njit(**NJIT_INLINE)
def piece_plan(kernel, a):
    """(inner, s_stop): whether the chord has nishimura's exact inner piece (a > 8/9), and where the
    pairs stop: s_1 = (1 - v_1) / 2 then, else 1/2."""
    if kernel == NISHIMURA and a > 8.0 / 9.0:
        return True, 0.5 * (1.0 - math.sqrt((a - 8.0 / 9.0) / a))
    return False, 0.5


@njit(**NJIT_INLINE)
def next_piece(kernel, a, b, inner, s_stop, alpha):
    """The piece that comes after the pairs up to alpha: (PAIR, beta) for the pair [alpha, beta] and
    [1 - beta, 1 - alpha]; (MIDDLE, .) for [alpha, 1 - alpha]; (INNER, .) for [s_1, 1 - s_1]; (DONE, .)."""
    if alpha >= s_stop:
        return (INNER if inner else DONE), alpha
    if not inner and middle_fits(kernel, a, b, alpha):
        return MIDDLE, 1.0 - alpha
    beta = piece_cut(kernel, a, b, alpha, s_stop)
    if not beta > alpha:  # a b > ~1e14: a spike narrower than the spacing of doubles in s; no bound can hold
        beta = s_stop
    return PAIR, beta


@njit(**NJIT_INLINE)
def pair_ends(t0, t1, beta):
    """(t_l, t_r): where the pair ending at beta ends on the left and starts on the right, one value at
    s = 1/2 so that the two halves meet bit for bit."""
    if beta >= 0.5:
        tl = t0 + 0.5 * (t1 - t0)
        return tl, tl
    return t0 + beta * (t1 - t0), t1 - beta * (t1 - t0)


@njit(**NJIT_INLINE)
def keep_piece(ta, tb, tmin, tmax):
    """Whether a piece [ta, tb] has length and overlaps (tmin, tmax)."""
    return tb > ta and tb > tmin and ta < tmax


@njit(**NJIT_INLINE)
def chord_pieces(kernel, a, b, q, t0, t1, tmin, tmax, p_t0, p_t1, p_c, n):
    """The pieces of q k(u) (nishimura, blinn; blobbiness b) on the chord [t0, t1] with 0 < a <= 1, as rows
    (t0, t1, control values) of p_t0, p_t1, p_c from index n on. Pieces of zero length or outside
    (tmin, tmax) are left out; all others are counted, but only rows below the arrays' capacity are written.
    Returns n plus their number. Consecutive pieces share their end t bit for bit.

    Written on scalars and inlined (as are its helpers) into sweep.gather_chords: a call there that takes
    the arrays would make numba count references to them on every chord."""
    cap = p_t0.shape[0]
    inner, s_stop = piece_plan(kernel, a)
    alpha = 0.0
    ta = t0
    tb = t1
    while True:
        kind, beta = next_piece(kernel, a, b, inner, s_stop, alpha)
        if kind == PAIR:
            tl, tr = pair_ends(t0, t1, beta)
            kl = keep_piece(ta, tl, tmin, tmax)
            kr = keep_piece(tr, tb, tmin, tmax)
            if (kl and n < cap) or (kr and n + kl < cap):
                c0, c1, c2, c3, c4, c5, c6 = piece_values(kernel, a, b, q, alpha, beta)
                if kl and n < cap:
                    store_curve(p_t0, p_t1, p_c, n, ta, tl, c0, c1, c2, c3, c4, c5, c6)
                if kr and n + kl < cap:  # the mirror: the same values, reversed
                    store_curve(p_t0, p_t1, p_c, n + kl, tr, tb, c6, c5, c4, c3, c2, c1, c0)
            n += kl + kr
            alpha = beta
            ta = tl
            tb = tr
            continue
        if kind != DONE and keep_piece(ta, tb, tmin, tmax):
            if n < cap:
                if kind == MIDDLE:
                    c0, c1, c2, c3, c4, c5, c6 = piece_values(kernel, a, b, q, alpha, beta)
                else:
                    c0, c1, c2, c3, c4, c5, c6 = nishimura_inner_values(a, q)
                store_curve(p_t0, p_t1, p_c, n, ta, tb, c0, c1, c2, c3, c4, c5, c6)
            n += 1
        return n
