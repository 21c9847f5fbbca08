"""cloudmeta.api.viewer and kernels/grid: the culled grid sampler equals cloudmeta.field, the grid's geometry is
right, sigma_t follows docs/model.md §4, and ``cloudmeta inspect`` writes pictures and grids off screen."""
import numpy as np
import pytest
import pyvista as pv
import yaml
from matplotlib.image import imread

import cloudmeta as cm
from cloudmeta.cli import main
from cloudmeta.errors import InputError
from cloudmeta.api.viewer import POINTS_MAX, _cull_cells, _nice_range, compare_slice, draw_volume, sample_grid
from cloudmeta.fit import VoxelGrid
from cloudmeta.kernels.grid import bin_balls
from tests.conftest import random_blob

SCENE = {
    "image": {"width": 64, "height": 48},
    "camera": {"position": [0, -9, 1], "look_at": [0, 0, 0.5], "up": [0, 0, 1], "fov": 35},
    "lights": [{"type": "directional", "direction": [0.5, -0.4, 0.8], "irradiance": 3.0},
               {"type": "point", "position": [2.5, -1, 2], "intensity": 10.0}],
    "media": [{"name": "puff", "kernel": "wyvill6", "threshold": 0.5, "density": {"mode": "field", "scale": 2.5},
               "balls": [{"center": [0, 0, 0.5], "radius": 1.6, "weight": 1.0},
                         {"center": [1.0, 0.2, 0.9], "radii": [1.2, 0.8, 0.7], "rotation": [0, 20, 30],
                          "weight": 0.9},
                         {"center": [-0.4, -0.5, 1.2], "radius": 0.8, "weight": -0.4}]}],
}


def write_scene(tmp_path, scene=SCENE, name="scene.yaml"):
    path = tmp_path / name
    path.write_text(yaml.safe_dump(scene))
    return str(path)


def assert_matches_field(grid, blob):
    got = grid.point_data["field"]
    ref = cm.field(blob, grid.points)
    assert np.count_nonzero(ref) > 50
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12)


# ------------------------------------------------------------------------------------- the grid sampler

@pytest.mark.parametrize("kernel", ["wyvill6", "murakami4", "nishimura", "blinn"])
@pytest.mark.parametrize("ellipsoids,negative", [(False, False), (True, False), (True, True)])
def test_grid_equals_the_field(rng, kernel, ellipsoids, negative):
    blob = random_blob(rng, 25, kernel, ellipsoids, negative)
    assert_matches_field(sample_grid(blob, 33), blob)


def test_grid_equals_the_field_where_the_cull_matters(rng):
    # 400 small balls spread over a large box: each cell lists a few of them
    n = 400
    blob = cm.Blob(rng.uniform(-15, 15, (n, 3)), rng.uniform(0.8, 2.0, (n, 3)), rng.uniform(-0.5, 1.5, n),
                   rotations=rng.uniform(0, 360, (n, 3)))
    cell_origin, cell_size, cell_dims, pad = _cull_cells(blob)
    cell_start, _ = bin_balls(blob.bounds, pad, cell_origin, cell_size, cell_dims)
    assert np.prod(cell_dims) > 100 and np.diff(cell_start).max() < n / 10
    assert_matches_field(sample_grid(blob, 64), blob)


def test_grid_equals_the_field_with_balls_far_apart(rng):
    # two clusters 1000 units apart: the cull grid is capped, and a grid over one cluster is still exact
    a = rng.uniform(-2, 2, (30, 3))
    blob = cm.Blob(np.vstack([a, a + 1000.0]), rng.uniform(0.6, 1.8, 60), rng.uniform(-0.5, 1.5, 60),
                   kernel="blinn")
    cell_origin, cell_size, cell_dims, pad = _cull_cells(blob)
    assert np.prod(cell_dims) <= (1 << 21)
    for shift in (0.0, 1000.0):
        assert_matches_field(sample_grid(blob, 40, bounds=(np.full(3, shift - 4.0), np.full(3, shift + 4.0))), blob)


def test_geometry_of_given_bounds():
    blob = cm.Blob([[5, 2.5, 1]], [1.0])
    for bounds in (((0, 0, 0), (10, 5, 2)), (0, 10, 0, 5, 0, 2)):
        grid = sample_grid(blob, 21, bounds=bounds)
        assert grid.dimensions == (21, 11, 5)
        np.testing.assert_allclose(grid.spacing, 0.5, rtol=1e-14)
        np.testing.assert_allclose(grid.origin, 0.0, atol=1e-14)
        np.testing.assert_allclose(grid.points[1] - grid.points[0], [0.5, 0, 0], atol=1e-14)  # x fastest
        np.testing.assert_allclose(grid.points[-1], [10, 5, 2], atol=1e-13)


def test_geometry_of_default_bounds(rng):
    blob = random_blob(rng, 10, ellipsoids=True)
    grid = sample_grid(blob, 30)
    lo, hi = blob.bbox
    h = grid.spacing[0]
    assert grid.spacing == (h, h, h)
    assert max(grid.dimensions) == 30
    b = np.array(grid.bounds)
    assert np.all(b[0::2] < lo) and np.all(b[1::2] > hi)  # padded
    assert np.all(b[1::2] - b[0::2] < (hi - lo) * 1.2 + 2 * h)  # slightly


def test_sphere_contour_has_the_analytic_radius():
    # wyvill6 at T = 0.5: (1 - u)^2 (1 - 4u/9) = 1/2 at u = 1/4, so the isosurface is a sphere of radius R/2
    centre, radius = np.array([0.3, -0.2, 0.1]), 2.0
    grid = sample_grid(cm.Blob([centre], [radius], kernel="wyvill6", threshold=0.5), 48)
    iso = grid.contour([0.5], scalars="field")
    r = np.linalg.norm(iso.points - centre, axis=1)
    assert iso.n_points > 100
    assert np.all(np.abs(r - radius / 2) < grid.spacing[0])


@pytest.mark.parametrize("mode", ["field", "excess", "uniform"])
def test_sigma_t_is_zero_outside_and_scaled_density_inside(tmp_path, mode):
    scene_dict = yaml.safe_load(yaml.safe_dump(SCENE))
    scene_dict["media"][0]["density"]["mode"] = mode
    scene = cm.load_scene(write_scene(tmp_path, scene_dict))
    grid = sample_grid(scene, 32)
    f, s, t = grid.point_data["field"], grid.point_data["sigma_t"], 0.5
    inside = f >= t
    assert 0 < np.count_nonzero(inside) < len(f)
    np.testing.assert_array_equal(s[~inside], 0.0)
    rho = {"field": f, "excess": f - t, "uniform": np.ones_like(f)}[mode]
    np.testing.assert_allclose(s[inside], 2.5 * rho[inside], rtol=1e-15)
    assert_matches_field(grid, scene.media[0].blob)


def test_arrays_of_several_media_and_surfaces(tmp_path):
    scene_dict = yaml.safe_load(yaml.safe_dump(SCENE))
    other = dict(scene_dict["media"][0], name="mist", density={"mode": "uniform", "scale": 0.5})
    scene_dict["media"].append(other)
    scene_dict["surfaces"] = [{"name": "rock", "balls": [{"center": [0, 0, -1], "radius": 1.0}]},
                              {"name": "puff", "balls": [{"center": [1, 0, -1], "radius": 1.0}]}]
    grid = sample_grid(cm.load_scene(write_scene(tmp_path, scene_dict)), 24)
    names = set(grid.point_data.keys())
    assert names == {"field:puff", "field:mist", "sigma_t:puff", "sigma_t:mist", "sigma_t", "field:rock",
                     "field:surface:puff"}
    np.testing.assert_allclose(grid.point_data["sigma_t"],
                               grid.point_data["sigma_t:puff"] + grid.point_data["sigma_t:mist"])
    assert grid.field_data["threshold:field:rock"][0] == 0.5


@pytest.mark.parametrize("kwargs,word", [
    (dict(resolution=1), "resolution"), (dict(resolution=2.5), "resolution"), (dict(resolution=True), "resolution"),
    (dict(resolution=100000), "resolution"), (dict(bounds=(0, 1, 2)), "bounds"),
    (dict(bounds=((0, 0, 0), (1, 0, 1))), "bounds"), (dict(bounds=((0, 0, 0), (1, np.nan, 1))), "bounds"),
])
def test_bad_arguments_name_themselves(kwargs, word):
    with pytest.raises(InputError, match=word):
        sample_grid(cm.Blob([[0, 0, 0]], [1.0]), **kwargs)
    with pytest.raises(InputError, match="scene_or_blob"):
        sample_grid("scene.yaml")


# ---------------------------------------------------------------------------------------- the command

def assert_picture(path):
    image = imread(path)
    assert image.ndim == 3 and image.shape[0] > 100 and image.shape[1] > 100
    pixels = image[..., :3].reshape(-1, 3)
    assert np.ptp(pixels, axis=0).max() > 0.3  # not one colour
    assert len(np.unique(np.round(pixels * 255), axis=0)) > 50


def test_screenshot(tmp_path, capsys):
    png = tmp_path / "inspect.png"
    assert main(["inspect", write_scene(tmp_path), "--screenshot", str(png), "--resolution", "32"]) == 0
    assert png.stat().st_size > 0
    assert_picture(png)
    assert f"wrote {png}" in capsys.readouterr().out


@pytest.mark.parametrize("plane", ["z=0.7", "x=-0.3", "y=0"])
def test_slice_screenshot(tmp_path, capsys, plane):
    png = tmp_path / "slice.png"
    assert main(["inspect", write_scene(tmp_path), "--slice", plane, "--screenshot", str(png),
                 "--resolution", "32"]) == 0
    assert_picture(png)
    assert f"wrote {png}" in capsys.readouterr().out


@pytest.mark.parametrize("plane,message", [("w=1", "--slice: expected AXIS=VALUE"), ("z", "--slice"),
                                           ("z=abc", "--slice"), ("z=50", "outside the scene")])
def test_bad_slice_is_an_error(tmp_path, capsys, plane, message):
    png = tmp_path / "slice.png"
    assert main(["inspect", write_scene(tmp_path), "--slice", plane, "--screenshot", str(png)]) == 2
    assert message in capsys.readouterr().err
    assert not png.exists()


def test_save_writes_a_grid_that_reads_back(tmp_path, capsys):
    path = write_scene(tmp_path)
    vti = tmp_path / "grid.vti"
    assert main(["inspect", path, "--save", str(vti), "--screenshot", str(tmp_path / "x.png"),
                 "--resolution", "24"]) == 0
    back = pv.read(vti)
    ref = sample_grid(cm.load_scene(path), 24)
    assert back.dimensions == ref.dimensions
    np.testing.assert_allclose(back.origin, ref.origin, rtol=0, atol=1e-15)
    np.testing.assert_allclose(back.spacing, ref.spacing, rtol=1e-15)
    assert set(back.point_data.keys()) == {"field", "sigma_t"}
    for name in ("field", "sigma_t"):
        np.testing.assert_array_equal(back.point_data[name], ref.point_data[name])
    assert back.field_data["threshold:field"][0] == 0.5
    assert f"wrote {vti}" in capsys.readouterr().out


def test_without_a_display(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr("sys.platform", "linux")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    path = write_scene(tmp_path)
    assert main(["inspect", path]) == 2
    assert "--screenshot" in capsys.readouterr().err
    vti = tmp_path / "grid.vti"
    assert main(["inspect", path, "--save", str(vti), "--resolution", "16"]) == 0  # writes, opens nothing
    assert vti.exists()


@pytest.mark.parametrize("option,path", [("--save", "grid.vtk"), ("--screenshot", "picture.pdf"),
                                         ("--screenshot", "no/such/folder/x.png")])
def test_bad_output_paths_are_errors(tmp_path, capsys, option, path):
    assert main(["inspect", write_scene(tmp_path), option, str(tmp_path / path)]) == 2
    assert option in capsys.readouterr().err


def test_the_window_view_builds_with_slice_widgets(tmp_path):
    scene = cm.load_scene(write_scene(tmp_path))
    plotter = pv.Plotter(off_screen=True)
    try:
        draw_volume(plotter, scene, sample_grid(scene, 24), widgets=True)
        assert len(plotter.widgets.plane_widgets) == 3
    finally:
        plotter.close()


# ------------------------------------------------------------------------------------------ many balls

def many_balls_scene(tmp_path, n=3000, seed=5):
    """SCENE's camera and lights with ``n`` small random balls (a few carving) in a 6 x 6 x 3 box."""
    rng = np.random.default_rng(seed)
    scene = yaml.safe_load(yaml.safe_dump(SCENE))
    centres = rng.uniform([-3, -3, 0], [3, 3, 3], (n, 3))
    weights = np.where(rng.random(n) < 0.1, -0.3, 1.0)
    scene["media"][0]["balls"] = [{"center": [float(v) for v in c], "radius": 0.5, "weight": float(w)}
                                  for c, w in zip(centres, weights)]
    return cm.load_scene(write_scene(tmp_path, scene, "many.yaml"))


def centre_actors(plotter):
    return [a for name, a in plotter.actors.items() if name.startswith("centres:")]


@pytest.mark.parametrize("balls", ["auto", "points", "all", "none"])
def test_many_balls_are_never_a_sphere_each(tmp_path, balls):
    scene = many_balls_scene(tmp_path)
    n = len(scene.media[0].blob.weights)
    plotter = pv.Plotter(off_screen=True)
    try:
        draw_volume(plotter, scene, sample_grid(scene, 24), widgets=False, balls=balls)
        actors = centre_actors(plotter)
        points = sum(a.mapper.dataset.n_points for a in actors)
        meshes = [(a, a.mapper.dataset) for a in plotter.actors.values()
                  if isinstance(getattr(getattr(a, "mapper", None), "dataset", None), pv.DataSet)]
        # all the meshes together, slices included, hold fewer points than a 50-point sphere a ball would
        assert len(plotter.actors) < 30 and sum(m.n_points for _, m in meshes) < 50 * n
        # no translucent isosurface: above BALLS_AS_SPRITES balls F = T is lines on the slices
        surfaces = [m for a, m in meshes if a.prop.opacity < 1 and isinstance(m, pv.PolyData) and m.n_faces]
        assert surfaces == []
        assert any(isinstance(m, pv.PolyData) and m.n_lines > 100 for _, m in meshes)
        if balls == "none":
            assert actors == []
        elif balls == "all":
            assert points == n and len(actors) == 2  # white and red, each one point cloud
            assert all(a.prop.render_points_as_spheres for a in actors)
        else:  # auto resolves to points above BALLS_AS_SPRITES
            assert 0 < points <= POINTS_MAX < n
            assert all(not a.prop.render_points_as_spheres and a.prop.point_size <= 2
                       and a.prop.opacity < 1 for a in actors)
    finally:
        plotter.close()


def test_few_balls_are_all_drawn_round(tmp_path):
    scene = cm.load_scene(write_scene(tmp_path))
    plotter = pv.Plotter(off_screen=True)
    try:
        draw_volume(plotter, scene, sample_grid(scene, 24), widgets=False)
        actors = centre_actors(plotter)
        assert sum(a.mapper.dataset.n_points for a in actors) == 3
        assert all(a.prop.render_points_as_spheres for a in actors)
    finally:
        plotter.close()


def test_many_balls_screenshot(tmp_path, capsys):
    many_balls_scene(tmp_path, n=800)
    png = tmp_path / "many.png"
    assert main(["inspect", str(tmp_path / "many.yaml"), "--screenshot", str(png), "--resolution", "24"]) == 0
    assert_picture(png)


# ------------------------------------------------------------------------------- grid | fit | difference

def grid_of_scene(tmp_path, bump=0.0, name="grid.npz"):
    """A voxel grid whose density is SCENE's sigma_t (mode field, scale 2.5) at the voxel centres, plus
    ``bump`` on a block of voxels at x > 0, y > 0 of the middle z layers. Returns (path, VoxelGrid)."""
    shape, lower, upper = (24, 20, 16), np.array([-2.0, -2.0, -1.0]), np.array([2.8, 2.0, 2.2])
    h = (upper - lower) / np.array(shape)
    axes = [lower[a] + (np.arange(shape[a]) + 0.5) * h[a] for a in range(3)]
    points = np.stack([g.ravel() for g in np.meshgrid(*axes, indexing="ij")], axis=1)
    blob = cm.load_scene(write_scene(tmp_path)).media[0].blob
    f = cm.field(blob, points).reshape(shape)
    density = np.where(f >= 0.5, 2.5 * f, 0.0)
    density[14:18, 12:16, 6:9] += bump  # x in [0.8, 1.6), y in [0.4, 1.2), z layers 6 to 8
    path = tmp_path / name
    np.savez(path, density=density, lower=lower, upper=upper)
    return str(path), VoxelGrid(density, lower, upper, str(path), "density", "")


def test_compare_slice_is_the_difference_point_by_point(tmp_path):
    scene = cm.load_scene(write_scene(tmp_path))
    _, exact = grid_of_scene(tmp_path)
    plane = compare_slice(scene, exact, 2, 0.3)
    layer = int(plane.field_data["layer"][0])
    assert layer == 6 and plane.dimensions == (24, 20, 1)  # z = 0.3 lies in layer floor(1.3 / 0.2)
    np.testing.assert_allclose(plane.field_data["position"][0], -1.0 + 6.5 * 0.2, rtol=1e-14)
    np.testing.assert_array_equal(plane.point_data["grid"], exact.density[:, :, 6].ravel(order="F"))
    np.testing.assert_allclose(plane.point_data["difference"], 0.0, atol=1e-11)
    assert plane.field_data["error"][0] < 1e-11

    _, bumped = grid_of_scene(tmp_path, bump=1.0, name="bumped.npz")
    plane = compare_slice(scene, bumped, 2, 0.3)
    diff = plane.point_data["difference"].reshape(20, 24).T  # (x, y)
    block = np.zeros((24, 20), dtype=bool)
    block[14:18, 12:16] = True
    np.testing.assert_allclose(diff[block], -1.0, atol=1e-11)
    np.testing.assert_allclose(diff[~block], 0.0, atol=1e-11)
    grid = bumped.density[:, :, 6]
    np.testing.assert_allclose(plane.field_data["error"][0], 4.0 / np.linalg.norm(grid), rtol=1e-9)
    # default plane: the middle of the box along z
    assert int(compare_slice(scene, bumped).field_data["layer"][0]) == 8


def panels(path):
    """The three panels of a compare screenshot, cropped to the plane's area (below the titles, above
    the colour bars), as float RGB."""
    image = imread(path)[..., :3]
    h, w = image.shape[:2]
    third = w // 3
    return [image[int(0.15 * h):int(0.75 * h), k * third:(k + 1) * third] for k in range(3)]


def test_compare_screenshot_panels_differ_where_the_fit_differs(tmp_path, capsys):
    scene = write_scene(tmp_path)
    exact, _ = grid_of_scene(tmp_path)
    bumped, _ = grid_of_scene(tmp_path, bump=1.5, name="bumped.npz")
    pictures = {}
    for label, grid in (("exact", exact), ("bumped", bumped)):
        png = tmp_path / f"{label}.png"
        assert main(["inspect", scene, "--grid", grid, "--slice", "z=0.3", "--screenshot", str(png)]) == 0
        out = capsys.readouterr().out
        assert "slice relative L2 error" in out and f"wrote {png}" in out
        assert_picture(png)
        pictures[label] = panels(png)
    grid, fit, diff = pictures["exact"]
    # same slice, same colours, same place (but for a few pixels of the axes' anti-aliased labels)
    assert (np.abs(grid - fit).max(axis=2) > 0.05).sum() < 20
    plane = diff.min(axis=2) > 0.9  # the difference's plane is white all over: no difference
    assert plane.sum() > 0.4 * plane.size
    reddish = lambda p: p[..., 0] - p[..., 2]
    grid, fit, diff = pictures["bumped"]
    changed = np.abs(grid - fit).max(axis=2) > 0.05
    assert changed.sum() > 100 and (changed & ~plane).sum() < 20  # on the plane only
    # the grid holds more than the fit in the block: blue (fit - grid < 0) there, and only there
    blue = plane & (reddish(diff) < -0.3)
    assert blue.sum() > 100
    rows, cols = np.nonzero(blue)
    crows, ccols = np.nonzero(changed)
    assert abs(rows.mean() - crows.mean()) < 10 and abs(cols.mean() - ccols.mean()) < 10
    assert (plane & (reddish(diff) > 0.3)).sum() == 0  # nowhere is the fit above the grid
    assert (plane & ~blue).sum() > 0.8 * plane.sum()  # and elsewhere the plane stays white
    assert (diff[plane & ~blue].min(axis=1) > 0.85).mean() > 0.95
    # the block is at x > 0.8, y > 0.4: right of and above the middle of the panel
    assert ccols.mean() > changed.shape[1] / 2 and crows.mean() < changed.shape[0] / 2


def test_compare_save_writes_the_three_arrays(tmp_path, capsys):
    grid, _ = grid_of_scene(tmp_path, bump=1.0)
    vti = tmp_path / "slice.vti"
    assert main(["inspect", write_scene(tmp_path), "--grid", grid, "--save", str(vti),
                 "--screenshot", str(tmp_path / "x.png")]) == 0
    back = pv.read(vti)
    assert set(back.point_data.keys()) == {"grid", "fit", "difference"}
    np.testing.assert_allclose(back.point_data["difference"], back.point_data["fit"] - back.point_data["grid"])


@pytest.mark.parametrize("extra,message", [
    (["--grid", "no_such_grid.npz"], "no_such_grid.npz: no such file"),
    (["--grid", "grid.txt"], "unknown voxel file type"),
    (["--var", "density"], "--var"),
    (["--grid", "GRID", "--slice", "z=5"], "outside the grid"),
    (["--grid", "GRID", "--var", "nothing"], "nothing"),
])
def test_bad_grid_is_one_line_exit_2(tmp_path, capsys, extra, message):
    grid, _ = grid_of_scene(tmp_path)
    (tmp_path / "grid.txt").write_text("1 2 3")
    extra = [grid if e == "GRID" else str(tmp_path / e) if e.startswith(("no_such", "grid.")) else e
             for e in extra]
    png = tmp_path / "x.png"
    assert main(["inspect", write_scene(tmp_path), *extra, "--screenshot", str(png)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("cloudmeta: error: ") and message in err
    assert not png.exists()


@pytest.mark.parametrize("top,lowest,end,labels", [(4.01, 4, 5.0, 6), (0.0796, 2, 0.08, 5), (2.36, 4, 2.5, 6),
                                                   (47.2, 4, 50.0, 6), (1.0, 4, 1.0, 6)])
def test_colour_bars_end_on_round_numbers(top, lowest, end, labels):
    got_end, got_labels = _nice_range(top, lowest)
    assert got_end == pytest.approx(end, rel=1e-12) and got_labels == labels and got_end >= top


def test_compare_a_fit_of_an_openvdb_file(tmp_path, capsys):
    # a small fit of a grid written by OpenVDB itself; the fit's own density check (fit.error.grid_field,
    # the balls summed voxel by voxel) gives the same fitted slice as the viewer's culled sampler
    from cloudmeta.fit import read_grid
    from cloudmeta.fit.error import grid_field

    vdb = "tests/data/vdb/cloud_half.vdb"
    scene_path = str(tmp_path / "fit.yaml")
    cm.fit_volume(vdb, scene_path, balls=400, rays=200)
    vti, png = tmp_path / "slice.vti", tmp_path / "fit.png"
    assert main(["inspect", scene_path, "--grid", vdb, "--slice", "y=11", "--save", str(vti),
                 "--screenshot", str(png)]) == 0
    assert "slice relative L2 error" in capsys.readouterr().out
    assert_picture(png)
    voxels = read_grid(vdb)
    medium = cm.load_scene(scene_path).media[0]
    layer = int((11 - voxels.lower[1]) // voxels.voxel[1])
    expected = medium.density.scale * grid_field(medium.blob, voxels.shape, voxels.lower, voxels.upper)[:, layer, :]
    back = pv.read(vti)
    assert back.dimensions == (24, 1, 16)
    np.testing.assert_allclose(back.point_data["fit"], expected.ravel(order="F"), rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(back.point_data["grid"], voxels.density[:, layer, :].ravel(order="F"))
    error = np.linalg.norm(back.point_data["difference"]) / np.linalg.norm(back.point_data["grid"])
    assert 0.01 < error < 0.5  # a fit of 400 balls: close, not exact


def test_many_balls_in_the_window_contours_follow_the_slices(tmp_path):
    from vtkmodules.vtkFiltersCore import vtkContourFilter

    scene = many_balls_scene(tmp_path, n=800)
    grid = sample_grid(scene, 24)
    plotter = pv.Plotter(off_screen=True)
    try:
        draw_volume(plotter, scene, grid, widgets=True)
        contours = [a.GetMapper().GetInputConnection(0, 0).GetProducer() for a in plotter.actors.values()
                    if hasattr(a, "GetMapper") and a.GetMapper() is not None
                    and a.GetMapper().GetNumberOfInputConnections(0)
                    and isinstance(a.GetMapper().GetInputConnection(0, 0).GetProducer(), vtkContourFilter)]
        assert len(contours) == 3
        widget = plotter.widgets.plane_widgets[2]  # the z slice
        for z in (grid.center[2], grid.center[2] + 0.4):
            widget.SetOrigin(grid.center[0], grid.center[1], z)
            for event in ("InteractionEvent", "EndInteractionEvent"):  # whichever the widget listens to
                widget.InvokeEvent(event)
            contours[2].Update()
            lines = pv.wrap(contours[2].GetOutput())
            assert lines.n_points > 20
            np.testing.assert_allclose(lines.points[:, 2], z, atol=1e-9)
    finally:
        plotter.close()
