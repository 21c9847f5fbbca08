"""All roots of a Bernstein polynomial g on [0, 1], in increasing order, by Bézier clipping.

A root counts only where the sign class really changes (class: g >= 0); a touch (double root) does not.
The scratch stack holds intervals still to examine; the lower one is always taken first, so roots come
out sorted without a sort.

Speed (a clipping step is a chain of dependent arithmetic, some 300 instructions; the loop is bound by its
latency):

- the curves are degree 6, and the loop keeps the current interval's 7 control values in scalar locals
  (registers) from step to step; arrays are touched only element by element, to push and pop the split
  stack and to write the roots. No array view is made and no function is called in ``clip_roots`` (every
  helper is inlined), so numba's reference-count pruning removes the atomic increment and decrement of
  each array argument (about 40 ns a call otherwise, more than a whole clipping step);
- the hull's crossing is found by gift wrapping from each end (``_walk``): one hop, usually, of six
  slopes, a minimum and one division, instead of building the hull;
- the subdivision to [smin, smax] forms the 7 blossoms f(s0, .., s1) in a pyramid 6 lerps deep rather than
  splitting twice (12 deep), each lerp a fused multiply-add (``_fma``);
- two intervals, where there are two (the two roots of a chord through a blob), are clipped side by side,
  so that the processor overlaps their two chains (see ``clip_roots``);
- the touch test's subdivision is skipped where |g| at the interval's start already exceeds the noise
  level, and Newton's second polishing step where it could not move the root.
"""
import numpy as np
from numba import njit

from .config import NJIT, NJIT_INLINE
from .bernstein import _casteljau_rows, _fma, store_curve

#: an iteration that keeps more than this fraction of its interval is stalling (near a multiple root):
#: split the interval in half instead
STALL = 0.8
#: maximum pending intervals; past it an interval is finished as if it had converged
STACK_DEPTH = 64
#: most clipping steps per root search, a guard against pathological input
MAX_STEPS = 400
#: the hull's crossing is widened by this much on both sides (in the interval's own parameter), so that
#: rounding in the crossing and in the subdivision cannot shave a root at the interval's end off
FAT = 1e-12

_SIXTH = 1.0 / 6.0
_INF = np.inf


# --- the steps of the loop, on the 7 control values as scalars -------------------------------------------

@njit(**NJIT_INLINE)
def _no_crossing7(c0, c1, c2, c3, c4, c5, c6):
    """True when the convex hull says the class (g >= 0) is the same on the whole interval."""
    lo = min(min(min(c0, c1), min(c2, c3)), min(min(c4, c5), c6))
    hi = max(max(max(c0, c1), max(c2, c3)), max(max(c4, c5), c6))
    return (lo >= 0.0) | (hi < 0.0)


@njit(**NJIT_INLINE)
def _walk(a0, a1, a2, a3, a4, a5, a6):
    """With a0 > 0: x (in s, the points being (i/6, a_i)) where their lower hull first meets 0, or -1 if
    it never does. Gift wrapping from point 0: the hull edge leaving a vertex goes to the point of least
    slope (the farthest, on a tie); if a point on or below 0 has that least slope, the edge reaches it and
    crosses 0 where its line does. Otherwise the walk hops to the edge's far end: the values are shifted so
    that the current vertex is a0 again (the emptied places get +inf, which no slope picks), so that the
    slopes always use the constant factors 6/j."""
    base = 0.0
    while True:
        s1 = (a1 - a0) * 6.0
        s2 = (a2 - a0) * 3.0
        s3 = (a3 - a0) * 2.0
        s4 = (a4 - a0) * 1.5
        s5 = (a5 - a0) * 1.2
        s6 = a6 - a0
        m = min(min(min(s1, s2), min(s3, s4)), min(s5, s6))
        if not m < 0.0:
            return -1.0  # every point left is at or above a0 > 0
        if (((s1 == m) & (a1 <= 0.0)) | ((s2 == m) & (a2 <= 0.0)) | ((s3 == m) & (a3 <= 0.0))
                | ((s4 == m) & (a4 <= 0.0)) | ((s5 == m) & (a5 <= 0.0)) | ((s6 == m) & (a6 <= 0.0))):
            return base + a0 / -m  # the edge to a point on or below 0: its line's zero
        # the edge ends above 0: hop to its far end (the farthest point on the line) and go on from there
        k = 6 if s6 == m else 5 if s5 == m else 4 if s4 == m else 3 if s3 == m else 2 if s2 == m else 1
        base += k * _SIXTH
        for _ in range(k):
            a0, a1, a2, a3, a4, a5, a6 = a1, a2, a3, a4, a5, a6, _INF


@njit(**NJIT_INLINE)
def _walk_from(c0, c1, c2, c3, c4, c5, c6):
    """``_walk`` on c_0's side: the curve as it is when c_0 > 0, negated when c_0 < 0."""
    if c0 > 0.0:
        return _walk(c0, c1, c2, c3, c4, c5, c6)
    return _walk(-c0, -c1, -c2, -c3, -c4, -c5, -c6)


@njit(**NJIT_INLINE)
def _hull7(c0, c1, c2, c3, c4, c5, c6):
    """[smin, smax] of a degree-6 curve (see ``hull_crossing``); smin > smax: nowhere. The left end is the
    first crossing of the hull's chain on c_0's side walked from the left (the lower chain when c_0 > 0,
    the upper one when c_0 < 0), the right end likewise from the right on c_6's side."""
    smin = 0.0
    smax = 1.0
    if c0 != 0.0:
        x = _walk_from(c0, c1, c2, c3, c4, c5, c6)
        if x < 0.0:
            return 2.0, -1.0
        smin = x
    if c6 != 0.0:
        x = _walk_from(c6, c5, c4, c3, c2, c1, c0)
        if x < 0.0:
            return 2.0, -1.0
        smax = 1.0 - x
    return smin, smax


@njit(**NJIT_INLINE)
def _subdivide7(c0, c1, c2, c3, c4, c5, c6, s0, s1):
    """Control values on [s0, s1] (0 <= s0 < s1 <= 1) of a degree-6 curve, reparametrised to [0, 1].

    The k-th is the blossom f(s0, .., s0, s1, .., s1) with k arguments s1: a lerp at s0 or at s1 of
    adjacent values applies one more argument, and the order does not matter. Applying s1 first where
    that lets two answers share a path, the 7 answers take 58 lerps (a + t (b - a), one fused multiply-add
    each; t in [0, 1] as in de Casteljau's algorithm) only 6 deep, where split-then-split takes 42 lerps
    12 deep: the depth is on the clipping loop's critical path."""
    # level 1: arguments (s0) and (s1)
    a0 = _fma(s0, c1 - c0, c0)
    a1 = _fma(s0, c2 - c1, c1)
    a2 = _fma(s0, c3 - c2, c2)
    a3 = _fma(s0, c4 - c3, c3)
    a4 = _fma(s0, c5 - c4, c4)
    a5 = _fma(s0, c6 - c5, c5)
    b0 = _fma(s1, c1 - c0, c0)
    b1 = _fma(s1, c2 - c1, c1)
    b2 = _fma(s1, c3 - c2, c2)
    b3 = _fma(s1, c4 - c3, c3)
    b4 = _fma(s1, c5 - c4, c4)
    b5 = _fma(s1, c6 - c5, c5)
    # level 2: (s0 s0), (s1 s1)
    c_0 = _fma(s0, a1 - a0, a0)
    c_1 = _fma(s0, a2 - a1, a1)
    c_2 = _fma(s0, a3 - a2, a2)
    c_3 = _fma(s0, a4 - a3, a3)
    c_4 = _fma(s0, a5 - a4, a4)
    d0 = _fma(s1, b1 - b0, b0)
    d1 = _fma(s1, b2 - b1, b1)
    d2 = _fma(s1, b3 - b2, b2)
    d3 = _fma(s1, b4 - b3, b3)
    d4 = _fma(s1, b5 - b4, b4)
    # level 3: (s0 s0 s0), (s1 s1 s0), (s1 s1 s1)
    e0 = _fma(s0, c_1 - c_0, c_0)
    e1 = _fma(s0, c_2 - c_1, c_1)
    e2 = _fma(s0, c_3 - c_2, c_2)
    e3 = _fma(s0, c_4 - c_3, c_3)
    f0 = _fma(s0, d1 - d0, d0)
    f1 = _fma(s0, d2 - d1, d1)
    f2 = _fma(s0, d3 - d2, d2)
    f3 = _fma(s0, d4 - d3, d3)
    g0 = _fma(s1, d1 - d0, d0)
    g1 = _fma(s1, d2 - d1, d1)
    g2 = _fma(s1, d3 - d2, d2)
    g3 = _fma(s1, d4 - d3, d3)
    # level 4: (s0 x4), (s1 s1 s0 s0), (s1 x4)
    h0 = _fma(s0, e1 - e0, e0)
    h1 = _fma(s0, e2 - e1, e1)
    h2 = _fma(s0, e3 - e2, e2)
    i0 = _fma(s0, f1 - f0, f0)
    i1 = _fma(s0, f2 - f1, f1)
    i2 = _fma(s0, f3 - f2, f2)
    j0 = _fma(s1, g1 - g0, g0)
    j1 = _fma(s1, g2 - g1, g1)
    j2 = _fma(s1, g3 - g2, g2)
    # level 5: (s0 x5), (s1 s1 s0 s0 s0), (s1 x4 s0), (s1 x5)
    k0 = _fma(s0, h1 - h0, h0)
    k1 = _fma(s0, h2 - h1, h1)
    l0 = _fma(s0, i1 - i0, i0)
    l1 = _fma(s0, i2 - i1, i1)
    m0 = _fma(s0, j1 - j0, j0)
    m1 = _fma(s0, j2 - j1, j1)
    n0 = _fma(s1, j1 - j0, j0)
    n1 = _fma(s1, j2 - j1, j1)
    # level 6: the answers, with 0..6 arguments s1
    return (_fma(s0, k1 - k0, k0), _fma(s1, k1 - k0, k0), _fma(s0, l1 - l0, l0), _fma(s1, l1 - l0, l0),
            _fma(s0, m1 - m0, m0), _fma(s1, m1 - m0, m0), _fma(s1, n1 - n0, n0))


@njit(**NJIT_INLINE)
def _polish7(c0, c1, c2, c3, c4, c5, c6, smin, smax):
    """Newton steps from the middle of [smin, smax], kept inside it (the root is known to be there): two,
    or one where the second could not move x any more. Value and slope come from one de Casteljau
    triangle: the apex, and 6 (v1 - v0) from the second-to-last row."""
    # |g''| / 2 <= 15 max |second difference| on [0, 1]: Newton's next step is at most that / |g'| times
    # the square of this one
    d2 = max(max(max(abs(c2 - 2.0 * c1 + c0), abs(c3 - 2.0 * c2 + c1)), max(abs(c4 - 2.0 * c3 + c2),
                                                                           abs(c5 - 2.0 * c4 + c3))),
             abs(c6 - 2.0 * c5 + c4))
    x = 0.5 * (smin + smax)
    for _ in range(2):
        (_, _, _, _, _, l5, v), (_, r1, _, _, _, _, _) = _casteljau_rows(c0, c1, c2, c3, c4, c5, c6, x)
        dv = 6.0 * (r1 - l5)  # B'(x) = 6 (the right edge's second - the left edge's sixth value)
        if dv == 0.0:
            break
        step = v / dv
        xn = x - step
        if xn < smin or xn > smax:
            break
        x = xn
        if 15.0 * d2 * (step * step) <= 1e-16 * abs(dv):
            break  # the next step would be below the rounding of x
    return x


@njit(**NJIT_INLINE)
def _is_noise7(g, r0, r1, eps_g, lo, g_lo):
    """True when g (7 control values) stays within eps_g of zero between r0 and r1 (so the two roots are
    one touch). lo lies in [r0, r1] when r0 <= lo, and g_lo = g(lo): a quick no."""
    if r1 <= r0:
        return True
    if r0 <= lo and abs(g_lo) > eps_g:
        return False
    c0, c1, c2, c3, c4, c5, c6 = _subdivide7(g[0], g[1], g[2], g[3], g[4], g[5], g[6], r0, r1)
    m = max(max(max(abs(c0), abs(c1)), max(abs(c2), abs(c3))), max(max(abs(c4), abs(c5)), abs(c6)))
    return m <= eps_g


# --- the root finder ---------------------------------------------------------------------------------------

_NONE = 0  # no root in the interval: the sign test rejects it
_ROOT = 1  # converged: [smin, smax] is below the tolerance
_SPLIT = 2  # stalled: split the interval in half
_CLIP = 3  # clip the interval to [smin, smax]

_EMPTY = 0  # lane B holds nothing
_RUN = 1  # lane B is clipping its interval
_WAIT = 2  # lane B's interval wants a split: left as it is, for lane A to take over
_FINISHED = 3  # lane B's interval is done; its root, if any, waits until everything below it is done


@njit(**NJIT_INLINE)
def _plan(c, w, tol_s, steps, can_split):
    """What one clipping step does to an interval of width w with control values c = (c0, .., c6), a tuple
    of scalars: (kind, smin, smax), kind one of _NONE, _ROOT, _SPLIT, _CLIP; [smin, smax] is the hull's
    crossing, widened by FAT ((0, 1) for _NONE)."""
    c0, c1, c2, c3, c4, c5, c6 = c
    if _no_crossing7(c0, c1, c2, c3, c4, c5, c6):
        return _NONE, 0.0, 1.0
    smin, smax = _hull7(c0, c1, c2, c3, c4, c5, c6)
    if smax < smin:
        # the sign test saw both classes, so the hull does meet 0: only rounding can make it miss, where the
        # control polygon runs (nearly) straight through one point on the axis
        if smin <= 1.0 and smax >= 0.0:
            smin, smax = smax, smin
        else:
            smin, smax = 0.0, 1.0  # a walk found no crossing at all: keep the whole interval
    smin = max(smin - FAT, 0.0)
    smax = min(smax + FAT, 1.0)
    if (smax - smin) * w <= tol_s or steps > MAX_STEPS:
        return _ROOT, smin, smax
    if smax - smin > STALL and can_split:
        return _SPLIT, smin, smax
    return _CLIP, smin, smax


@njit(**NJIT)
def clip_roots(g, tol_s, eps_g, st_lo, st_hi, st_c, roots, rising):
    """Roots of g (Bernstein, degree 6, on [0, 1]) where the class g >= 0 changes; returns their number.

    tol_s: width in s below which an interval is a root; eps_g: |g| below this is numerical noise.
    Writes roots[k] (sorted) and rising[k] (True where g goes from < 0 to >= 0). Two consecutive roots
    with |g| <= eps_g everywhere between them are one noisy touch (a double root) and both are dropped.
    Scratch: st_lo, st_hi (STACK_DEPTH,), st_c (STACK_DEPTH, 7).

    The intervals and their steps are those of depth-first clipping (a converged interval is a root when
    the class differs at its ends; a stalled one is split, its upper half pushed on the stack), but two
    intervals are clipped side by side where there are two: lane A works through them in order, lane B
    takes the next pending one, and while both are clipping, their two steps run in one loop iteration
    (the two hulls, then the two subdivisions), so that the processor overlaps two chains of dependent
    arithmetic. Lane B never splits (it waits for lane A to take its interval over) and holds its root
    back until lane A has finished everything below it, so the roots come out in order.
    """
    a0, a1, a2, a3, a4, a5, a6 = g[0], g[1], g[2], g[3], g[4], g[5], g[6]
    if _no_crossing7(a0, a1, a2, a3, a4, a5, a6):
        return 0
    n_roots = 0
    top = 0  # pending intervals on the stack
    a_lo = 0.0
    a_hi = 1.0
    b_mode = _EMPTY
    b_base = 0  # stack size when lane B took its interval: entries above it lie below lane B's interval
    b_lo = b_hi = b_r = 0.0
    b0 = b1 = b2 = b3 = b4 = b5 = b6 = 0.0
    b_root = False
    b_up = False
    steps = 0
    while True:
        if b_mode == _EMPTY and top > 0:
            top -= 1
            b_base = top
            b_lo = st_lo[top]
            b_hi = st_hi[top]
            b0, b1, b2, b3, b4, b5, b6 = (st_c[top, 0], st_c[top, 1], st_c[top, 2], st_c[top, 3],
                                          st_c[top, 4], st_c[top, 5], st_c[top, 6])
            b_mode = _RUN
        # one step of lane A and, when it is clipping, one of lane B: first both hulls, then both subdivisions
        a_w = a_hi - a_lo
        steps += 1
        ka, sa0, sa1 = _plan((a0, a1, a2, a3, a4, a5, a6), a_w, tol_s, steps, top < STACK_DEPTH - 2)
        b_run = b_mode == _RUN
        kb = _NONE
        sb0 = 0.0
        sb1 = 1.0
        b_w = b_hi - b_lo
        if b_run:
            steps += 1
            kb, sb0, sb1 = _plan((b0, b1, b2, b3, b4, b5, b6), b_w, tol_s, steps, True)
        if ka == _CLIP:
            a0, a1, a2, a3, a4, a5, a6 = _subdivide7(a0, a1, a2, a3, a4, a5, a6, sa0, sa1)
            a_lo, a_hi = a_lo + sa0 * a_w, a_lo + sa1 * a_w
        if b_run:
            if kb == _CLIP:
                b0, b1, b2, b3, b4, b5, b6 = _subdivide7(b0, b1, b2, b3, b4, b5, b6, sb0, sb1)
                b_lo, b_hi = b_lo + sb0 * b_w, b_lo + sb1 * b_w
            elif kb == _SPLIT:
                b_mode = _WAIT  # lane A will take the interval over as it is, and redo this step
                steps -= 1
            else:
                b_mode = _FINISHED
                b_up = b6 >= 0.0
                b_root = kb == _ROOT and (b0 >= 0.0) != b_up
                if b_root:
                    b_r = b_lo + b_w * _polish7(b0, b1, b2, b3, b4, b5, b6, sb0, sb1)

        if ka == _CLIP:
            continue
        if ka == _SPLIT:
            # stalled near a multiple root: split, push the upper half, go on with the lower half
            (a0, a1, a2, a3, a4, a5, a6), (d0, d1, d2, d3, d4, d5, d6) = _casteljau_rows(
                a0, a1, a2, a3, a4, a5, a6, 0.5)
            mid = 0.5 * (a_lo + a_hi)
            store_curve(st_lo, st_hi, st_c, top, mid, a_hi, d0, d1, d2, d3, d4, d5, d6)
            top += 1
            a_hi = mid
            continue
        if ka == _ROOT:
            # converged: every root of the interval lies in [smin, smax], so the classes at its two ends tell
            # whether the class changes across it (odd multiplicity) or not (a touch)
            up = a6 >= 0.0
            if (a0 >= 0.0) != up:
                r = a_lo + a_w * _polish7(a0, a1, a2, a3, a4, a5, a6, sa0, sa1)
                if n_roots > 0 and rising[n_roots - 1] != up and _is_noise7(
                        g, roots[n_roots - 1], r, eps_g, a_lo, a0):
                    n_roots -= 1  # two crossings within the noise of g: one touch, the pair cancels
                elif n_roots < roots.shape[0]:
                    roots[n_roots] = r
                    rising[n_roots] = up
                    n_roots += 1

        # lane A is done with its interval: on to the next one in order
        while True:
            if top > (0 if b_mode == _EMPTY else b_base):
                top -= 1  # an interval below lane B's
                a_lo = st_lo[top]
                a_hi = st_hi[top]
                a0, a1, a2, a3, a4, a5, a6 = (st_c[top, 0], st_c[top, 1], st_c[top, 2], st_c[top, 3],
                                              st_c[top, 4], st_c[top, 5], st_c[top, 6])
                break
            if b_mode == _EMPTY:
                return n_roots
            if b_mode == _FINISHED:
                # everything below lane B's interval is done: its root comes next
                if b_root:
                    if n_roots > 0 and rising[n_roots - 1] != b_up and _is_noise7(
                            g, roots[n_roots - 1], b_r, eps_g, b_lo, b0):
                        n_roots -= 1
                    elif n_roots < roots.shape[0]:
                        roots[n_roots] = b_r
                        rising[n_roots] = b_up
                        n_roots += 1
                b_mode = _EMPTY
                continue
            # lane B is clipping or waiting: lane A takes its interval over
            a_lo, a_hi, a0, a1, a2, a3, a4, a5, a6 = b_lo, b_hi, b0, b1, b2, b3, b4, b5, b6
            b_mode = _EMPTY
            break


# --- the same steps on arrays (tests, the benchmark's step mirror) -----------------------------------------

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
    likewise the right end with c_n. ``hull`` is scratch of length n + 1 (unused for degree 6, which takes
    the scalar gift wrapping of ``clip_roots``; other degrees use Andrew's monotone chain)."""
    n = c.shape[0] - 1
    if n == 6:
        return _hull7(c[0], c[1], c[2], c[3], c[4], c[5], c[6])
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
        if cn != 0.0 and (cn < 0.0) == (c0 < 0.0):  # the same chain serves the right end
            return smin, _first_crossing(c, hull, m, False) / n
    if cn != 0.0:
        x = _first_crossing(c, hull, _chain(c, cn < 0.0, hull), False)
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
