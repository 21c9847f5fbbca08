"""validation/peers/povray_peer.py: the POV-Ray scene read right, translated to an equivalent cloudmeta scene."""
import math

import numpy as np
import pytest

import cloudmeta as cm
from validation.peers import povray_peer as peer

POV = """camera { perspective location <0,-14,2.5> look_at <0,0,2> up z right -x*4/3 sky z angle 50 }
light_source { <10,-10,20> color rgb 1 }
background { color rgb <0.2,0.3,0.5> }
blob { threshold 0.5
  sphere { <-2.096,0.177,1.480>, 0.802, 1 }
  sphere { <1.006,-1.738,0.053>, 0.919, 1.5 }
  pigment { color rgb <0.9,0.7,0.6> } finish { diffuse 0.8 } }
"""


def test_parse_pov(tmp_path):
    path = tmp_path / "b2.pov"
    path.write_text(POV)
    pov = peer.parse_pov(path)
    np.testing.assert_array_equal(pov["location"], [0, -14, 2.5])
    np.testing.assert_array_equal(pov["look_at"], [0, 0, 2])
    np.testing.assert_array_equal(pov["light"], [10, -10, 20])
    np.testing.assert_array_equal(pov["background"], [0.2, 0.3, 0.5])
    np.testing.assert_array_equal(pov["pigment"], [0.9, 0.7, 0.6])
    assert (pov["angle"], pov["threshold"], pov["diffuse"]) == (50.0, 0.5, 0.8)
    np.testing.assert_array_equal(pov["balls"], [[-2.096, 0.177, 1.480, 0.802, 1], [1.006, -1.738, 0.053, 0.919, 1.5]])


def test_horizontal_angle_becomes_vertical_fov():
    fov = peer.vertical_fov(50, 512, 384)
    assert math.tan(math.radians(fov) / 2) * 512 / 384 == pytest.approx(math.tan(math.radians(25)), rel=1e-14)


def test_scene_is_a_murakami4_surface_lit_like_povray(tmp_path):
    path = tmp_path / "b2.pov"
    path.write_text(POV)
    pov = peer.parse_pov(path)
    yaml_path, d_ref = peer.write_scene(pov, tmp_path, "b2")
    scene = cm.load_scene(yaml_path)
    (surface,) = scene.surfaces
    assert surface.blob.kernel == "murakami4" and surface.blob.threshold == 0.5
    np.testing.assert_allclose(surface.blob.weights, [1, 1.5])
    (light,) = scene.lights
    centroid = pov["balls"][:, :3].mean(axis=0)
    assert d_ref == pytest.approx(np.linalg.norm(pov["light"] - centroid))
    # colour / pi * I / d_ref^2 = diffuse * colour at the centroid's distance
    np.testing.assert_allclose(np.asarray(light.intensity) / (math.pi * d_ref ** 2), 0.8)
    np.testing.assert_allclose(scene.ambient, 0.1)
    assert (scene.image.width, scene.image.height) == (512, 384)


def test_pixel_rays_are_the_renderers(tmp_path):
    """The comparison's rays meet the blob where the render's alpha says they do."""
    path = tmp_path / "b2.pov"
    path.write_text(POV)
    pov = peer.parse_pov(path)
    yaml_path, _ = peer.write_scene(pov, tmp_path, "b2")
    scene = cm.load_scene(yaml_path, width=32, height=24)
    alpha = cm.render(scene, progress=False)[..., 3]
    origins, dirs = peer.pixel_rays(pov, 32, 24)
    t = cm.first_hit(scene.surfaces[0].blob, origins, dirs).reshape(24, 32)
    assert np.isfinite(t).any()
    np.testing.assert_array_equal(np.isfinite(t), alpha > 0.5)


def test_skips_without_povray(monkeypatch, capsys):
    monkeypatch.setattr(peer.shutil, "which", lambda name: None)
    assert peer.main([]) == dict(skipped=True)
    assert "apt-get install povray" in capsys.readouterr().out
