"""One ray through one blob: chords -> composite intervals -> roots and inside pieces -> optical depth.

The ray's field is piecewise: between consecutive chord ends the set of balls on the ray is fixed, and
the field there is one degree-6 Bernstein polynomial, the sum of each ball's curve cut to the interval
(docs/model.md §2). Inside pieces are the parts of those intervals where F >= T, each carrying F's control
values on itself, so every later integral is exact.

Scratch arrays come from ``alloc_scratch`` and are reused ray after ray; ``capacity`` is the most chords
one ray may meet before the caller must allocate a larger scratch.
"""
import numpy as np
from numba import njit

from .config import NJIT, NJIT_INLINE
from .bernstein import NCOEF, _casteljau_rows, store_curve, subdivide
from .density import density_mean
from .clipping import STACK_DEPTH, clip_roots
from .records import SweepScratch
from .metaball import chord, chord_pieces, control_values, is_piecewise

#: inside pieces per composite interval at most: a degree-6 curve changes class at most 6 times
PIECES_PER_INTERVAL = 4
#: transitions per composite interval at most: 6 crossings plus one at its start
ROOTS_PER_INTERVAL = 8
#: |g| below NOISE * (T + sum of |control values|) is rounding noise (a touch, not a segment)
NOISE = 64.0 * 2.220446049250313e-16



@njit(**NJIT)
def alloc_scratch(capacity):
    """Per-thread work arrays for rays that meet at most ``capacity`` chords."""
    p = max(capacity, 1)
    n_pieces = PIECES_PER_INTERVAL * 2 * p
    return SweepScratch(
        chord_t0=np.empty(p), chord_t1=np.empty(p), chord_c=np.empty((p, NCOEF)),
        bp=np.empty(2 * p), order=np.empty(p, np.int64), act=np.empty(p, np.int64),
        iv_t0=np.empty(2 * p), iv_t1=np.empty(2 * p), iv_c=np.empty((2 * p, NCOEF)), iv_mag=np.empty(2 * p),
        out_t0=np.empty(n_pieces), out_t1=np.empty(n_pieces), out_c=np.empty((n_pieces, NCOEF)),
        roots=np.empty(ROOTS_PER_INTERVAL * 2 * p),
        st_lo=np.empty(STACK_DEPTH), st_hi=np.empty(STACK_DEPTH), st_c=np.empty((STACK_DEPTH, NCOEF)),
        g=np.empty(NCOEF), loc=np.empty(16), rising=np.empty(16, np.bool_))


@njit(**NJIT)
def capacity_of(scratch):
    return scratch.chord_t0.shape[0]


#: below this many items an insertion sort beats the heap sort
SMALL_SORT = 24


@njit(**NJIT)
def heap_argsort(keys, idx, n):
    """Sort idx[:n] (a permutation of 0..n-1, filled here) by keys, in place, without allocating."""
    if n <= SMALL_SORT:
        insertion_argsort(keys, idx, n)
        return
    for i in range(n):
        idx[i] = i
    for start in range(n // 2 - 1, -1, -1):
        _sift(keys, idx, start, n)
    for end in range(n - 1, 0, -1):
        idx[0], idx[end] = idx[end], idx[0]
        _sift(keys, idx, np.int64(0), end)  # np.int64: one signature, not one for Literal[int](0)


@njit(**NJIT_INLINE)
def insertion_sort(a, n):
    """Sort a[:n] in place (stable, without allocating): for few items."""
    for i in range(1, n):
        v = a[i]
        j = i - 1
        while j >= 0 and a[j] > v:
            a[j + 1] = a[j]
            j -= 1
        a[j + 1] = v


@njit(**NJIT_INLINE)
def insertion_argsort(keys, idx, n):
    """idx[:n] = the indices 0..n-1 ordered by keys (stable), without allocating: for few items, or items
    mostly in order already."""
    for i in range(n):
        idx[i] = i
    for i in range(1, n):
        v = idx[i]
        j = i - 1
        while j >= 0 and keys[idx[j]] > keys[v]:
            idx[j + 1] = idx[j]
            j -= 1
        idx[j + 1] = v


@njit(**NJIT)
def _sift(keys, idx, root, n):
    while True:
        child = 2 * root + 1
        if child >= n:
            return
        if child + 1 < n and keys[idx[child + 1]] > keys[idx[child]]:
            child += 1
        if keys[idx[root]] >= keys[idx[child]]:
            return
        idx[root], idx[child] = idx[child], idx[root]
        root = child


@njit(**NJIT)
def heap_sort(a, n):
    """Sort a[:n] in place."""
    if n <= SMALL_SORT:
        insertion_sort(a, n)
        return
    for start in range(n // 2 - 1, -1, -1):
        _sift_values(a, start, n)
    for end in range(n - 1, 0, -1):
        a[0], a[end] = a[end], a[0]
        _sift_values(a, np.int64(0), end)


@njit(**NJIT)
def _sift_values(a, root, n):
    while True:
        child = 2 * root + 1
        if child >= n:
            return
        if child + 1 < n and a[child + 1] > a[child]:
            child += 1
        if a[root] >= a[child]:
            return
        a[root], a[child] = a[child], a[root]
        root = child


@njit(**NJIT)
def gather_chords(o, d, tmin, tmax, blob, cand, n_cand, scratch):
    """Chords of the candidate balls (cand[:n_cand]) of ``blob`` (a records.BlobRecord) that overlap
    [tmin, tmax], with their control values.

    wyvill6 and murakami4 give one exact curve per chord; nishimura and blinn (``blobbiness`` b) give
    several pieces per chord, each a degree-6 curve within 1e-12 |q| of the kernel (metaball.chord_pieces,
    inlined). A call left in this function (one that takes the arrays, or any non-inlined jitted one) would
    make numba count references to all of its arrays on every call, which costs the polynomial kernels
    about 5% per ray.
    Returns how many curves there are; only the first ``capacity`` are written, so a larger count tells
    the caller to grow the scratch and call again.
    """
    p_t0, p_t1, p_c = scratch.chord_t0, scratch.chord_t1, scratch.chord_c
    centers, frames, weights = blob.centers, blob.frames, blob.weights
    kernel, blobbiness = blob.kernel, blob.blobbiness
    cap = p_t0.shape[0]
    piecewise = is_piecewise(kernel)
    n = 0
    for k in range(n_cand):
        i = cand[k]
        t0, t1, a = chord(o, d, centers[i], frames[i])
        if a <= 0.0 or t1 <= tmin or t0 >= tmax or weights[i] == 0.0:
            continue
        if not piecewise:
            if n < cap:
                p_t0[n] = t0
                p_t1[n] = t1
                control_values(kernel, min(a, 1.0), weights[i], p_c[n])
            n += 1
            continue
        n = chord_pieces(kernel, min(a, 1.0), blobbiness, weights[i], t0, t1, tmin, tmax, p_t0, p_t1, p_c, n)
    return n


@njit(**NJIT_INLINE)
def gather_all_chords(o, d, tmin, tmax, blob, cand, n_cand, scratch):
    """``gather_chords`` into a scratch large enough for all of them (a new one, twice the count, when the
    ray meets more chords than this one holds). Returns (scratch, the number of curves)."""
    n_p = gather_chords(o, d, tmin, tmax, blob, cand, n_cand, scratch)
    if n_p > capacity_of(scratch):
        scratch = alloc_scratch(2 * n_p)
        gather_chords(o, d, tmin, tmax, blob, cand, n_cand, scratch)
    return scratch, n_p


@njit(**NJIT_INLINE)
def sort_breakpoints(p_t0, p_t1, n, bp, order):
    """bp[:2n]: every piece's two ends, sorted; order[:n]: the pieces by start."""
    for k in range(n):
        bp[2 * k] = p_t0[k]
        bp[2 * k + 1] = p_t1[k]
    heap_sort(bp, 2 * n)
    heap_argsort(p_t0, order, n)


@njit(**NJIT_INLINE)
def advance_active(ta, p_t0, p_t1, order, act, n_act, i_s, n):
    """Sweep step at breakpoint ta: pieces that ended drop out of act, pieces that start join (no piece
    end lies inside (ta, next breakpoint)). i_s: how many pieces, by start, have joined so far.
    Returns (n_act, i_s)."""
    j = 0
    for m in range(n_act):
        if p_t1[act[m]] > ta:
            act[j] = act[m]
            j += 1
    n_act = j
    while i_s < n and p_t0[order[i_s]] <= ta:
        act[n_act] = order[i_s]
        n_act += 1
        i_s += 1
    return n_act, i_s


@njit(**NJIT_INLINE)
def add_active(lo, hi, act, n_act, p_t0, p_t1, p_c):
    """F's control values on [lo, hi] (and their summed magnitude): the active chords' curves cut to
    [lo, hi] and added in the order of act. Each chord keeps the rest of its curve, [hi, t1], in place of
    its control values (p_t0 becomes hi). Scalars and 2-D indexing only: array views here cost more than
    the arithmetic. (composite and sweep_first_inside share it, so both add the same numbers.)"""
    a0 = a1 = a2 = a3 = a4 = a5 = a6 = 0.0
    mag = 0.0
    for m in range(n_act):
        i = act[m]
        r0, r1, r2, r3, r4, r5, r6 = p_c[i, 0], p_c[i, 1], p_c[i, 2], p_c[i, 3], p_c[i, 4], p_c[i, 5], p_c[i, 6]
        if lo > p_t0[i]:  # the ray starts inside this chord (tmin): drop what lies before
            _, (r0, r1, r2, r3, r4, r5, r6) = _casteljau_rows(r0, r1, r2, r3, r4, r5, r6,
                                                              (lo - p_t0[i]) / (p_t1[i] - p_t0[i]))
            p_t0[i] = lo
        if hi < p_t1[i]:
            (b0, b1, b2, b3, b4, b5, b6), (r0, r1, r2, r3, r4, r5, r6) = _casteljau_rows(
                r0, r1, r2, r3, r4, r5, r6, (hi - lo) / (p_t1[i] - lo))
            store_curve(p_t0, p_t1, p_c, i, hi, p_t1[i], r0, r1, r2, r3, r4, r5, r6)
        else:
            b0, b1, b2, b3, b4, b5, b6 = r0, r1, r2, r3, r4, r5, r6
        a0 += b0
        a1 += b1
        a2 += b2
        a3 += b3
        a4 += b4
        a5 += b5
        a6 += b6
        mag += abs(b0) + abs(b1) + abs(b2) + abs(b3) + abs(b4) + abs(b5) + abs(b6)
    return a0, a1, a2, a3, a4, a5, a6, mag


@njit(**NJIT)
def composite(n_p, tmin, tmax, scratch):
    """Cut every chord's curve to the intervals between consecutive chord ends and add them up.

    Writes the intervals (clipped to [tmin, tmax]) with F's control values and the mean magnitude of
    the added control values (the scale of F's rounding error); returns their number. Each active
    chord keeps the rest of its curve, [ta, t1], in place of its control values (p_t0 becomes ta), so
    one de Casteljau split per chord and interval gives both the part on the interval and the rest.
    """
    p_t0, p_t1, p_c = scratch.chord_t0, scratch.chord_t1, scratch.chord_c
    bp, order, act = scratch.bp, scratch.order, scratch.act
    iv_t0, iv_t1, iv_c, iv_mag = scratch.iv_t0, scratch.iv_t1, scratch.iv_c, scratch.iv_mag
    sort_breakpoints(p_t0, p_t1, n_p, bp, order)
    n_act = 0
    i_s = 0
    n_iv = 0
    for k in range(2 * n_p - 1):
        ta = bp[k]
        tb = bp[k + 1]
        if ta >= tmax:
            break
        if tb <= ta:
            continue
        n_act, i_s = advance_active(ta, p_t0, p_t1, order, act, n_act, i_s, n_p)
        lo = max(ta, tmin)
        hi = min(tb, tmax)
        if n_act == 0 or hi <= lo:
            continue
        a0, a1, a2, a3, a4, a5, a6, mag = add_active(lo, hi, act, n_act, p_t0, p_t1, p_c)
        store_curve(iv_t0, iv_t1, iv_c, n_iv, lo, hi, a0, a1, a2, a3, a4, a5, a6)
        iv_mag[n_iv] = mag / NCOEF
        n_iv += 1
    return n_iv


@njit(**NJIT)
def inside_pieces(n_iv, threshold, tmin, tmax, tol_t, first_only, scratch):
    """Split the composite intervals at the roots of F - T: returns (pieces, transitions).

    Writes the inside pieces (t0, t1, F's control values on the piece) and the transitions: the t where
    the class F >= T changes, in order. A transition at a composite boundary (the class differs across
    it, as at a gap after a discontinuous kernel) counts too; the ray's start tmin never does.
    With first_only (opaque surfaces) the sweep stops where the ray is first inside: one transition,
    that t (tmin itself when the ray starts inside), and no pieces.
    """
    iv_t0, iv_t1, iv_c, iv_mag = scratch.iv_t0, scratch.iv_t1, scratch.iv_c, scratch.iv_mag
    o_t0, o_t1, o_c, roots = scratch.out_t0, scratch.out_t1, scratch.out_c, scratch.roots
    st_lo, st_hi, st_c, g = scratch.st_lo, scratch.st_hi, scratch.st_c, scratch.g
    loc, rising = scratch.loc, scratch.rising
    n_out = np.int64(0)  # not the literal 0: _emit would compile once more for Literal[int](0)
    n_roots = 0
    inside = False
    t_prev = tmin  # where the last interval ended; F = 0 < T in gaps
    for k in range(n_iv):
        ta = iv_t0[k]
        tb = iv_t1[k]
        if ta > t_prev and inside:
            roots[n_roots] = t_prev
            n_roots += 1
            inside = False
        for q in range(NCOEF):
            g[q] = iv_c[k, q] - threshold
        start_in = g[0] >= 0.0
        if start_in != inside:
            if ta > tmin or first_only:  # first_only is never inside here: this is an entry
                roots[n_roots] = ta
                n_roots += 1
                if first_only:
                    return n_out, n_roots
            inside = start_in
        w = tb - ta
        eps_g = NOISE * (threshold + iv_mag[k] * NCOEF)
        m = clip_roots(g, tol_t / w, eps_g, st_lo, st_hi, st_c, loc, rising)
        s_in = 0.0
        for j in range(m):
            if rising[j] == inside:
                continue  # inconsistent with the class we are in: rounding; keep the class we have
            roots[n_roots] = ta + loc[j] * w
            n_roots += 1
            if inside:
                _emit(iv_c[k], ta, tb, s_in, loc[j], o_t0, o_t1, o_c, n_out)
                n_out += 1
            else:
                s_in = loc[j]
            inside = rising[j]
            if first_only:
                return n_out, n_roots
        if inside:
            _emit(iv_c[k], ta, tb, s_in, 1.0, o_t0, o_t1, o_c, n_out)
            n_out += 1
        t_prev = tb
    if inside and t_prev < tmax:
        roots[n_roots] = t_prev  # inside up to a chord end: only a kernel with a jump at u = 1 does this
        n_roots += 1
    return n_out, n_roots


@njit(**NJIT)
def _emit(c, ta, tb, s0, s1, o_t0, o_t1, o_c, n_out):
    # ends at 0 and 1 are the interval's own ends, bit for bit, so that adjacent pieces join exactly
    o_t0[n_out] = ta + s0 * (tb - ta) if s0 > 0.0 else ta
    o_t1[n_out] = ta + s1 * (tb - ta) if s1 < 1.0 else tb
    subdivide(c, s0, s1, o_c[n_out])


@njit(**NJIT)
def pieces_optical_depth(n_out, mode, threshold, scale, scratch):
    """tau over the inside pieces: scale times the sum of length x mean density, exact."""
    o_t0, o_t1, o_c = scratch.out_t0, scratch.out_t1, scratch.out_c
    tau = 0.0
    for k in range(n_out):
        tau += (o_t1[k] - o_t0[k]) * density_mean(o_c[k], mode, threshold)
    return scale * tau


@njit(**NJIT)
def trace_blob(o, d, tmin, tmax, blob, tol_t, cand, n_cand, first_only, scratch):
    """Chords, composite and inside pieces of one ray through ``blob`` (a records.BlobRecord; its balls
    cand[:n_cand]); grows the scratch when the ray meets more chords than it holds.
    Returns (scratch, n_pieces, n_transitions)."""
    scratch, n_p = gather_all_chords(o, d, tmin, tmax, blob, cand, n_cand, scratch)
    if n_p == 0:
        return scratch, 0, 0
    n_iv = composite(n_p, tmin, tmax, scratch)
    n_out, n_roots = inside_pieces(n_iv, blob.threshold, tmin, tmax, tol_t, first_only, scratch)
    return scratch, n_out, n_roots


@njit(**NJIT)
def first_entry(o, d, tmin, tmax, blob, tol_t, cand, n_cand, scratch):
    """Where the ray is first inside the blob (F >= T) within [tmin, tmax]: the first entering root,
    tmin if the ray starts inside, inf if it never enters. Returns (scratch, t)."""
    scratch, _, n_tr = trace_blob(o, d, tmin, tmax, blob, tol_t, cand, n_cand, True, scratch)
    if n_tr == 0:
        return scratch, np.inf
    return scratch, scratch.roots[0]


# --- the first hit alone: an incremental sweep that stops at the first entry -----------------------------

@njit(**NJIT_INLINE)
def _starts_before(keys, a, b):
    """The order of the chords' starts, ties by index: the order of a stable sort (insertion_argsort)."""
    return keys[a] < keys[b] or (keys[a] == keys[b] and a < b)


@njit(**NJIT_INLINE)
def _sift_min(keys, heap, root, n):
    """Restore the min-heap heap[:n] (by _starts_before) below root."""
    while True:
        child = 2 * root + 1
        if child >= n:
            return
        if child + 1 < n and _starts_before(keys, heap[child + 1], heap[child]):
            child += 1
        if not _starts_before(keys, heap[child], heap[root]):
            return
        heap[root], heap[child] = heap[child], heap[root]
        root = child


@njit(**NJIT)
def start_heap(keys, heap, n):
    """heap[:n]: the indices 0..n-1 as a min-heap of the chords' starts (O(n), where a sort is O(n log n):
    a first hit takes only the chords up to the hit off it)."""
    for i in range(n):
        heap[i] = i
    for root in range(n // 2 - 1, -1, -1):
        _sift_min(keys, heap, root, n)


@njit(**NJIT_INLINE)
def pop_start(keys, heap, n):
    """Take the earliest start off the heap heap[:n]: returns (its chord, n - 1)."""
    i = heap[0]
    n -= 1
    heap[0] = heap[n]
    _sift_min(keys, heap, 0, n)
    return i, n


@njit(**NJIT)
def sweep_first_inside(n_p, threshold, tmin, tmax, tol_t, scratch):
    """Where the ray is first inside (F >= T) within [tmin, tmax], from the chords gathered in the scratch:
    the first entering root, the start of the first interval where F >= T already (tmin when the ray
    starts inside), inf if it never enters.

    The sweep of ``composite`` followed by ``inside_pieces`` with first_only, walked interval by interval
    and stopped at the first entry, so that an opaque surface pays only for the intervals up to its hit.
    Each interval's control values are those composite writes, bit for bit: the same chords, added in the
    same order (act holds the active chords by start, ties by index, as composite's sort puts them; its
    heap sort of more than SMALL_SORT chords may order chords that start at the same t otherwise, which
    changes only the order of adding their control values), cut by the same de Casteljau splits, since
    the breakpoints visited are the same (the next one is the nearest of the next chord start and the
    active chords' ends: no other chord end can lie before it). The starts come off a heap, so only those
    before the hit are ordered. An interval where the convex hull of F stays below T has no root and is
    not clipped; the others are clipped by the same ``clip_roots`` call as inside_pieces makes, and take
    the same roots (a root counts only where the class changes; a touch does not enter).
    """
    p_t0, p_t1, p_c = scratch.chord_t0, scratch.chord_t1, scratch.chord_c
    heap, act = scratch.order, scratch.act
    st_lo, st_hi, st_c, g = scratch.st_lo, scratch.st_hi, scratch.st_c, scratch.g
    loc, rising = scratch.loc, scratch.rising
    start_heap(p_t0, heap, n_p)
    n_heap = n_p
    n_act = 0
    ta = p_t0[heap[0]]
    while ta < tmax:
        # advance_active at ta: chords that ended drop out (in order), chords that start join (by start)
        j = 0
        for m in range(n_act):
            if p_t1[act[m]] > ta:
                act[j] = act[m]
                j += 1
        n_act = j
        while n_heap > 0 and p_t0[heap[0]] <= ta:
            i, n_heap = pop_start(p_t0, heap, n_heap)
            act[n_act] = i
            n_act += 1
        if n_act == 0:
            if n_heap == 0:
                break
            ta = p_t0[heap[0]]  # a gap: F = 0 < T up to the next chord
            continue
        # the next breakpoint: the next start, or the nearest end of an active chord
        tb = p_t0[heap[0]] if n_heap > 0 else np.inf
        for m in range(n_act):
            tb = min(tb, p_t1[act[m]])
        lo = max(ta, tmin)
        hi = min(tb, tmax)
        if hi <= lo:  # before tmin
            ta = tb
            continue
        a0, a1, a2, a3, a4, a5, a6, mag = add_active(lo, hi, act, n_act, p_t0, p_t1, p_c)
        if a0 - threshold >= 0.0:
            return lo  # inside from the interval's start on (tmin, or a jump at a chord end)
        # the hull bound: all control values below T, no root on the interval (clip_roots would say so too)
        top = max(max(max(a0, a1), max(a2, a3)), max(max(a4, a5), a6))
        if top - threshold >= 0.0:
            g[0] = a0 - threshold
            g[1] = a1 - threshold
            g[2] = a2 - threshold
            g[3] = a3 - threshold
            g[4] = a4 - threshold
            g[5] = a5 - threshold
            g[6] = a6 - threshold
            w = hi - lo
            eps_g = NOISE * (threshold + (mag / NCOEF) * NCOEF)  # as inside_pieces reads iv_mag
            n_r = clip_roots(g, tol_t / w, eps_g, st_lo, st_hi, st_c, loc, rising)
            for j in range(n_r):
                if rising[j]:
                    return lo + loc[j] * w
        ta = tb
    return np.inf


@njit(**NJIT)
def first_inside(o, d, tmin, tmax, blob, tol_t, cand, n_cand, scratch):
    """first_entry's answer (the first entering root within [tmin, tmax], tmin if the ray starts inside,
    inf if it never enters) by the incremental sweep, which stops at the first entry. Returns (scratch, t)."""
    scratch, n_p = gather_all_chords(o, d, tmin, tmax, blob, cand, n_cand, scratch)
    if n_p == 0:
        return scratch, np.inf
    return scratch, sweep_first_inside(n_p, blob.threshold, tmin, tmax, tol_t, scratch)
