"""The stages of the single-scattering estimator (cloudmeta.kernels.radiance) on their own: elementary
intervals against the naive sum of the pieces, the product-integration weights against a fine quadrature,
the depth inversion, the camera ray, and the whole estimator on a closed form."""
import math
import textwrap

import numpy as np
import pytest

from cloudmeta.renderer import pack
from cloudmeta.kernels import single as kr
from cloudmeta.kernels.lighting import N_COUNTS
from cloudmeta.kernels.media import alloc_ray_pieces
from cloudmeta.kernels.records import Camera
from cloudmeta.renderer.quality import Quality
from cloudmeta.scene import load_scene
from tests import naive

QUALITY = Quality(tolerance=1e-3, max_tau=1.0, max_length=0.5, max_angle=0.1, cutoff=1e-4, tol_t=1e-9)


def test_elementary_intervals_add_the_media(rng):
    """Three pieces of two media, overlapping: per interval sigma_t of each medium and of all, and the
    optical depth from the ray's start, against the naive evaluation and integral of the pieces."""
    pieces = [(0.0, 2.0, 0), (1.0, 3.0, 1), (2.5, 4.0, 0)]
    rp = alloc_ray_pieces(8, 2)
    coeffs = rng.uniform(0.1, 2.0, (3, 7))
    for k, (t0, t1, m) in enumerate(pieces):
        rp.t0[k], rp.t1[k], rp.medium[k] = t0, t1, m
        rp.c[k] = coeffs[k]

    def sigma(t, medium=None):
        return sum(naive.bernstein_eval(coeffs[k], (t - t0) / (t1 - t0)) for k, (t0, t1, m) in enumerate(pieces)
                   if t0 <= t <= t1 and medium in (None, m))

    n_el = kr.elementary_intervals(3, rp)
    np.testing.assert_array_equal(rp.el_t0[:n_el], [0.0, 1.0, 2.0, 2.5, 3.0])
    np.testing.assert_array_equal(rp.el_t1[:n_el], [1.0, 2.0, 2.5, 3.0, 4.0])
    x, w = np.polynomial.legendre.leggauss(8)
    depth = 0.0
    for k in range(n_el):
        a, b = rp.el_t0[k], rp.el_t1[k]
        assert rp.el_u0[k] == pytest.approx(depth, rel=1e-13, abs=1e-15)
        for s in (0.2, 0.7):
            t = a + s * (b - a)
            assert naive.bernstein_eval(rp.el_S[k], s) == pytest.approx(sigma(t), rel=1e-13)
            for m in range(2):
                assert naive.bernstein_eval(rp.el_sig[k, m], s) == pytest.approx(sigma(t, m), rel=1e-13, abs=1e-15)
        depth += 0.5 * (b - a) * sum(wi * sigma(a + 0.5 * (b - a) * (xi + 1)) for xi, wi in zip(x, w))
    assert rp.el_u0[n_el] == pytest.approx(depth, rel=1e-13)


@pytest.mark.parametrize("h", [1e-3, 0.5, 4.0, 15.0])
def test_exp_weights_integrate_exp_times_the_lagrange_basis(h):
    quad = pack.quadrature(QUALITY)
    for x, lag in ((quad.gauss_x, quad.gauss_lag), (quad.kronrod_x, quad.kronrod_lag)):
        out = np.empty(16)
        kr._exp_weights(h, lag, quad.fine_y, quad.fine_w, out)
        np.testing.assert_allclose(out[:len(x)], naive.exp_weights(h, x), rtol=1e-10, atol=1e-14 * h)


def test_depth_to_s_inverts_the_exact_cumulative(rng):
    S = rng.uniform(0.2, 3.0, 7)
    w = 1.7
    total = w * S.mean()
    s_prev, u_prev = 0.0, 0.0
    for u in np.linspace(0.05, 0.95, 7) * total:  # increasing, as the nodes come
        s = kr._depth_to_s(S, w, u, s_prev, u_prev)
        x, wt = np.polynomial.legendre.leggauss(12)
        cum = w * 0.5 * s * sum(wi * naive.bernstein_eval(S, 0.5 * s * (xi + 1)) for xi, wi in zip(x, wt))
        assert cum == pytest.approx(u, rel=1e-12)
        s_prev, u_prev = s, u


def test_camera_ray_through_the_centre_looks_forward():
    camera = Camera(np.zeros(3), np.array([0.0, 1.0, 0.0]), np.array([0.5, 0.0, 0.0]), np.array([0.0, 0.0, 0.25]),
                         5, 3, 1, 0)
    d = np.empty(3)
    kr.camera_ray(camera, 1, 2, 0, 1, d)
    np.testing.assert_allclose(d, [0.0, 1.0, 0.0], atol=1e-16)
    kr.camera_ray(camera, 0, 4, 0, 1, d)  # top right pixel: right and up, normalised
    x, y = 2.0 * 4.5 / 5 - 1.0, 1.0 - 2.0 * 0.5 / 3
    ref = np.array([0.5 * x, 1.0, 0.25 * y])
    np.testing.assert_allclose(d, ref / np.linalg.norm(ref), rtol=1e-15)


def test_single_scattering_of_an_absorbing_ball(tmp_path):
    """The estimator alone on a closed form: a uniform ball (sigma_t 0.8, inside radius 1) that only
    absorbs, in front of a white background: L = T = exp(-0.8 * 2) through its centre, t_hit = inf."""
    path = tmp_path / "s.yaml"
    path.write_text(textwrap.dedent("""
        image: {width: 1, height: 1}
        camera: {position: [0, -6, 0], look_at: [0, 0, 0], up: [0, 0, 1], fov: 1}
        background: [1, 1, 1]
        lights: [{type: directional, direction: [0, -1, 0], irradiance: 2}]
        media:
          - {kernel: wyvill6, threshold: 0.5, density: {mode: uniform, scale: 0.8}, albedo: 0.0,
             balls: [{center: [0, 0, 0], radius: 2.0}]}
        """))
    scene = load_scene(path)
    radiance, alpha, t_hit, _ = axis_ray(scene, QUALITY)
    t = math.exp(-0.8 * 2.0)
    np.testing.assert_allclose([*radiance, 1.0 - alpha], [t, t, t, t], rtol=1e-12)
    assert t_hit == np.inf


def axis_ray(scene, quality):
    """(radiance, alpha, t_hit, counters) of the single-scattering estimator on the ray from (0, -6, 0) along
    +y at ``quality``: the scene's one pixel, whose centre ray is the camera's axis, through the image kernel
    that every render of a media-only scene compiles (a kernel entry of its own would compile the estimator
    once more)."""
    quad = pack.quadrature(quality)
    records = pack.scene_records(scene, quad, 16)
    camera = pack.pack_camera(scene, 0)
    image, depth, counts = np.zeros((1, 1, 4)), np.full((1, 1), np.inf), np.zeros((1, 1, N_COUNTS))
    kr.render_pixels(camera, records, quad, np.int64(0), np.int64(0), np.int64(1), image, depth, counts)
    return image[0, 0, :3].copy(), image[0, 0, 3], depth[0, 0], counts[0, 0]


def axis_ray_radiance(scene, quality):
    """(radiance, counters) of ``axis_ray``."""
    radiance, _, _, count = axis_ray(scene, quality)
    return radiance, count


def test_steps_grow_with_the_view_depth(tmp_path):
    """Quality.growth g: the step limits at view depth u are max_tau and max_length times e^(g u), since a
    step's error reaches the image through e^-u. On a thick uniform ball lit from the side (J follows the
    shadow depth along the ray), g = 1 takes fewer nodes than equal steps, and both agree with a converged
    quadrature within the tolerance."""
    path = tmp_path / "s.yaml"
    path.write_text(textwrap.dedent("""
        image: {width: 1, height: 1}
        camera: {position: [0, -6, 0], look_at: [0, 0, 0], up: [0, 0, 1], fov: 1}
        lights: [{type: directional, direction: [1, 0.3, 0.2], irradiance: 2}]
        media:
          - {kernel: wyvill6, threshold: 0.5, density: {mode: uniform, scale: 5.0}, albedo: 0.9,
             balls: [{center: [0, 0, 0.3], radius: 2.0}]}
        """))
    scene = load_scene(path)
    converged, _ = axis_ray_radiance(scene, Quality(tolerance=1e-9, max_tau=0.02, max_length=10.0, max_angle=0.1,
                                                    cutoff=0.0, tol_t=1e-9))
    coarse = dict(tolerance=1e-3, max_tau=0.5, max_length=10.0, max_angle=0.1, cutoff=1e-4, tol_t=1e-9)
    equal, count = axis_ray_radiance(scene, Quality(**coarse))
    grown, count_grown = axis_ray_radiance(scene, Quality(**coarse, growth=1.0))
    n_equal, n_grown = count[kr.COUNT_NODES], count_grown[kr.COUNT_NODES]
    assert converged[0] > 0.0
    np.testing.assert_allclose(equal, converged, rtol=1e-3)
    np.testing.assert_allclose(grown, converged, rtol=1e-3)
    assert n_grown < 0.7 * n_equal


def test_steps_split_around_the_folds_of_the_light(tmp_path):
    """A ball between the light and a ray's segment: the shadow rays from the nodes enter it, or not, and the
    light's optical depth along the ray has a fold at each edge of its shadow. Steps whose rules disagree are cut
    around the first fold their nodes bracket (their shadow rays' entries differ), and the radiance agrees with
    a converged quadrature within the tolerance."""
    path = tmp_path / "s.yaml"
    path.write_text(textwrap.dedent("""
        image: {width: 1, height: 1}
        camera: {position: [0, -6, 0], look_at: [0, 0, 0], up: [0, 0, 1], fov: 1}
        lights: [{type: directional, direction: [1, 0, 0], irradiance: 2}]
        media:
          - {kernel: wyvill6, threshold: 0.5, density: {mode: uniform, scale: 3.0}, albedo: 0.9,
             balls: [{center: [0, 0, 0], radius: 2.0}, {center: [3.2, 0.3, 0], radius: 1.0}]}
        """))
    scene = load_scene(path)
    converged, _ = axis_ray_radiance(scene, Quality(tolerance=1e-10, max_tau=0.005, max_length=10.0, max_angle=0.1,
                                                    cutoff=0.0, tol_t=1e-9))
    got, count = axis_ray_radiance(scene, Quality(tolerance=1e-4, max_tau=4.0, max_length=10.0, max_angle=0.1,
                                                  cutoff=1e-6, tol_t=1e-9))
    assert count[kr.COUNT_FOLDS] >= 1 and count[kr.COUNT_SPLITS] >= count[kr.COUNT_FOLDS]
    np.testing.assert_allclose(got, converged, rtol=1e-3)


def test_fold_bracket_and_the_parts_around_it():
    """fold_bracket: the first neighbours whose known entries differ; push_fold_parts: the three parts tile the
    part, the first in u on top, and each is as many halvings deep as its share of the width says."""
    assert kr.fold_bracket(np.array([1.0, 1.0, 2.0, 2.0, 1.0]), np.int64(5)) == 1
    assert kr.fold_bracket(np.array([1.0, -1.0, 2.0, 3.0]), np.int64(4)) == 2  # -1: unknown
    assert kr.fold_bracket(np.array([1.0, 1.0, 1.0]), np.int64(3)) == -1
    u, h, depth = np.zeros(8), np.zeros(8), np.zeros(8)
    top = kr.push_fold_parts(u, h, depth, np.int64(0), 2.0, 0.5, 1.0, 0.25, 0.375)
    assert top == 3
    np.testing.assert_allclose(u[1:4], [2.0 + 0.1875, 2.125, 2.0])
    np.testing.assert_allclose(h[1:4], [0.3125, 0.0625, 0.125])
    np.testing.assert_allclose(depth[1:4], [1.0 - math.log2(0.625), 4.0, 3.0])


def test_tail_share_counts_the_whole_tail_across_a_fold():
    """tail_share: a tenth of the Legendre tail where the Gauss nodes' shadow rays all enter the media alike (or
    are unknown), the whole tail where two neighbours among them differ; nodes between them (the Kronrod
    columns) are not looked at."""
    cols = np.array([1, 3, 5, 7, 9, 11, 13], dtype=np.int64)
    n = np.int64(7)
    topo = np.full(15, 2.0)
    assert kr.tail_share(topo, cols, n) == kr.TAIL_SHARE
    topo[0] = topo[14] = 3.0  # a change outside the Gauss columns
    assert kr.tail_share(topo, cols, n) == kr.TAIL_SHARE
    topo[9] = -1.0  # a map lookup: unknown, no fold seen
    assert kr.tail_share(topo, cols, n) == kr.TAIL_SHARE
    topo[11] = topo[13] = 3.0  # the change from 2 hides behind the unknown node: no known pair differs
    assert kr.tail_share(topo, cols, n) == kr.TAIL_SHARE
    topo[13] = 4.0  # nodes 11 and 13 differ: a fold between them
    assert kr.tail_share(topo, cols, n) == 1.0
