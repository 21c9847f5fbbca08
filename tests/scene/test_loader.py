"""cloudmeta.scene: a valid scene loads with the right values; every bad one is a SceneError naming the
file and the exact key path (docs/model.md §9)."""
import copy
import dataclasses
import os

import numpy as np
import pytest
import yaml

from cloudmeta.scene.blob import rotation_matrix
from cloudmeta.scene.colour import parse_colour
from cloudmeta.errors import SceneError
from cloudmeta.scene import Density, Phase, PointLight, RenderSettings, load_scene

BASE = {
    "image": {"width": 64, "height": 48, "spp": 2},
    "camera": {"position": [0, -12, 2], "look_at": [0, 0, 2], "up": [0, 0, 1], "fov": 40},
    "background": [0.3, 0.45, 0.8],
    "ambient": [0.05, 0.07, 0.1],
    "lights": [
        {"type": "directional", "direction": [0, -3, 4], "irradiance": 3.0, "color": {"temperature": 5800}},
        {"type": "point", "position": [0, 0, 8], "intensity": 40.0},
    ],
    "media": [{
        "name": "cumulus", "kernel": "wyvill6", "threshold": 0.5,
        "density": {"mode": "excess", "scale": 1.5}, "albedo": 0.9, "phase": {"type": "hg", "g": 0.6},
        "balls": [
            {"center": [0, 0, 2], "radius": 1.5, "weight": 1.0},
            {"center": [1, 0, 2.3], "radii": [1.2, 0.8, 0.6], "rotation": [0, 0, 30], "weight": -0.5},
        ],
    }],
    "surfaces": [{"name": "hand", "color": [0.8, 0.6, 0.5], "balls": [{"center": [0, 0, -3], "radius": 1}]}],
    "render": {"quality": "fine", "tolerance": 0.002, "cutoff": 0.01, "shadows": "map", "shadow_map": 64},
    "output": {"path": "out/cumulus.exr", "png": "cumulus.png", "exposure": -1.0},
}

SPHERES_CSV = "x, y, z, radius, weight\n0, 0, 0, 1.0, 1\n\n1,2,3 , 0.5, -0.25\n"
ELLIPSOIDS_CSV = "x,y,z,rx,ry,rz,ax,ay,az,weight\n0,0,0,1,2,3,90,0,0,1\n"


def write(tmp_path, data, name="scene.yaml"):
    path = tmp_path / name
    path.write_text(data if isinstance(data, str) else yaml.safe_dump(data))
    return path


def test_01_full_scene_values(tmp_path):
    s = load_scene(write(tmp_path, BASE))
    assert s.path == str(tmp_path / "scene.yaml")
    assert (s.image.width, s.image.height, s.image.spp) == (64, 48, 2)
    np.testing.assert_array_equal(s.camera.position, [0, -12, 2])
    assert s.camera.fov == 40.0
    np.testing.assert_array_equal(s.background, [0.3, 0.45, 0.8])
    np.testing.assert_array_equal(s.ambient, [0.05, 0.07, 0.1])

    sun, lamp = s.lights
    np.testing.assert_allclose(sun.direction, [0, -0.6, 0.8])
    np.testing.assert_allclose(sun.irradiance, 3.0 * parse_colour({"temperature": 5800}, "c"))
    assert isinstance(lamp, PointLight)
    np.testing.assert_array_equal(lamp.intensity, [40, 40, 40])

    (m,) = s.media
    assert m.name == "cumulus" and m.albedo == 0.9
    assert m.density == Density("excess", 1.5) and m.phase == Phase("hg", g=0.6)
    b = m.blob
    assert b.kernel == "wyvill6" and b.threshold == 0.5 and len(b) == 2
    np.testing.assert_array_equal(b.radii, [[1.5, 1.5, 1.5], [1.2, 0.8, 0.6]])
    np.testing.assert_array_equal(b.weights, [1.0, -0.5])
    np.testing.assert_array_equal(b.rotations[0], np.eye(3))
    c, sn = np.sqrt(3) / 2, 0.5  # Rz(30 degrees): the ellipsoid's first axis turns towards +y
    np.testing.assert_allclose(b.rotations[1], [[c, -sn, 0], [sn, c, 0], [0, 0, 1]], atol=1e-15)

    (hand,) = s.surfaces
    assert hand.name == "hand" and hand.blob.kernel == "wyvill6"
    np.testing.assert_array_equal(hand.color, [0.8, 0.6, 0.5])

    assert s.render == RenderSettings(quality="fine", tolerance=0.002, cutoff=0.01, shadows="map", shadow_map=64)
    assert s.output.path == os.path.join(str(tmp_path), "out", "cumulus.exr")
    assert s.output.png == os.path.join(str(tmp_path), "cumulus.png")
    assert s.output.exposure == -1.0
    lo, hi = s.bbox()
    np.testing.assert_allclose(lo, [-1.5, -1.5, -4.0])
    assert hi[2] == pytest.approx(3.5)


def test_02_defaults(tmp_path):
    data = {"image": {"width": 4, "height": 3}, "camera": {"position": [0, -5, 0], "look_at": [0, 0, 0]},
            "media": [{"balls": [{"center": [0, 0, 0], "radius": 1}]}],
            "surfaces": [{"balls": [{"center": [3, 0, 0], "radius": 1}]}]}
    s = load_scene(write(tmp_path, data))
    assert s.image.spp == 1 and s.camera.fov == 40.0
    np.testing.assert_array_equal(s.camera.up, [0, 0, 1])
    np.testing.assert_array_equal(s.background, [0, 0, 0])
    assert s.ambient is None and s.lights == ()
    m = s.media[0]
    assert m.name == "medium0" and m.albedo == 1.0
    assert m.density == Density("field", 1.0) and m.phase == Phase("isotropic")
    assert m.blob.kernel == "wyvill6" and m.blob.threshold == 0.5 and m.blob.weights.tolist() == [1.0]
    assert s.surfaces[0].name == "surface0"
    np.testing.assert_array_equal(s.surfaces[0].color, [1, 1, 1])
    assert s.render == RenderSettings()
    assert (s.output.path, s.output.png, s.output.exposure) == (None, None, None)  # None: the display's default


def test_03_overrides_replace_image_settings(tmp_path):
    s = load_scene(write(tmp_path, BASE), width=10, spp=np.int64(16))
    assert (s.image.width, s.image.height, s.image.spp) == (10, 48, 16)
    assert type(s.image.spp) is int


def test_04_balls_from_csv(tmp_path):
    (tmp_path / "spheres.csv").write_text(SPHERES_CSV)
    (tmp_path / "ellipsoids.csv").write_text(ELLIPSOIDS_CSV)
    data = copy.deepcopy(BASE)
    data["media"][0].pop("balls")
    data["media"][0]["balls_file"] = "spheres.csv"
    data["surfaces"][0].pop("balls")
    data["surfaces"][0]["balls_file"] = "ellipsoids.csv"
    s = load_scene(write(tmp_path, data))
    b = s.media[0].blob
    np.testing.assert_array_equal(b.centers, [[0, 0, 0], [1, 2, 3]])
    np.testing.assert_array_equal(b.radii, [[1, 1, 1], [0.5, 0.5, 0.5]])
    np.testing.assert_array_equal(b.weights, [1, -0.25])
    e = s.surfaces[0].blob
    np.testing.assert_array_equal(e.radii, [[1, 2, 3]])
    np.testing.assert_allclose(e.rotations[0], rotation_matrix([90, 0, 0]), atol=1e-15)


def test_05_other_kernels_and_phases(tmp_path):
    data = copy.deepcopy(BASE)
    data["media"][0].update(kernel="blinn", blobbiness=2.5,
                            phase={"type": "double_hg", "g1": 0.8, "g2": -0.3, "w": 0.7})
    data["render"] = {"colourspace": "acescg"}
    s = load_scene(write(tmp_path, data))
    assert s.media[0].blob.kernel == "blinn" and s.media[0].blob.blobbiness == 2.5
    assert s.media[0].phase == Phase("double_hg", g1=0.8, g2=-0.3, w=0.7)
    assert s.render.colourspace == "ACEScg"  # canonical spelling
    np.testing.assert_allclose(s.lights[0].irradiance,
                               3.0 * parse_colour({"temperature": 5800}, "c", "ACEScg"))


def test_06_scene_is_immutable(tmp_path):
    s = load_scene(write(tmp_path, BASE))
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.camera.fov = 10
    for arr in (s.camera.position, s.background, s.lights[0].direction, s.lights[0].irradiance,
                s.surfaces[0].color, s.media[0].blob.centers):
        with pytest.raises(ValueError):
            arr[0] = 1.0


def edit(path, value):
    """A copy of BASE with ``value`` set at ``path`` (a tuple of keys and indices); DELETE removes it."""
    data = copy.deepcopy(BASE)
    *parents, last = path
    node = data
    for key in parents:
        node = node[key]
    if value is DELETE:
        del node[last]
    else:
        node[last] = value
    return data


DELETE = object()
M0, B0 = ("media", 0), ("media", 0, "balls", 0)

# (what, edit path, new value, expected key path, fragment of the message)
BAD_VALUES = [
    ("unknown top key", ("colour",), 1, "colour", "unknown key"),
    ("unknown ball key", B0 + ("radiuss",), 1, "media[0].balls[0].radiuss", "unknown key"),
    ("unknown light key", ("lights", 0, "power"), 1, "lights[0].power", "unknown key"),
    ("key of another light type", ("lights", 0, "intensity"), 1, "lights[0].intensity", "unknown key"),
    ("unknown phase key", M0 + ("phase", "gg"), 1, "media[0].phase.gg", "did you mean 'g'"),
    ("key of another phase", M0 + ("phase", "g1"), 0.1, "media[0].phase.g1", "unknown key"),
    ("unknown density key", M0 + ("density", "scal"), 1, "media[0].density.scal", "unknown key"),
    ("unknown render key", ("render", "speed"), 1, "render.speed", "unknown key"),
    ("unknown output key", ("output", "exr"), "a.exr", "output.exr", "unknown key"),
    ("unknown surface key", ("surfaces", 0, "colour"), [1, 1, 1], "surfaces[0].colour", "did you mean 'color'"),
    ("missing camera.position", ("camera", "position"), DELETE, "camera.position", "missing required key"),
    ("missing image.width", ("image", "width"), DELETE, "image.width", "missing required key"),
    ("missing image", ("image",), DELETE, "image", "missing required key"),
    ("missing light type", ("lights", 1, "type"), DELETE, "lights[1].type", "missing required key"),
    ("missing ball center", B0 + ("center",), DELETE, "media[0].balls[0].center", "missing required key"),
    ("missing hg g", M0 + ("phase",), {"type": "hg"}, "media[0].phase.g", "missing required key"),
    ("bool is not a number", ("camera", "fov"), True, "camera.fov", "boolean"),
    ("text is not a number", M0 + ("albedo",), "high", "media[0].albedo", "the text 'high'"),
    ("1e3 is text in YAML", M0 + ("threshold",), "1e3", "media[0].threshold", "1.0e+3"),
    ("null is not a number", ("camera", "fov"), None, "camera.fov", "got null"),
    ("vector of 2", ("camera", "look_at"), [0, 0], "camera.look_at", "a list of 3 finite numbers"),
    ("non-finite number", ("camera", "position"), [0, float("inf"), 0], "camera.position", "finite"),
    ("nan weight", B0 + ("weight",), float("nan"), "media[0].balls[0].weight", "finite"),
    ("radius 0", B0 + ("radius",), 0, "media[0].balls[0].radius", "> 0"),
    ("radius < 0", B0 + ("radius",), -1.0, "media[0].balls[0].radius", "> 0"),
    ("a radii <= 0", ("media", 0, "balls", 1, "radii"), [1, -1, 1], "media[0].balls[1].radii", "> 0"),
    ("radius and radii", B0 + ("radii",), [1, 1, 1], "media[0].balls[0].radii", "not both"),
    ("rotation of a sphere", B0 + ("rotation",), [0, 0, 1], "media[0].balls[0].rotation", "ellipsoid"),
    ("threshold 0", M0 + ("threshold",), 0, "media[0].threshold", "> 0"),
    ("albedo > 1", M0 + ("albedo",), 1.5, "media[0].albedo", "[0, 1]"),
    ("albedo < 0", M0 + ("albedo",), -0.1, "media[0].albedo", "[0, 1]"),
    ("hg |g| = 1", M0 + ("phase",), {"type": "hg", "g": 1.0}, "media[0].phase.g", "(-1, 1)"),
    ("double_hg |g2| = 1", M0 + ("phase",), {"type": "double_hg", "g1": 0.5, "g2": -1, "w": 0.5},
     "media[0].phase.g2", "(-1, 1)"),
    ("double_hg w > 1", M0 + ("phase",), {"type": "double_hg", "g1": 0.5, "g2": -0.5, "w": 1.5},
     "media[0].phase.w", "[0, 1]"),
    ("zero light direction", ("lights", 0, "direction"), [0, 0, 0], "lights[0].direction", "not all 0"),
    ("position == look_at", ("camera", "look_at"), [0, -12, 2], "camera.look_at", "camera.position"),
    ("up parallel to view", ("camera", "up"), [0, -2, 0], "camera.up", "not parallel"),
    ("fov 180", ("camera", "fov"), 180, "camera.fov", "(0, 180)"),
    ("fov 0", ("camera", "fov"), 0, "camera.fov", "(0, 180)"),
    ("width 0", ("image", "width"), 0, "image.width", "an integer >= 1"),
    ("height not int", ("image", "height"), 2.5, "image.height", "an integer >= 1"),
    ("spp negative", ("image", "spp"), -1, "image.spp", "an integer >= 1"),
    ("irradiance < 0", ("lights", 0, "irradiance"), -1, "lights[0].irradiance", ">= 0"),
    ("intensity < 0", ("lights", 1, "intensity"), -0.5, "lights[1].intensity", ">= 0"),
    ("density scale < 0", M0 + ("density", "scale"), -1, "media[0].density.scale", ">= 0"),
    ("unknown kernel", M0 + ("kernel",), "gauss", "media[0].kernel", "wyvill6"),
    ("unknown density mode", M0 + ("density", "mode"), "soft", "media[0].density.mode", "excess"),
    ("unknown phase type", M0 + ("phase", "type"), "mie", "media[0].phase.type", "double_hg"),
    ("unknown light type", ("lights", 0, "type"), "spot", "lights[0].type", "directional"),
    ("medium without balls", M0 + ("balls",), [], "media[0].balls", "at least one ball"),
    ("medium with no balls key", M0 + ("balls",), DELETE, "media[0].balls", "missing required key"),
    ("surface without balls", ("surfaces", 0, "balls"), [], "surfaces[0].balls", "at least one ball"),
    ("balls and balls_file", M0 + ("balls_file",), "c.csv", "media[0].balls_file", "not both"),
    ("balls not a list", M0 + ("balls",), {"center": [0, 0, 0]}, "media[0].balls", "expected a list"),
    ("ball not a mapping", M0 + ("balls", 0), [0, 0, 0, 1], "media[0].balls[0]", "expected a mapping"),
    ("blobbiness with wyvill6", M0 + ("blobbiness",), 3, "media[0].blobbiness", "blinn"),
    ("a surface may share a medium's name", ("surfaces", 0, "name"), "cumulus", None, None),  # valid
    ("bad temperature", ("lights", 0, "color"), {"temperature": 100}, "lights[0].color.temperature",
     "kelvin"),
    ("negative colour", ("background",), [0.1, -1, 0], "background[1]", ">= 0"),
    ("unknown illuminant", ("ambient",), {"illuminant": "D66"}, "ambient.illuminant", "D65"),
    ("bad surface colour", ("surfaces", 0, "color"), "pink", "surfaces[0].color", "[r, g, b]"),
    ("unknown colourspace", ("render", "colourspace"), "Rec. 9999", "render.colourspace", "ACEScg"),
    ("render quality", ("render", "quality"), "best", "render.quality", "reference"),
    ("render tolerance 1", ("render", "tolerance"), 1, "render.tolerance", "a number in [0, 1)"),
    ("render max_tau 0", ("render", "max_tau"), 0, "render.max_tau", "> 0"),
    ("render max_length", ("render", "max_length"), -1, "render.max_length", "> 0"),
    ("render cutoff 1", ("render", "cutoff"), 1.0, "render.cutoff", "[0, 1)"),
    ("render root_tolerance", ("render", "root_tolerance"), 0, "render.root_tolerance", "> 0"),
    ("render shadows", ("render", "shadows"), "soft", "render.shadows", "exact, map, hybrid"),
    ("render shadow_map 1", ("render", "shadow_map"), 1, "render.shadow_map", ">= 2"),
    ("output exposure", ("output", "exposure"), "bright", "output.exposure", "finite number"),
    ("output path", ("output", "path"), 3, "output.path", "string"),
    ("render not a mapping", ("render",), [1], "render", "expected a mapping"),
    ("lights not a list", ("lights",), {"type": "point"}, "lights", "expected a list"),
]


@pytest.mark.parametrize("what, path, value, key_path, fragment", BAD_VALUES, ids=[b[0] for b in BAD_VALUES])
def test_07_bad_value_names_file_and_key_path(tmp_path, what, path, value, key_path, fragment):
    file = write(tmp_path, edit(path, value))
    if key_path is None:
        load_scene(file)  # a valid variation
        return
    with pytest.raises(SceneError) as exc:
        load_scene(file)
    assert exc.value.file == str(file) and exc.value.key_path == key_path
    assert str(exc.value).startswith(f"{file}: {key_path}: ")
    assert fragment in exc.value.detail


def no_things(data):
    del data["media"], data["surfaces"]


def twin_media(data):
    data["media"].append(copy.deepcopy(data["media"][0]))


def default_name_taken(data):
    # surfaces[0] gets the default name surface0, which surfaces[2] also asks for
    balls = data["surfaces"][0]["balls"]
    data["surfaces"] = [{"balls": balls}, data["surfaces"][0], {"name": "surface0", "balls": balls}]


@pytest.mark.parametrize("build, key_path, fragment", [
    (no_things, "media", "at least one medium or surface"),
    (twin_media, "media[1].name", "unique"),
    (default_name_taken, "surfaces[2].name", "unique"),
])
def test_08_scene_level_errors(tmp_path, build, key_path, fragment):
    data = copy.deepcopy(BASE)
    build(data)
    with pytest.raises(SceneError) as exc:
        load_scene(write(tmp_path, data))
    assert exc.value.key_path == key_path and fragment in exc.value.detail


@pytest.mark.parametrize("what, csv, fragment", [
    ("wrong header", "x,y,z,r,weight\n0,0,0,1,1\n", "line 1: expected the header"),
    ("short row", "x,y,z,radius,weight\n0,0,0,1,1\n\n0,0,1\n", "line 4: expected 5 comma-separated"),
    ("not a number", "x,y,z,radius,weight\n0,0,0,1,1\n0,a,0,1,1\n", "line 3: expected finite numbers"),
    ("non-finite", "x,y,z,radius,weight\n0,0,0,1,1\n0,0,0,1,nan\n", "line 3: expected finite numbers"),
    ("radius 0", "x,y,z,radius,weight\n0,0,0,0,1\n", "line 2: expected radii > 0, got radius 0"),
    # a number > 0 that rounds to 0: quoted as written, not as the 0 it became (issue #27)
    ("radius 1e-400", "x,y,z,radius,weight\n0,0,0,1e-400,1\n", "line 2: expected radii > 0, got radius 1e-400"),
    ("ellipsoid ry 1e-400", "x,y,z,rx,ry,rz,ax,ay,az,weight\n0,0,0,1,1e-400,1,0,0,0,1\n",
     "line 2: expected radii > 0, got rx 1, ry 1e-400, rz 1"),
    ("empty", "\n", "expected a header line"),
    ("header only", "x,y,z,rx,ry,rz,ax,ay,az,weight\n", "at least one ball"),
    ("missing file", None, "cannot read the balls file"),
])
def test_09_bad_balls_csv(tmp_path, what, csv, fragment):
    if csv is not None:
        (tmp_path / "balls.csv").write_text(csv)
    data = copy.deepcopy(BASE)
    data["media"][0].pop("balls")
    data["media"][0]["balls_file"] = "balls.csv"
    file = write(tmp_path, data)
    with pytest.raises(SceneError) as exc:
        load_scene(file)
    assert exc.value.file == str(file) and exc.value.key_path == "media[0].balls_file"
    assert fragment in exc.value.detail
    if csv is not None and "line" in fragment:
        assert str(tmp_path / "balls.csv") in exc.value.detail


@pytest.mark.parametrize("what, text, fragment", [
    ("syntax error", "image: {width: 4, height: 3\ncamera: [\n", "invalid YAML at line"),
    ("tab indentation", "image:\n\twidth: 4\n", "invalid YAML"),
    ("duplicate key", "image: {width: 4, height: 3}\nimage: {width: 5, height: 3}\n", "duplicate key 'image'"),
    ("top level is a list", "- image\n- camera\n", "expected a mapping"),
    ("empty file", "", "got null"),
])
def test_10_bad_yaml(tmp_path, what, text, fragment):
    file = write(tmp_path, text)
    with pytest.raises(SceneError) as exc:
        load_scene(file)
    assert exc.value.file == str(file) and exc.value.key_path is None
    assert str(exc.value).startswith(f"{file}: ") and fragment in exc.value.detail


def test_11_missing_scene_file(tmp_path):
    with pytest.raises(SceneError, match="cannot read the scene file"):
        load_scene(tmp_path / "nope.yaml")


@pytest.mark.parametrize("override, key_path", [({"width": 0}, "image.width"), ({"spp": 1.5}, "image.spp"),
                                                ({"height": True}, "image.height")])
def test_12_bad_overrides(tmp_path, override, key_path):
    with pytest.raises(SceneError) as exc:
        load_scene(write(tmp_path, BASE), **override)
    assert exc.value.key_path == key_path


# --- issue #15: limits and the numeric domain, checked at load time with the key path -----------------------

HOSTILE = [
    ("width 1e9", ("image", "width"), 10 ** 9, "image.width", "<= 16384"),
    ("width of 400 digits", ("image", "width"), 10 ** 400, "image.width", "an integer of 401 digits"),
    ("100000 x 100000", ("image",), {"width": 16384, "height": 16384}, "image.height", "pixels"),
    ("spp 2**64", ("image", "spp"), 2 ** 64, "image.spp", "<= 65536"),
    ("spp 1e9", ("image", "spp"), 10 ** 9, "image.spp", "<= 65536"),
    ("samples", ("image",), {"width": 8192, "height": 8192, "spp": 128}, "image.spp", "samples"),
    ("shadow map 1e6", ("render", "shadow_map"), 10 ** 6, "render.shadow_map", "<= 8192"),
    ("max_length 1e-12", ("render", "max_length"), 1e-12, "render.max_length", "steps"),
    ("max_tau 1e-12", ("render", "max_tau"), 1e-12, "render.max_tau", "at least"),
    ("root_tolerance 1e-20", ("render", "root_tolerance"), 1e-20, "render.root_tolerance", "diagonal"),
    ("centre 1e308", B0 + ("center",), [1e308, 0, 0], "media[0].balls[0].center", "1e+100"),
    # a ball far from the rest sets no tolerance (Scene.length_scale): it is refused for lying too far away
    ("centre far off", B0 + ("center",), [1e9, 0, 0], "media[0].balls[0].center", "x the scene's length"),
    ("radius 1e308", B0 + ("radius",), 1e308, "media[0].balls[0].radius", "1e+100"),
    ("radius 1e-300", B0 + ("radius",), 1e-300, "media[0].balls[0].radius", "1e-100"),
    ("radius 1e-9", B0 + ("radius",), 1e-9, "media[0].balls[0].radius", "root tolerances"),
    ("radii 1e-9", ("media", 0, "balls", 1, "radii"), [1, 1e-9, 1], "media[0].balls[1].radii", "root tolerances"),
    ("camera 1e308", ("camera", "position"), [0, -1e308, 2], "camera.position", "1e+100"),
    ("camera far off", ("camera", "position"), [0, -1e10, 2], "camera.position", "x the scene's length"),
    ("point light far off", ("lights", 1, "position"), [0, 0, 1e10], "lights[1].position", "x the scene's length"),
    ("look_at too close", ("camera",), {"position": [0, 0, 0], "look_at": [1e-300, 0, 0]}, "camera.look_at",
     "at least 1e-100"),
    ("weight 1e308", B0 + ("weight",), 1e308, "media[0].balls[0].weight", "x threshold"),
    ("threshold 1e-300", M0 + ("threshold",), 1e-300, "media[0].threshold", "1e-100"),
    ("threshold true", M0 + ("threshold",), True, "media[0].threshold", "boolean"),
    ("scale 1e308", M0 + ("density", "scale"), 1e308, "media[0].density.scale", "optical depth"),
    ("irradiance 1e308", ("lights", 0, "irradiance"), 1e308, "lights[0].irradiance", "1e+30"),
    ("intensity 1e308", ("lights", 1, "intensity"), 1e308, "lights[1].intensity", "diagonal^2"),
    ("colour 1e308", ("lights", 0, "color"), [1e308, 1, 1], "lights[0].color", "1e+30"),
    ("colour of 400 digits", ("background",), [10 ** 400, 0, 0], "background[0]", "finite"),
    ("phase too sharp", M0 + ("phase",), {"type": "hg", "g": 0.9999999999999999}, "lights", "brightest radiance"),
    ("exposure 2000", ("output", "exposure"), 2000, "output.exposure", "within +-64"),
    ("fov 1e-300", ("camera", "fov"), 1e-300, "camera.fov", "(0, 180)"),
    ("blobbiness 1e308", M0 + ("blobbiness",), 1e308, "media[0].blobbiness", "blinn"),  # wyvill6: refused anyway
    ("rotation 1e300", ("media", 0, "balls", 1, "rotation"), [0, 0, 1e300], "media[0].balls[1].rotation", "1e6"),
    ("direction 1e200 is fine", ("lights", 0, "direction"), [1e200, 0, 1e199], None, None),
    ("up 1e-300 is fine", ("camera", "up"), [0, 0, 1e-300], None, None),
]


@pytest.mark.parametrize("what, path, value, key_path, fragment", HOSTILE, ids=[h[0] for h in HOSTILE])
def test_13_limits_and_domain_name_the_key(tmp_path, what, path, value, key_path, fragment):
    file = write(tmp_path, edit(path, value))
    if key_path is None:
        s = load_scene(file)
        assert np.all(np.isfinite(s.camera.up)) and np.all(np.isfinite(s.lights[0].direction))
        np.testing.assert_allclose(np.linalg.norm(s.lights[0].direction), 1.0)
        return
    with pytest.raises(SceneError) as exc:
        load_scene(file)
    assert exc.value.file == str(file) and exc.value.key_path == key_path, str(exc.value)
    assert fragment in exc.value.detail, exc.value.detail
    assert len(str(exc.value).splitlines()) == 1


def test_14_memory_a_render_needs_is_checked(tmp_path, monkeypatch):
    from cloudmeta.scene import limits
    monkeypatch.setattr(limits, "physical_memory", lambda: 2 ** 30)
    with pytest.raises(SceneError) as exc:
        load_scene(write(tmp_path, edit(("image",), {"width": 8192, "height": 4096})))
    assert exc.value.key_path == "image" and "GiB" in exc.value.detail
    with pytest.raises(SceneError) as exc:
        load_scene(write(tmp_path, edit(("render", "shadow_map"), 4096)))
    assert exc.value.key_path == "render.shadow_map"


def _with_balls_file(tmp_path, target):
    data = copy.deepcopy(BASE)
    data["media"][0].pop("balls")
    data["media"][0]["balls_file"] = str(target)
    return write(tmp_path, data)


@pytest.mark.parametrize("target", ["/dev/zero", "/dev/urandom", "fifo", "folder"])
def test_15_balls_file_must_be_a_regular_file(tmp_path, target):
    if target == "fifo":
        os.mkfifo(tmp_path / "fifo")  # opening it for reading would block
    if target == "folder":
        (tmp_path / "folder").mkdir()
    file = _with_balls_file(tmp_path, target if target.startswith("/") else tmp_path / target)
    with pytest.raises(SceneError) as exc:
        load_scene(file)
    assert exc.value.key_path == "media[0].balls_file"
    assert "not a regular file" in exc.value.detail or "a folder" in exc.value.detail


@pytest.mark.parametrize("what, csv, fragment, absent", [
    ("another file's first line", "root:$6$secret:19000:0:99999:7:::\n", "not a valid header (1 fields)", "secret"),
    ("underscore", "x,y,z,radius,weight\n1_0,0,0,1,1\n", "line 2: expected finite numbers", None),
    ("non-ASCII digits", "x,y,z,radius,weight\n\u0661,0,0,1,1\n", "line 2: expected finite numbers", None),
    ("infinity", "x,y,z,radius,weight\n0,0,0,1,infinity\n", "line 2: expected finite numbers", None),
    ("a long line", "x" * 10000, "longer than 4096", None),
    ("binary", None, "UTF-8", None),
    ("centre 1e308", "x,y,z,radius,weight\n1e308,0,0,1,1\n", "line 2: expected coordinates within", None),
    ("radius 1e-300", "x,y,z,radius,weight\n0,0,0,1e-300,1\n", "line 2: expected radii from", None),
    ("weight 1e308", "x,y,z,radius,weight\n0,0,0,1,1e308\n", "line 2: expected a weight", None),
])
def test_16_balls_csv_errors_quote_no_file_contents(tmp_path, what, csv, fragment, absent):
    target = tmp_path / "balls.csv"
    if csv is None:
        target.write_bytes(bytes(range(128, 256)) * 4)
    else:
        target.write_text(csv, encoding="utf-8")
    with pytest.raises(SceneError) as exc:
        load_scene(_with_balls_file(tmp_path, target))
    assert exc.value.key_path == "media[0].balls_file" and fragment in exc.value.detail, exc.value.detail
    assert absent is None or absent not in str(exc.value)


@pytest.mark.parametrize("what, text, fragment", [
    ("complex key", "? [image, camera]\n: 1\n", "complex key"),
    ("deep nesting", "image: " + "[" * 100000 + "]" * 100000 + "\n", "nested more than"),
    ("deep block nesting", "image:\n" + "- " * 100000 + "x\n", "nested more than"),
    ("recursive alias", "image: &a [*a]\n", "recursive alias"),
    ("integer of 5000 digits", "image: {width: " + "9" * 5000 + "}\n", "4300 digits"),
    ("a key that is a number", "1: 2\n", "a key that is text"),
])
def test_17_hostile_yaml(tmp_path, what, text, fragment):
    file = write(tmp_path, text)
    with pytest.raises(SceneError) as exc:
        load_scene(file)
    assert exc.value.file == str(file) and fragment in exc.value.detail
    assert len(str(exc.value).splitlines()) == 1


def test_18_scene_file_must_be_a_regular_file(tmp_path):
    os.mkfifo(tmp_path / "scene.yaml")
    for path in ("/dev/zero", tmp_path / "scene.yaml", tmp_path):
        with pytest.raises(SceneError, match="not a regular file|a folder"):
            load_scene(path)


def test_19_inputs_are_recorded_for_the_output_checks(tmp_path):
    (tmp_path / "spheres.csv").write_text(SPHERES_CSV)
    data = copy.deepcopy(BASE)
    data["media"][0].pop("balls")
    data["media"][0]["balls_file"] = "spheres.csv"
    s = load_scene(write(tmp_path, data))
    assert s.inputs == (str(tmp_path / "scene.yaml"), str(tmp_path / "spheres.csv"))


def test_20_render_overrides_are_validated(tmp_path):
    s = load_scene(write(tmp_path, BASE), render={"quality": "draft", "shadow_map": 32, "shadows": None})
    assert (s.render.quality, s.render.shadow_map, s.render.shadows) == ("draft", 32, "map")
    with pytest.raises(SceneError) as exc:
        load_scene(write(tmp_path, BASE), render={"shadow_map": 10 ** 6})
    assert exc.value.key_path == "render.shadow_map"


@pytest.mark.parametrize("text", ["root:$6$secretHASH:19000:0:99999:7:::\ndaemon:*:19000:0:99999:7:::\n",
                                  "root:$6$secretHASH:19000\n", "- root:$6$secretHASH\n"])
def test_21_a_file_that_is_no_scene_is_not_quoted(tmp_path, text):
    """``cloudmeta render /etc/shadow``: refused without echoing a line of the file."""
    with pytest.raises(SceneError) as exc:
        load_scene(write(tmp_path, text))
    assert "secret" not in str(exc.value)
