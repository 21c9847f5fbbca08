"""Bernstein polynomials on [0, 1], kept in local form (never a global power basis).

Every curve in the engine has DEGREE 6 (NCOEF = 7 control values); lower-degree kernels are elevated,
and the hot routines are written out for that degree.
"""
from llvmlite import ir
from numba import njit
from numba.core import cgutils, types
from numba.extending import intrinsic

from .config import NJIT, NJIT_INLINE

DEGREE = 6
NCOEF = DEGREE + 1


@intrinsic
def _fma(typingctx, x, y, z):
    """x * y + z rounded once: LLVM's llvm.fma, the processor's fused multiply-add. IEEE 754's
    fusedMultiplyAdd, so the same result on every machine (unlike fastmath's optional contraction, which
    stays off)."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        f64 = ir.DoubleType()
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(f64, [f64, f64, f64]),
                                            "llvm.fma.f64")
        return builder.call(fn, args)
    return sig, codegen


@njit(**NJIT_INLINE)
def _casteljau_rows(c0, c1, c2, c3, c4, c5, c6, t):
    """All rows of de Casteljau's triangle at t for a degree-6 curve, on scalars: the lerps of one row
    are independent, so they run in parallel instead of waiting on each other as an in-place loop does.
    Each lerp u a + t b is one product and one fused multiply-add (two operations and roundings, not three).
    Returns the left edge (control values on [0, t]) and the right edge (on [t, 1])."""
    u = 1.0 - t
    p0 = _fma(u, c0, t * c1)
    p1 = _fma(u, c1, t * c2)
    p2 = _fma(u, c2, t * c3)
    p3 = _fma(u, c3, t * c4)
    p4 = _fma(u, c4, t * c5)
    p5 = _fma(u, c5, t * c6)
    q0 = _fma(u, p0, t * p1)
    q1 = _fma(u, p1, t * p2)
    q2 = _fma(u, p2, t * p3)
    q3 = _fma(u, p3, t * p4)
    q4 = _fma(u, p4, t * p5)
    r0 = _fma(u, q0, t * q1)
    r1 = _fma(u, q1, t * q2)
    r2 = _fma(u, q2, t * q3)
    r3 = _fma(u, q3, t * q4)
    s0 = _fma(u, r0, t * r1)
    s1 = _fma(u, r1, t * r2)
    s2 = _fma(u, r2, t * r3)
    v0 = _fma(u, s0, t * s1)
    v1 = _fma(u, s1, t * s2)
    w0 = _fma(u, v0, t * v1)
    return (c0, p0, q0, r0, s0, v0, w0), (w0, v1, s2, r3, q4, p5, c6)


@njit(**NJIT_INLINE)
def subdivide(c, s0, s1, out):
    """Control values of the same degree-6 curve on [s0, s1] (0 <= s0 < s1 <= 1), reparametrised to
    [0, 1]: keep [0, s1] of a split at s1, then the part from s0 / s1 on of a split of that."""
    c0, c1, c2, c3, c4, c5, c6 = c[0], c[1], c[2], c[3], c[4], c[5], c[6]
    if s1 < 1.0:
        (c0, c1, c2, c3, c4, c5, c6), _ = _casteljau_rows(c0, c1, c2, c3, c4, c5, c6, s1)
    if s0 > 0.0:
        _, (c0, c1, c2, c3, c4, c5, c6) = _casteljau_rows(c0, c1, c2, c3, c4, c5, c6, s0 / s1)
    out[0] = c0
    out[1] = c1
    out[2] = c2
    out[3] = c3
    out[4] = c4
    out[5] = c5
    out[6] = c6


@njit(**NJIT)
def bernstein_mean(c):
    """Integral over [0, 1] of a Bernstein polynomial: the mean of its control values."""
    acc = 0.0
    for i in range(c.shape[0]):
        acc += c[i]
    return acc / c.shape[0]


@njit(**NJIT)
def bernstein_integral(c, s0, s1, work):
    """Integral over [s0, s1] of the curve: (s1 - s0) times the mean of the subdivided control values."""
    if s1 <= s0:
        return 0.0
    subdivide(c, s0, s1, work)
    return (s1 - s0) * bernstein_mean(work[:c.shape[0]])


@njit(**NJIT_INLINE)
def bernstein_eval(c, s):
    """B(s) of a degree-6 curve: the apex of one de Casteljau triangle (on scalars)."""
    (_, _, _, _, _, _, apex), _ = _casteljau_rows(c[0], c[1], c[2], c[3], c[4], c[5], c[6], s)
    return apex


@njit(**NJIT_INLINE)
def bernstein_cumulative(c, s):
    """Integral over [0, s] of a degree-6 curve: the antiderivative is the degree-7 curve with control
    values e_k = sum_{j<k} c_j / 7, evaluated here by de Casteljau on scalars."""
    e1 = c[0] / 7.0
    e2 = e1 + c[1] / 7.0
    e3 = e2 + c[2] / 7.0
    e4 = e3 + c[3] / 7.0
    e5 = e4 + c[4] / 7.0
    e6 = e5 + c[5] / 7.0
    e7 = e6 + c[6] / 7.0
    # one de Casteljau row takes degree 7 to degree 6; the rest is the degree-6 triangle
    u = 1.0 - s
    (_, _, _, _, _, _, apex), _ = _casteljau_rows(s * e1, u * e1 + s * e2, u * e2 + s * e3, u * e3 + s * e4,
                                                  u * e4 + s * e5, u * e5 + s * e6, u * e6 + s * e7, s)
    return apex


@njit(**NJIT)
def elevate(c, out):
    """Degree elevation by one: out (len n+2) is the same curve as c (len n+1)."""
    n = c.shape[0] - 1
    out[0] = c[0]
    out[n + 1] = c[n]
    for i in range(1, n + 1):
        a = i / (n + 1.0)
        out[i] = a * c[i - 1] + (1.0 - a) * c[i]


@njit(**NJIT_INLINE)
def store_curve(lo, hi, c, n, t0, t1, c0, c1, c2, c3, c4, c5, c6):
    """Row n of a table of degree-6 curves: the interval [t0, t1] in lo, hi and the control values in c."""
    lo[n] = t0
    hi[n] = t1
    c[n, 0] = c0
    c[n, 1] = c1
    c[n, 2] = c2
    c[n, 3] = c3
    c[n, 4] = c4
    c[n, 5] = c5
    c[n, 6] = c6
