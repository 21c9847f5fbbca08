"""Opaque metaball surfaces (docs/model.md §6) and CSG through negative weights (issue 7): the first hit and the
normal through the API, and rendered surfaces against closed forms and an independent isosurface render."""
import math

import numba
import numpy as np
import pytest
import yaml

import cloudmeta as cm
from cloudmeta.renderer import render
from cloudmeta.scene import load_scene
from tests import naive
from tests.conftest import random_blob, random_rays

KERNELS = ("wyvill6", "murakami4", "nishimura", "blinn")
AXIS_CAMERA = {"position": [0.0, -6.0, 0.0], "look_at": [0.0, 0.0, 0.0], "up": [0.0, 0.0, 1.0], "fov": 1.0}


# ------------------------------------------------------------------------------------------- helpers

def iso_radius_murakami4(R, T, q=1.0):
    """q (1 - u)^2 = T at u = 1 - sqrt(T / q): the isosurface of one ball is a sphere of radius R sqrt(u)."""
    return R * math.sqrt(1.0 - math.sqrt(T / q))


def sphere_surface(r, center=(0.0, 0.0, 0.0), T=0.25, color=(0.8, 0.6, 0.5), name=None):
    """A surface whose isosurface is the sphere of radius r: one murakami4 ball."""
    R = r / math.sqrt(1.0 - math.sqrt(T))
    s = {"kernel": "murakami4", "threshold": T, "color": list(color),
         "balls": [{"center": [float(c) for c in center], "radius": R}]}
    if name:
        s["name"] = name
    return s


def uniform_medium(r, sigma, center=(0.0, 0.0, 0.0), albedo=1.0, name=None):
    """A medium of uniform sigma_t inside the sphere of radius r: a wyvill6 ball of radius 2r at T = 0.5."""
    m = {"kernel": "wyvill6", "threshold": 0.5, "density": {"mode": "uniform", "scale": sigma}, "albedo": albedo,
         "phase": {"type": "isotropic"}, "balls": [{"center": [float(c) for c in center], "radius": 2.0 * r}]}
    if name:
        m["name"] = name
    return m


def make_scene(tmp_path, surfaces=(), media=(), lights=(), camera=None, size=1, background=(0, 0, 0),
               ambient=None, render_settings=None, name="s.yaml", spp=1):
    data = {"image": {"width": size, "height": size, "spp": spp}, "camera": camera or AXIS_CAMERA,
            "background": [float(c) for c in background], "lights": list(lights),
            "render": render_settings or {"quality": "reference"}}
    if ambient is not None:
        data["ambient"] = [float(c) for c in ambient]
    if surfaces:
        data["surfaces"] = list(surfaces)
    if media:
        data["media"] = list(media)
    path = tmp_path / name
    path.write_text(yaml.safe_dump(_plain(data)))
    return load_scene(path)


def _plain(value):
    """numpy numbers and arrays as the Python floats and lists that YAML writes."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def directional(direction, irradiance):
    return {"type": "directional", "direction": [float(c) for c in direction], "irradiance": float(irradiance)}


def pixel_rays(camera, width, height):
    """The pixel-centre rays of a pinhole camera (docs/model.md §8), written out independently of the renderer:
    (origins, unit directions), row-major from the top row."""
    pos, look, up = (np.array(camera[k], float) for k in ("position", "look_at", "up"))
    fwd = (look - pos) / np.linalg.norm(look - pos)
    right = np.cross(fwd, up)
    right /= np.linalg.norm(right)
    true_up = np.cross(right, fwd)
    half = math.tan(math.radians(camera["fov"]) / 2)
    j, i = np.meshgrid(np.arange(width), np.arange(height))
    x = (2.0 * (j + 0.5) / width - 1.0) * half * width / height
    y = (1.0 - 2.0 * (i + 0.5) / height) * half
    d = fwd + x.reshape(-1, 1) * right + y.reshape(-1, 1) * true_up
    return np.broadcast_to(pos, d.shape).copy(), d / np.linalg.norm(d, axis=1)[:, None]


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


def _surfaces_record(blobs):
    from types import SimpleNamespace

    from cloudmeta.renderer.pack import pack_surfaces
    return pack_surfaces([SimpleNamespace(blob=b, color=(0.5, 0.5, 0.5)) for b in blobs])


def _full_sweep_hit(o, d, tmax, surf, tol_t, stop_at_first):
    """The surfaces' first hit (or, with stop_at_first, whether any surface is hit) by the full sweep
    (sweep.first_entry), each surface traced up to the nearest hit so far: the twin of
    surfaces.first_surface_hit and surfaces_block before the incremental sweep."""
    from cloudmeta.kernels import sweep as ks
    from cloudmeta.kernels.records import BlobRecord
    t_hit, s_hit = np.inf, -1
    for s in range(len(surf.start) - 1):
        lo, hi = surf.start[s], surf.start[s + 1]
        rec = BlobRecord(surf.centers, surf.frames, surf.weights, surf.kernel[s], surf.blobbiness[s],
                         surf.threshold[s])
        cand = np.arange(lo, hi)
        _, t = ks.first_entry(o, d, 0.0, min(t_hit, tmax), rec, tol_t, cand, hi - lo, ks.alloc_scratch(4))
        if t < t_hit:
            t_hit, s_hit = t, s
            if stop_at_first or t_hit == 0.0:
                break
    return t_hit, s_hit


def test_first_surface_hit_and_shadow_rays_match_the_full_sweep(rng):
    """surfaces.first_surface_hit and surfaces_block (the incremental sweep, each surface up to the nearest
    hit so far) give the full sweep's answers bit for bit: three surfaces of different kernels, camera rays
    from outside and from inside the surfaces, shadow rays with t_max cut-offs."""
    from cloudmeta.kernels import surfaces as ksurf
    from cloudmeta.kernels import sweep as ks
    blobs = [random_blob(rng, 15, k, ellipsoids=True, negative=True) for k in ("blinn", "murakami4", "nishimura")]
    blobs.append(random_blob(rng, 15, "wyvill6", negative=True, box=1.5))
    surf = _surfaces_record(blobs)
    o, d = random_rays(rng, 150)
    o = np.concatenate([o, surf.centers[:40]])  # from inside balls, often inside a surface
    d = np.concatenate([d, d[:40]])
    cand = np.empty(len(surf.weights), np.int64)
    stack = np.empty(256, np.int64)
    tol_t = 1e-9
    kinds = dict(hit=0, inside=0, blocked=0, free=0)
    for i in range(len(o)):
        _, t, s = ksurf.first_surface_hit(o[i], d[i], surf, tol_t, ks.alloc_scratch(4), cand, stack)
        ref_t, ref_s = _full_sweep_hit(o[i], d[i], np.inf, surf, tol_t, False)
        assert (t, s) == (ref_t, ref_s), i
        kinds["hit"] += t < np.inf
        kinds["inside"] += t == 0.0
        for tmax in (0.5 * t if t < np.inf else 5.0, t + 1.0 if t < np.inf else 30.0):
            _, blocked = ksurf.surfaces_block(o[i], d[i], tmax, surf, tol_t, ks.alloc_scratch(4), cand, stack)
            ref_blocked = _full_sweep_hit(o[i], d[i], tmax, surf, tol_t, True)[0] < np.inf
            assert blocked == ref_blocked, (i, tmax)
            kinds["blocked" if blocked else "free"] += 1
    assert kinds["hit"] > 40 and kinds["inside"] > 5 and kinds["blocked"] > 40 and kinds["free"] > 40, kinds


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


def test_a_negative_twin_renders_as_background(tmp_path):
    twins = [{"center": [0.0, 0.0, 0.0], "radius": 2.0, "weight": 1.0},
             {"center": [0.0, 0.0, 0.0], "radius": 2.0, "weight": -1.0}]
    s = make_scene(tmp_path, surfaces=[{"kernel": "murakami4", "threshold": 0.25, "balls": twins}],
                   media=[{"threshold": 0.5, "density": {"mode": "uniform", "scale": 1.0}, "balls": twins}],
                   lights=[directional([0, -1, 1], 3.0)], ambient=[0.2, 0.2, 0.2], background=[0.1, 0.2, 0.3],
                   size=6, camera=dict(AXIS_CAMERA, fov=40.0), render_settings={"quality": "draft"})
    img, depth = render(s, progress=False, depth=True)
    np.testing.assert_array_equal(img[..., :3], np.broadcast_to(np.float32([0.1, 0.2, 0.3]), (6, 6, 3)))
    assert np.all(img[..., 3] == 0) and np.all(depth == np.inf)


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


# ------------------------------------------------------------------------------------------- rendering

def test_lit_sphere_lambertian_and_depth_in_every_pixel(tmp_path):
    """One directional light and ambient: at a hit x on the sphere n = (x - c) / r, so every pixel's
    radiance is colour (E max(0, n.l) / pi + L_amb), and its depth is the exact ray-sphere entry."""
    r, E, T = 1.0, 2.5, 0.3
    colour, ambient, background = np.array([0.8, 0.6, 0.5]), np.array([0.05, 0.1, 0.2]), np.array([0.3, 0.4, 0.5])
    light = np.array([0.3, -0.8, 0.5]) / np.linalg.norm([0.3, -0.8, 0.5])
    camera = dict(AXIS_CAMERA, fov=25.0)
    size = 17
    s = make_scene(tmp_path, surfaces=[sphere_surface(r, T=T, color=colour)], lights=[directional(light, E)],
                   ambient=ambient, background=background, camera=camera, size=size)
    img, depth = render(s, progress=False, depth=True)
    o, d = pixel_rays(camera, size, size)
    t, disc = sphere_entry(o, d, np.zeros(3), r)
    hit = disc > 0
    assert 50 < np.count_nonzero(hit) < size * size
    clear = np.abs(disc) > 1e-6
    n = o + np.where(hit, t, 0.0)[:, None] * d
    expected = colour * (E * np.maximum(0.0, n @ light)[:, None] / math.pi + ambient)
    img, depth = img.reshape(-1, 4), depth.ravel()
    np.testing.assert_allclose(depth[hit & clear], t[hit & clear], rtol=1e-9)
    np.testing.assert_allclose(img[hit & clear, :3], expected[hit & clear], rtol=1e-6)
    assert np.all(img[hit & clear, 3] == 1.0)
    np.testing.assert_array_equal(img[~hit & clear, :3], np.broadcast_to(background.astype(np.float32), (np.count_nonzero(~hit & clear), 3)))
    assert np.all(img[~hit & clear, 3] == 0.0) and np.all(depth[~hit & clear] == np.inf)
    # the centre pixel: n = (0, -1, 0)
    centre = img.reshape(size, size, 4)[size // 2, size // 2, :3]
    np.testing.assert_allclose(centre, colour * (E * 0.8 / np.linalg.norm([0.3, -0.8, 0.5]) / math.pi + ambient),
                               rtol=1e-6)


def test_surface_in_fog(tmp_path):
    """A sphere (radius 1) inside a uniform fog ball (radius 2), light from behind the camera, ambient: the
    fog is seen over L = 1 before the surface only. In-scattering w E / (8 pi) (1 - e^-2 sigma L) (each
    point lit through e^-sigma x and seen through e^-sigma x), plus w L_amb (1 - e^-sigma L); the surface
    lit by E e^-sigma L (n.l = 1), seen through e^-sigma L."""
    sigma, w, E, amb = 0.7, 0.8, 2.0, 0.3
    colour = np.array([0.8, 0.6, 0.5])
    s = make_scene(tmp_path, surfaces=[sphere_surface(1.0, color=colour)], media=[uniform_medium(2.0, sigma, albedo=w)],
                   lights=[directional([0, -1, 0], E)], ambient=[amb] * 3, background=[5, 5, 5])
    img = render(s, progress=False)
    L = 1.0
    fog = w * E / (8 * math.pi) * (1 - math.exp(-2 * sigma * L)) + w * amb * (1 - math.exp(-sigma * L))
    surface = colour * (E * math.exp(-sigma * L) / math.pi + amb) * math.exp(-sigma * L)
    np.testing.assert_allclose(img[0, 0, :3], fog + surface, rtol=1e-6)
    assert img[0, 0, 3] == 1.0


def test_surface_behind_a_fog_slab_and_media_behind_it(tmp_path):
    """Fog in front (a uniform ball seen through its diameter) and a second medium behind the surface,
    lit from behind it: the front fog's closed form (tests/renderer/test_render.py) plus the surface seen through
    e^-2 sigma R; the medium behind contributes nothing, to rounding."""
    sigma, E = 0.8, 2.5
    colour = np.array([0.7, 0.7, 0.7])
    front = uniform_medium(1.0, sigma, center=(0, -3.5, 0), name="front")
    behind = uniform_medium(1.0, 2.0, center=(0, 3, 0), name="behind")
    lights = [directional([0, -1, 0], E), directional([0, 1, 0], 7.0)]
    s = make_scene(tmp_path, surfaces=[sphere_surface(1.0, color=colour)], media=[front, behind], lights=lights)
    img = render(s, progress=False)
    fog = E / (8 * math.pi) * (1 - math.exp(-4 * sigma))
    surface = colour * E * math.exp(-2 * sigma) / math.pi * math.exp(-2 * sigma)
    np.testing.assert_allclose(img[0, 0, :3], fog + surface, rtol=1e-6)
    s2 = make_scene(tmp_path, surfaces=[sphere_surface(1.0, color=colour)], media=[front], lights=lights,
                    name="s2.yaml")
    np.testing.assert_allclose(img, render(s2, progress=False), rtol=1e-12)


def test_surface_shadowed_by_a_medium(tmp_path):
    """The shadow ray from the sphere's front point (n.l = 1/sqrt 2) crosses a uniform ball of radius 0.5
    through its centre: T_l = e^-2 sigma 0.5. The camera ray passes that ball outside its support."""
    sigma, E = 1.3, 3.0
    colour = np.array([0.9, 0.5, 0.2])
    l = np.array([0.0, -1.0, 1.0]) / math.sqrt(2)
    blocker = uniform_medium(0.5, sigma, center=np.array([0, -1.0, 0]) + 3 * l, albedo=0.0)
    s = make_scene(tmp_path, surfaces=[sphere_surface(1.0, color=colour)], media=[blocker],
                   lights=[directional(l, E)], background=[1, 1, 1])
    img = render(s, progress=False)
    np.testing.assert_allclose(img[0, 0, :3], colour * E / math.sqrt(2) / math.pi * math.exp(-sigma), rtol=1e-6)


@pytest.mark.parametrize("shadows", ["exact", "map"])
def test_surfaces_cast_shadows_on_surfaces_and_media(tmp_path, shadows):
    """A sphere in the shadow of another sphere gets only its ambient term; a uniform ball in the shadow of
    a sphere scatters nothing, so its pixel is the background through e^-2 sigma. With shadows: map the
    maps hold media only and surfaces are tested by exact shadow rays: the same values."""
    colour, amb, E, sigma = np.array([0.8, 0.6, 0.5]), np.array([0.1, 0.2, 0.3]), 3.0, 0.6
    l = np.array([0.0, -1.0, 1.0]) / math.sqrt(2)
    occluder = sphere_surface(0.5, center=np.array([0, -1.0, 0]) + 3 * l, name="occluder")
    settings = {"quality": "reference", "shadows": shadows}
    s = make_scene(tmp_path, surfaces=[sphere_surface(1.0, color=colour, name="lit"), occluder],
                   media=[uniform_medium(0.5, sigma, center=(5, 0, 5))], lights=[directional(l, E)],
                   ambient=amb, render_settings=settings)
    np.testing.assert_allclose(render(s, progress=False)[0, 0, :3], colour * amb, rtol=1e-6)
    # the medium under a sphere, lit from straight above; the camera ray misses the sphere's support
    up = [0.0, 0.0, 1.0]
    media = [uniform_medium(1.0, sigma, albedo=1.0)]
    for with_occluder in (True, False):
        surfaces = [sphere_surface(1.5, center=(0, 0, 3))] if with_occluder else [sphere_surface(0.2, center=(9, 9, 9))]
        s = make_scene(tmp_path, surfaces=surfaces, media=media, lights=[directional(up, E)], background=[0.5] * 3,
                       render_settings=settings, name=f"m{with_occluder}.yaml")
        value = render(s, progress=False)[0, 0, :3]
        if with_occluder:
            np.testing.assert_allclose(value, 0.5 * math.exp(-2 * sigma), rtol=1e-6)
        else:
            assert np.all(value > 0.5 * math.exp(-2 * sigma) + 0.01)


def test_camera_inside_a_hollow_shell_sees_the_inner_wall(tmp_path):
    """The shell of test_a_negative_ball_carves_a_hollow_shell, seen from its centre with a point light
    there: depth r_in, n . l = 1, E = I / r_in^2 (Lambertian: colour I / (pi r_in^2))."""
    I = 2.0
    colour = np.array([0.6, 0.7, 0.8])
    balls = [{"center": [0.0, 0.0, 0.0], "radius": 2.0, "weight": 1.0},
             {"center": [0.0, 0.0, 0.0], "radius": 1.0, "weight": -1.0}]
    camera = {"position": [0.0, 0.0, 0.0], "look_at": [0.3, 1.0, 0.2], "up": [0.0, 0.0, 1.0], "fov": 60.0}
    s = make_scene(tmp_path, surfaces=[{"kernel": "murakami4", "threshold": SHELL_T, "color": colour.tolist(),
                                         "balls": balls}],
                   lights=[{"type": "point", "position": [0.0, 0.0, 0.0], "intensity": I}], camera=camera, size=5)
    img, depth = render(s, progress=False, depth=True)
    np.testing.assert_allclose(depth, SHELL_R_IN, rtol=1e-9)
    np.testing.assert_allclose(img[..., :3], np.broadcast_to(colour * I / (math.pi * SHELL_R_IN ** 2), (5, 5, 3)),
                               rtol=1e-6)
    assert np.all(img[..., 3] == 1.0)


def test_a_carved_medium_is_seen_through_its_hole(tmp_path):
    """The hollow shell as a uniform medium: the view ray through the centre crosses 2 (r_out - r_in) of it."""
    sigma = 0.9
    balls = [{"center": [0.0, 0.0, 0.0], "radius": 2.0, "weight": 1.0},
             {"center": [0.0, 0.0, 0.0], "radius": 1.0, "weight": -1.0}]
    s = make_scene(tmp_path, media=[{"kernel": "murakami4", "threshold": SHELL_T, "balls": balls, "albedo": 0.0,
                                     "density": {"mode": "uniform", "scale": sigma}}], background=[1, 1, 1])
    expected = math.exp(-2 * sigma * (SHELL_R_OUT - SHELL_R_IN))
    img = render(s, progress=False)
    np.testing.assert_allclose(img[0, 0], [expected] * 3 + [1 - expected], rtol=1e-6)


def test_camera_inside_a_surface(tmp_path):
    """Depth 0, alpha 1, no media; the lights are shut out (the shadow ray starts inside), ambient remains."""
    colour, amb = np.array([0.8, 0.6, 0.5]), np.array([0.1, 0.2, 0.3])
    s = make_scene(tmp_path, surfaces=[sphere_surface(1.0, center=(0.2, -6, 0.1), color=colour)],
                   media=[uniform_medium(1.0, 2.0)], lights=[directional([0, -1, 0], 3.0)], ambient=amb,
                   background=[1, 1, 1], size=3)
    img, depth = render(s, progress=False, depth=True)
    assert np.all(depth == 0.0) and np.all(img[..., 3] == 1.0)
    np.testing.assert_allclose(img[..., :3], np.broadcast_to(colour * amb, (3, 3, 3)), rtol=1e-6)


def random_surface_dict(rng, kernel, n, threshold, offset):
    """A random blob as a scene's surface: ellipsoids, some negative balls."""
    blob = random_blob(rng, n, kernel, ellipsoids=True, negative=True, threshold=threshold)
    balls = [{"center": (c + offset).tolist(), "radii": r.tolist(), "rotation": a.tolist(), "weight": float(q)}
             for c, r, a, q in zip(blob.centers, blob.radii, rng.uniform(0, 360, (n, 3)), blob.weights)]
    s = {"kernel": kernel, "threshold": threshold, "balls": balls}
    if kernel == "blinn":
        s["blobbiness"] = 3.0
    return s


@pytest.mark.parametrize("kernels", [("wyvill6", "murakami4"), ("nishimura", "blinn"), ("murakami4", "wyvill6")])
def test_rendered_depth_matches_dense_sampling_of_the_field(tmp_path, rng, kernels):
    """Two random surfaces (ellipsoids, negative balls) in one scene: each pixel's depth against an
    independent render of the same isosurfaces, the first sample of cloudmeta.field along the pixel's ray
    that is inside either blob (every 2e-3), refined by bisection."""
    surfaces = [random_surface_dict(rng, kernels[0], 8, 0.5, np.array([-1.0, 0.0, 0.0])),
                random_surface_dict(rng, kernels[1], 6, 0.4, np.array([1.5, 1.0, 0.5]))]
    camera = {"position": [2.0, -13.0, 4.0], "look_at": [0.2, 0.3, 0.2], "up": [0.0, 0.0, 1.0], "fov": 28.0}
    size = 28
    s = make_scene(tmp_path, surfaces=surfaces, lights=[directional([0.3, -0.5, 0.8], 2.0)], camera=camera,
                   size=size, render_settings={"quality": "draft"})
    _, depth = render(s, progress=False, depth=True)
    o, d = pixel_rays(camera, size, size)
    ref = np.min([naive.first_hit(lambda p, b=surf.blob: cm.field(b, p), surf.blob.threshold, o, d, 5.0, 25.0, 2e-3)
                  for surf in s.surfaces], axis=0)
    depth = depth.ravel()
    hit = np.isfinite(ref)
    assert 150 < np.count_nonzero(hit) < size * size - 50
    np.testing.assert_array_equal(np.isfinite(depth), hit)
    np.testing.assert_allclose(depth[hit], ref[hit], rtol=0, atol=1e-6)


def test_media_only_scenes_have_no_depth(tmp_path):
    s = make_scene(tmp_path, media=[uniform_medium(1.0, 0.8)], size=4, camera=dict(AXIS_CAMERA, fov=30.0))
    img, depth = render(s, progress=False, depth=True)
    assert np.all(depth == np.inf) and img[..., 3].max() > 0.5


def test_same_image_whatever_the_thread_count(tmp_path):
    l = [0.3, -0.5, 0.8]
    s = make_scene(tmp_path, surfaces=[sphere_surface(1.0), sphere_surface(0.6, center=(1.2, -0.5, 1.0))],
                   media=[uniform_medium(1.5, 0.8, center=(-0.5, -1.0, 0.5), albedo=0.9)],
                   lights=[directional(l, 3.0), {"type": "point", "position": [2.0, -3.0, 2.0], "intensity": 5.0}],
                   ambient=[0.1, 0.1, 0.1], camera=dict(AXIS_CAMERA, fov=35.0), size=20, spp=4,
                   render_settings={"quality": "draft"})
    numba.set_num_threads(1)
    try:
        one = render(s, progress=False)
    finally:
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    two = render(s, progress=False)
    np.testing.assert_array_equal(one, two)
    assert np.count_nonzero(one[..., 3] == 1.0) > 50  # the surfaces are in the picture


def test_the_readme_example_renders():
    """docs/surfaces.yaml, the README's picture, at a thumbnail: the ground fills the bottom, the blob the middle."""
    from pathlib import Path
    s = load_scene(Path(__file__).resolve().parents[2] / "docs" / "surfaces.yaml", width=16, height=12)
    img, depth = render(s, progress=False, depth=True)
    assert np.all(np.isfinite(depth[-1])) and np.all(img[-1, :, 3] == 1.0)
    assert np.isfinite(depth[6, 8]) and np.all(img[0, 0, :3] > 0)
