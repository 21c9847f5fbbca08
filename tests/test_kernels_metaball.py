import numpy as np
import pytest

from cloudmeta.blob import rotation_matrix
from cloudmeta.kernels import metaball as km
from tests import naive

KERNEL_IDS = {"wyvill6": km.WYVILL6, "murakami4": km.MURAKAMI4}


@pytest.mark.parametrize("kernel", ["wyvill6", "murakami4"])
@pytest.mark.parametrize("a", [1e-6, 0.1, 0.5, 0.77, 1.0])
def test_control_values_match_the_curve(kernel, a):
    out = np.empty(7)
    km.control_values(KERNEL_IDS[kernel], a, 1.3, out)
    np.testing.assert_allclose(out, naive.control_values(kernel, a, 1.3), rtol=1e-10, atol=1e-13)


def test_wyvill6_paper_numbers_with_erratum():
    """MODEL.md §2: d_3 = 8 a^2 (8a + 5) / 45; the paper's own numbers 2.31 (a = 1) and 0.4 (a = 0.5)."""
    out = np.empty(7)
    km.control_values(km.WYVILL6, 1.0, 1.0, out)
    np.testing.assert_allclose(out, [0, 0, 16 / 27, 104 / 45, 16 / 27, 0, 0], rtol=1e-15)
    assert round(out[2], 2) == 0.59 and round(out[3], 2) == 2.31
    km.control_values(km.WYVILL6, 0.5, 1.0, out)
    assert out[3] == pytest.approx(0.4, rel=1e-15)


def test_murakami4_is_eq18_elevated():
    out = np.empty(7)
    km.control_values(km.MURAKAMI4, 0.5, 1.0, out)
    deg4 = np.array([0, 0, 8 / 3 * 0.25, 0, 0])
    for s in np.linspace(0, 1, 9):
        assert naive.bernstein_eval(out, s) == pytest.approx(naive.bernstein_eval(deg4, s), abs=1e-15)


def test_sphere_chord_matches_textbook(rng):
    for _ in range(50):
        o = rng.normal(size=3) * 5
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        c = rng.normal(size=3)
        r = rng.uniform(0.5, 3)
        ref = naive.chord_sphere(o, d, c, r)
        t0, t1, a = km.chord(o, d, c, np.eye(3) / r)
        if ref is None:
            assert a <= 1e-12
        else:
            np.testing.assert_allclose([t0, t1, a], ref, rtol=1e-9, atol=1e-11)


def test_ellipsoid_chord_matches_model(rng):
    hits = 0
    for _ in range(100):
        o = rng.normal(size=3) * 5
        c = rng.normal(size=3)
        d = c + rng.normal(size=3) - o
        d /= np.linalg.norm(d)
        radii = rng.uniform(0.5, 3, 3)
        q = rotation_matrix(rng.uniform(0, 360, 3))
        ref = naive.chord_ellipsoid(o, d, c, radii, q)
        t0, t1, a = km.chord(o, d, c, naive.unit_frame(radii, q))
        if ref is None:
            assert a <= 1e-12
        else:
            hits += 1
            np.testing.assert_allclose([t0, t1, a], ref, rtol=1e-9, atol=1e-11)
            # the ends lie on the support: u = 1
            for t in (t0, t1):
                assert km.unit_distance2(o + t * d, c, naive.unit_frame(radii, q)) == pytest.approx(1.0, abs=1e-9)
    assert hits > 10


def test_chord_far_from_origin_keeps_its_precision():
    """The stable form of D keeps 1e-9 accuracy at 1e6 units, where B^2 - C loses ~6 digits."""
    c = np.array([1e6, 1e6, 0.0])
    o = c + np.array([-50.0, 0.3, 0.0])
    t0, t1, a = km.chord(o, np.array([1.0, 0, 0]), c, np.eye(3))
    # (o - c) itself carries the rounding of 1e6 + 0.3 (ulp 1.2e-10), so 1e-9 is what can be asked
    assert a == pytest.approx(1 - 0.09, rel=1e-9)
    assert t0 == pytest.approx(50 - np.sqrt(0.91), abs=1e-9)


@pytest.mark.parametrize("kernel", ["wyvill6", "murakami4", "nishimura", "blinn"])
def test_falloff_matches_model(kernel, rng):
    kid = {"wyvill6": 0, "murakami4": 1, "nishimura": 2, "blinn": 3}[kernel]
    u = np.concatenate([rng.uniform(0, 1.2, 50), [0.0, 1 / 9, 0.999999, 1.0]])
    got = np.array([km.falloff(kid, x, 4.0) for x in u])
    np.testing.assert_allclose(got, naive.falloff(kernel, u), rtol=1e-14, atol=1e-15)
