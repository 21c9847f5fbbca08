"""The clouds' shadow on a ground the scene places (renderer.ground, docs/atmosphere.md): the loss of the
background against a closed form (the chord of a uniform sphere, a surface's full shadow), the render's
background shaded by exactly that loss times the view's transmittance, tiles bit-identical to the frame."""
import math

import numpy as np
import pytest
import yaml

from cloudmeta.renderer import render
from cloudmeta.renderer.ground import SUBPIXELS, ground_shadow
from cloudmeta.renderer.pack import background_along, pack_scene
from cloudmeta.scene import load_scene
from tests import naive
from tests.renderer.test_surfaces import sphere_surface, uniform_medium

SUN = {"type": "sun", "elevation": 35, "azimuth": 195}  # behind the camera: the shadow shows through the sphere
CAMERA = {"position": [0.0, -6.0, 2.5], "look_at": [0.3, 1.5, 0.3], "up": [0, 0, 1], "fov": 40}
CENTRE, RADIUS, SIGMA = np.array([0.2, 0.4, 1.2]), 0.9, 1.3


def scene(tmp_path, ground=-0.3, media=(), surfaces=(), size=(24, 16), scattering="single", name="g.yaml"):
    sky = {"ground_albedo": 0.3} if ground is None else {"ground_albedo": 0.3, "ground_height": ground}
    data = {"image": {"width": size[0], "height": size[1], "spp": 1}, "camera": CAMERA, "background": {"sky": sky},
            "lights": [SUN], "render": {"quality": "draft", "scattering": scattering}}
    if media:
        data["media"] = list(media)
    if surfaces:
        data["surfaces"] = list(surfaces)
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data))
    return load_scene(path)


def naive_loss(s, blocked):
    """Per pixel the mean over the SUBPIXELS^2 points of L_sun(e) (1 - T_sun(g)), T_sun from ``blocked(g, l)``:
    the transmittance from the ground point g towards the sun l."""
    cam = pack_scene(s, 0).camera
    out = np.zeros((cam.height, cam.width, 3))
    o = np.asarray(cam.position)
    for i in range(cam.height):
        for j in range(cam.width):
            for a in range(SUBPIXELS):
                for b in range(SUBPIXELS):
                    x = 2.0 * (j + (b + 0.5) / SUBPIXELS) / cam.width - 1.0
                    y = 1.0 - 2.0 * (i + (a + 0.5) / SUBPIXELS) / cam.height
                    d = cam.forward + x * cam.right + y * cam.up
                    d = d / np.linalg.norm(d)
                    if d[2] >= 0.0:
                        continue
                    g = o + (s.ground.height - o[2]) / d[2] * d
                    shade = 1.0 - blocked(g, s.ground.direction)
                    out[i, j] += background_along(s.ground.sun, d[None])[0] * shade / SUBPIXELS ** 2
    return out


def sphere_transmittance(g, light, centre=CENTRE, radius=RADIUS, sigma=SIGMA):
    """e^-(sigma x the chord of the sphere beyond g along light)."""
    hit = naive.chord_sphere(g, light, centre, radius)
    if hit is None or hit[1] <= 0.0:
        return 1.0
    return math.exp(-sigma * (hit[1] - max(hit[0], 0.0)))


def test_loss_of_a_uniform_sphere_against_its_chords(tmp_path):
    s = scene(tmp_path, media=[uniform_medium(RADIUS, SIGMA, CENTRE)])
    packed = pack_scene(s, 0)
    window = ((0, 16), (0, 24))
    loss = ground_shadow(s, packed.records, packed.camera, packed.quadrature.tol_t, window)
    expected = naive_loss(s, sphere_transmittance)
    assert np.count_nonzero(expected[..., 1]) > 10 and np.count_nonzero(expected[..., 1] == 0) > 10  # in and out
    np.testing.assert_allclose(loss, expected, rtol=1e-9, atol=1e-12 * expected.max())
    # the frame's pixels alone: any tile gives them bit for bit
    tile = ground_shadow(s, packed.records, packed.camera, packed.quadrature.tol_t, ((3, 11), (5, 19)))
    np.testing.assert_array_equal(tile, loss[3:11, 5:19])
    assert ground_shadow(scene(tmp_path, ground=None, media=[uniform_medium(RADIUS, SIGMA, CENTRE)]),
                         packed.records, packed.camera, packed.quadrature.tol_t, window) is None


def test_a_surface_casts_a_full_shadow(tmp_path):
    medium = uniform_medium(0.2, 0.5, (4.0, 6.0, 0.5))  # far off the shadow: the scene needs no medium but has one
    s = scene(tmp_path, media=[medium], surfaces=[sphere_surface(RADIUS, CENTRE)])
    packed = pack_scene(s, 0)
    loss = ground_shadow(s, packed.records, packed.camera, packed.quadrature.tol_t, ((0, 16), (0, 24)))

    def blocked(g, light):
        hit = naive.chord_sphere(g, light, CENTRE, RADIUS)
        t_medium = sphere_transmittance(g, light, np.array([4.0, 6.0, 0.5]), 0.2, 0.5)
        return 0.0 if hit is not None and hit[1] > 0.0 else t_medium
    expected = naive_loss(s, blocked)
    whole = naive_loss(s, lambda g, light: 0.0)  # the sun's whole share of every pixel's ground
    full = (whole[..., 1] > 0.0) & np.all(expected == whole, axis=-1)
    assert np.count_nonzero(full) > 5 and np.count_nonzero(expected[..., 1] == 0.0) > 10  # full shadow and none
    np.testing.assert_allclose(loss, expected, rtol=1e-6, atol=1e-9 * expected.max())
    np.testing.assert_allclose(loss[full], whole[full], rtol=1e-12)


@pytest.mark.parametrize("scattering", ["single", "approximate"])
def test_the_render_shades_the_background_it_sees(tmp_path, scattering):
    """With the ground placed, the image is the image without it less the loss times the view's transmittance
    (1 - alpha): the sphere's shadow shows beside it and, dimmed, through it; the rest is unchanged."""
    media = [uniform_medium(RADIUS, SIGMA, CENTRE)]
    placed = scene(tmp_path, media=media, scattering=scattering)
    bare = scene(tmp_path, ground=None, media=media, scattering=scattering, name="b.yaml")
    image = render(placed, progress=False)
    plain = render(bare, progress=False)
    packed = pack_scene(placed, 0)
    loss = ground_shadow(placed, packed.records, packed.camera, packed.quadrature.tol_t, ((0, 16), (0, 24)))
    np.testing.assert_array_equal(image[..., 3], plain[..., 3])
    expected = plain[..., :3].astype(np.float64) - loss * (1.0 - plain[..., 3:4].astype(np.float64))
    np.testing.assert_allclose(image[..., :3], expected, rtol=0, atol=4e-7 * float(plain[..., :3].max()))  # float32 twice
    shadowed = loss[..., 1] > 0
    assert np.any(shadowed & (plain[..., 3] == 0)) and np.any(shadowed & (plain[..., 3] > 0.05))
    np.testing.assert_array_equal(image[~shadowed], plain[~shadowed])
    # a tile is the frame's pixels
    tile = render(placed, progress=False, rows=(4, 13), columns=(2, 21))
    np.testing.assert_array_equal(tile, image[4:13, 2:21])


def test_the_docs_picture_shows_the_shadow():
    """docs/ground_shadow.yaml at a thumbnail: the frame is ground, and a patch of it lies in the cloud's shadow
    (dark wherever the cloud hides the sun entirely), away from the cloud itself."""
    from pathlib import Path
    s = load_scene(Path(__file__).resolve().parents[2] / "docs" / "ground_shadow.yaml", width=48, height=30)
    packed = pack_scene(s, 0)
    loss = ground_shadow(s, packed.records, packed.camera, packed.quadrature.tol_t, ((0, 30), (0, 48)))
    image = render(s, progress=False)
    shaded = loss[..., 1] > 0.5 * background_along(s.ground.sun, np.array([[0.0, 0.0, -1.0]]))[0, 1]
    assert 10 < np.count_nonzero(shaded) < 0.2 * shaded.size
    assert np.all(image[shaded, 3] < 0.01)  # the shadow is seen beside the cloud, not through it
