"""All roots of a Bernstein polynomial g on [0, 1], in increasing order, by Bézier clipping.

A root counts only where the sign class really changes (class: g >= 0); a touch (double root) does not.
The scratch stack holds intervals still to examine; the lower one is always taken first, so roots come
out sorted without a sort.
"""
import numpy as np
from numba import njit

from ..config import NJIT, NJIT_INLINE
from .bernstein import _casteljau_rows, split, subdivide

#: an iteration that keeps more than this fraction of its interval is stalling (near a multiple root):
#: split the interval in half instead
STALL = 0.8
#: maximum pending intervals; past it an interval is finished as if it had converged
STACK_DEPTH = 64
#: most clipping steps per root search, a guard against pathological input
MAX_STEPS = 400


@njit(**NJIT_INLINE)
def _chain(c, upper, hull):
    """Lower (or upper) convex hull of the points (i, c_i), which come sorted in i: Andrew's monotone
    chain. Writes the vertices' indices into hull (as floats) and returns their number."""
    m = 0
    for i in range(c.shape[0]):
        while m >= 2:
            o = int(hull[m - 2])
            a = int(hull[m - 1])
            cross = (a - o) * (c[i] - c[o]) - (c[a] - c[o]) * (i - o)
            if (cross < 0.0) if upper else (cross > 0.0):
                break  # a proper turn: the middle vertex stays (collinear ones go)
            m -= 1
        hull[m] = i
        m += 1
    return m


@njit(**NJIT_INLINE)
def _first_crossing(c, hull, m, from_left):
    """Walk the chain from one end to its first vertex on the other side of 0 (or on it): the x (in index
    units) where that edge meets 0, or -1 if the chain stays on its side."""
    for k in range(m - 1):
        if from_left:
            a = int(hull[k])
            b = int(hull[k + 1])
        else:
            a = int(hull[m - 1 - k])
            b = int(hull[m - 2 - k])
        ca = c[a]
        cb = c[b]
        if cb == 0.0 or (ca > 0.0) != (cb > 0.0):
            return a + (b - a) * (ca / (ca - cb))
    return -1.0


@njit(**NJIT_INLINE)
def hull_crossing(c, hull):
    """[smin, smax]: where the convex hull of the control points (i/n, c_i) meets g = 0 (smin > smax:
    nowhere). The left end lies on the lower chain when c_0 > 0 and on the upper chain when c_0 < 0;
    likewise the right end with c_n. ``hull`` is scratch of length n + 1."""
    n = c.shape[0] - 1
    c0 = c[0]
    cn = c[n]
    smin = 0.0
    smax = 1.0
    if c0 != 0.0:
        m = _chain(c, c0 < 0.0, hull)
        x = _first_crossing(c, hull, m, True)
        if x < 0.0:
            return 2.0, -1.0
        smin = x / n
        if cn != 0.0 and (cn < 0.0) == (c0 < 0.0):
            x = _first_crossing(c, hull, m, False)
            smax = x / n
            return smin, smax
    if cn != 0.0:
        m = _chain(c, cn < 0.0, hull)
        x = _first_crossing(c, hull, m, False)
        if x < 0.0:
            return 2.0, -1.0
        smax = x / n
    return smin, smax


@njit(**NJIT_INLINE)
def _no_crossing(c):
    """True when the convex hull says the class (g >= 0) is the same on the whole interval."""
    lo = c[0]
    hi = c[0]
    for i in range(1, c.shape[0]):
        lo = min(lo, c[i])
        hi = max(hi, c[i])
    return lo >= 0.0 or hi < 0.0


@njit(**NJIT_INLINE)
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
            smin, smax = hull_crossing(c, work[1])
            if smax < smin:
                break
            w = hi - lo
            if (smax - smin) * w <= tol_s or steps > MAX_STEPS:
                # converged: every root of this interval lies in [smin, smax], so the classes at its two
                # ends tell whether the class changes across it (odd multiplicity) or not (a touch)
                up = c[nc - 1] >= 0.0
                if (c[0] >= 0.0) != up:
                    r = lo + w * _polish(c, smin, smax)
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
                split(c, 0.5, st_c[top + 1], st_c[top])
                st_lo[top] = mid
                st_hi[top] = hi
                top += 1
                c = st_c[top]
                hi = mid
            else:
                subdivide(c, smin, smax, c)  # safe in place: subdivide reads all of c first
                w = hi - lo
                lo, hi = lo + smin * w, lo + smax * w
    return n_roots


@njit(**NJIT)
def _is_noise(g, r0, r1, eps_g, work):
    """True when g stays within eps_g of zero between r0 and r1 (so the two roots are one touch)."""
    if r1 <= r0:
        return True
    subdivide(g, r0, r1, work)
    return _max_abs(work) <= eps_g


@njit(**NJIT_INLINE)
def _value_slope(c, x):
    """g(x) and g'(x) of a degree-6 curve from one de Casteljau triangle: the apex is the value, the
    second-to-last row's two points give the slope 6 (v1 - v0)."""
    left, right = _casteljau_rows(c[0], c[1], c[2], c[3], c[4], c[5], c[6], x)
    return left[6], 6.0 * (right[1] - left[5])


@njit(**NJIT_INLINE)
def _polish(c, smin, smax):
    """Two Newton steps from the middle of [smin, smax], kept inside it (the root is known to be there)."""
    x = 0.5 * (smin + smax)
    for _ in range(2):
        v, dv = _value_slope(c, x)
        if dv == 0.0:
            break
        xn = x - v / dv
        if xn < smin or xn > smax:
            break
        x = xn
    return x
