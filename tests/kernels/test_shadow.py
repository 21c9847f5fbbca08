"""The shadow rays' fused sweep (cloudmeta.kernels.shadow) against the full sweep (composite, inside_pieces,
pieces_optical_depth) and against the naive optical depth: every kernel, ellipsoids, negative balls, rays
from outside and from inside, cut by tmin and tmax, tangent rays, every density mode."""
import numpy as np
import pytest
from scipy.optimize import brentq

import cloudmeta as cm

from cloudmeta.api.rays import blob_record
from cloudmeta.kernels import shadow as ksh
from cloudmeta.kernels import sweep as ks
from cloudmeta.kernels.kinds import DENSITY_FIELD, DENSITY_MODES
from tests import naive
from tests.conftest import random_blob, random_rays

MODES = DENSITY_MODES


def full_sweep_pieces(o, d, tmin, tmax, rec, tol_t):
    """(number of inside pieces, the scratch holding them) of the full sweep: chords, composite, inside_pieces."""
    cand = np.arange(rec.centers.shape[0])
    scratch = ks.alloc_scratch(4096)
    n_p = ks.gather_chords(o, d, tmin, tmax, rec, cand, len(cand), scratch)
    if n_p == 0:
        return 0, scratch
    n_iv = ks.composite(n_p, tmin, tmax, scratch)
    n_out, _ = ks.inside_pieces(n_iv, rec.threshold, tmin, tmax, tol_t, False, scratch)
    return n_out, scratch


def full_sweep_depth(o, d, tmin, tmax, rec, mode, tol_t):
    n_out, scratch = full_sweep_pieces(o, d, tmin, tmax, rec, tol_t)
    if n_out == 0:
        return 0.0
    return ks.pieces_optical_depth(n_out, mode, rec.threshold, 1.7, scratch)


def fused_depth(o, d, tmin, tmax, rec, mode, tol_t, capacity=4096):
    cand = np.arange(rec.centers.shape[0])
    _, rho, _ = ksh.column_density(o, d, tmin, tmax, rec, mode, tol_t, cand, len(cand), ks.alloc_scratch(capacity))
    return 1.7 * rho


def rays_inside_and_out(rng, blob, n):
    """Rays from outside, and rays from inside (ball centres and random points) in random directions."""
    o, d = random_rays(rng, n)
    inner = np.concatenate([blob.centers[: n // 2], rng.uniform(-1.5, 1.5, (n // 2, 3))])
    di = rng.normal(size=inner.shape)
    di /= np.linalg.norm(di, axis=1)[:, None]
    return np.concatenate([o, inner]), np.concatenate([d, di])


@pytest.mark.parametrize("kernel", ["wyvill6", "murakami4", "nishimura", "blinn"])
@pytest.mark.parametrize("mode", list(MODES))
def test_fused_depth_equals_full_sweep(rng, kernel, mode):
    """Every ray, from outside and inside, cut or not by tmin / tmax: the same optical depth as the full
    sweep to rounding."""
    blob = random_blob(rng, 14, kernel, ellipsoids=True, negative=True)
    rec = blob_record(blob)
    o, d = rays_inside_and_out(rng, blob, 40)
    checked = 0
    for i in range(len(o)):
        for tmin, tmax in ((0.0, np.inf), (0.0, 9.0 + 3.0 * (i % 5)), (1.5, np.inf), (0.3, 2.0)):
            ref = full_sweep_depth(o[i], d[i], tmin, tmax, rec, MODES[mode], 1e-12)
            got = fused_depth(o[i], d[i], tmin, tmax, rec, MODES[mode], 1e-12)
            assert got == pytest.approx(ref, rel=1e-10, abs=1e-11), (i, tmin, tmax)
            checked += ref > 0.0
    assert checked > 60


@pytest.mark.parametrize("kernel", ["wyvill6", "murakami4"])
def test_fused_depth_against_naive(rng, kernel):
    """Against tests/naive.py's optical depth (numpy roots of the power-basis field, quadrature-free)."""
    blob = random_blob(rng, 10, kernel, negative=True)
    rec = blob_record(blob)
    o, d = rays_inside_and_out(rng, blob, 30)
    for i in range(len(o)):
        for mode in MODES:
            ref = naive.optical_depth(blob, o[i], d[i], density=mode, scale=1.7)
            got = fused_depth(o[i], d[i], 0.0, np.inf, rec, MODES[mode], 1e-12)
            assert got == pytest.approx(ref, rel=1e-8, abs=1e-9), (i, mode)


def test_tangent_and_touching_rays():
    """A ray tangent to the isosurface of one ball (F touches T: a double root, no inside length) and
    rays just inside and outside of it; a ray along the axis of two balls whose fields meet at T."""
    one = cm.Blob(np.zeros((1, 3)), np.array([1.0]), np.array([1.0]), kernel="wyvill6", threshold=0.5)
    rec = blob_record(one)
    # wyvill6: k(u0) = 0.5; the ray at distance sqrt(u0) from the centre just touches F = T
    u0 = brentq(lambda u: (1 - u) ** 2 * (1 - 4 * u / 9) - 0.5, 0.0, 1.0, xtol=1e-15)
    d = np.array([1.0, 0.0, 0.0])
    for off in (-1e-7, 0.0, 1e-7):
        o = np.array([-3.0, np.sqrt(u0) + off, 0.0])
        for mode in MODES.values():
            ref = full_sweep_depth(o, d, 0.0, np.inf, rec, mode, 1e-12)
            got = fused_depth(o, d, 0.0, np.inf, rec, mode, 1e-12)
            assert got == pytest.approx(ref, rel=1e-9, abs=1e-12)
            if off > 0.0:
                assert got == 0.0  # outside: no inside length
            if off < 0.0:
                assert got > 0.0
    two = cm.Blob(np.array([[-0.9, 0, 0], [0.9, 0, 0]]), np.array([1.0, 1.0]), np.array([1.0, 1.0]),
                  kernel="wyvill6", threshold=0.5)
    rec2 = blob_record(two)
    o = np.array([-3.0, 0.0, 0.0])
    for mode in MODES.values():
        assert fused_depth(o, d, 0.0, np.inf, rec2, mode, 1e-12) == pytest.approx(
            full_sweep_depth(o, d, 0.0, np.inf, rec2, mode, 1e-12), rel=1e-12)


def test_scratch_grows(rng):
    """A ray that meets more chords than the scratch holds grows it and gives the same depth."""
    blob = random_blob(rng, 40, "wyvill6")
    rec = blob_record(blob)
    o, d = rays_inside_and_out(rng, blob, 10)
    for i in range(len(o)):
        assert fused_depth(o[i], d[i], 0.0, np.inf, rec, DENSITY_FIELD, 1e-12, capacity=1) == \
            fused_depth(o[i], d[i], 0.0, np.inf, rec, DENSITY_FIELD, 1e-12)


def full_sweep_entries(o, d, tmin, tmax, rec, tol_t):
    """The ray's entries into {F >= T} from the full sweep's inside pieces: a piece that does not start where the
    one before it ended (the pieces are cut at the composite intervals' ends)."""
    n_out, scratch = full_sweep_pieces(o, d, tmin, tmax, rec, tol_t)
    return sum(1 for k in range(n_out) if k == 0 or scratch.out_t0[k] > scratch.out_t1[k - 1])


@pytest.mark.parametrize("kernel", ["wyvill6", "blinn"])
def test_entries_count_the_inside_parts(rng, kernel):
    """column_density's count of entries (what the quadrature's fold splits compare between nodes) is the number
    of separate inside parts the full sweep finds, on rays from outside and inside, cut or not."""
    blob = random_blob(rng, 14, kernel, ellipsoids=True, negative=True)
    rec = blob_record(blob)
    o, d = rays_inside_and_out(rng, blob, 40)
    seen = set()
    for i in range(len(o)):
        for tmin, tmax in ((0.0, np.inf), (1.5, np.inf), (0.3, 2.0)):
            cand = np.arange(rec.centers.shape[0])
            _, _, entries = ksh.column_density(o[i], d[i], tmin, tmax, rec, DENSITY_FIELD, 1e-12, cand, len(cand),
                                               ks.alloc_scratch(64))
            assert entries == full_sweep_entries(o[i], d[i], tmin, tmax, rec, 1e-12), (i, tmin, tmax)
            seen.add(entries)
    assert {0, 1, 2} <= seen  # rays that miss, enter once and enter more than once
