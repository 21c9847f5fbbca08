"""The accuracy scene suite of issue #11 (scenes/suite/, validation/references/suite.py): every scene is what its tags
say, the suite covers every value of every axis at least twice, the generator writes the committed files,
every scene renders, the committed references are there, current and finite, and (quick check) the
references of three cheap scenes agree with validation/accuracy/single_scattering.py's independent numpy
reference."""
import filecmp
import importlib.util

import numpy as np
import pytest
import yaml

import cloudmeta as cm
from validation.accuracy import suite_references
from validation.references import suite as S

PATHS = S.scene_paths()
IDS = [p.stem for p in PATHS]


def _raw(path):
    return yaml.safe_load(path.read_text(encoding="utf-8"))


def test_at_least_12_scenes_cover_every_value_of_every_axis_twice():
    assert len(PATHS) >= 12
    cov = S.coverage()
    for axis, values in S.AXES.items():
        assert set(cov[axis]) == set(values), (axis, set(cov[axis]) ^ set(values))  # no unknown values
        for v in values:
            assert len(cov[axis][v]) >= 2, (axis, v, cov[axis][v])
    for p in PATHS:
        assert set(S.tags(p)) == set(S.AXES), p.name


@pytest.mark.parametrize("path", PATHS, ids=IDS)
def test_tags_say_what_the_scene_is(path):
    tags, raw, scene = S.tags(path), _raw(path), cm.load_scene(path)
    (med,) = raw["media"]
    (medium,) = scene.media
    assert [med["density"]["mode"]] == tags["density"]
    assert [med["phase"]["type"]] == tags["phase"]
    assert tags["ambient"] == (["yes"] if scene.ambient is not None else ["no"])
    kinds = sorted(lt["type"] for lt in raw["lights"])
    want = sorted("point" if t.startswith("point") else "directional" for t in tags["lighting"])
    assert kinds == want
    blob = medium.blob
    n = len(blob)
    geometry = tags["geometry"][0]
    expect = {"cumulus": lambda: n == 77, "bank": lambda: n >= 1000, "puffs": lambda: n == 500,
              "ellipsoids": lambda: n == 150 and not blob.is_sphere.any(),
              "carved": lambda: (blob.weights < 0).sum() >= 5,
              "deck": lambda: np.ptp(blob.centers[:, 2]) < 0.05 * np.ptp(blob.centers[:, 0]),
              "generated": lambda: n == 4000, "wisps": lambda: n == 400 and blob.is_sphere.all(),
              "rotated": lambda: n == 150 and not blob.is_sphere.any()}
    assert expect[geometry](), (geometry, n)
    assert scene.image.width * scene.image.height <= 64 * 48 and scene.image.spp == 1


def test_lamps_inside_and_outside_and_the_strongest_forward_scattering():
    from validation.accuracy.single_scattering import plain_media
    gs = []
    for p in PATHS:
        raw, tags = _raw(p), S.tags(p)
        (m,) = plain_media(raw, p.parent)
        ph = raw["media"][0]["phase"]
        gs += [ph.get("g", 0.0), ph.get("g1", 0.0)]
        lamps = [lt for lt in raw["lights"] if lt["type"] == "point"]
        for lamp in lamps:
            inside = m.field(np.array([lamp["position"]], float))[0] >= m.threshold
            assert inside == ("point_inside" in tags["lighting"]), p.name
    assert max(gs) >= 0.9


def test_generator_writes_the_committed_files(tmp_path):
    spec = importlib.util.spec_from_file_location("make_suite", S.SUITE / "make_suite.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    written = mod.write_all(tmp_path)
    assert len(written) == len(mod.BALL_SETS) + len(PATHS)
    for path in written:
        assert filecmp.cmp(path, S.SUITE / path.name, shallow=False), path.name


@pytest.mark.parametrize("path", PATHS, ids=IDS)
def test_every_scene_renders_tiny(path):
    scene = S.with_settings(cm.load_scene(path, width=8, height=6), quality="draft")
    img = cm.render(scene, progress=False)
    assert img.shape == (6, 8, 4) and np.all(np.isfinite(img))
    assert img[..., :3].min() >= 0 and img[..., :3].max() > 0
    assert 0 <= img[..., 3].min() and img[..., 3].max() <= 1 + 1e-6 and img[..., 3].max() > 0.1


@pytest.mark.parametrize("path", PATHS, ids=IDS)
def test_committed_reference_is_there_current_and_finite(path):
    entry = S.cached(path.stem)
    assert entry is not None, f"run python -m validation.accuracy.suite_references ({path.stem} has no reference)"
    ref, tight, meta = entry
    scene = cm.load_scene(path)
    assert ref.shape == tight.shape == (scene.image.height, scene.image.width, 4)
    assert np.all(np.isfinite(ref)) and np.all(np.isfinite(tight))
    assert meta["fingerprint"] == S.fingerprint(path), "stale: run python -m validation.accuracy.suite_references"
    assert meta["ref_vs_tighter"] < suite_references.CONVERGED
    assert meta["numpy_rel_rmse"] < suite_references.AGREE


#: the cheapest scenes for the numpy reference (77 or 48 balls; a sun, a lamp inside, a sun with carving)
QUICK = ("cumulus_front", "cumulus_point_inside", "carved_side")
#: the numpy reference at rtol 1e-6 is itself good to about 1e-6; at rtol 1e-8 the committed references of
#: these three scenes agree with it to 1.4e-8 .. 6.5e-8 (validation/reference_images/suite/*.json)
QUICK_BOUND = 2e-5


@pytest.mark.parametrize("name", QUICK)
def test_reference_agrees_with_the_numpy_reference(name):
    path = S.SUITE / f"{name}.yaml"
    ref = np.load(S.CACHE / f"{name}.npy").astype(np.float64)
    scene = cm.load_scene(path)
    grid = suite_references.grid_pixels(scene.image.height, scene.image.width, stride=12, offset=6)
    rad, trans, _, _ = suite_references.numpy_reference(path, grid, rtol=1e-6)
    got = ref[grid[:, 0], grid[:, 1]]
    rmse = np.sqrt(np.mean((got[:, :3] - rad) ** 2)) / np.sqrt(np.mean(rad ** 2))
    assert rmse < QUICK_BOUND, rmse
    assert np.abs(got[:, 3] - (1 - trans)).max() < 1e-5
    assert (1 - trans).max() > 0.5  # the pixels see the cloud, not only the sky


#: issue #23: the six black-background scenes held out of the presets' tuning, and the hardest tuning scene
HELD_OUT = ("generated_front", "generated_grazing", "wisps_front", "wisps_point", "rotated_side", "rotated_back")


@pytest.mark.parametrize("name", HELD_OUT + ("deck_grazing",))
@pytest.mark.parametrize("preset", ["draft", "default"])
def test_presets_keep_their_target_relative_to_the_scattered_light(name, preset):
    """Each preset's target (draft 3e-3, default 1e-3) holds relative to the mean scattered radiance,
    against the committed converged reference, on scenes nobody tuned on."""
    path = S.SUITE / f"{name}.yaml"
    scene = cm.load_scene(path)
    img = cm.render(S.with_settings(scene, quality=preset), progress=False)
    ref = np.load(S.CACHE / f"{name}.npy").astype(np.float64)
    assert S.rel_rmse_scattered(img, ref, scene.background) <= S.TARGETS[preset]
