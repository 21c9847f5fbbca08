"""cloudmeta.colour: scene colours, chromaticities and the sRGB preview encoding (docs/model.md §7)."""
import numpy as np
import pytest

from cloudmeta.scene.colour import (DEFAULT_COLOURSPACE, chromaticities, encode_srgb, parse_colour,
                              working_colourspace)
from cloudmeta.errors import InputError


def luminance(rgb, colourspace=DEFAULT_COLOURSPACE):
    return float(working_colourspace(colourspace).matrix_RGB_to_XYZ[1] @ rgb)


def test_01_rgb_list_passes_through():
    rgb = parse_colour([0.25, 0.5, 2], "background")
    assert rgb.dtype == np.float64 and rgb.shape == (3,)
    np.testing.assert_array_equal(rgb, [0.25, 0.5, 2.0])


def test_02_d65_is_white_in_bt709():
    np.testing.assert_allclose(parse_colour({"illuminant": "D65"}, "c"), [1, 1, 1], atol=1e-3)


def test_03_blackbody_6504k_is_near_white_with_unit_luminance():
    rgb = parse_colour({"temperature": 6504}, "c")
    np.testing.assert_allclose(rgb, [1, 1, 1], atol=0.05)
    assert luminance(rgb) == pytest.approx(1.0, abs=1e-9)


def test_04_blackbody_3000k_is_reddish():
    r, g, b = parse_colour({"temperature": 3000}, "c")
    assert r > g > b > 0
    assert luminance([r, g, b]) == pytest.approx(1.0, abs=1e-9)


def test_05_illuminant_a_is_warmer_than_d65():
    r, g, b = parse_colour({"illuminant": "A"}, "c")
    assert r > g > b


def test_06_out_of_gamut_blackbody_is_clipped_to_non_negative():
    # 1000 K lies outside the BT.709 gamut: its blue would be negative
    rgb = parse_colour({"temperature": 1000}, "c")
    assert rgb.min() == 0.0 and rgb[0] > 1


def test_07_blackbody_is_cached():
    a = parse_colour({"temperature": 4321}, "c")
    b = parse_colour({"temperature": 4321}, "c")
    np.testing.assert_array_equal(a, b)


def test_08_other_working_colourspace():
    # D65 in ACEScg (white D60) is not neutral; with no adaptation it must differ from (1, 1, 1)
    rgb = parse_colour({"illuminant": "D65"}, "c", "ACEScg")
    assert luminance(rgb, "ACEScg") == pytest.approx(1.0, abs=1e-9)
    assert not np.allclose(rgb, 1, atol=1e-2)


@pytest.mark.parametrize("value, where, fragment", [
    ([1, 2], "c", "[r, g, b]"),
    ([1, -0.5, 0], "c[1]", ">= 0"),
    ([1, True, 0], "c[1]", "finite number"),
    ([1, float("nan"), 0], "c[1]", "finite number"),
    ("red", "c", "temperature"),
    ({"temperature": 500}, "c.temperature", "[1000, 40000]"),
    ({"temperature": "hot"}, "c.temperature", "kelvin"),
    ({"illuminant": "D66"}, "c.illuminant", "SDS_ILLUMINANTS"),
    ({"temperature": 5000, "illuminant": "D65"}, "c", "expected"),
])
def test_09_bad_colours_raise_value_error_with_key_path(value, where, fragment):
    with pytest.raises(ValueError) as exc:
        parse_colour(value, "c")
    assert str(exc.value).startswith(f"{where}: ")
    assert fragment in str(exc.value)


def test_10_unknown_colourspace():
    with pytest.raises(InputError, match="colourspace"):
        working_colourspace("Not A Space")


def test_11_chromaticities_of_bt709():
    assert chromaticities() == pytest.approx((0.64, 0.33, 0.30, 0.60, 0.15, 0.06, 0.3127, 0.3290))


def test_12_encode_srgb_values():
    out = encode_srgb(np.array([[0.0, 0.5, 1.0], [2.0, -1.0, 0.0031308]]))
    assert out.dtype == np.uint8
    # sRGB(0.5) = 0.7354 -> 187.5 -> 188; sRGB(0.0031308) = 0.0404 -> 10
    np.testing.assert_array_equal(out, [[0, 188, 255], [255, 0, 10]])


def test_13_encode_srgb_exposure_is_in_stops():
    np.testing.assert_array_equal(encode_srgb([0.25, 0.25, 0.25], exposure=1.0), encode_srgb([0.5, 0.5, 0.5]))


def test_14_encode_srgb_converts_other_primaries():
    # ACEScg white maps to the display white through chromatic adaptation
    np.testing.assert_array_equal(encode_srgb([1.0, 1.0, 1.0], colourspace="ACEScg"), [255, 255, 255])
    r, g, b = encode_srgb([1.0, 0.0, 0.0], colourspace="ACEScg")
    assert r == 255 and g == 0 and b == 0  # wider than sRGB: clipped


def test_15_encode_srgb_refuses_nan():
    with pytest.raises(InputError, match="linear_rgb"):
        encode_srgb([np.nan, 0, 0])


def _fresh_store(monkeypatch, folder):
    import cloudmeta.scene.colour as cc
    monkeypatch.setenv("CLOUDMETA_CACHE_DIR", str(folder))
    monkeypatch.delenv("CLOUDMETA_NO_CACHE", raising=False)
    monkeypatch.setattr(cc, "_STORE", None)
    cc._xyz_blackbody.cache_clear()
    cc._xyz_illuminant.cache_clear()
    return cc


def test_16_stored_numbers_are_colour_sciences_bit_for_bit(monkeypatch, tmp_path):
    import colour

    cc = _fresh_store(monkeypatch, tmp_path)
    computed = [parse_colour({"temperature": 5200}, "c"), parse_colour({"illuminant": "A"}, "c", "ACEScg"),
                np.array(chromaticities("ACEScg"))]
    assert len(list(tmp_path.glob("colour-*.json"))) == 1
    cc = _fresh_store(monkeypatch, tmp_path)  # a later process: read back from the file
    stored = [parse_colour({"temperature": 5200}, "c"), parse_colour({"illuminant": "A"}, "c", "ACEScg"),
              np.array(chromaticities("ACEScg"))]
    for a, b in zip(computed, stored):
        np.testing.assert_array_equal(a, b)
    xyz = np.array(cc._xyz_unit_luminance(colour.sd_blackbody(5200.0)))
    np.testing.assert_array_equal(stored[0], np.maximum(
        colour.RGB_COLOURSPACES[DEFAULT_COLOURSPACE].matrix_XYZ_to_RGB @ xyz, 0.0))


def test_16b_processes_side_by_side_keep_each_others_colours(monkeypatch, tmp_path):
    """Process A reads the store, process B stores a colour, then A stores another: the file keeps both
    (a lost update made a parallel test run import colour-science again, and its start-up test fail)."""
    import json

    cc = _fresh_store(monkeypatch, tmp_path)
    parse_colour([1, 1, 1], "c")  # A: reads the (empty) store, stores the default colourspace
    store_a = cc._STORE
    cc = _fresh_store(monkeypatch, tmp_path)
    parse_colour({"temperature": 5200}, "c")  # B, started after A: stores a blackbody
    monkeypatch.setattr(cc, "_STORE", store_a)  # back to A, which has not seen B's entry
    cc._xyz_illuminant.cache_clear()
    parse_colour({"illuminant": "A"}, "c")  # A stores an illuminant
    keys = set(json.loads(next(tmp_path.glob("colour-*.json")).read_text()))
    assert {"blackbody:5200.0", "illuminant:A"} <= keys, keys


def test_17_unknown_names_still_fail_with_a_store(monkeypatch, tmp_path):
    _fresh_store(monkeypatch, tmp_path)
    parse_colour([1, 1, 1], "c")
    with pytest.raises(InputError, match="colourspace"):
        parse_colour([1, 1, 1], "c", "Not A Space")
    with pytest.raises(ValueError, match="c.illuminant"):
        parse_colour({"illuminant": "NOPE"}, "c")


def test_18_a_render_imports_neither_colour_science_nor_plotting_libraries(tmp_path):
    """With its colours stored, loading and rendering a scene and writing its EXR and PNG imports none of
    colour-science, matplotlib, pyvista, tqdm (no progress bar)."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    probe = (
        "import sys, cloudmeta as cm\n"
        f"s = cm.load_scene({str(root / 'scenes' / 'cumulus.yaml')!r}, width=4, height=3)\n"
        "img = cm.render(s, progress=False)\n"
        f"cm.write_exr(img, {str(tmp_path / 'x.exr')!r})\n"
        "print(sorted(m for m in ('colour', 'matplotlib', 'pyvista', 'tqdm') if m in sys.modules))\n"
        f"cm.write_png(img, {str(tmp_path / 'x.png')!r})\n"
        "print(sorted(m for m in ('colour', 'matplotlib', 'pyvista', 'tqdm') if m in sys.modules))\n")
    env = dict(os.environ, PYTHONPATH=str(root))
    runs = [subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, check=True)
            for _ in range(2)]  # the first may have to store the colours
    assert runs[1].stdout.splitlines() == ["[]", "[]"]


def test_19_srgb_table_reproduces_colour_science_for_every_double_tried():
    import colour

    import cloudmeta.scene.colour as cc

    thresholds = cc._srgb_thresholds()
    rng = np.random.default_rng(3)
    x = np.concatenate([rng.uniform(-0.1, 1.2, 200_000), rng.uniform(0, 0.01, 100_000),
                        10.0 ** rng.uniform(-12, 0, 100_000),
                        thresholds, np.nextafter(thresholds, -np.inf), np.nextafter(thresholds, np.inf),
                        [0.0, -0.0, 0.0031308, 1.0, 2.0, -1.0, 5e-324]])
    expected = np.rint(np.clip(colour.cctf_encoding(x, function="sRGB"), 0.0, 1.0) * 255.0).astype(np.uint8)
    np.testing.assert_array_equal(encode_srgb(np.repeat(x[:, None], 3, axis=1))[:, 0], expected)
