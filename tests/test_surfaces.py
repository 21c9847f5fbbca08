"""Opaque metaball surfaces (MODEL.md §6) and CSG through negative weights (issue 7): the first hit and the
normal through the API."""
import math

import numpy as np
import pytest

import cloudmeta as cm
from tests import naive
from tests.conftest import random_blob, random_rays

KERNELS = ("wyvill6", "murakami4", "nishimura", "blinn")


# ------------------------------------------------------------------------------------------- helpers

def iso_radius_murakami4(R, T, q=1.0):
    """q (1 - u)^2 = T at u = 1 - sqrt(T / q): the isosurface of one ball is a sphere of radius R sqrt(u)."""
    return R * math.sqrt(1.0 - math.sqrt(T / q))


def sphere_entry(o, d, c, r):
    """Where rays o + t d (|d| = 1) enter the sphere |x - c| = r, and the discriminant (inf on a miss)."""
    oc = o - c
    b = -(oc * d).sum(axis=1)
    disc = b * b - (oc * oc).sum(axis=1) + r * r
    return np.where(disc > 0, b - np.sqrt(np.abs(disc)), np.inf), disc


# ------------------------------------------------------------------------------------------- the API

@pytest.mark.parametrize("T", [0.05, 0.25, 0.5, 0.9])
def test_murakami4_ball_is_the_sphere_of_radius_r_sqrt_1_minus_sqrt_t(rng, T):
    R = 1.7
    c = np.array([0.3, -0.2, 0.5])
    r = iso_radius_murakami4(R, T)
    blob = cm.Blob([c], [R], kernel="murakami4", threshold=T)
    o, d = random_rays(rng, 300, box=1.2 * r, dist=6.0)
    o += c
    expected, disc = sphere_entry(o, d, c, r)
    clear = np.abs(disc) > 1e-6 * r * r  # not within rounding of a tangent ray
    got = cm.first_hit(blob, o, d)
    assert np.count_nonzero(clear & (disc > 0)) > 100
    np.testing.assert_allclose(got[clear], expected[clear], rtol=1e-9)
    # from inside: 0; a t_max before the sphere: a miss
    assert np.all(cm.first_hit(blob, c + 0.99 * r * d, d) == 0.0)
    hits = np.flatnonzero(clear & (disc > 0))
    assert np.all(cm.first_hit(blob, o[hits], d[hits], t_max=expected[hits] * (1 - 1e-6)) == np.inf)
    np.testing.assert_allclose(cm.first_hit(blob, o[hits], d[hits], t_max=expected[hits] * 1.01), expected[hits],
                               rtol=1e-9)


@pytest.mark.parametrize("kernel", KERNELS)
def test_first_hit_is_the_first_root(rng, kernel):
    """The first-root-only sweep stops where the full sweep finds its first root, bit for bit; a ray that
    starts inside (the middle of its first segment) gets 0."""
    blob = random_blob(rng, 10, kernel, ellipsoids=True, negative=True)
    o, d = random_rays(rng, 150)
    got = cm.first_hit(blob, o, d)
    segs = cm.segments(blob, o, d)
    for i, r in enumerate(cm.roots(blob, o, d)):
        assert got[i] == (r[0] if len(r) else np.inf), i
    hit = [i for i in range(len(o)) if len(segs[i])]
    assert len(hit) > 20
    mid = np.array([segs[i][0].mean() for i in hit])
    assert np.all(cm.first_hit(blob, o[hit] + mid[:, None] * d[hit], d[hit]) == 0.0)


@pytest.mark.parametrize("ellipsoids", [False, True])
@pytest.mark.parametrize("kernel", KERNELS)
def test_normals_match_finite_differences_of_the_field(rng, kernel, ellipsoids):
    blob = random_blob(rng, 8, kernel, ellipsoids, negative=True)
    o, d = random_rays(rng, 400)
    t = cm.first_hit(blob, o, d)
    hit = np.isfinite(t)
    x = o[hit] + t[hit, None] * d[hit]
    # central differences need k smooth across +-h: keep away from each support's edge u = 1 (blinn's field
    # jumps there) and nishimura's seam u = 1/9 (k'' jumps)
    u = (np.einsum("nij,pnj->pni", blob.frames, x[:, None, :] - blob.centers[None]) ** 2).sum(axis=2)
    smooth = np.all(np.abs(u - 1.0) > 1e-3, axis=1) & np.all(np.abs(u - 1.0 / 9.0) > 1e-3, axis=1)
    x, dx = x[smooth], d[hit][smooth]
    assert len(x) > 100
    np.testing.assert_allclose(cm.field(blob, x), blob.threshold, rtol=0, atol=1e-9)  # on the isosurface
    h = 1e-5
    fd = np.stack([(cm.field(blob, x + h * e) - cm.field(blob, x - h * e)) / (2 * h) for e in np.eye(3)], axis=1)
    np.testing.assert_allclose(cm.gradient(blob, x), fd, rtol=0, atol=1e-6)
    n = cm.normal(blob, x)
    np.testing.assert_allclose(n, -fd / np.linalg.norm(fd, axis=1)[:, None], rtol=0, atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, rtol=1e-14)
    assert np.all((n * dx).sum(axis=1) < 0)  # F rises through T at the first hit: n faces the ray


def test_normal_is_nan_where_the_gradient_vanishes():
    blob = cm.Blob([[0.0, 0.0, 0.0]], [2.0])
    assert np.all(np.isnan(cm.normal(blob, [[0.0, 0.0, 0.0], [5.0, 0.0, 0.0]])))
    np.testing.assert_allclose(cm.normal(blob, [[0.0, 0.0, 1.0]]), [[0.0, 0.0, 1.0]], atol=1e-15)


def test_api_validates_its_input():
    blob = cm.Blob([[0.0, 0.0, 0.0]], [2.0])
    with pytest.raises(cm.InputError, match="directions"):
        cm.first_hit(blob, [0, 0, 0], [0, 0, 0])
    with pytest.raises(cm.InputError, match="t_max"):
        cm.first_hit(blob, [0, 0, 0], [1, 0, 0], t_max=-1.0)
    with pytest.raises(cm.InputError, match="blob"):
        cm.first_hit("blob", [0, 0, 0], [1, 0, 0])
    with pytest.raises(cm.InputError, match="points"):
        cm.normal(blob, [[0, 0]])
    with pytest.raises(cm.InputError, match=r"points\[1\]"):
        cm.gradient(blob, [[0, 0, 0], [np.nan, 0, 0]])


# ------------------------------------------------------------------------------------------- CSG

@pytest.mark.parametrize("kernel", KERNELS)
def test_a_negative_twin_removes_a_ball(rng, kernel):
    """q k(u) - q k(u) = 0: a ball with a negative twin (same centre, radius, |weight|) is not there."""
    only_twins = cm.Blob([[0.5, 0.3, 0.0]] * 2, [1.8, 1.8], [1.2, -1.2], kernel=kernel)
    alone = cm.Blob([[0.0, 0.0, 0.0]], [2.0], kernel=kernel)
    with_twins = cm.Blob([[0.0, 0.0, 0.0], [0.5, 0.3, 0.0], [0.5, 0.3, 0.0]], [2.0, 1.8, 1.8], [1.0, 1.2, -1.2],
                         kernel=kernel)
    o, d = random_rays(rng, 100, box=1.0)
    assert np.all(cm.first_hit(only_twins, o, d) == np.inf)
    assert all(len(r) == 0 for r in cm.roots(only_twins, o, d))
    assert np.all(cm.optical_depth(only_twins, o, d, density="uniform") == 0.0)
    ref = cm.first_hit(alone, o, d)
    assert np.count_nonzero(np.isfinite(ref)) > 50
    np.testing.assert_allclose(cm.first_hit(with_twins, o, d), ref, rtol=0, atol=1e-12)
    for a, b in zip(cm.roots(with_twins, o, d), cm.roots(alone, o, d)):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)


SHELL_T = 0.25
#: murakami4, (1, R = 2) minus (1, R = 1) at one centre: for r < 1, F = (3v/4)(2 - 5v/4), v = r^2, which
#: dips below T = 1/4 inside r_in, v_in = (12 - 2 sqrt 21) / 15; outside r = 1, F = (1 - v/4)^2 = T at v = 2
SHELL_R_IN = math.sqrt((12 - 2 * math.sqrt(21)) / 15)
SHELL_R_OUT = math.sqrt(2.0)


def shell_blob():
    return cm.Blob([[0.0, 0.0, 0.0]] * 2, [2.0, 1.0], [1.0, -1.0], kernel="murakami4", threshold=SHELL_T)


def test_a_negative_ball_carves_a_hollow_shell():
    """The field dips below T inside the positive ball: four roots through the hole, exact optical depth of
    the shell, first hit on the outer wall from outside and on the inner wall from inside the hole."""
    blob = shell_blob()
    np.testing.assert_allclose(cm.field(blob, [[SHELL_R_IN, 0, 0], [0, SHELL_R_OUT, 0]]), SHELL_T, rtol=1e-14)
    for p in (0.0, 0.2, 0.43, 0.9, 1.3):
        so = math.sqrt(SHELL_R_OUT ** 2 - p * p)
        expected = [5 - so, 5 + so]
        if p < SHELL_R_IN:
            si = math.sqrt(SHELL_R_IN ** 2 - p * p)
            expected = [5 - so, 5 - si, 5 + si, 5 + so]
        o, d = [-5.0, p, 0.0], [1.0, 0.0, 0.0]
        np.testing.assert_allclose(cm.roots(blob, o, d)[0], expected, rtol=0, atol=1e-12)
        length = expected[1] - expected[0] + (expected[3] - expected[2] if len(expected) == 4 else 0.0)
        assert cm.optical_depth(blob, o, d, density="uniform", scale=1.5)[0] == pytest.approx(1.5 * length, rel=1e-12)
        assert cm.first_hit(blob, o, d)[0] == pytest.approx(5 - so, rel=1e-12)
    dirs = np.random.default_rng(3).normal(size=(50, 3))
    np.testing.assert_allclose(cm.first_hit(blob, [0.0, 0.0, 0.0], dirs), SHELL_R_IN, rtol=1e-12)


@pytest.mark.parametrize("kernel", ["wyvill6", "murakami4"])
def test_a_negative_ball_carves_a_dent_like_the_independent_solver(rng, kernel):
    """A heavier negative ball centred on a positive ball's surface: roots, first hits and optical depth
    against numpy (tests/naive.py), which knows nothing of Bernstein curves."""
    blob = cm.Blob([[0.0, 0.0, 0.0], [1.1, 0.2, 0.0]], [2.4, 1.3], [1.0, -1.6], kernel=kernel, threshold=0.4)
    o, d = random_rays(rng, 80, box=1.5)
    got, first = cm.roots(blob, o, d), cm.first_hit(blob, o, d)
    tau = cm.optical_depth(blob, o, d, density="field")
    carved = 0
    for i in range(len(o)):
        ref = naive.crossings(blob, o[i], d[i])
        np.testing.assert_allclose(got[i], ref, rtol=0, atol=1e-9)
        assert first[i] == pytest.approx(ref[0] if len(ref) else np.inf, abs=1e-9)
        assert tau[i] == pytest.approx(naive.optical_depth(blob, o[i], d[i]), rel=1e-10, abs=1e-13)
        carved += len(ref) == 4
    assert carved > 0  # some rays pass through the dent and out again
