"""The voxel readers (cloudmeta.fit.grid, numpy_grid, netcdf, vdb): OpenVDB files written by OpenVDB itself
(tests/data/vdb, validation/tools/write_vdb_fixtures.py) read voxel for voxel; numpy and NetCDF round trips;
every bad file one InputError line that names it."""
import json
import struct
import sys
from pathlib import Path

import numpy as np
import pytest

from cloudmeta.errors import InputError
from cloudmeta.fit import LiquidWater, VoxelGrid, parse_conversion, read_grid
from cloudmeta.fit.vdb import describe_vdb

try:
    import xarray as xr
    import netCDF4  # noqa: F401  (xarray's NetCDF backend)
except ImportError:
    xr = None
try:
    import blosc
except ImportError:
    blosc = None

#: the optional extra "fit" (xarray, netCDF4, blosc): without it these tests cannot run
needs_netcdf = pytest.mark.skipif(xr is None, reason="the fit extra (xarray, netCDF4) is not installed")
needs_blosc = pytest.mark.skipif(blosc is None, reason="the fit extra (blosc) is not installed")

VDB = Path(__file__).resolve().parent.parent / "data" / "vdb"

#: file -> (reference stem, grid name, compression flags (1 zlib, 2 active mask, 4 Blosc), half, type)
FIXTURES = {
    "sphere_blosc": ("sphere_blosc", None, 6, False, "Tree_float_5_4_3"),
    "tiles_blosc": ("tiles_blosc", None, 6, False, "Tree_float_5_4_3"),
    "tiles_zlib": ("tiles_blosc", None, 3, False, "Tree_float_5_4_3"),
    "tiles_double": ("tiles_blosc", None, 6, False, "Tree_double_5_4_3"),
    "cloud_half": ("cloud_half", None, 6, True, "Tree_float_5_4_3"),
    "cloud_raw": ("cloud_raw", None, 0, False, "Tree_float_5_4_3"),
    "cloud_zlib_nomask": ("two_grids", "density", 1, False, "Tree_float_5_4_3"),
    "scaled_translated": ("scaled_translated", None, 6, False, "Tree_float_5_4_3"),
    "two_grids": ("two_grids", "density", 6, False, "Tree_float_5_4_3"),
}


def one_line_naming(exc, path):
    text = str(exc.value)
    assert "\n" not in text
    assert str(path) in text
    return text


# --- OpenVDB -------------------------------------------------------------------------------------------


@needs_blosc
@pytest.mark.parametrize("name", sorted(FIXTURES))
def test_vdb_every_voxel_as_openvdb_reads_it(name):
    stem, grid, compression, half, kind = FIXTURES[name]
    reference = np.load(VDB / f"{stem}.npy")
    box = json.loads((VDB / f"{stem}.json").read_text())
    info = describe_vdb(VDB / f"{name}.vdb", variable=grid)
    assert (info["compression"], info["half"], info["type"]) == (compression, half, kind)  # the path tested
    g = read_grid(VDB / f"{name}.vdb", variable=grid)
    assert g.density.dtype == np.float64 and g.shape == reference.shape
    assert np.array_equal(g.density, reference.astype(np.float64))
    np.testing.assert_allclose(g.lower, box["lower"], rtol=1e-13, atol=1e-12)
    np.testing.assert_allclose(g.upper, box["upper"], rtol=1e-13, atol=1e-12)
    assert g.variable == "density" or name == "cloud_half" and g.variable == "cloud"
    assert g.source == str(VDB / f"{name}.vdb") and g.units == ""


@needs_blosc
def test_vdb_tiles_at_every_level_are_in_the_box():
    """The tiles file's box meets an inactive root tile (0.25), an inactive 128^3 tile (0.5), an active and an
    inactive 8^3 tile (0.6, 0.3): each fills its voxels."""
    g = read_grid(VDB / "tiles_blosc.vdb")
    d = g.density
    lo = np.array(json.loads((VDB / "tiles_blosc.json").read_text())["index_min"])

    def at(ijk):
        return d[tuple(np.array(ijk) - lo)]

    assert at((4100, 4090, 4090)) == np.float32(0.25)  # x >= 4096, y, z < 4096: the root tile
    assert at((4090, 4100, 4090)) == np.float32(0.5)   # the 128^3 tile at (3968, 4096, 3968)
    assert at((4090, 4090, 4084)) == np.float32(0.6)   # the active 8^3 tile
    assert at((4084, 4084, 4090)) == np.float32(0.3)   # the inactive 8^3 tile
    assert (d == np.float32(0.25)).sum() >= 8 ** 3


@needs_blosc
def test_vdb_two_grids_pick_by_name():
    path = VDB / "two_grids.vdb"
    with pytest.raises(InputError) as exc:
        read_grid(path)
    assert "temperature" in one_line_naming(exc, path) and "density" in str(exc.value)
    with pytest.raises(InputError) as exc:
        read_grid(path, variable="pressure")
    assert "no grid named 'pressure'" in one_line_naming(exc, path)
    assert read_grid(path, variable="temperature").shape == (10, 10, 10)


@needs_blosc
@pytest.mark.parametrize("name, message", [("refuse_vec3s", "unsupported grid type Tree_vec3s_5_4_3"),
                                           ("refuse_level_set", "level set"),
                                           ("refuse_rotated", "unsupported transform")])
def test_vdb_refused_with_one_line(name, message):
    path = VDB / f"{name}.vdb"
    with pytest.raises(InputError) as exc:
        read_grid(path)
    assert message in one_line_naming(exc, path)


@needs_blosc
@pytest.mark.parametrize("name", ["sphere_blosc", "tiles_zlib", "cloud_half", "cloud_raw"])
def test_vdb_truncated_anywhere_one_line(tmp_path, name):
    data = (VDB / f"{name}.vdb").read_bytes()
    path = tmp_path / f"{name}.vdb"
    for end in sorted(set(np.linspace(0, len(data) - 1, 60).astype(int).tolist()) | {len(data) - 1, 7, 8, 12}):
        path.write_bytes(data[:end])
        with pytest.raises(InputError) as exc:
            read_grid(path)
        assert "truncated file" in one_line_naming(exc, path), end


@needs_blosc
def test_vdb_corrupted_header_one_line(tmp_path):
    data = (VDB / "sphere_blosc.vdb").read_bytes()
    path = tmp_path / "bad.vdb"

    def check(bad, message):
        path.write_bytes(bytes(bad))
        with pytest.raises(InputError) as exc:
            read_grid(path)
        assert message in one_line_naming(exc, path)

    check(b"\x00" + data[1:], "not an OpenVDB file")
    check(data[:8] + (300).to_bytes(4, "little") + data[12:], "unsupported OpenVDB file format version 300")
    check(data[:8] + (221).to_bytes(4, "little") + data[12:], "version 221")
    at = data.index(b"Tree_float_5_4_3")
    check(data[:at] + b"Tree_flaot_5_4_3" + data[at + 16:], "unsupported grid type Tree_flaot_5_4_3")
    at = data.index(b"UniformScaleTranslateMap")
    check(data[:at] + b"UniformScaleTranslateMaq" + data[at + 24:], "unsupported transform")
    at = data.index(b"fog volume")
    check(data[:at] + b"level set!" + data[at + 10:], "grid class 'level set!'")
    # a descriptor whose grid offset points past the end
    at = data.index(b"Tree_float_5_4_3") + 16 + 4  # type, then an empty instance-parent string
    check(data[:at] + (len(data) + 10).to_bytes(8, "little") + data[at + 8:], "outside the file")


@needs_blosc
def test_vdb_corrupted_anywhere_is_input_error_or_values(tmp_path):
    """Bytes flipped at random: the reader either reads a grid (a changed voxel value passes unnoticed) or
    raises one InputError line; nothing else escapes."""
    rng = np.random.default_rng(7)
    for name in ("sphere_blosc", "tiles_zlib", "cloud_half"):
        data = (VDB / f"{name}.vdb").read_bytes()
        path = tmp_path / f"{name}.vdb"
        for at in rng.integers(0, len(data), 60):
            bad = bytearray(data)
            bad[at] ^= int(rng.integers(1, 256))
            path.write_bytes(bytes(bad))
            try:
                read_grid(path)
            except InputError as exc:
                assert "\n" not in str(exc) and str(path) in str(exc)


def test_vdb_needs_blosc_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "blosc", None)
    with pytest.raises(InputError) as exc:
        read_grid(VDB / "sphere_blosc.vdb")
    assert "pip install blosc" in one_line_naming(exc, VDB / "sphere_blosc.vdb")
    assert read_grid(VDB / "tiles_zlib.vdb").shape == (28, 28, 28)  # zlib needs nothing more


def patched_transform(data, was, kind, payload):
    """The file's bytes with its grid's transform (map ``was``, a scale-translate map) replaced by map ``kind``
    with ``payload`` (doubles), the descriptor's end offset moved by the change of length."""
    at = data.index(struct.pack("<I", len(was)) + was.encode())
    old = 4 + len(was) + 6 * 24
    new = struct.pack("<I", len(kind)) + kind.encode() + struct.pack(f"<{len(payload)}d", *payload)
    out = bytearray(data[:at] + new + data[at + old:])
    grid_pos = data.index(b"Tree_float_5_4_3") + 16 + 4
    end = struct.unpack("<q", out[grid_pos + 16:grid_pos + 24])[0]
    out[grid_pos + 16:grid_pos + 24] = struct.pack("<q", end + len(new) - old)
    return bytes(out)


@needs_blosc
def test_vdb_affine_and_negative_scales(tmp_path):
    """An AffineMap without rotation reads as the scale and translation it holds; a negative scale flips
    its axis (voxel 0 lowest in world space). The maps rewritten in place: the sphere's (0.1 and -0.8) as an
    AffineMap, the scaled noise's with a negative x scale."""
    data = (VDB / "sphere_blosc.vdb").read_bytes()
    reference = np.load(VDB / "sphere_blosc.npy").astype(np.float64)
    box = json.loads((VDB / "sphere_blosc.json").read_text())
    path = tmp_path / "affine.vdb"
    m = np.diag([0.1, 0.1, 0.1, 1.0])
    m[3, :3] = -0.8  # row vectors: world = (i, j, k, 1) m
    path.write_bytes(patched_transform(data, "UniformScaleTranslateMap", "AffineMap", m.ravel().tolist()))
    g = read_grid(path)
    assert np.array_equal(g.density, reference)
    np.testing.assert_allclose(g.lower, box["lower"], atol=1e-12)
    np.testing.assert_allclose(g.upper, box["upper"], atol=1e-12)
    m[1, 0] = 0.05  # a shear
    path.write_bytes(patched_transform(data, "UniformScaleTranslateMap", "AffineMap", m.ravel().tolist()))
    with pytest.raises(InputError, match="rotation, shear"):
        read_grid(path)
    path = tmp_path / "flipped.vdb"
    data = (VDB / "scaled_translated.vdb").read_bytes()
    reference = np.load(VDB / "scaled_translated.npy").astype(np.float64)
    box = json.loads((VDB / "scaled_translated.json").read_text())
    # ScaleTranslateMap: translation, scale, then four cached vectors the reader does not need
    path.write_bytes(patched_transform(data, "ScaleTranslateMap", "ScaleTranslateMap",
                                       [1.0, 2.0, 3.0, -0.5, 0.25, 2.0] + [0.0] * 12))
    g = read_grid(path)
    assert np.array_equal(g.density, reference[::-1]) and not np.array_equal(reference, reference[::-1])
    (i0, j0, k0), (i1, j1, k1) = box["index_min"], box["index_max"]
    np.testing.assert_allclose(g.lower, [(i1 + 0.5) * -0.5 + 1, (j0 - 0.5) * 0.25 + 2, (k0 - 0.5) * 2 + 3])
    np.testing.assert_allclose(g.upper, [(i0 - 0.5) * -0.5 + 1, (j1 + 0.5) * 0.25 + 2, (k1 + 0.5) * 2 + 3])


@needs_blosc
def test_vdb_takes_no_box_or_time():
    for kwargs in ({"box": ((0, 0, 0), (1, 1, 1))}, {"time": 0}):
        with pytest.raises(InputError):
            read_grid(VDB / "sphere_blosc.vdb", **kwargs)


@needs_blosc
def test_vdb_conversion_scales():
    g = read_grid(VDB / "sphere_blosc.vdb", conversion=2.5)
    assert np.array_equal(g.density, 2.5 * np.load(VDB / "sphere_blosc.npy").astype(np.float64))
    with pytest.raises(InputError, match="box's length unit is unknown"):
        read_grid(VDB / "sphere_blosc.vdb", conversion=LiquidWater(10e-6, "g m-3"))


# --- numpy ---------------------------------------------------------------------------------------------


@pytest.fixture
def cloud(rng):
    return rng.random((5, 4, 3))


def test_npz_round_trip(tmp_path, cloud):
    path = tmp_path / "cloud.npz"
    np.savez(path, density=cloud.astype(np.float32), lower=[-1.0, 0.0, 2.0], upper=[4.0, 2.0, 3.5], units="km")
    g = read_grid(path)
    assert np.array_equal(g.density, cloud.astype(np.float32).astype(np.float64))
    assert g.lower.tolist() == [-1, 0, 2] and g.upper.tolist() == [4, 2, 3.5] and g.units == "km"
    np.testing.assert_allclose(g.voxel, [1.0, 0.5, 0.5])
    np.testing.assert_allclose(g.centres(1), [0.25, 0.75, 1.25, 1.75])
    assert (g.source, g.variable) == (str(path), "density")
    assert not g.density.flags.writeable and not g.lower.flags.writeable


def test_npz_other_variable_and_box(tmp_path, cloud):
    path = tmp_path / "cloud.npz"
    np.savez(path, ext=cloud, other=cloud[:2])
    with pytest.raises(InputError) as exc:
        read_grid(path)
    assert "no array 'density'" in one_line_naming(exc, path) and "ext" in str(exc.value)
    with pytest.raises(InputError) as exc:
        read_grid(path, variable="ext")
    assert "no lower and upper" in one_line_naming(exc, path)
    g = read_grid(path, variable="ext", box={"lower": [0, 0, 0], "upper": [5, 4, 3], "units": "m"})
    assert np.array_equal(g.density, cloud) and g.units == "m" and g.variable == "ext"


def test_npy_box_argument_or_sidecar(tmp_path, cloud):
    path = tmp_path / "cloud.npy"
    np.save(path, cloud)
    with pytest.raises(InputError) as exc:
        read_grid(path)
    assert "cloud.box.json" in one_line_naming(exc, path)
    g = read_grid(path, box=((0, 0, 0), (10, 8, 6)))
    assert np.array_equal(g.density, cloud) and g.upper.tolist() == [10, 8, 6] and g.units == ""
    (tmp_path / "cloud.box.json").write_text('{"lower": [1, 1, 1], "upper": [2, 2, 2], "units": "km"}')
    g = read_grid(path)
    assert g.lower.tolist() == [1, 1, 1] and g.units == "km"
    (tmp_path / "cloud.box.json").write_text('{"lower": [1, 1, 1], "upper": [2, 2')
    with pytest.raises(InputError, match="not a readable JSON box"):
        read_grid(path)


def test_numpy_bad_files_one_line(tmp_path, cloud):
    path = tmp_path / "cloud.npy"
    np.save(path, cloud)
    data = path.read_bytes()
    box = ((0, 0, 0), (1, 1, 1))
    for bad, message in ((data[:len(data) - 9], "not a readable numpy file"), (b"garbage" * 20, "not a readable"),
                         (data[:40], "not a readable")):
        path.write_bytes(bad)
        with pytest.raises(InputError) as exc:
            read_grid(path, box=box)
        assert message in one_line_naming(exc, path)
    npz = tmp_path / "cloud.npz"
    np.savez(npz, density=cloud, lower=[0, 0, 0], upper=[1, 1, 1])
    npz.write_bytes(npz.read_bytes()[:-30])
    with pytest.raises(InputError) as exc:
        read_grid(npz)
    one_line_naming(exc, npz)
    for array, message in ((cloud[0], "expected a 3D density"), (-cloud, "must be >= 0"),
                           (np.where(cloud > 0.5, np.nan, cloud), "not finite"), (cloud[:0], "empty")):
        np.save(path, array)
        with pytest.raises(InputError) as exc:
            read_grid(path, box=box)
        assert message in one_line_naming(exc, path)
    np.save(path, cloud)
    for wrong in (((0, 0, 0), (1, 0, 1)), ((0, 0), (1, 1)), "box"):
        with pytest.raises(InputError):
            read_grid(path, box=wrong)
    with pytest.raises(InputError, match="unknown voxel file type"):
        read_grid(tmp_path / "cloud.raw")
    with pytest.raises(InputError, match="no such file"):
        read_grid(tmp_path / "absent.npy")


# --- NetCDF --------------------------------------------------------------------------------------------



def les_file(path, values, *, z=None, units="m", value_units="kg m-3", name="lwc", times=(0.0, 60.0)):
    """An LES-like file: name(time, z, y, x), centres on an even grid of 25 m (z: 40 m from 500 m)."""
    nt, nz, ny, nx = values.shape
    z = 500.0 + 40.0 * np.arange(nz) + 20.0 if z is None else z
    scale = 1e-3 if units == "km" else 1.0
    coords = {"x": ("x", (25.0 * np.arange(nx) + 12.5) * scale, {"units": units}),
              "y": ("y", (25.0 * np.arange(ny) + 12.5) * scale, {"units": units}),
              "z": ("z", np.asarray(z) * scale, {"units": units}), "time": ("time", list(times), {"units": "s"})}
    data = {name: (("time", "z", "y", "x"), values, {"units": value_units} if value_units else {}),
            "pressure": (("z",), np.linspace(9e4, 8e4, nz))}
    xr.Dataset(data, coords=coords).to_netcdf(path)
    return path


@pytest.fixture
def lwc(rng):
    return rng.random((2, 4, 5, 6)) * 1e-3  # kg m-3


@needs_netcdf
def test_netcdf_round_trip_with_conversion(tmp_path, lwc):
    path = les_file(tmp_path / "les.nc", lwc)
    g = read_grid(path, time=1, conversion=LiquidWater(10e-6))
    # x, y, z order; sigma_t = 3 LWC / (2 rho_w r_e) per metre
    np.testing.assert_allclose(g.density, lwc[1].transpose(2, 1, 0) * 3 / (2 * 1000.0 * 10e-6), rtol=1e-15)
    assert g.lower.tolist() == [0, 0, 500] and g.upper.tolist() == [150, 125, 660]
    assert (g.units, g.variable, g.source) == ("m", "lwc", str(path))
    # the same file in km: sigma_t per km is 1000 times larger, the box 1000 times smaller
    km = read_grid(les_file(tmp_path / "km.nc", lwc, units="km"), time=1, conversion=LiquidWater(10e-6))
    np.testing.assert_allclose(km.density, 1000 * g.density, rtol=1e-12)
    np.testing.assert_allclose(km.upper, g.upper / 1000, rtol=1e-12)
    gm3 = read_grid(les_file(tmp_path / "g.nc", lwc * 1000, value_units="g m-3"), time=1,
                    conversion=LiquidWater(10e-6))
    np.testing.assert_allclose(gm3.density, g.density, rtol=1e-12)
    mixing = les_file(tmp_path / "q.nc", lwc, value_units="kg kg-1")
    with pytest.raises(InputError, match="air_density"):
        read_grid(mixing, time=1, conversion=LiquidWater(10e-6))
    np.testing.assert_allclose(read_grid(mixing, time=1, conversion=LiquidWater(10e-6, air_density=1.1)).density,
                               1.1 * g.density, rtol=1e-12)


@needs_netcdf
def test_netcdf_values_as_extinction(tmp_path, lwc):
    sigma = lwc * 100  # per km
    path = les_file(tmp_path / "ext.nc", sigma, value_units="km-1", name="extinction")
    g = read_grid(path, time=0)
    np.testing.assert_allclose(g.density, sigma[0].transpose(2, 1, 0) / 1000, rtol=1e-15)  # per m, the box's unit
    g = read_grid(les_file(tmp_path / "plain.nc", sigma, value_units="", name="sigma"), time=0)
    np.testing.assert_allclose(g.density, sigma[0].transpose(2, 1, 0), rtol=1e-15)
    with pytest.raises(InputError) as exc:  # a water content without a conversion
        read_grid(les_file(tmp_path / "les.nc", lwc), time=0)
    assert "LiquidWater" in one_line_naming(exc, tmp_path / "les.nc")


@needs_netcdf
def test_netcdf_descending_and_single_time(tmp_path, lwc):
    z = 500.0 + 40.0 * np.arange(4)[::-1] + 20.0
    path = les_file(tmp_path / "down.nc", lwc[:1], z=z, value_units="", times=(0.0,))
    g = read_grid(path)  # one time: no index needed
    np.testing.assert_allclose(g.density, lwc[0, ::-1].transpose(2, 1, 0), rtol=1e-15)
    assert g.lower[2] == 500 and g.upper[2] == 660


@needs_netcdf
def test_netcdf_refusals_one_line(tmp_path, lwc):
    path = les_file(tmp_path / "les.nc", lwc, value_units="")
    for kwargs, message in (({}, "give a time index 0..1"), ({"time": 2}, "time index must be"),
                            ({"variable": "qv", "time": 0}, "no variable 'qv'"),
                            ({"variable": "pressure"}, "expected 3 spatial dimensions"),
                            ({"time": 0, "box": ((0, 0, 0), (1, 1, 1))}, "drop the box")):
        with pytest.raises(InputError) as exc:
            read_grid(path, **kwargs)
        assert message in one_line_naming(exc, path)
    uneven = les_file(tmp_path / "uneven.nc", lwc, z=[500, 540, 600, 700], value_units="")
    with pytest.raises(InputError) as exc:
        read_grid(uneven, time=0)
    assert "not evenly spaced" in one_line_naming(exc, uneven)
    data = path.read_bytes()
    for end in (10, len(data) // 2, len(data) - 100):
        cut = tmp_path / f"cut{end}.nc"
        cut.write_bytes(data[:end])
        with pytest.raises(InputError) as exc:
            read_grid(cut, time=0)
        one_line_naming(exc, cut)


@needs_netcdf
def test_netcdf_without_coordinates_takes_a_box(tmp_path, rng):
    values = rng.random((3, 4, 5))
    path = tmp_path / "bare.nc"
    xr.Dataset({"sigma": (("x", "y", "z"), values)}).to_netcdf(path)
    with pytest.raises(InputError, match="has no coordinate"):
        read_grid(path)
    g = read_grid(path, box={"lower": [0, 0, 0], "upper": [3, 4, 5], "units": "km"})
    assert np.array_equal(g.density, values) and g.units == "km"


@needs_netcdf
def test_netcdf_needs_the_extra(monkeypatch, tmp_path, lwc):
    path = les_file(tmp_path / "les.nc", lwc)
    monkeypatch.setitem(sys.modules, "xarray", None)
    with pytest.raises(InputError) as exc:
        read_grid(path, time=0)
    assert "pip install xarray netCDF4" in one_line_naming(exc, path)


# --- the record and the conversions --------------------------------------------------------------------


def test_voxel_grid_copies_and_freezes(cloud):
    g = VoxelGrid(cloud, [0, 0, 0], [1, 1, 1], "here", "density", "m")
    cloud[0, 0, 0] = 5.0
    assert g.density[0, 0, 0] != 5.0 and not g.density.flags.writeable
    with pytest.raises(InputError, match="box is empty"):
        VoxelGrid(cloud, [0, 0, 0], [1, 0, 1], "here", "density", "m")


def test_parse_conversion():
    assert parse_conversion("") is None and parse_conversion("none") is None
    assert parse_conversion("2.5") == 2.5
    assert parse_conversion("lwc:10um") == LiquidWater(10e-6, None)
    assert parse_conversion("lwc:1e-5m:g m-3") == LiquidWater(1e-5, "g m-3")
    for bad in ("lwc", "lwc:10", "lwc:10 furlongs", "twice"):
        with pytest.raises(InputError):
            parse_conversion(bad)
