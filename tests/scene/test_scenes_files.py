"""The scenes in scenes/: every YAML loads, the stand-ins for the paper's figures have the balls they claim
and surfaces in one piece, and every generator (scenes/make_*.py) writes exactly the files committed."""
import filecmp
import importlib.util
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy import ndimage

from cloudmeta import load_scene
from cloudmeta.scene.blob import rotation_matrix
from cloudmeta.api.viewer import sample_grid

SCENES = Path(__file__).resolve().parents[2] / "scenes"
YAMLS = sorted(SCENES.glob("*.yaml"))
GENERATORS = sorted(SCENES.glob("make_*.py"))


def test_found_the_scenes():
    names = {p.stem for p in YAMLS}
    assert {"cumulus", "organic", "hand", "creature", "cumulus_landscape", "kernels"} <= names
    assert len(GENERATORS) >= 6


@pytest.mark.parametrize("path", YAMLS, ids=lambda p: p.name)
def test_every_scene_loads(path):
    scene = load_scene(path)
    assert scene.media or scene.surfaces


def _balls(scene, kind):
    return [len(thing.blob) for thing in getattr(scene, kind)]


def test_ball_counts_of_the_paper_stand_ins():
    # the paper: a stomach of 190 balls, a hand of 94, a killer whale of 890 on a sea floor of 740
    organic = load_scene(SCENES / "organic.yaml")
    assert _balls(organic, "surfaces") == [190] and not organic.media
    assert (organic.surfaces[0].blob.weights < 0).sum() == 4  # the crater
    hand = load_scene(SCENES / "hand.yaml")
    assert _balls(hand, "surfaces") == [94]
    assert not hand.surfaces[0].blob.is_sphere.all()  # ellipsoid fingers
    creature = load_scene(SCENES / "creature.yaml")
    whale, floor = _balls(creature, "surfaces")
    assert whale >= 500 and floor >= 700 and whale + floor >= 1500
    assert [m.density.mode for m in creature.media] == ["uniform"]
    landscape = load_scene(SCENES / "cumulus_landscape.yaml")
    assert _balls(landscape, "media") == [77] and _balls(landscape, "surfaces") == [400]
    kernels = load_scene(SCENES / "kernels.yaml")
    assert sorted(s.blob.kernel for s in kernels.surfaces) == ["blinn", "murakami4", "nishimura", "wyvill6"]


@pytest.mark.parametrize("name", ["organic", "hand", "creature", "cumulus_landscape"])
def test_surfaces_are_one_piece(name):
    """Each surface's inside F >= T, sampled on a 72-point grid, is one connected region."""
    for surface in load_scene(SCENES / f"{name}.yaml").surfaces:
        grid = sample_grid(surface.blob, 72)
        inside = np.asarray(grid.point_data["field"]).reshape(tuple(grid.dimensions)[::-1]) >= surface.blob.threshold
        _, pieces = ndimage.label(inside)
        assert pieces == 1, f"{name}: surface {surface.name} is in {pieces} pieces"


@pytest.mark.parametrize("script", GENERATORS, ids=lambda p: p.name)
def test_generators_reproduce_their_files(script, tmp_path):
    subprocess.run([sys.executable, str(script), str(tmp_path)], check=True, capture_output=True, cwd=SCENES.parent)
    written = sorted(tmp_path.iterdir())
    assert written, f"{script.name} wrote nothing"
    for path in written:
        committed = SCENES / path.name
        assert committed.exists(), f"{script.name} writes {path.name}, which scenes/ lacks"
        assert filecmp.cmp(path, committed, shallow=False), f"{script.name}: {path.name} differs from scenes/"


def _shapes():
    spec = importlib.util.spec_from_file_location("scene_shapes", SCENES / "shapes.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_ellipsoid_rows_put_the_radii_on_the_asked_axes():
    shapes = _shapes()
    rng = np.random.default_rng(1)
    for _ in range(50):
        axis, normal = rng.normal(size=3), rng.normal(size=3)
        row = shapes.ellipsoid(rng.normal(size=3), axis, normal, (3.0, 2.0, 1.0))
        q = rotation_matrix(np.array(row[6:9]))
        e1 = axis / np.linalg.norm(axis)
        e3 = normal - np.dot(normal, e1) * e1
        e3 /= np.linalg.norm(e3)
        np.testing.assert_allclose(q[:, 0], e1, atol=1e-12)
        np.testing.assert_allclose(q[:, 2], e3, atol=1e-12)
