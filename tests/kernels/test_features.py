"""kernels.features: the helpers that compile to their trivial case where a scene lacks surfaces and maps."""
from pathlib import Path

import numpy as np
from numba import njit

from cloudmeta.kernels import optional as features
from cloudmeta.renderer.pack import pack_scene
from cloudmeta.scene import load_scene

ROOT = Path(__file__).resolve().parents[2]


@njit
def _probe(surf, maps, o, d):
    return features.surface_balls(surf), features.light_map(maps, 0), features.misses_surfaces(o, d, surf)


def _records(name):
    return pack_scene(load_scene(ROOT / name, width=4, height=3), 0)[1]


def test_without_surfaces_and_maps_the_helpers_give_the_trivial_answer():
    rec = _records("scenes/cumulus.yaml")
    assert rec.surfaces is None and rec.lights.maps is None
    o, d = np.zeros(3), np.array([0.0, 1.0, 0.0])
    assert _probe(None, None, o, d) == (0, -1, True)
    assert (features.surface_balls(None), features.light_map(None, 0), features.misses_surfaces(o, d, None)) == \
        (0, -1, True)


def test_with_surfaces_the_helpers_read_the_records_as_their_python_twins_do():
    rec = _records("docs/surfaces.yaml")
    surf, maps = rec.surfaces, rec.lights.maps
    assert surf is not None and maps is not None
    o = np.array([0.0, -9.0, 3.0])
    for d in (np.array([0.0, 1.0, -0.2]), np.array([0.0, -1.0, 0.0])):
        d = d / np.linalg.norm(d)
        got = _probe(surf, maps, o, d)
        assert got == (features.surface_balls(surf), features.light_map(maps, 0),
                       features.misses_surfaces(o, d, surf))
    assert got[0] == len(surf.centers) and got[1] == -1
    assert _probe(surf, maps, o, np.array([0.0, 1.0, -0.2]) / np.hypot(1, 0.2))[2] is False
    far = np.array([0.0, -100.0, 50.0])
    assert _probe(surf, maps, far, np.array([0.0, -1.0, 0.0]))[2] is True  # away from every box
