"""Laguerre's method, the paper's comparison for Bézier clipping (Nishita & Nakamae, Table 1).

A Bernstein polynomial on [0, 1] is converted to power form; ALL its complex roots are found by Laguerre's
method with deflation (Numerical Recipes' ``laguer``/``zroots``, with the break-limit-cycle fractional steps),
each root is then polished against the undeflated polynomial, and the real roots in [0, 1] are kept, sorted.
Everything is numba-compiled with the same flags style as the engine, so that the timing comparison with
``cloudmeta.kernels.clipping.clip_roots`` is fair. Scratch arrays are passed in (no allocation per call).
"""
import math

import numpy as np
from numba import njit

EPSS = 2.220446049250313e-16  # machine epsilon: the round-off limit of the evaluation of p(x)
MR = 8                        # fractional steps every MT iterations break rare limit cycles
MT = 10
MAXIT = MT * MR
FRAC = np.array([0.0, 0.5, 0.25, 0.75, 0.13, 0.38, 0.62, 0.88, 1.0])
#: the engine's compile flags (cloudmeta/kernels/config.py), so that both methods are compiled alike
NJIT = dict(cache=True, fastmath=False, nogil=True, error_model="numpy")
BINOM = np.array([[math.comb(n, k) if k <= n else 0 for k in range(16)] for n in range(16)], dtype=np.float64)


@njit(**NJIT)
def bernstein_to_power(c, out):
    """Power coefficients a_k of sum_i c_i C(n,i) s^i (1-s)^(n-i): a_k = sum_{i<=k} c_i C(n,i) C(n-i,k-i) (-1)^(k-i)."""
    n = c.shape[0] - 1
    for k in range(n + 1):
        out[k] = 0.0
    for i in range(n + 1):
        ci = c[i] * BINOM[n, i]
        if ci == 0.0:
            continue
        sign = 1.0
        for j in range(n - i + 1):
            out[i + j] += sign * ci * BINOM[n - i, j]
            sign = -sign


@njit(**NJIT)
def laguer(a, m, x, tol):
    """One root of the degree-m polynomial a[0..m] (complex, power form) from the start x.

    Stops at the round-off limit of p(x) (NR), when a step changes nothing, or when |step| <= tol.
    Returns (root, iterations).
    """
    for it in range(1, MAXIT + 1):
        b = a[m]
        err = abs(b)
        d = 0j
        f = 0j
        abx = abs(x)
        for j in range(m - 1, -1, -1):  # p, p' and p''/2 by Horner
            f = x * f + d
            d = x * d + b
            b = x * b + a[j]
            err = abs(b) + abx * err
        err *= EPSS
        if abs(b) <= err:
            return x, it
        g = d / b
        g2 = g * g
        h = g2 - 2.0 * f / b
        sq = np.sqrt((m - 1) * (m * h - g2))
        gp = g + sq
        gm = g - sq
        abp = abs(gp)
        abm = abs(gm)
        if abp < abm:
            gp = gm
        if max(abp, abm) > 0.0:
            dx = m / gp
        else:
            dx = (1.0 + abx) * complex(math.cos(it), math.sin(it))
        x1 = x - dx
        if x1 == x:
            return x, it
        if it % MT != 0:
            x = x1
        else:
            x = x - FRAC[it // MT] * dx
        if abs(dx) <= tol:
            return x, it
    return x, MAXIT


@njit(**NJIT)
def laguerre_roots(c, tol, apow, ad, aorig, zroots, out):
    """Real roots in [0, 1] of the Bernstein polynomial c, by Laguerre + deflation + polishing.

    Scratch: apow (n+1,) float; ad, aorig, zroots (n+1,) complex. Writes the sorted real roots in [0, 1]
    to out; returns (count, total Laguerre iterations, degree).
    """
    bernstein_to_power(c, apow)
    m = c.shape[0] - 1
    while m > 0 and apow[m] == 0.0:
        m -= 1
    for j in range(m + 1):
        ad[j] = apow[j]
        aorig[j] = apow[j]
    iters = 0
    for j in range(m, 0, -1):  # find a root of the deflated polynomial of degree j, then divide it out
        x, it = laguer(ad, j, 0j, tol)
        iters += it
        if abs(x.imag) <= 2.0 * EPSS * abs(x.real):
            x = complex(x.real, 0.0)
        zroots[j - 1] = x
        b = ad[j]
        for jj in range(j - 1, -1, -1):
            cc = ad[jj]
            ad[jj] = b
            b = x * b + cc
    n_out = 0
    imag_tol = max(tol, 1e-12)
    for j in range(m):  # polish against the undeflated polynomial, keep the real ones in [0, 1]
        x, it = laguer(aorig, m, zroots[j], tol)
        iters += it
        if abs(x.imag) <= imag_tol and -tol <= x.real <= 1.0 + tol:
            r = min(max(x.real, 0.0), 1.0)
            k = n_out  # insertion sort: at most 6 roots
            while k > 0 and out[k - 1] > r:
                out[k] = out[k - 1]
                k -= 1
            out[k] = r
            n_out += 1
    return n_out, iters, m


def scratch(n=6):
    return (np.empty(n + 1), np.empty(n + 1, np.complex128), np.empty(n + 1, np.complex128),
            np.empty(n + 1, np.complex128), np.empty(n + 1))
