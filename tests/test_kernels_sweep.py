"""One ray through one blob (cloudmeta.kernels.sweep): the composited field against the naive field, the
sorts against numpy's, the density modes against MODEL.md §4."""
import numpy as np
import pytest

from cloudmeta.engine import blob_record
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


def test_density_modes_follow_the_model():
    c = np.array([0.5, 0.9, 1.4, 1.1, 0.8, 0.6, 0.5])
    t = 0.5
    assert ks.density_mean(c, ks.DENSITY_FIELD, t) == pytest.approx(c.mean(), rel=1e-15)
    assert ks.density_mean(c, ks.DENSITY_EXCESS, t) == pytest.approx(c.mean() - t, rel=1e-15)
    assert ks.density_mean(c, ks.DENSITY_UNIFORM, t) == 1.0
    for f in (0.5, 0.7, 2.0):
        assert ks.rho_value(f, ks.DENSITY_FIELD, t) == f
        assert ks.rho_value(f, ks.DENSITY_EXCESS, t) == f - t
        assert ks.rho_value(f, ks.DENSITY_UNIFORM, t) == 1.0
