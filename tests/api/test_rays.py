import numpy as np
import pytest

import cloudmeta as cm
from cloudmeta.kernels.sweep import NOISE
from tests import naive
from tests.conftest import random_blob, random_rays

CASES = [(k, e, n) for k in ("wyvill6", "murakami4") for e in (False, True) for n in (False, True)]


@pytest.mark.parametrize("kernel,ellipsoids,negative", CASES)
def test_roots_match_an_independent_solver(rng, kernel, ellipsoids, negative):
    blob = random_blob(rng, 12, kernel, ellipsoids, negative)
    o, d = random_rays(rng, 60)
    got = cm.roots(blob, o, d)
    hits = 0
    for i in range(len(o)):
        ref = naive.crossings(blob, o[i], d[i])
        assert len(got[i]) == len(ref), (i, got[i], ref)
        np.testing.assert_allclose(got[i], ref, rtol=0, atol=1e-9)
        hits += len(ref) > 0
    assert hits > 10


@pytest.mark.parametrize("kernel,ellipsoids,negative", CASES)
@pytest.mark.parametrize("density", ["field", "excess", "uniform"])
def test_optical_depth_is_exact(rng, kernel, ellipsoids, negative, density):
    blob = random_blob(rng, 10, kernel, ellipsoids, negative)
    o, d = random_rays(rng, 25)
    got = cm.optical_depth(blob, o, d, density=density, scale=1.7)
    ref = np.array([naive.optical_depth(blob, o[i], d[i], density=density, scale=1.7) for i in range(len(o))])
    assert np.count_nonzero(ref) > 8
    np.testing.assert_allclose(got, ref, rtol=1e-10, atol=1e-13)


def test_segments_are_the_inside_between_roots(rng):
    blob = random_blob(rng, 15, negative=True)
    o, d = random_rays(rng, 40)
    for segs, rts, oi, di in zip(cm.segments(blob, o, d), cm.roots(blob, o, d), o, d):
        assert segs.size == rts.size  # rays start and end outside
        np.testing.assert_array_equal(segs.ravel(), rts)
        for t0, t1 in segs:
            mids = oi + np.linspace(t0, t1, 7)[1:-1, None] * di
            assert np.all(naive.field(blob, mids) >= blob.threshold - 1e-12)


def test_single_ball_isosurface_radius_is_half_r():
    """wyvill6 at T = 0.5: k(1/4) = 0.5, so the surface is the sphere of radius R/2."""
    blob = cm.Blob([[1.0, 2.0, 3.0]], [3.0])
    r = cm.roots(blob, [1.0, -10.0, 3.0], [0, 1, 0])[0]
    np.testing.assert_allclose(r, [12 - 1.5, 12 + 1.5], rtol=0, atol=1e-12)


def test_tangent_rays_neither_invent_nor_drop_segments():
    """Rays at distance p from the centre of one ball, iso-radius r = R/2: inside length 2 sqrt(r^2 - p^2)."""
    R = 2.0
    r = R / 2
    blob = cm.Blob([[0.0, 0.0, 0.0]], [R])
    tol = 1e-9 * blob.diagonal
    for rel in (-1e-3, -1e-6, -1e-9, -1e-12, 0.0, 1e-12, 1e-9, 1e-6):
        p = r * (1 + rel)
        segs = cm.segments(blob, [-5.0, p, 0.0], [1, 0, 0])[0]
        length = float(np.sum(segs[:, 1] - segs[:, 0])) if len(segs) else 0.0
        exact = 2 * np.sqrt(max(r * r - p * p, 0.0))
        # near tangency the length is as sensitive as sqrt: compare with the exact length of this ray
        # a segment whose F - T never exceeds the touch level eps_g = 64 eps (T + sum|c|) is one touch
        # (docs/model_notes.md); F'' = 2 |k'(1/4)| / R^2 along the ray at the tangent point
        eps_g = NOISE * (0.5 + 1.8)
        f2 = 2 * (22 / 9 - 34 / 9 / 4 + 12 / 9 / 16) / R ** 2
        assert abs(length - exact) <= tol + 2 * np.sqrt(2 * eps_g / f2), (rel, length, exact)
        assert len(segs) <= 1


def test_grazing_the_support_changes_nothing():
    """A ray grazing ball B's support (D -> 0) while inside ball A: same roots as without B."""
    a = cm.Blob([[0, 0, 0]], [2.0])
    ab = cm.Blob([[0, 0, 0], [0, 3.0, 0]], [2.0, 1.0])
    for y in (1.0 * (1 - 1e-12), 1.0, 1.0 * (1 + 1e-12), 0.999999):
        o, d = [-5.0, 3.0 - y, 0.0], [1, 0, 0]
        ra, rab = cm.roots(a, o, d)[0], cm.roots(ab, o, d)[0]
        ref = naive.crossings(ab, np.array(o), np.array(d, float))
        assert len(rab) == len(ref)
        np.testing.assert_allclose(rab, ref, atol=1e-9)
        if y >= 1.0:
            np.testing.assert_allclose(rab, ra, atol=1e-12)


def test_ray_starting_inside_and_t_max(rng):
    blob = cm.Blob([[0, 0, 0]], [2.0])
    segs = cm.segments(blob, [0, 0, 0], [0, 0, 1])[0]
    np.testing.assert_allclose(segs, [[0.0, 1.0]], atol=1e-12)
    assert cm.roots(blob, [0, 0, 0], [0, 0, 1])[0] == pytest.approx([1.0])
    # t_max cuts the segment and the optical depth
    tau = cm.optical_depth(blob, [0, 0, -5], [0, 0, 1], t_max=4.5, density="uniform")
    assert tau[0] == pytest.approx(0.5, abs=1e-12)
    assert cm.optical_depth(blob, [0, 0, -5], [0, 0, 1], t_max=3.9)[0] == 0.0


def test_far_from_the_origin(rng):
    blob = random_blob(rng, 8)
    shifted = cm.Blob(blob.centers + 1e6, blob.radii, blob.weights)
    o, d = random_rays(rng, 20)
    ref = cm.optical_depth(blob, o, d)
    got = cm.optical_depth(shifted, o + 1e6, d)
    np.testing.assert_allclose(got, ref, rtol=1e-6, atol=1e-8)  # o + 1e6 itself rounds at 1e-10


def test_negative_ball_removes_an_equal_ball():
    blob = cm.Blob([[0, 0, 0], [0, 0, 0]], [2.0, 2.0], [1.0, -1.0])
    assert cm.roots(blob, [-5, 0.1, 0], [1, 0, 0])[0].size == 0
    assert cm.field(blob, [[0.3, 0.1, 0]])[0] == 0.0


def test_field_matches_naive(rng):
    blob = random_blob(rng, 20, ellipsoids=True, negative=True)
    pts = rng.uniform(-4, 4, (200, 3))
    np.testing.assert_allclose(cm.field(blob, pts), naive.field(blob, pts), rtol=1e-13, atol=1e-14)


def test_many_crossings_on_one_ray_are_all_returned():
    """A row of 40 separate balls: 80 roots, more than the first pass holds."""
    n = 40
    blob = cm.Blob(np.c_[np.arange(n) * 3.0, np.zeros(n), np.zeros(n)], np.ones(n))
    r = cm.roots(blob, [-5, 0, 0], [1, 0, 0])[0]
    assert len(r) == 2 * n
    np.testing.assert_allclose(r[:2], [4.5, 5.5], atol=1e-12)
    assert len(cm.segments(blob, [-5, 0, 0], [1, 0, 0])[0]) == n


@pytest.mark.parametrize("call,match", [
    (lambda b: cm.roots(b, [[0, 0, np.nan]], [[0, 0, 1]]), r"origins\[0\]"),
    (lambda b: cm.roots(b, [[0, 0, 0], [1, 1, 1]], [[0, 0, 1], [0, 0, 0]]), r"directions\[1\]"),
    (lambda b: cm.roots(b, np.zeros((2, 3)), np.ones((3, 3))), "same number of rays"),
    (lambda b: cm.roots(b, np.zeros((2, 2)), np.ones((2, 2))), r"origins: expected shape"),
    (lambda b: cm.optical_depth(b, [0, 0, 0], [0, 0, 1], density="foggy"), "density"),
    (lambda b: cm.optical_depth(b, [0, 0, 0], [0, 0, 1], t_max=-1.0), r"t_max\[0\]"),
    (lambda b: cm.field(b, [[0, 0, np.inf]]), r"points\[0\]"),
])
def test_bad_input_names_the_argument(call, match):
    blob = cm.Blob([[0, 0, 0]], [1.0])
    with pytest.raises(cm.InputError, match=match):
        call(blob)
    assert issubclass(cm.InputError, ValueError)


# --- nishimura and blinn (issue 7, part 3): against brentq / quad on the true field ---------------------

def _true_breakpoints(blob, o, d):
    """t where some ball's u crosses 1 (chord ends) or, for nishimura, 1/9: between consecutive ones the
    true field is smooth."""
    levels = (1.0, 1 / 9) if blob.kernel == "nishimura" else (1.0,)
    ts = []
    for i in range(len(blob)):
        c0, c1, c2 = naive._ball_u_poly(blob, i, o, d, 0.0)
        for level in levels:
            disc = c1 * c1 - 4 * c2 * (c0 - level)
            if disc > 0:
                ts += [(-c1 - np.sqrt(disc)) / (2 * c2), (-c1 + np.sqrt(disc)) / (2 * c2)]
    return sorted(t for t in ts if t > 0)


def reference_trace(blob, o, d, density="field", scale=1.0, samples=400):
    """(crossings, tau) of the true field F = sum q k(u) (naive.falloff), with no Bernstein form: sign
    changes on dense samples between breakpoints refined by brentq; class changes across a breakpoint
    (blinn's jump at u = 1) count as crossings there; tau by scipy quad between breakpoints and crossings."""
    from scipy.integrate import quad
    from scipy.optimize import brentq

    o, d = np.asarray(o, float), np.asarray(d, float) / np.linalg.norm(d)
    T = blob.threshold
    F = lambda t: naive.field(blob, (o + np.atleast_1d(t)[:, None] * d)) - T  # noqa: E731
    rho = {"field": lambda t: F(t)[0] + T, "excess": lambda t: F(t)[0], "uniform": lambda t: 1.0}[density]
    bps = _true_breakpoints(blob, o, d)
    roots, tau, inside = [], 0.0, False
    for ta, tb in zip(bps[:-1], bps[1:]):
        if tb - ta <= 1e-13:
            continue
        nudge = 1e-12 * (tb - ta)
        ts = np.linspace(ta + nudge, tb - nudge, samples)
        g = F(ts)
        cls = g >= 0
        if cls[0] != inside:
            roots.append(ta)
        cuts = [ta]
        for k in np.flatnonzero(cls[1:] != cls[:-1]):
            r = brentq(lambda t: F(t)[0], ts[k], ts[k + 1], xtol=1e-15, rtol=4 * np.finfo(float).eps)
            roots.append(r)
            cuts.append(r)
        cuts.append(tb)
        for x0, x1 in zip(cuts[:-1], cuts[1:]):
            if F(0.5 * (x0 + x1))[0] >= 0:
                tau += quad(rho, x0, x1, epsabs=0, epsrel=1e-13, limit=200)[0]
        inside = bool(cls[-1])
    if inside:
        roots.append(bps[-1])
    return np.array(roots), scale * tau


def piecewise_blob(rng, kernel, b, ellipsoids, negative, threshold, n=10):
    base = random_blob(rng, n, "wyvill6", ellipsoids, negative)
    return cm.Blob(base.centers, base.radii, base.weights, kernel=kernel, threshold=threshold,
                   rotations=base.rotations, blobbiness=b)


PIECEWISE_CASES = [("nishimura", 4.0, False, False, 0.5), ("nishimura", 4.0, True, True, 0.5),
                   ("nishimura", 4.0, False, False, 0.8), ("blinn", 4.0, False, False, 0.5),
                   ("blinn", 4.0, True, True, 0.5), ("blinn", 1.0, True, False, 0.6),
                   ("blinn", 12.0, False, True, 0.1), ("blinn", 4.0, False, False, 0.012)]


@pytest.mark.parametrize("kernel,b,ellipsoids,negative,threshold", PIECEWISE_CASES)
def test_piecewise_kernels_match_brentq_and_quad(rng, kernel, b, ellipsoids, negative, threshold):
    """roots and segments within 1e-9 (absolute) of brentq on the true field, tau within 1e-9 (relative)
    of quad, for all three density modes."""
    blob = piecewise_blob(rng, kernel, b, ellipsoids, negative, threshold)
    o, d = random_rays(rng, 30)
    got_roots, got_segs = cm.roots(blob, o, d), cm.segments(blob, o, d)
    taus = {m: cm.optical_depth(blob, o, d, density=m, scale=1.3) for m in ("field", "excess", "uniform")}
    hits = 0
    for i in range(len(o)):
        ref, ref_tau = reference_trace(blob, o[i], d[i])
        assert len(got_roots[i]) == len(ref), (i, got_roots[i], ref)
        np.testing.assert_allclose(got_roots[i], ref, rtol=0, atol=1e-9)
        np.testing.assert_allclose(got_segs[i].ravel(), ref, rtol=0, atol=1e-9)
        for m in ("field", "excess", "uniform"):
            ref_tau = reference_trace(blob, o[i], d[i], density=m, scale=1.3)[1]
            assert taus[m][i] == pytest.approx(ref_tau, rel=1e-9, abs=1e-13), (i, m)
        hits += len(ref) > 0
    assert hits > 8


@pytest.mark.parametrize("T", [0.05, 0.3, 0.5, 2 / 3 - 1e-6, 2 / 3, 0.7, 0.95])
def test_single_nishimura_ball_isosurface_radius(T):
    """k(u) = T/q: u = (1 - T/q) / 3 where T/q >= 2/3, else sqrt(u) = 1 - sqrt(2 T / (3 q)); on axis
    and off axis (the inside length is 2 sqrt(r^2 - p^2))."""
    R, q = 2.5, 1.2
    k = T / q
    r = R * (np.sqrt((1 - k) / 3) if k >= 2 / 3 else 1 - np.sqrt(2 * k / 3))
    blob = cm.Blob([[1.0, -2.0, 0.5]], [R], [q], kernel="nishimura", threshold=T)
    got = cm.roots(blob, [1.0, -12.0, 0.5], [0, 1, 0])[0]
    np.testing.assert_allclose(got, [10 - r, 10 + r], rtol=0, atol=1e-12)
    for p in (0.3 * r, 0.9 * r, 0.999 * r):
        segs = cm.segments(blob, [-9.0, -2.0 + p, 0.5], [1, 0, 0])[0]
        assert segs.shape == (1, 2)
        np.testing.assert_allclose(segs[0], [10 - np.sqrt(r * r - p * p), 10 + np.sqrt(r * r - p * p)],
                                   rtol=0, atol=1e-9)


def test_single_blinn_ball_isosurface_radius():
    """exp(-b u) = T/q: u = ln(q/T) / b."""
    R, q, b = 2.0, 1.0, 3.0
    for T in (0.1, 0.5, 0.9):
        r = R * np.sqrt(np.log(q / T) / b)
        blob = cm.Blob([[0.0, 0.0, 0.0]], [R], [q], kernel="blinn", threshold=T, blobbiness=b)
        np.testing.assert_allclose(cm.roots(blob, [-8.0, 0.0, 0.0], [1, 0, 0])[0], [8 - r, 8 + r], rtol=0, atol=1e-11)
        segs = cm.segments(blob, [-8.0, 0.4 * r, 0.0], [1, 0, 0])[0]
        np.testing.assert_allclose(segs[0], [8 - 0.9165151389911680 * r, 8 + 0.9165151389911680 * r], atol=1e-9)


def test_blinn_jump_at_the_support():
    """T below q exp(-b): the field jumps from 0 to above T where the ray enters the support, so the
    transitions are the chord ends exactly, and the inside is the whole chord (or the union of chords)."""
    b = 4.0
    T = 0.5 * np.exp(-b)
    blob = cm.Blob([[0.0, 0.0, 0.0]], [2.0], [1.0], kernel="blinn", threshold=T, blobbiness=b)
    for p in (0.0, 1.0, 1.9, 1.999999):
        h = np.sqrt(4.0 - p * p)
        np.testing.assert_allclose(cm.roots(blob, [-6.0, p, 0.0], [1, 0, 0])[0], [6 - h, 6 + h], rtol=0, atol=1e-12)
        tau = cm.optical_depth(blob, [-6.0, p, 0.0], [1, 0, 0], density="uniform")[0]
        assert tau == pytest.approx(2 * h, rel=1e-12)
        # field density: the integral of exp(-b u) over the chord, u = (p^2 + x^2) / R^2
        from scipy.integrate import quad
        ref = quad(lambda x: np.exp(-b * (p * p + x * x) / 4.0), -h, h, epsabs=0, epsrel=1e-13)[0]
        assert cm.optical_depth(blob, [-6.0, p, 0.0], [1, 0, 0])[0] == pytest.approx(ref, rel=1e-11)
    two = cm.Blob([[0.0, 0.0, 0.0], [3.0, 0.0, 0.0]], [2.0, 2.0], [1.0, 1.0], kernel="blinn", threshold=T,
                  blobbiness=b)
    np.testing.assert_allclose(cm.segments(two, [-6.0, 0.0, 0.0], [1, 0, 0])[0], [[4.0, 11.0]], atol=1e-12)
    # just above q exp(-b) on a grazing ray: nothing; on a central ray the crossing is inside the ball
    blob = cm.Blob([[0.0, 0.0, 0.0]], [2.0], [1.0], kernel="blinn", threshold=1.001 * np.exp(-b), blobbiness=b)
    assert cm.roots(blob, [-6.0, 1.9999, 0.0], [1, 0, 0])[0].size == 0  # max F = exp(-b (1 - 1e-4)) < T
    r = 2.0 * np.sqrt(-np.log(1.001 * np.exp(-b)) / b)
    np.testing.assert_allclose(cm.roots(blob, [-6.0, 0.0, 0.0], [1, 0, 0])[0], [6 - r, 6 + r], atol=1e-10)


@pytest.mark.parametrize("kernel", ["nishimura", "blinn"])
def test_piecewise_kernels_render(tmp_path, kernel):
    """A tiny scene renders with each kernel: finite, the cloud in front of the background, the centre
    pixel's transmittance exp(-tau) with tau from cm.optical_depth."""
    import textwrap
    extra = "blobbiness: 3.0" if kernel == "blinn" else ""
    path = tmp_path / f"{kernel}.yaml"
    path.write_text(textwrap.dedent(f"""
        image: {{width: 9, height: 9}}
        camera: {{position: [0, -8, 0], look_at: [0, 0, 0], up: [0, 0, 1], fov: 30}}
        background: [1, 1, 1]
        lights: [{{type: directional, direction: [0.3, -1, 0.4], irradiance: 2.0}}]
        render: {{quality: draft}}
        media:
          - kernel: {kernel}
            {extra}
            threshold: 0.3
            density: {{mode: field, scale: 1.5}}
            albedo: 0.0
            phase: {{type: isotropic}}
            balls: [{{center: [0, 0, 0], radius: 2.0}}, {{center: [0.8, 0.3, 0.2], radius: 1.2, weight: 0.7}}]
        """))
    scene = cm.load_scene(path)
    img = cm.render(scene, progress=False)
    assert img.shape == (9, 9, 4) and np.all(np.isfinite(img))
    blob = scene.media[0].blob
    tau = cm.optical_depth(blob, [0, -8, 0], [0, 1, 0], density="field", scale=1.5)[0]
    assert tau > 0.1
    np.testing.assert_allclose(img[4, 4, :3], np.exp(-tau), rtol=1e-5)  # albedo 0: transmittance only
    assert img[0, 0, 3] == 0.0 and img[4, 4, 3] == pytest.approx(1 - np.exp(-tau), rel=1e-5)


# --- issue #15: wrong types are InputErrors; directions of any magnitude ----------------------------------

@pytest.mark.parametrize("call, match", [
    (lambda b: cm.optical_depth(b, [0, 0, -5], [0, 0, 1], scale="2"), "scale"),
    (lambda b: cm.optical_depth(b, [0, 0, -5], [0, 0, 1], scale=True), "scale"),
    (lambda b: cm.optical_depth(b, [0, 0, -5], [0, 0, 1], density=["field"]), "density"),
    (lambda b: cm.roots(b, [[0, 0, -5], [0, 0]], [0, 0, 1]), "origins: expected an array of numbers, got a ragged"),
    (lambda b: cm.roots(b, [0, 0, -5], [0, 0, 1], t_max="far"), "t_max"),
    (lambda b: cm.roots(b, [0, 0, -5], [0, 0, 1], tolerance="tight"), "tolerance"),
    (lambda b: cm.roots(b, [0, 0, -1e300], [0, 0, 1]), r"origins\[0\]: expected coordinates within"),
    (lambda b: cm.field(b, "abc"), "points"),
    (lambda b: cm.field(None, [0, 0, 0]), "blob"),
])
def test_wrong_types_are_input_errors(call, match):
    with pytest.raises(cm.InputError, match=match):
        call(cm.Blob([[0, 0, 0]], [2.0]))


@pytest.mark.parametrize("scale", [1e200, 1e-160, 5e-324, 1.7e308])
def test_directions_of_any_magnitude_give_the_roots_of_the_unit_direction(scale):
    blob = cm.Blob([[0, 0, 0]], [2.0])
    want = cm.roots(blob, [0.1, 0, -5], [0, 0, 1])[0]
    got = cm.roots(blob, [0.1, 0, -5], [0, 0, scale])[0]
    assert len(want) == 2
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(cm.optical_depth(blob, [0.1, 0, -5], [0, 0, scale]),
                                  cm.optical_depth(blob, [0.1, 0, -5], [0, 0, 1]))


def test_no_rays_broadcast_to_no_results():
    """One origin with no directions (or none with one) is no rays, as numpy broadcasts (1, 3) with (0, 3):
    empty results, not numpy's broadcast ValueError (issue #27)."""
    blob = cm.Blob([[0, 0, 0]], [1.0])
    for o, d in (([[0, 0, -5]], np.zeros((0, 3))), (np.zeros((0, 3)), [0, 0, 1]), (np.zeros((0, 3)), np.zeros((0, 3)))):
        assert cm.roots(blob, o, d) == [] and cm.segments(blob, o, d) == []
        assert cm.optical_depth(blob, o, d).shape == (0,) and cm.first_hit(blob, o, d).shape == (0,)
    with pytest.raises(cm.InputError, match="t_max"):
        cm.roots(blob, [[0, 0, -5]], np.zeros((0, 3)), t_max=[1.0])
    with pytest.raises(cm.InputError, match="same number of rays"):
        cm.roots(blob, np.zeros((2, 3)), np.zeros((0, 3)))
