"""All roots of a Bernstein polynomial g on [0, 1], in increasing order, by Bézier clipping.

A root counts only where the sign class really changes (class: g >= 0); a touch (double root) does not.
The scratch stack holds intervals still to examine; the lower one is always taken first, so roots come
out sorted without a sort.
"""
import numpy as np
from numba import njit

from ..config import NJIT
from .bernstein import subdivide

#: an iteration that keeps more than this fraction of its interval is stalling (near a multiple root):
#: split the interval in half instead
STALL = 0.8
#: maximum pending intervals; past it an interval is finished as if it had converged
STACK_DEPTH = 64
#: most clipping steps per root search, a guard against pathological input
MAX_STEPS = 400


@njit(**NJIT)
def hull_crossing(c):
    """[smin, smax]: where the convex hull of the control points (i/n, c_i) meets g = 0 (smin > smax: nowhere).

    The hull's intersection with the axis is spanned by the crossings of the segments between points of
    opposite sign, plus the points on the axis: O(n^2) pairs, no hull construction needed.
    """
    n = c.shape[0] - 1
    smin = 2.0
    smax = -1.0
    for i in range(n + 1):
        ci = c[i]
        if ci == 0.0:
            x = i / n
            smin = min(smin, x)
            smax = max(smax, x)
            continue
        for j in range(i + 1, n + 1):
            cj = c[j]
            if (ci < 0.0 < cj) or (cj < 0.0 < ci):
                x = (i + (j - i) * ci / (ci - cj)) / n
                smin = min(smin, x)
                smax = max(smax, x)
    return max(smin, 0.0), min(smax, 1.0)


@njit(**NJIT)
def _no_crossing(c):
    """True when the convex hull says the class (g >= 0) is the same on the whole interval."""
    lo = c[0]
    hi = c[0]
    for i in range(1, c.shape[0]):
        lo = min(lo, c[i])
        hi = max(hi, c[i])
    return lo >= 0.0 or hi < 0.0


@njit(**NJIT)
def _max_abs(c):
    m = 0.0
    for i in range(c.shape[0]):
        m = max(m, abs(c[i]))
    return m


@njit(**NJIT)
def clip_roots(g, tol_s, eps_g, st_lo, st_hi, st_c, work, roots, rising):
    """Roots of g (Bernstein, on [0, 1]) where the class g >= 0 changes; returns their number.

    tol_s: width in s below which an interval is a root; eps_g: |g| below this is numerical noise.
    Writes roots[k] (sorted) and rising[k] (True where g goes from < 0 to >= 0). Two consecutive roots
    with |g| <= eps_g everywhere between them are one noisy touch (a double root) and both are dropped.
    Scratch: st_lo, st_hi (STACK_DEPTH,), st_c (STACK_DEPTH, n+1), work (2, n+1).
    """
    nc = g.shape[0]
    n_roots = 0
    if _no_crossing(g):
        return 0
    st_lo[0] = 0.0
    st_hi[0] = 1.0
    st_c[0, :] = g
    top = 1
    steps = 0
    while top > 0:
        top -= 1
        lo = st_lo[top]
        hi = st_hi[top]
        c = st_c[top]
        while True:
            steps += 1
            if _no_crossing(c):
                break
            smin, smax = hull_crossing(c)
            if smax < smin:
                break
            w = hi - lo
            if (smax - smin) * w <= tol_s or steps > MAX_STEPS:
                # converged: every root of this interval lies in [smin, smax], so the classes at its two
                # ends tell whether the class changes across it (odd multiplicity) or not (a touch)
                up = c[nc - 1] >= 0.0
                if (c[0] >= 0.0) != up:
                    r = lo + w * _polish(c, smin, smax, work[0])
                    if n_roots > 0 and rising[n_roots - 1] != up and _is_noise(g, roots[n_roots - 1], r, eps_g, work[0]):
                        n_roots -= 1  # two crossings within the noise of g: one touch, the pair cancels
                    elif n_roots < roots.shape[0]:
                        roots[n_roots] = r
                        rising[n_roots] = up
                        n_roots += 1
                break
            if smax - smin > STALL and top < STACK_DEPTH - 2:
                # stalled near a multiple root: split, push the upper half, go on with the lower half
                mid = 0.5 * (lo + hi)
                subdivide(c, 0.5, 1.0, work[0])
                subdivide(c, 0.0, 0.5, work[1])
                st_lo[top] = mid
                st_hi[top] = hi
                st_c[top, :] = work[0]
                top += 1
                c = st_c[top]
                c[:] = work[1]
                hi = mid
            else:
                subdivide(c, smin, smax, work[0])
                w = hi - lo
                lo, hi = lo + smin * w, lo + smax * w
                c[:] = work[0]
    return n_roots


@njit(**NJIT)
def _is_noise(g, r0, r1, eps_g, work):
    """True when g stays within eps_g of zero between r0 and r1 (so the two roots are one touch)."""
    if r1 <= r0:
        return True
    subdivide(g, r0, r1, work)
    return _max_abs(work) <= eps_g


@njit(**NJIT)
def _value_slope(c, x, work):
    """g(x) and g'(x) of a Bernstein curve: de Casteljau down to two points p0, p1."""
    n = c.shape[0] - 1
    for i in range(n + 1):
        work[i] = c[i]
    for r in range(1, n):
        for i in range(n + 1 - r):
            work[i] = (1.0 - x) * work[i] + x * work[i + 1]
    return (1.0 - x) * work[0] + x * work[1], n * (work[1] - work[0])


@njit(**NJIT)
def _polish(c, smin, smax, work):
    """Two Newton steps from the middle of [smin, smax], kept inside it (the root is known to be there)."""
    x = 0.5 * (smin + smax)
    for _ in range(2):
        v, dv = _value_slope(c, x, work)
        if dv == 0.0:
            break
        xn = x - v / dv
        if xn < smin or xn > smax:
            break
        x = xn
    return x
