"""Bernstein polynomials on [0, 1], kept in local form (never a global power basis).

Every curve in the engine has DEGREE 6 (NCOEF = 7 control values); lower-degree kernels are elevated.
"""
import numpy as np
from numba import njit

from ..config import NJIT

DEGREE = 6
NCOEF = DEGREE + 1


@njit(**NJIT)
def bernstein_eval(c, s):
    """B(s) by de Casteljau's algorithm (stable: only convex combinations for s in [0, 1])."""
    n = c.shape[0]
    w = np.empty(n)  # tiny, used only outside hot loops; hot loops use subdivide into scratch
    for i in range(n):
        w[i] = c[i]
    for r in range(1, n):
        for i in range(n - r):
            w[i] = (1.0 - s) * w[i] + s * w[i + 1]
    return w[0]


@njit(**NJIT)
def subdivide(c, s0, s1, out):
    """Control values of the same curve on [s0, s1] (0 <= s0 < s1 <= 1), reparametrised to [0, 1].

    Two de Casteljau splits: keep [0, s1], then the part of that from s0 / s1 on.
    """
    n = c.shape[0]
    for i in range(n):
        out[i] = c[i]
    if s1 < 1.0:
        # left part of a split at s1: out[i] becomes the first point of the i-th de Casteljau row
        for r in range(1, n):
            for i in range(n - 1, r - 1, -1):
                out[i] = (1.0 - s1) * out[i - 1] + s1 * out[i]
    if s0 > 0.0:
        u = s0 / s1
        # right part of a split at u: out[i] becomes the last point of the row
        for r in range(1, n):
            for i in range(n - r):
                out[i] = (1.0 - u) * out[i] + u * out[i + 1]


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


@njit(**NJIT)
def bernstein_cumulative(c, s, work):
    """Integral over [0, s]: the antiderivative is a degree n+1 curve with control values
    e_k = sum_{j<k} c_j / (n+1); evaluated by de Casteljau in ``work`` (length n+2)."""
    n1 = c.shape[0]
    acc = 0.0
    work[0] = 0.0
    for k in range(1, n1 + 1):
        acc += c[k - 1]
        work[k] = acc / n1
    for r in range(1, n1 + 1):
        for i in range(n1 + 1 - r):
            work[i] = (1.0 - s) * work[i] + s * work[i + 1]
    return work[0]


@njit(**NJIT)
def elevate(c, out):
    """Degree elevation by one: out (len n+2) is the same curve as c (len n+1)."""
    n = c.shape[0] - 1
    out[0] = c[0]
    out[n + 1] = c[n]
    for i in range(1, n + 1):
        a = i / (n + 1.0)
        out[i] = a * c[i - 1] + (1.0 - a) * c[i]
