"""The approximate mode's grid method (renderer.fluence, kernels.fluence): photons deposit the light scattered
towards the camera on a grid; the quadrature gathers it. It keeps the white furnace, agrees with the unbiased
estimator on a small cloud, does not depend on the thread count, and is compiled only where it is used."""
import os
import subprocess
import sys
import textwrap
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from cloudmeta.errors import SceneError
from cloudmeta.kernels.optics import HG, phase
from cloudmeta.renderer import render, render_frame
from cloudmeta.kernels.fluence import COLLISIONS, FLIGHTS
from cloudmeta.kernels.kinds import DIRECTIONAL
from cloudmeta.renderer.fluence import delta_split, phase_peak, with_radiance_grid
from cloudmeta.renderer.multiple import render_multiple
from cloudmeta.renderer.pack import pack_scene
from cloudmeta.renderer.quality import resolve_settings
from cloudmeta.scene import load_scene
from tests.renderer.test_approximate import cloud

GRID = "{quality: draft, scattering: approximate, method: grid, grid: {cells: 12, photons: 40000}"


@pytest.mark.parametrize("deposit", ["flights", "collisions"])
def test_white_furnace(tmp_path, deposit):
    """Albedo 1, no lights, a uniform environment L: the radiance is L everywhere and in every direction, so the
    light scattered towards the camera per unit sigma_s is L in every cell, up to the photons' noise, and the
    image is L. With collisions each cell holds the integral of sigma_s S over that of sigma_s."""
    block = GRID.replace("40000", "200000").replace("}", f", deposit: {deposit}}}")
    scene = cloud(tmp_path, block + ", max_order: 100000}", lights="[]", albedo=1.0, background="[0.5, 0.7, 1.0]")
    grid = with_radiance_grid(scene, pack_scene(scene, 0), 0).records.radiance
    full = grid.filled[:, 0] > 0.5 * grid.filled[:, 0].max()  # collisions: the cells well inside the medium
    cells = grid.coef[full, :, 0] / grid.filled[full, 0:1]
    np.testing.assert_allclose(np.median(cells, axis=0), [0.5, 0.7, 1.0], rtol=0.02)
    img = render(scene, progress=False)
    np.testing.assert_allclose(img[..., :3].mean(axis=(0, 1)), [0.5, 0.7, 1.0], rtol=0.02)
    # per pixel within the photons' noise: collisions are noisier (docs/approximate.md: 1.2-2x)
    assert np.abs(img[..., :3] / np.array([0.5, 0.7, 1.0]) - 1).max() < (0.08 if deposit == "flights" else 0.12)


@pytest.mark.parametrize("lights, deposit", [(None, "flights"), (None, "collisions"),
                                             ("[{type: point, position: [2.5, -2.5, 2.0], intensity: 40.0}]", "flights")])
def test_agrees_with_the_unbiased_estimator(tmp_path, lights, deposit):
    """A small cloud lit by the sun (or a point light) and a blue sky: the grid method's image (either deposit)
    against 1024 unbiased paths per pixel (their noise subtracted), relative to the scattered light, within 12 %
    (single scattering alone misses by far more)."""
    block = ("{quality: default, scattering: approximate, method: grid, grid: {cells: 16, photons: 400000, "
             f"deposit: {deposit}}}, max_order: 32}}")
    scene = cloud(tmp_path, block, lights=lights, size=12)
    grid_img = render(scene, progress=False)[..., :3].astype(np.float64)
    single = render(replace(scene, render=replace(scene.render, scattering="single")), progress=False)
    mean, stderr = render_multiple(replace(scene, render=replace(scene.render, scattering="multiple")), paths=1024)
    truth = single[..., :3] + mean
    background = np.array([0.2, 0.3, 0.5]) * (1 - single[..., 3:4])
    scattered = float(np.mean(truth - background))
    noise2 = float(np.mean(stderr ** 2))  # the paths' own variance, out of the squared error

    def error(img):
        return np.sqrt(max(float(np.mean((img - truth) ** 2)) - noise2, 0.0)) / scattered
    assert error(single[..., :3]) > 0.3
    assert error(grid_img) < 0.12


def test_bit_identical_whatever_the_thread_count(tmp_path):
    import numba
    scene = cloud(tmp_path, GRID + "}", size=10)
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = render_frame(scene, progress=False)
        numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
        two = render_frame(scene, progress=False)
    finally:
        numba.set_num_threads(before)
    np.testing.assert_array_equal(one.image, two.image)
    three = render_frame(scene, progress=False, seed=3)
    assert not np.array_equal(one.image, three.image)  # the photons follow the seed


def test_settings(tmp_path):
    scene = cloud(tmp_path, "{quality: fine, scattering: approximate, method: grid, grid: {photons: 1000}}")
    assert resolve_settings(scene).grid == (56, 1000, FLIGHTS)
    assert resolve_settings(cloud(tmp_path, "{quality: draft, scattering: approximate, method: grid}")).grid == \
        (24, 1 << 21, FLIGHTS)
    assert resolve_settings(cloud(tmp_path, "{scattering: approximate, method: grid, grid: {deposit: collisions}}")
                            ).grid == (40, 1 << 23, COLLISIONS)
    # reference has a grid too (fine's), and a frame in any other mode none
    assert resolve_settings(cloud(tmp_path, "{quality: reference, scattering: approximate, method: grid}")).grid[:2] \
        == (56, 1 << 25)
    assert resolve_settings(cloud(tmp_path, "{quality: fine, scattering: approximate}")).grid is None
    with pytest.raises(SceneError, match=r"render\.grid\.deposit"):
        cloud(tmp_path, "{scattering: approximate, method: grid, grid: {deposit: voxels}}")
    with pytest.raises(SceneError, match=r"render\.grid\.cells"):
        cloud(tmp_path, "{scattering: approximate, method: grid, grid: {cells: 1}}")
    with pytest.raises(SceneError, match=r"render\.grid\.photons"):
        cloud(tmp_path, "{scattering: approximate, method: grid, grid: {photons: 0}}")
    with pytest.raises(SceneError, match=r"render\.grid"):
        cloud(tmp_path, "{scattering: approximate, method: grid, grid: {voxels: 3}}")
    surface = """surfaces:
          - {kernel: wyvill6, threshold: 0.5, balls: [{center: [0, 0, -3], radius: 1}]}"""
    with pytest.raises(SceneError, match=r"render\.method"):
        render(cloud(tmp_path, GRID + "}", extra=surface), progress=False)


def test_a_single_scattering_scene_traces_no_photons(tmp_path):
    """A fresh process rendering a single-scattering scene compiles none of kernels.fluence's photon kernels.
    (The gather is inlined where it is used; kernels.features compiles it to black without a grid, which the
    render hashes of single-scattering scenes, unchanged by it, show.)"""
    scene = cloud(tmp_path, "{quality: draft}", size=4)
    code = textwrap.dedent(f"""
        import cloudmeta as cm
        from cloudmeta.kernels import fluence
        cm.render(cm.load_scene({scene.path!r}), progress=False)
        print(len(fluence.trace_photons.signatures), len(fluence.deposit.signatures), len(fluence.emit.signatures))
        """)
    root = Path(__file__).resolve().parents[2]
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=dict(os.environ, PYTHONPATH=str(root)))
    assert run.returncode == 0, run.stderr
    assert run.stdout.split() == ["0", "0", "0"]


def test_delta_split_of_the_forward_peak():
    """f, the part of Henyey-Greenstein above p_c = p(cos_c) inside the cone, against its closed form; the camera
    ray's media lose f sigma_s of their extinction and keep their scattering coefficient."""
    g, degrees = 0.9, 10.0
    cos_c = np.cos(np.radians(degrees))
    p_c = phase(HG, g, 0.0, 0.0, cos_c)
    inside = (1 - g * g) / (2 * g) * (1 / (1 - g) - 1 / np.sqrt(1 + g * g - 2 * g * cos_c))  # P(cos > cos_c)
    f, clamp = phase_peak(np.array([HG, g, 0.0, 0.0]), cos_c)
    assert clamp == p_c
    np.testing.assert_allclose(f, inside - 2 * np.pi * (1 - cos_c) * p_c, rtol=1e-6)
    media = pack_scene(load_scene(Path(__file__).parents[2] / "scenes" / "cumulus.yaml"), 0).records.media
    peak, view = delta_split(media, degrees)
    f0, _ = phase_peak(media.phase[0], cos_c)
    np.testing.assert_allclose(peak[0], [cos_c, phase(*media.phase[0], cos_c)])
    np.testing.assert_allclose(view.scale * view.albedo, media.scale * media.albedo)  # sigma_s kept
    np.testing.assert_allclose(view.scale, media.scale - f0 * media.albedo * media.scale)  # sigma_t - f sigma_s


def test_photons_outside_the_suns_footprint_are_skipped_without_changing_the_grid(tmp_path):
    """A directional light's photons whose straight flight meets no cell with media are not traced
    (renderer.fluence.sun_footprint): they would scatter nothing and deposit nothing, so the grid is the same to
    the last bit as with every photon traced; and the footprint covers the projection of every ball."""
    from cloudmeta.renderer import fluence
    scene = cloud(tmp_path, GRID + "}", size=10)
    records = pack_scene(scene, 0).records
    peak, _ = delta_split(records.media, fluence.PEAK_DEGREES)
    original = fluence.photon_sources
    used = []

    def spy(rec, centre, radius, photons, mgrid=None):
        used.append(original(rec, centre, radius, photons, mgrid))
        return used[-1]
    try:
        fluence.photon_sources = spy
        grid = resolve_settings(scene).grid
        skipped = fluence.radiance_grid(scene, records, 0, scene.camera.position, peak, grid)
        fluence.photon_sources = lambda rec, centre, radius, photons, mgrid=None: original(rec, centre, radius, photons)
        traced = fluence.radiance_grid(scene, records, 0, scene.camera.position, peak, grid)
    finally:
        fluence.photon_sources = original
    sun = int(np.flatnonzero(used[0].kind == DIRECTIONAL)[0])  # the directional light: part of its disk is skipped
    assert 0.0 < used[0].footprint[sun].mean() < 1.0
    assert np.abs(traced.coef).sum() > 0
    np.testing.assert_array_equal(skipped.coef, traced.coef)
    mgrid = fluence.majorant_grid(scene, records.media)
    w = -np.asarray(records.lights.vec[0], np.float64)
    centre, radius = np.zeros(3), 10.0
    footprint, axes = fluence.sun_footprint(mgrid, w, centre, radius)
    assert 0 < footprint.mean() < 1
    px = 2 * radius / footprint.shape[0]
    for blob in (m.blob for m in scene.media):  # every ball's centre projects into the footprint
        for c in blob.centers:
            q = (np.asarray(c) - centre) @ axes.T + radius
            assert footprint[int(q[0] // px), int(q[1] // px)] == 1
