"""kernels.ground: the exact transmittance from points towards the sun through every medium, 0 behind a
surface, against the naive optical depth of each medium (tests/naive.py) and a surface's naive first hit; the
same on any number of threads."""
import numba
import numpy as np
import yaml

from cloudmeta.renderer.ground import sun_transmittance
from cloudmeta.renderer.pack import pack_scene
from cloudmeta.scene import load_scene
from tests import naive


def two_media_scene(tmp_path, rng, surface=False):
    """Two media of random balls (excess and field density) and, with ``surface``, one spherical surface."""
    media = []
    for mode, scale, shift in (("excess", 2.5, -0.8), ("field", 1.2, 0.9)):
        centres = rng.uniform(-1.2, 1.2, (6, 3)) + [shift, 0.0, 1.5]
        media.append({"density": {"mode": mode, "scale": scale}, "kernel": "wyvill6", "threshold": 0.5,
                      "balls": [{"center": c.tolist(), "radius": float(r)}
                                for c, r in zip(centres, rng.uniform(0.8, 1.6, 6))]})
    data = {"image": {"width": 4, "height": 4}, "camera": {"position": [0, -9, 1.5], "look_at": [0, 0, 1.5]},
            "background": {"sky": {"elevation": 55, "azimuth": 30, "ground_height": -1.0}}, "media": media}
    if surface:
        data["surfaces"] = [{"kernel": "wyvill6", "threshold": 0.5,
                             "balls": [{"center": [0.3, 0.2, 3.8], "radius": 1.4}]}]
    path = tmp_path / "two.yaml"
    path.write_text(yaml.safe_dump(data))
    return load_scene(path)


def ground_points(rng, n):
    return np.column_stack([rng.uniform(-4, 4, n), rng.uniform(-4, 4, n), np.full(n, -1.0)])


def test_transmittance_through_two_media_against_the_naive_depth(tmp_path, rng):
    s = two_media_scene(tmp_path, rng)
    packed = pack_scene(s, 0)
    points = ground_points(rng, 300)
    l_dir = s.ground.direction
    got = sun_transmittance(packed.records, l_dir, points, packed.quadrature.tol_t)
    media = [(m.blob, m.density.mode, m.density.scale) for m in s.media]
    want = np.array([np.exp(-naive.media_optical_depth(media, p, l_dir)) for p in points])
    assert np.count_nonzero(want < 0.99) > 30 and np.count_nonzero(want == 1.0) > 30  # shaded and in the sun
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12)
    # the same, bit for bit, on one thread
    threads = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        np.testing.assert_array_equal(sun_transmittance(packed.records, l_dir, points, packed.quadrature.tol_t), got)
    finally:
        numba.set_num_threads(threads)


def test_a_surface_in_the_way_gives_zero(tmp_path, rng):
    s = two_media_scene(tmp_path, rng, surface=True)
    packed = pack_scene(s, 0)
    points = ground_points(rng, 300)
    l_dir = s.ground.direction
    got = sun_transmittance(packed.records, l_dir, points, packed.quadrature.tol_t)
    media = [(m.blob, m.density.mode, m.density.scale) for m in s.media]
    surface = s.surfaces[0].blob
    blocked = np.array([len(naive.crossings(surface, p, l_dir)) > 0 for p in points])
    want = np.array([np.exp(-naive.media_optical_depth(media, p, l_dir)) for p in points])
    want[blocked] = 0.0
    assert np.count_nonzero(blocked) > 10 and np.count_nonzero(~blocked & (want < 0.99)) > 10
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12)
