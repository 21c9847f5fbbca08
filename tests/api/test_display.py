"""cloudmeta.api.display: white balance, auto exposure and the OpenColorIO display transform of the PNG; the
raw preview byte for byte as before; the EXR untouched by any of it; bad settings refused in one line."""
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from PIL import Image

import cloudmeta.api.display as d
from cloudmeta.api.io import encode_outputs, png_settings, write_png
from cloudmeta.errors import InputError, OutputError, SceneError
from cloudmeta.scene import load_scene
from cloudmeta.scene.colour import encode_srgb, parse_colour

ROOT = Path(__file__).resolve().parents[2]


def image(h=6, w=9, seed=3, alpha=True):
    rng = np.random.default_rng(seed)
    im = rng.uniform(0, 3, (h, w, 4 if alpha else 3))
    if alpha:
        im[..., 3] = rng.uniform(0, 1, (h, w))
    return im


def scene_file(tmp_path, output=None, **top):
    data = {"image": {"width": 8, "height": 6}, "camera": {"position": [0, -10, 0], "look_at": [0, 0, 0]},
            "lights": [{"type": "sun", "elevation": 35, "azimuth": 125}], "background": "sky",
            "media": [{"balls": [{"center": [0, 0, 0], "radius": 1, "weight": 1}]}]}
    data.update(top)
    if output is not None:
        data["output"] = output
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


# --- white balance -----------------------------------------------------------------------------------------

@pytest.mark.parametrize("light", [{"temperature": 3200}, {"temperature": 9000}, {"illuminant": "A"}])
def test_white_balance_maps_the_illuminant_to_the_white_point(light):
    rgb = parse_colour(light)
    out = d.balance_matrix(tuple(rgb)) @ (2.5 * rgb)  # any strength of that light: a grey
    np.testing.assert_allclose(out / out.mean(), [1, 1, 1], atol=1e-9)
    # Y is kept: adaptation changes the colour of the light, not how bright it is
    assert d.luminance(out) == pytest.approx(2.5 * d.luminance(rgb), rel=1e-9)


def test_white_balance_is_colour_sciences_cat02_von_kries():
    import colour
    rgb = parse_colour({"temperature": 4000})
    m = d.balance_matrix(tuple(rgb))
    xyz_rgb = np.linalg.inv(colour.RGB_COLOURSPACES["ITU-R BT.709"].matrix_XYZ_to_RGB)
    source = xyz_rgb @ rgb
    target = colour.xy_to_XYZ(colour.RGB_COLOURSPACES["sRGB"].whitepoint)
    sample = np.array([0.3, 0.5, 0.2])
    want = colour.RGB_COLOURSPACES["ITU-R BT.709"].matrix_XYZ_to_RGB @ colour.adaptation.chromatic_adaptation_VonKries(
        xyz_rgb @ sample, source / source[1], target, transform="CAT02")
    np.testing.assert_allclose(m @ sample, want, rtol=1e-9)


def test_white_balance_none_and_named():
    np.testing.assert_allclose(d.balance_matrix("none"), np.eye(3), atol=1e-9)  # BT.709 is the display's
    d65 = d.balance_matrix("D65") @ parse_colour({"illuminant": "D65"})
    np.testing.assert_allclose(d65 / d65.mean(), [1, 1, 1], atol=1e-9)
    d50 = d.balance_matrix("D50") @ parse_colour({"illuminant": "D50"})
    np.testing.assert_allclose(d50 / d50.mean(), [1, 1, 1], atol=1e-9)


def test_scene_illuminant_is_the_sun_and_the_sky(tmp_path):
    s = load_scene(scene_file(tmp_path))
    np.testing.assert_allclose(d.scene_illuminant(s), s.lights[0].irradiance + np.pi * s.background, rtol=1e-12)
    warm = d.scene_illuminant(s)
    assert warm[0] > warm[1] > warm[2]  # a sun 35 degrees high through the air is warm
    s = load_scene(scene_file(tmp_path, ambient=[0.1, 0.2, 0.3], background=[0, 0, 0],
                              lights=[{"type": "point", "position": [0, 0, 2], "intensity": 8}]))
    np.testing.assert_allclose(d.scene_illuminant(s), 8 / 4 + np.pi * np.array([0.1, 0.2, 0.3]))


# --- exposure ----------------------------------------------------------------------------------------------

def test_auto_exposure_brings_its_percentile_to_its_level():
    im = image(40, 50)
    im[im[..., 3] <= d.AUTO_ALPHA, :3] *= 0.3  # a sky darker than the cloud
    stops = d.auto_exposure(im[..., :3], im[..., 3], "aces")
    y = d.luminance(im[..., :3])[im[..., 3] > d.AUTO_ALPHA]
    assert np.percentile(y, d.AUTO_PERCENTILE) * 2 ** stops == pytest.approx(d.AUTO_LEVEL["aces"], rel=1e-12)
    # a background (alpha <= 0.5) darker than the cloud does not count ...
    dark = im.copy()
    dark[dark[..., 3] <= d.AUTO_ALPHA, :3] *= 0.01
    assert d.auto_exposure(dark[..., :3], dark[..., 3], "aces") == stops
    # ... a brighter one does: the frame's percentile then reaches the level, the cloud stays below it
    bright = im.copy()
    bright[bright[..., 3] <= d.AUTO_ALPHA, :3] = 1e3
    lower = d.auto_exposure(bright[..., :3], bright[..., 3], "aces")
    assert np.percentile(d.luminance(bright[..., :3]), d.AUTO_PERCENTILE) * 2 ** lower == pytest.approx(
        d.AUTO_LEVEL["aces"], rel=1e-12)
    assert lower < stops
    # no cloud: every pixel counts; black: 0 stops
    assert d.auto_exposure(im[..., :3], np.zeros(im.shape[:2]), "raw") == pytest.approx(
        np.log2(d.AUTO_LEVEL["raw"] / np.percentile(d.luminance(im[..., :3]), d.AUTO_PERCENTILE)))
    assert d.auto_exposure(np.zeros((3, 3, 3)), None) == 0.0


def test_auto_exposure_in_the_raw_picture():
    im = image(40, 50)
    im[..., :3] = im[..., :1] * 0.1  # greys, all below the level: nothing clips
    codes, stops = d.display_image(im, display="raw", exposure="auto")
    np.testing.assert_array_equal(codes, encode_srgb(im[..., :3], stops))


# --- the displays ------------------------------------------------------------------------------------------

def test_raw_is_the_old_encoding_byte_for_byte(tmp_path):
    im = image()
    for stops in (0.0, 1.0, -2.5):
        write_png(im, tmp_path / "a.png", exposure=stops, display="raw")
        old = encode_srgb(im[..., :3], stops)
        np.testing.assert_array_equal(np.asarray(Image.open(tmp_path / "a.png")), old)
    write_png(im, tmp_path / "b.png", display="raw")  # raw's default exposure: 0 stops
    np.testing.assert_array_equal(np.asarray(Image.open(tmp_path / "b.png")), encode_srgb(im[..., :3], 0.0))
    # another working colourspace: the old path converts it to sRGB's primaries the same way
    codes, _ = d.display_image(im, "ACEScg", display="raw", exposure=0.5)
    np.testing.assert_array_equal(codes, encode_srgb(im[..., :3], 0.5, "ACEScg"))


def test_aces_is_a_tone_curve_that_keeps_greys_grey():
    greys = np.repeat(np.geomspace(1e-3, 64, 49)[:, None], 3, axis=1)[None]
    shown = d.ocio_display(greys)[0]
    np.testing.assert_allclose(shown[:, 0], shown[:, 1], atol=2e-6)
    np.testing.assert_allclose(shown[:, 2], shown[:, 1], atol=2e-6)
    assert np.all(np.diff(shown[:, 1]) > 0)           # monotone
    assert 0.99 < shown[-1, 1] < 1.0                  # highlights roll off towards white, not clipped at 1
    level = d.ocio_display(np.full((1, 1, 3), d.AUTO_LEVEL["aces"]))[0, 0, 1]
    assert 0.75 < level < 0.9                         # auto exposure's level: bright, below the shoulder's end
    assert d.ocio_processor()[2].startswith("ACES")


def test_default_picture_is_managed(tmp_path):
    im = image()
    write_png(im, tmp_path / "a.png")  # aces, no scene: white balance none, auto exposure
    stops = d.auto_exposure(im[..., :3], im[..., 3], "aces")
    want = np.rint(d.ocio_display(im[..., :3] * 2 ** stops) * 255).astype(np.uint8)
    np.testing.assert_array_equal(np.asarray(Image.open(tmp_path / "a.png")), want)


def test_exr_is_untouched_by_the_display_settings(tmp_path):
    im = image()
    illuminant = parse_colour({"temperature": 4000})
    blobs = []
    for i, kw in enumerate([dict(display="raw"), dict(display="aces", white_balance="none", exposure=3.0),
                            dict(display="aces", white_balance=tuple(illuminant), exposure="auto"),
                            dict(display="raw", white_balance="D50", exposure="auto")]):
        tmps = [str(tmp_path / f"{i}.exr"), str(tmp_path / f"{i}.png")]
        encode_outputs(im, tmps, exposure=kw.pop("exposure", 0.0), **kw)
        blobs.append((tmp_path / f"{i}.exr").read_bytes())
    assert all(b == blobs[0] for b in blobs[1:])


def test_cli_display_flags(tmp_path, capsys):
    from cloudmeta.cli import main
    scene = str(ROOT / "scenes" / "cumulus.yaml")
    common = ["render", scene, "--width", "12", "--height", "9", "--quality", "draft", "-q"]
    assert main(common + ["-v", "-o", str(tmp_path / "a.exr"), "--png", str(tmp_path / "a.png")]) == 0
    assert "PNG: ACES" in capsys.readouterr().out  # a detail, behind -v
    assert main(common + ["-o", str(tmp_path / "b.exr"), "--png", str(tmp_path / "b.png"), "--display", "raw",
                          "--exposure", "1.5"]) == 0
    assert (tmp_path / "a.exr").read_bytes() == (tmp_path / "b.exr").read_bytes()
    from cloudmeta.api.io import read_exr
    linear = read_exr(tmp_path / "b.exr")[0].astype(np.float64)
    np.testing.assert_array_equal(np.asarray(Image.open(tmp_path / "b.png")), encode_srgb(linear[..., :3], 1.5))
    assert main(common + ["-v", "-o", str(tmp_path / "c.exr"), "--png", str(tmp_path / "c.png"),
                          "--white-balance", "D50", "--exposure", "auto"]) == 0
    assert "white balance D50, exposure auto" in capsys.readouterr().out


# --- bad settings ------------------------------------------------------------------------------------------

@pytest.mark.parametrize("output, key, expect", [
    ({"display": "srgb"}, "output.display", "aces, raw"),
    ({"white_balance": "D66"}, "output.white_balance", "D65"),
    ({"white_balance": [1, 1, 1]}, "output.white_balance", "CIE illuminant"),
    ({"exposure": "bright"}, "output.exposure", "auto or a finite number"),
    ({"exposure": 100}, "output.exposure", "+-64"),
    ({"tone": "filmic"}, "output.tone", ""),
])
def test_bad_output_keys_name_their_path(tmp_path, output, key, expect):
    with pytest.raises(SceneError) as exc:
        load_scene(scene_file(tmp_path, output))
    text = str(exc.value)
    assert "\n" not in text and f"{key}:" in text and expect in text and "s.yaml" in text


def test_output_keys_load(tmp_path):
    s = load_scene(scene_file(tmp_path, {"display": "raw", "white_balance": "D50", "exposure": "auto"}))
    assert (s.output.display, s.output.white_balance, s.output.exposure) == ("raw", "D50", "auto")
    s = load_scene(scene_file(tmp_path))
    assert (s.output.display, s.output.white_balance, s.output.exposure) == ("aces", None, None)
    assert png_settings(s.output.display, None, None, s)[:3] == ("aces", "scene", "auto")
    assert png_settings("raw", None, None, s)[:3] == ("raw", "none", 0.0)


@pytest.mark.parametrize("kw, label", [
    (dict(display="filmic"), "display"), (dict(white_balance="blue"), "white_balance"),
    (dict(white_balance=[1, -1, 0]), "white_balance"), (dict(exposure="bright"), "exposure"),
    (dict(exposure=float("nan")), "exposure"), (dict(white_balance="scene"), "white_balance"),
])
def test_bad_api_settings_are_one_line_errors(tmp_path, kw, label):
    with pytest.raises(InputError) as exc:
        write_png(image(), tmp_path / "x.png", **kw)
    assert str(exc.value).startswith(f"{label}:") and "\n" not in str(exc.value)
    assert not (tmp_path / "x.png").exists()


@pytest.mark.parametrize("flag, value, expect", [("--white-balance", "D66", "--white-balance:"),
                                                  ("--exposure", "2000", "within +-64")])
def test_bad_cli_flags(tmp_path, capsys, flag, value, expect):
    from cloudmeta.cli import main
    assert main(["render", str(ROOT / "scenes" / "cumulus.yaml"), "-o", str(tmp_path / "o.exr"), "--png",
                 str(tmp_path / "o.png"), flag, value]) == 2
    err = capsys.readouterr().err
    assert expect in err and err.count("\n") == 1


def test_missing_opencolorio_says_what_to_install(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "PyOpenColorIO", None)  # import fails
    d.ocio_processor.cache_clear()
    try:
        with pytest.raises(InputError, match="pip install opencolorio") as exc:
            write_png(image(), tmp_path / "a.png")
        assert "\n" not in str(exc.value)
        write_png(image(), tmp_path / "b.png", display="raw")  # the raw path needs no OpenColorIO
        assert (tmp_path / "b.png").exists() and not (tmp_path / "a.png").exists()
    finally:
        d.ocio_processor.cache_clear()


# --- sequences and tiles -----------------------------------------------------------------------------------

def _frames_scene(tmp_path):
    from tests.scene.test_animation import ANIMATED, write_scene
    return write_scene(tmp_path, ANIMATED)


def _png(path):
    return np.asarray(Image.open(path))


def test_a_sequence_gets_one_picture_held_from_its_first_frame(tmp_path):
    from cloudmeta.api.cluster import render_frames
    from cloudmeta.api.io import read_exr
    scene = _frames_scene(tmp_path)
    out = tmp_path / "a"
    out.mkdir()
    report = render_frames(scene, range(3), out / "f_{frame}.exr", png=out / "f_{frame}.png", progress=False)
    assert report.rendered == [0, 1, 2] and report.png == ("aces", "scene", "auto") and report.exposure_frame == 0
    first = load_scene(scene, frame=0)
    illuminant = d.scene_illuminant(first)  # the white balance of the whole sequence: its first frame's light
    images = [read_exr(out / f"f_{f}.exr")[0] for f in range(3)]
    assert report.stops == d.exposure_of(images[0], illuminant=illuminant)
    for f in range(3):  # every frame: the managed picture at the held exposure and white balance
        want, _ = d.display_image(images[f], display="aces", white_balance="scene", exposure=report.stops,
                                  illuminant=illuminant)
        np.testing.assert_array_equal(_png(out / f"f_{f}.png"), want)
    # the light brightens over the sequence: an exposure chosen per frame would have changed (flicker)
    assert abs(d.exposure_of(images[2], illuminant=illuminant) - report.stops) > 0.05
    per_frame, _ = d.display_image(images[2], display="aces", white_balance="scene", exposure="auto",
                                   illuminant=illuminant)
    assert not np.array_equal(_png(out / "f_2.png"), per_frame)
    # a re-run that skips the first frame reads its EXR back: the same exposure, the same bytes
    before = (out / "f_1.png").read_bytes()
    (out / "f_1.png").unlink()
    (out / "f_1.exr").unlink()
    again = render_frames(scene, range(3), out / "f_{frame}.exr", png=out / "f_{frame}.png", progress=False)
    assert again.skipped == [0, 2] and again.rendered == [1] and again.stops == report.stops
    assert (out / "f_1.png").read_bytes() == before
    # ... and where that EXR cannot be read, one line names it before any work
    (out / "f_1.exr").unlink()
    (out / "f_0.exr").write_bytes(b"not an exr")
    with pytest.raises(OutputError, match=r"f_0\.exr: cannot read frame 0, whose image sets the sequence's auto "):
        render_frames(scene, range(3), out / "f_{frame}.exr", png=out / "f_{frame}.png", progress=False)
    assert not (out / "f_1.exr").exists()
    # the first frame asked for sets it, whatever its number
    other = render_frames(scene, [2, 0], tmp_path / "b_{frame}.exr", png=tmp_path / "b_{frame}.png", progress=False)
    assert other.exposure_frame == 2 and other.stops == d.exposure_of(
        images[2], illuminant=d.scene_illuminant(load_scene(scene, frame=2)))


def test_sequence_display_settings_leave_the_exrs_bit_identical(tmp_path):
    from cloudmeta.api.cluster import render_frames
    from cloudmeta.api.io import read_exr
    from cloudmeta.renderer import render
    scene = _frames_scene(tmp_path)
    runs = {"aces": {}, "raw": dict(display="raw", exposure=1.5),
            "d50": dict(white_balance="D50", exposure="auto"), "tiled": dict(tiles=(2, 2))}
    for name, kw in runs.items():
        (tmp_path / name).mkdir()
        report = render_frames(scene, [0, 2], tmp_path / name / "f_{frame}.exr",
                               png=tmp_path / name / "f_{frame}.png", progress=False, **kw)
        assert report.rendered == [0, 2]
    for f in (0, 2):
        blobs = [(tmp_path / name / f"f_{f}.exr").read_bytes() for name in runs]
        assert all(b == blobs[0] for b in blobs[1:])
        # the single image's pixels, as cloudmeta.cli writes them
        assert np.array_equal(read_exr(tmp_path / "aces" / f"f_{f}.exr")[0],
                              render(load_scene(scene, frame=f), progress=False))
        # a tiled frame is displayed once assembled: one exposure for the frame, the same picture
        assert (tmp_path / "tiled" / f"f_{f}.png").read_bytes() == (tmp_path / "aces" / f"f_{f}.png").read_bytes()
        linear = read_exr(tmp_path / "raw" / f"f_{f}.exr")[0].astype(np.float64)
        np.testing.assert_array_equal(_png(tmp_path / "raw" / f"f_{f}.png"), encode_srgb(linear[..., :3], 1.5))
    assert not np.array_equal(_png(tmp_path / "d50" / "f_0.png"), _png(tmp_path / "aces" / "f_0.png"))


def test_sequence_settings_come_from_the_scene_and_are_checked_before_work(tmp_path, monkeypatch, capsys):
    from cloudmeta.api.cluster import render_frames
    from cloudmeta.cli import main
    from tests.scene.test_animation import ANIMATED, write_scene
    raw = write_scene(tmp_path, ANIMATED + "output: {display: raw, exposure: -1}\n", "raw.yaml")
    report = render_frames(raw, [0], tmp_path / "r.exr", png=tmp_path / "r.png", progress=False)
    assert report.png == ("raw", "none", -1.0) and report.stops == -1.0 and report.exposure_frame is None
    scene = _frames_scene(tmp_path)
    for kw, label in ((dict(display="srgb"), "display:"), (dict(white_balance="D66"), "white_balance:"),
                      (dict(exposure="bright"), "exposure:")):
        with pytest.raises(InputError) as exc:
            render_frames(scene, [0], tmp_path / "x_{frame}.exr", png=tmp_path / "x_{frame}.png", progress=False,
                          **kw)
        assert str(exc.value).startswith(label)
    monkeypatch.setitem(sys.modules, "PyOpenColorIO", None)  # OpenColorIO missing: refused before rendering
    d.ocio_processor.cache_clear()
    try:
        assert main(["render", str(scene), "--frames", "0:2", "-o", str(tmp_path / "c_{frame}.exr"), "--png",
                     str(tmp_path / "c_{frame}.png"), "-q"]) == 2
        err = capsys.readouterr().err
        assert "pip install opencolorio" in err and err.count("\n") == 1
        assert not list(tmp_path.glob("c_*"))
        assert main(["render", str(scene), "--frames", "0:2", "-o", str(tmp_path / "c_{frame}.exr"), "--png",
                     str(tmp_path / "c_{frame}.png"), "-q", "--display", "raw"]) == 0
    finally:
        monkeypatch.undo()
        d.ocio_processor.cache_clear()
    assert main(["render", str(scene), "--frames", "0:2", "-o", str(tmp_path / "v_{frame}.exr"), "--png",
                 str(tmp_path / "v_{frame}.png"), "-q", "-v", "--white-balance", "D50"]) == 0
    said = capsys.readouterr().out
    assert "white balance D50, exposure auto" in said and "measured on frame 0, held for every frame" in said
    assert main(["render", str(scene), "--frames", "0:2", "-o", str(tmp_path / "w_{frame}.exr"), "--png",
                 str(tmp_path / "w_{frame}.png"), "-q", "--white-balance", "D66"]) == 2
    assert "--white-balance:" in capsys.readouterr().err
