"""The fit (cloudmeta.fit.fit, error, writer, cli): non-negative, deterministic weights; the error falls with
more balls; the reported errors equal an independent computation (numpy's sum of the ball fields, scipy's
trilinear interpolant); the scene and balls file written together or not at all, never over a file the fit
did not write; a bad grid ends in one line and exit 2."""
import os

import numpy as np
import pytest

import cloudmeta as cm
from cloudmeta.cli import main
from cloudmeta.errors import InputError, OutputError
from cloudmeta.fit import VoxelGrid, fit_volume
from cloudmeta.fit import error as E
from cloudmeta.fit import writer
from cloudmeta.fit.fit import fit_arrays
from cloudmeta.fit.procedural import noise_cloud


@pytest.fixture(scope="module")
def cloud():
    return noise_cloud((20, 18, 16), seed=7, octaves=3, base_cells=3, coverage=0.7, peak=3.0, size=2.0)


@pytest.fixture
def grid_file(tmp_path, cloud):
    d, lo, hi = cloud
    path = tmp_path / "cloud.npz"
    np.savez(path, density=d, lower=lo, upper=hi)
    return path


def test_procedural_cloud_is_deterministic_and_not_metaballs(cloud):
    d, lo, hi = cloud
    d2, _, _ = noise_cloud((20, 18, 16), seed=7, octaves=3, base_cells=3, coverage=0.7, peak=3.0, size=2.0)
    assert np.array_equal(d, d2)
    assert d.min() == 0.0 and d.max() == pytest.approx(3.0)
    assert 0.1 < (d > 0).mean() < 0.6
    assert np.allclose(hi - lo, [2.0, 1.8, 1.6])


def test_weights_non_negative_and_deterministic(cloud):
    a = fit_arrays(*cloud, balls=150, progress=False)
    b = fit_arrays(*cloud, balls=150, progress=False)
    assert 0 < len(a) <= 150
    assert (a.weights > 0).all()
    assert np.array_equal(a.centers, b.centers) and np.array_equal(a.weights, b.weights)
    assert np.array_equal(a.radii, b.radii)
    lo, hi = cloud[1], cloud[2]
    assert ((a.centers >= lo) & (a.centers <= hi)).all()


def test_fit_is_the_same_on_one_thread_as_on_several(cloud):
    import numba
    threads = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = fit_arrays(*cloud, balls=150, progress=False)
    finally:
        numba.set_num_threads(threads)
    many = fit_arrays(*cloud, balls=150, progress=False)
    assert np.array_equal(one.centers, many.centers) and np.array_equal(one.weights, many.weights)


def test_solver_residual_matches_an_independent_least_squares(cloud):
    """The fitted weights are a non-negative least-squares solution: on the balls it kept, scipy's nnls on
    the same kernel columns leaves no smaller residual than 1 % below the fit's."""
    from scipy.optimize import nnls
    from cloudmeta.fit.fit import _Problem
    d, lo, hi = cloud
    r = fit_arrays(d, lo, hi, balls=60, progress=False)
    P = _Problem(d, lo, hi)
    A = np.concatenate([P.columns(c[None], R).toarray() for c, R in zip(r.centers, r.radii)], axis=1)
    fit_res = np.linalg.norm(A @ r.weights - P.yflat)
    best = nnls(A, P.yflat, maxiter=5000)[1]
    assert fit_res == pytest.approx(r.density_error * P.ynorm, rel=1e-6)
    assert best <= fit_res <= 1.01 * best


def test_refinement_radii_lower_the_error(cloud, monkeypatch):
    """Each refinement ball at the best of a few radii (fit.RADIUS_CHOICES) against its level's radius alone:
    on this cloud, 300 balls 0.0579 against 0.0810 density L2 error."""
    from cloudmeta.fit import fit as F
    many = fit_arrays(*cloud, balls=300, progress=False)
    monkeypatch.setattr(F, "RADIUS_CHOICES", (1.0,))
    one = fit_arrays(*cloud, balls=300, progress=False)
    assert many.density_error < 0.8 * one.density_error
    assert many.density_error == pytest.approx(0.0579, abs=0.002)
    assert len(np.unique(many.radii)) > len(np.unique(one.radii))


def test_error_falls_with_more_balls(cloud):
    d, lo, hi = cloud
    errors = []
    for n in (30, 120, 480):
        r = fit_volume((d, lo, hi), balls=n, rays=400, progress=False)
        errors.append((r.errors["density"], r.errors["depth"]))
    dens, depth = zip(*errors)
    assert dens[0] > dens[1] > dens[2]
    assert depth[0] > depth[1] > depth[2]
    assert depth[2] < 0.5 * depth[0]


def _naive_field(centers, radii, weights, points, chunk=20_000):
    out = np.empty(len(points))
    for s in range(0, len(points), chunk):
        p = points[s:s + chunk]
        u = ((p[:, None, :] - centers[None, :, :]) ** 2).sum(axis=2) / radii[None, :] ** 2
        out[s:s + chunk] = np.where(u < 1, (1 - u) ** 2 * (1 - 4 * u / 9), 0.0) @ weights
    return out


def test_reported_errors_equal_an_independent_computation(tmp_path, grid_file, cloud):
    from scipy.interpolate import RegularGridInterpolator
    d, lo, hi = cloud
    out = tmp_path / "fit.yaml"
    r = fit_volume(grid_file, out, balls=120, rays=200, progress=False)
    text = out.read_text()
    assert f"density relative L2 error on the grid {r.errors['density']:.4g}" in text
    assert f"optical-depth relative RMSE {r.errors['depth']:.4g} along 200 random rays" in text
    # the scene as the loader reads it: mode field, its scale and balls
    scene = cm.load_scene(out)
    medium = scene.media[0]
    assert medium.density.mode == "field"
    rows = np.loadtxt(tmp_path / "fit.csv", delimiter=",", skiprows=2)
    c, rad, q = rows[:, :3], rows[:, 3], rows[:, 4]
    assert len(rows) == len(r) and (q > 0).all()
    scale = medium.density.scale
    # density: numpy's sum of the ball fields at the voxel centres
    h = (hi - lo) / np.array(d.shape)
    axes = [lo[a] + (np.arange(d.shape[a]) + 0.5) * h[a] for a in range(3)]
    pts = np.stack([x.ravel() for x in np.meshgrid(*axes, indexing="ij")], axis=1)
    f = scale * _naive_field(c, rad, q, pts)
    f = np.where(f >= scale * medium.blob.threshold, f, 0.0)   # mode field: 0 where F < T
    dens = np.linalg.norm(f - d.ravel()) / np.linalg.norm(d)
    assert r.errors["density"] == pytest.approx(dens, rel=1e-9)
    # optical depth: the same rays, both sides integrated finely by other code (32 samples per voxel)
    o, dirs, length = E.random_rays(lo, hi, 200, E.SEED)
    interp = RegularGridInterpolator([np.concatenate([[a[0] - h[i]], a, [a[-1] + h[i]]]) for i, a in enumerate(axes)],
                                     np.pad(d, 1), method="linear")
    m = 32 * int(np.ceil(length.max() / h.min()))
    s = (np.arange(m) + 0.5) / m
    pts = o[:, None, :] + (s[None, :, None] * length[:, None, None]) * dirs[:, None, :]
    ref = interp(pts.reshape(-1, 3)).reshape(len(o), m).mean(axis=1) * length
    fit = scale * _naive_field(c, rad, q, pts.reshape(-1, 3)).reshape(len(o), m).mean(axis=1) * length
    rmse = np.sqrt(np.mean((fit - ref) ** 2)) / np.sqrt(np.mean(ref ** 2))
    assert r.errors["depth"] == pytest.approx(rmse, rel=2e-3)


def test_error_target_stops_the_fit(cloud):
    r = fit_volume(cloud, error=0.06, rays=400, progress=False)
    assert r.errors["depth"] <= 0.06
    loose = fit_volume(cloud, error=0.2, rays=400, progress=False)
    assert len(loose) < len(r)


def test_cli_writes_both_files_and_refuses_to_overwrite(tmp_path, grid_file, capsys):
    out = tmp_path / "scene.yaml"
    assert main(["fit", str(grid_file), "-o", str(out), "--balls", "60", "-q"]) == 0
    printed = capsys.readouterr().out
    assert "optical-depth relative RMSE" in printed and "density relative L2 error" in printed
    csv = tmp_path / "scene.csv"
    before = (out.read_bytes(), csv.read_bytes())
    assert main(["fit", str(grid_file), "-o", str(out), "--balls", "60", "-q"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "refusing to overwrite" in err
    assert (out.read_bytes(), csv.read_bytes()) == before
    assert main(["fit", str(grid_file), "-o", str(out), "--balls", "30", "-q", "--overwrite"]) == 0
    assert len(np.loadtxt(csv, delimiter=",", skiprows=2)) <= 30
    # a file that the fit did not write is never replaced, even with --overwrite
    hand = tmp_path / "hand.yaml"
    hand.write_text("image: {width: 8, height: 8}\n")
    assert main(["fit", str(grid_file), "-o", str(hand), "--balls", "30", "-q", "--overwrite"]) == 2
    assert hand.read_text() == "image: {width: 8, height: 8}\n"
    assert not (tmp_path / "hand.csv").exists()


def test_writing_is_atomic(tmp_path, cloud, monkeypatch):
    r = fit_volume(cloud, balls=40, rays=100, progress=False)
    calls = []

    def second_write_fails(path, *args, **kwargs):
        calls.append(path)
        if len(calls) == 2:
            raise OSError("disk full")
        return open(path, *args, **kwargs)

    import cloudmeta.api.io as api_io  # the scene and its balls file are written by api.io.write_texts
    monkeypatch.setattr(api_io, "open", second_write_fails, raising=False)
    with pytest.raises(OSError):
        writer.write_fit(r, tmp_path / "a.yaml", r.errors)
    assert len(calls) == 2 and os.listdir(tmp_path) == []   # the first file written, then both removed
    monkeypatch.undo()
    writer.write_fit(r, tmp_path / "a.yaml", r.errors)
    assert sorted(os.listdir(tmp_path)) == ["a.csv", "a.yaml"]


@pytest.mark.parametrize("content", ["zeros", "garbage", "flat"])
def test_bad_grid_exit_2_one_line(tmp_path, capsys, content):
    if content == "garbage":
        path = tmp_path / "bad.npz"
        path.write_bytes(b"not a numpy file")
    else:
        path = tmp_path / "bad.npz"
        d = np.zeros((8, 8, 8)) if content == "zeros" else np.ones((8, 8, 1))
        np.savez(path, density=d, lower=[0, 0, 0], upper=[1, 1, 1])
    assert main(["fit", str(path), "-o", str(tmp_path / "s.yaml"), "--balls", "10", "-q"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("cloudmeta: error:") and "bad.npz" in err
    assert not (tmp_path / "s.yaml").exists()


def test_bad_arguments(cloud, tmp_path):
    with pytest.raises(InputError):
        fit_volume(cloud, balls=0)
    with pytest.raises(InputError):
        fit_volume(cloud, error=1.5)
    with pytest.raises(OutputError):
        fit_volume(cloud, tmp_path / "x.txt", balls=10)
    assert isinstance(VoxelGrid(*cloud, "", "", ""), VoxelGrid)
