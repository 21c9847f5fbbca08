"""One ray through one blob (cloudmeta.kernels.sweep): the composited field against the naive field, the
sorts against numpy's, the density modes against docs/model.md §4."""
import numpy as np
import pytest

from cloudmeta.api.rays import blob_record
from cloudmeta.kernels import sweep as ks
from cloudmeta.kernels.bernstein import bernstein_eval
from tests import naive
from tests.conftest import random_blob, random_rays


@pytest.mark.parametrize("kernel", ["wyvill6", "murakami4", "nishimura", "blinn"])
def test_composite_intervals_carry_the_field(rng, kernel):
    """Between consecutive chord ends the composite control values are F on that interval: checked at
    points inside each interval against the naive field (the plain sum over balls)."""
    blob = random_blob(rng, 12, kernel, ellipsoids=True, negative=True)
    o, d = random_rays(rng, 20)
    rec = blob_record(blob)
    cand = np.arange(len(blob))
    checked = 0
    for i in range(len(o)):
        scratch = ks.alloc_scratch(4096)
        n_p = ks.gather_chords(o[i], d[i], 0.0, np.inf, rec, cand, len(blob), scratch)
        n_iv = ks.composite(n_p, 0.0, np.inf, scratch)
        t0, t1, c = scratch.iv_t0[:n_iv], scratch.iv_t1[:n_iv], scratch.iv_c[:n_iv]
        assert np.all(t1 > t0) and np.all(t0[1:] >= t1[:-1])  # in order, disjoint
        for k in range(n_iv):
            for s in (0.1, 0.5, 0.9):
                t = t0[k] + s * (t1[k] - t0[k])
                ref = naive.field(blob, o[i] + t * d[i])[0]
                assert bernstein_eval(c[k], s) == pytest.approx(ref, abs=1e-11 * np.abs(blob.weights).sum())
                checked += 1
    assert checked > 50


@pytest.mark.parametrize("n", [0, 1, 7, 24, 25, 200])
def test_sorts_match_numpy(rng, n):
    keys = rng.uniform(-1, 1, n)
    keys[: n // 3] = 0.5  # ties
    a = keys.copy()
    ks.heap_sort(a, n)
    np.testing.assert_array_equal(a, np.sort(keys))
    idx = np.empty(max(n, 1), np.int64)
    ks.heap_argsort(keys, idx, n)
    np.testing.assert_array_equal(keys[idx[:n]], np.sort(keys))
    assert sorted(idx[:n]) == list(range(n))
    ks.insertion_argsort(keys, idx, n)  # stable: ties keep their order
    np.testing.assert_array_equal(idx[:n], np.argsort(keys, kind="stable"))


# --- the first hit by the incremental sweep (sweep.first_inside) against the full sweep (first_entry) ------

KERNELS = ("wyvill6", "murakami4", "nishimura", "blinn")
TOL_T = 1e-9


def _both(rec, n, o, d, tmin, tmax, tol_t=TOL_T):
    """(full sweep, incremental sweep) first entries of one ray, each with a fresh small scratch (so that
    the scratch's growth is exercised too)."""
    cand = np.arange(n)
    _, ref = ks.first_entry(o, d, tmin, tmax, rec, tol_t, cand, n, ks.alloc_scratch(4))
    _, got = ks.first_inside(o, d, tmin, tmax, rec, tol_t, cand, n, ks.alloc_scratch(4))
    return ref, got


@pytest.mark.parametrize("kernel", KERNELS)
def test_first_inside_is_the_full_sweeps_first_entry(rng, kernel):
    """Bit for bit the first entry of the full sweep, on rays from outside, rays that start inside a
    chord (tmin > 0, at ball centres and inside segments), and t_max cut-offs before, at and after the
    hit."""
    blob = random_blob(rng, 30, kernel, ellipsoids=True, negative=True)
    rec = blob_record(blob)
    n = len(blob)
    o, d = random_rays(rng, 120)
    kinds = dict(hit=0, miss=0, inside=0, cut=0)
    for i in range(len(o)):
        ref, got = _both(rec, n, o[i], d[i], 0.0, np.inf)
        assert got == ref, (i, got, ref)
        kinds["hit" if ref < np.inf else "miss"] += 1
        if ref == np.inf:
            continue
        for tmax in (0.5 * ref, ref, np.nextafter(ref, np.inf), ref + 0.3, ref + 3.0):
            r2, g2 = _both(rec, n, o[i], d[i], 0.0, tmax)
            assert g2 == r2, (i, tmax, g2, r2)
            kinds["cut"] += r2 == np.inf
        for tmin in (ref + 1e-3, ref + 0.4, ref + 1.5):  # from inside the first segment, or past it
            r2, g2 = _both(rec, n, o[i], d[i], tmin, np.inf)
            assert g2 == r2, (i, tmin, g2, r2)
            kinds["inside"] += r2 == tmin
    for c in blob.centers:  # rays from the balls' centres, inside their chords
        for dd in d[:10]:
            ref, got = _both(rec, n, c, dd, 0.0, np.inf)
            assert got == ref
            kinds["inside"] += ref == 0.0
    assert kinds["hit"] > 20 and kinds["miss"] > 5 and kinds["inside"] > 20 and kinds["cut"] > 20, kinds


@pytest.mark.parametrize("kernel", KERNELS)
def test_first_inside_on_tangent_rays(rng, kernel):
    """Rays that graze a ball's support (chords of almost no length) and rays past the supports' rims."""
    blob = random_blob(rng, 12, kernel, negative=True)
    rec = blob_record(blob)
    n = len(blob)
    for i in range(n):
        c, r = blob.centers[i], blob.radii[i, 0]
        for _ in range(8):
            d = rng.normal(size=3)
            d /= np.linalg.norm(d)
            side = np.cross(d, rng.normal(size=3))
            side /= np.linalg.norm(side)
            for f in (1.0 - 1e-12, 1.0 - 1e-7, 1.0 - 1e-3, 1.0, 1.0 + 1e-9):
                o = c + f * r * side - 8.0 * d
                ref, got = _both(rec, n, o, d, 0.0, np.inf)
                assert got == ref, (i, f, got, ref)


def _touch_threshold(blob, o, d, t_touch):
    """F at t_touch on the ray as the sweep composites it (the control values of the interval holding
    t_touch): with T set to it the ray touches F = T there."""
    rec = blob_record(blob)
    scratch = ks.alloc_scratch(64)
    n_p = ks.gather_chords(o, d, 0.0, np.inf, rec, np.arange(len(blob)), len(blob), scratch)
    n_iv = ks.composite(n_p, 0.0, np.inf, scratch)
    for k in range(n_iv):
        t0, t1 = scratch.iv_t0[k], scratch.iv_t1[k]
        if t0 < t_touch < t1:  # inside an interval: at an interval's start g >= 0 would count as inside
            return bernstein_eval(scratch.iv_c[k], (t_touch - t0) / (t1 - t0))
    raise AssertionError("no interval holds the touch")


@pytest.mark.parametrize("kernel", KERNELS)
def test_a_touch_does_not_enter(kernel):
    """A ray that touches the isosurface (a double root of F - T, at the peak of F on the ray) does not
    enter: no hit, from both sweeps; slightly below that T it enters at two roots close together."""
    import cloudmeta as cm
    o = np.array([-3.0, 0.25, 0.0])  # u >= 1/16 on the ray: nishimura's inner piece holds the peak
    d = np.array([1.0, 0.0, 0.0])
    probe = cm.Blob([[0.0, 0.0, 0.0]], [1.0], [1.0], kernel=kernel, threshold=0.1)
    peak = _touch_threshold(probe, o, d, 3.0)  # the closest point to the centre, s = 1/2 of the chord
    for T, enters in ((peak, False), (peak * (1 - 1e-6), True)):
        blob = cm.Blob([[0.0, 0.0, 0.0]], [1.0], [1.0], kernel=kernel, threshold=T)
        ref, got = _both(blob_record(blob), 1, o, d, 0.0, np.inf)
        assert got == ref
        assert (got < np.inf) == enters, (T, got)
        if enters:
            assert 2.99 < got < 3.0


@pytest.mark.parametrize("kernel", KERNELS)
def test_first_inside_in_a_dense_blob(rng, kernel):
    """Many chords per ray (the heap sort's range, gaps and long active lists) and a coarse tolerance."""
    blob = random_blob(rng, 300, kernel, negative=True, box=4.0)
    rec = blob_record(blob)
    o, d = random_rays(rng, 40, box=4.0, dist=15.0)
    hits = 0
    for i in range(len(o)):
        for tol_t in (TOL_T, 1e-4):
            ref, got = _both(rec, len(blob), o[i], d[i], 0.0, np.inf, tol_t)
            assert got == ref, (i, tol_t, got, ref)
            hits += ref < np.inf
    assert hits > 20


@pytest.mark.parametrize("kernel", KERNELS)
@pytest.mark.parametrize("n_balls", [4, 60])
def test_first_inside_with_twin_balls(rng, kernel, n_balls):
    """Balls with a twin at the same place (CSG's negative twins, duplicates): chords that start at the same
    t. With few chords the full sweep's sort is stable like the heap of starts: bit for bit the same; past
    SMALL_SORT chords its heap sort may add the twins' control values in the other order: the same hits,
    t within 1e-12 (relative)."""
    base = random_blob(rng, n_balls, kernel, box=1.0 + n_balls / 20)
    w = np.concatenate([base.weights, np.where(rng.random(n_balls) < 0.5, -0.4, 0.7) * base.weights])
    import cloudmeta as cm
    blob = cm.Blob(np.concatenate([base.centers] * 2), np.concatenate([base.radii[:, 0]] * 2), w,
                   kernel=kernel, threshold=0.5)
    rec = blob_record(blob)
    o, d = random_rays(rng, 60, box=1.0 + n_balls / 20)
    hits = 0
    for i in range(len(o)):
        ref, got = _both(rec, len(blob), o[i], d[i], 0.0, np.inf)
        if 2 * n_balls <= ks.SMALL_SORT:
            assert got == ref
        else:
            assert (got < np.inf) == (ref < np.inf) and got == pytest.approx(ref, rel=1e-12, abs=1e-12)
        hits += ref < np.inf
    assert hits > 10
