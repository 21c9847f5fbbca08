"""Writes the OpenVDB test files of tests/data/vdb/ with OpenVDB itself, and beside each the dense array that
OpenVDB reads back from it, for the numpy reader of cloudmeta.fit.vdb to match voxel for voxel.

Runs under the system Python that has the pyopenvdb module (Debian: apt-get install python3-openvdb; run
/usr/bin/python3 validation/tools/write_vdb_fixtures.py [folder]), not the project's environment; it skips
(exit 0, one line) where pyopenvdb is missing. pyopenvdb saves with its library's default compression
(Blosc where the library has it) and cannot choose another, so the zlib, uncompressed and double-precision
files are re-saved by a short C++ program against the same library (compiled here when g++ and the
OpenVDB headers, Debian: libopenvdb-dev and libboost-dev, are present; those files are skipped otherwise).

For each NAME.vdb: NAME.npy (the values over the grid's active-voxel bounding box, as OpenVDB's copyToArray
gives them) and NAME.json (that box in index space, and in world space through the grid's transform: the
outer faces of the first and last voxels); the files re-saved from another (SAME) hold its values, which
OpenVDB's reading of them is checked against here.

    sphere_blosc         a sphere of fog, 0.1 voxels centred on the origin (uniform scale + translation)
    tiles_blosc          noise around the corner where root, internal and leaf nodes meet, with tiles of
                         constant value at every level and leaves of one, two and many inactive values
    tiles_zlib           the same saved with zlib (class unknown: OpenVDB never zips a fog volume)
    tiles_double         the same as a double-precision grid
    cloud_half           noise saved as half floats
    scaled_translated    noise through a non-uniform scale and a translation
    two_grids            two grids, "temperature" and "density"
    cloud_zlib_nomask    two_grids saved with zlib and no active-mask compression
    cloud_raw            scaled_translated saved uncompressed
    refuse_*             a vector grid, a level set and a rotated transform, which the reader refuses

    --big PATH   also write a 128^3 noise cloud at PATH (Blosc) and beside it as PATH_half (half floats,
                 Blosc), PATH_zlib and PATH_raw (uncompressed), for timing the reader (not fixtures)
    --cumulus PATH   also write a 128^3 cumulus-like cloud at PATH (Blosc; ``cumulus`` below), for the fit's
                 error on a cloud-like OpenVDB file (validation/accuracy/fit_clouds.py; not a fixture)
"""
import json
import os
import shutil
import subprocess
import sys
import tempfile

import numpy as np

try:
    import pyopenvdb as vdb
except ImportError:
    print("write_vdb_fixtures: skipped: no pyopenvdb module (apt-get install python3-openvdb; run with "
          "/usr/bin/python3)")
    sys.exit(0)

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT = os.path.join(HERE, "..", "..", "tests", "data", "vdb")

#: the files that hold another file's values: their reference is that file's
SAME = {"tiles_zlib.vdb": "tiles_blosc", "tiles_double.vdb": "tiles_blosc", "cloud_zlib_nomask.vdb": "two_grids"}

#: re-saves every grid of a file with the given compression flags (1 zlib, 2 active mask, 4 Blosc),
#: as double precision where asked
RESAVE = r"""
#include <openvdb/openvdb.h>
#include <cstdlib>
#include <string>
int main(int argc, char** argv) {
    openvdb::initialize();
    openvdb::io::File in(argv[1]);
    in.open();
    openvdb::GridPtrVec grids = *in.getGrids();
    in.close();
    if (argc > 4 && std::string(argv[4]) == "double") {
        for (auto& g : grids) {
            auto f = openvdb::gridPtrCast<openvdb::FloatGrid>(g);
            auto d = openvdb::DoubleGrid::create(double(f->background()));
            for (auto it = f->tree().cbeginValueAll(); it; ++it) {  // tiles and voxels, active or not
                openvdb::CoordBBox box;
                it.getBoundingBox(box);
                if (it.isVoxelValue()) d->tree().setValueOnly(it.getCoord(), double(*it));
                else d->tree().fill(box, double(*it), it.isValueOn());
                if (it.isVoxelValue() && it.isValueOn()) d->tree().setValueOn(it.getCoord());
            }
            d->setTransform(f->transform().copy());
            d->setName(f->getName());
            d->setGridClass(f->getGridClass());
            g = d;
        }
    }
    openvdb::io::File out(argv[2]);
    out.setCompression(std::atoi(argv[3]));
    out.write(grids);
    out.close();
    return 0;
}
"""


def noise(shape, seed, scale=0.6):
    """A smooth, positive noise: random values box-blurred three times, raised to a cloudy contrast."""
    rng = np.random.default_rng(seed)
    field = rng.random(shape)
    for _ in range(3):
        for axis in range(3):
            field = (np.roll(field, 1, axis) + field + np.roll(field, -1, axis)) / 3
    field = np.clip((field - field.mean()) * 8 + 0.3, 0, None)
    return (scale * field).astype(np.float32)


def _value_noise(rng, n, cells):
    """Value noise on an n^3 grid: random values on a lattice of ``cells`` cells a side, interpolated with a
    smoothstep between lattice points (numpy only: the system Python has no scipy)."""
    x = (np.arange(n) + 0.5) / n * cells
    i0 = np.minimum(np.floor(x).astype(np.int64), cells - 1)
    f = x - i0
    f = f * f * (3.0 - 2.0 * f)
    lattice = rng.random((cells + 1,) * 3)
    a = lattice[i0] * (1 - f)[:, None, None] + lattice[i0 + 1] * f[:, None, None]
    a = a[:, i0] * (1 - f)[None, :, None] + a[:, i0 + 1] * f[None, :, None]
    return a[:, :, i0] * (1 - f)[None, None, :] + a[:, :, i0 + 1] * f[None, None, :]


def _fbm(rng, n, octaves, cells):
    """Fractal value noise (gain 1/2), in [0, 1], mean about 1/2."""
    out, amp, total = np.zeros((n, n, n)), 1.0, 0.0
    for o in range(octaves):
        out += amp * _value_noise(rng, n, cells * 2 ** o)
        total += amp
        amp *= 0.5
    return out / total


def cumulus(n=128, seed=11):
    """A cumulus-like field on n^3 voxels (index k up): two towers, each a column with a flat base, sides
    that bulge and a domed top, its surface displaced by fractal noise (the turrets and holes of a
    cauliflower cloud, down to 2 voxels), the water content growing with height above the base (adiabatic)
    and with the depth inside the surface, times noise. No metaballs: a noise-displaced envelope."""
    rng = np.random.default_rng(seed)
    t = (np.arange(n) + 0.5) / n
    x, y, z = t[:, None, None], t[None, :, None], t[None, None, :]
    shape_noise = _fbm(rng, n, 5, 8) - 0.5
    water_noise = _fbm(rng, n, 4, 3)
    field = np.zeros((n, n, n))
    for cx, cy, base, top, width in ((0.45, 0.5, 0.12, 0.9, 0.3), (0.8, 0.3, 0.12, 0.55, 0.15)):
        h = (z - base) / (top - base)                                 # 0 at the base, 1 at the top
        radius = width * np.sqrt(np.clip(1.0 - np.clip(h, 0, None) ** 2.5, 0.0, None)) * (1.0 + 0.25 * np.sin(
            np.pi * np.clip(h, 0, 1)))                                 # widest a third of the way up
        d = np.sqrt((x - cx) ** 2 + (y - cy) ** 2) / np.maximum(radius, 1e-6) - 1.0
        depth = -(d + 1.8 * shape_noise)                             # > 0 inside the displaced surface
        inside = np.clip(depth / 0.25, 0.0, 1.0) ** 0.6
        water = inside * np.clip(h, 0.0, None) ** 0.5 * (h >= 0) * (h <= 1)
        field = np.maximum(field, water)
    field *= 0.5 + water_noise
    field = np.clip(field - 0.02, 0.0, None)                          # no water below a threshold: the edge
    return (field / field.max()).astype(np.float32)


def fog_sphere(radius):
    n = 2 * radius + 1
    x = np.arange(n) - radius
    r = np.sqrt(x[:, None, None] ** 2 + x[None, :, None] ** 2 + x[None, None, :] ** 2) / radius
    return np.clip(1.0 - r * r, 0.0, None).astype(np.float32)


def grid_from(array, origin, name, fog=True):
    grid = vdb.FloatGrid(0.0)
    grid.copyFromArray(array, ijk=origin, tolerance=0.0)  # zeros stay background (not stored)
    grid.name = name
    if fog:
        grid.gridClass = vdb.GridClass.FOG_VOLUME
    return grid


def sphere():
    grid = grid_from(fog_sphere(8), (0, 0, 0), "density")
    grid.transform = vdb.createLinearTransform([[0.1, 0, 0, 0], [0, 0.1, 0, 0], [0, 0, 0.1, 0],
                                                [-0.8, -0.8, -0.8, 1]])  # centred on the origin
    return grid


def tiles():
    """Noise around the corner (4096, 4096, 4096) where root, internal and leaf nodes meet, with tiles of
    constant value at every level: an inactive root tile (4096^3), an inactive 128^3 tile, an active and
    an inactive 8^3 tile."""
    grid = grid_from(noise((12, 12, 12), 1), (4084, 4084, 4084), "density")
    lit = noise((12, 12, 12), 2)
    grid.copyFromArray(lit, ijk=(4096, 4096, 4096), tolerance=0.0)
    grid.fill((4096, 0, 0), (8191, 4095, 4095), 0.25, active=False)          # a root tile
    grid.fill((3968, 4096, 3968), (4095, 4223, 4095), 0.5, active=False)     # a 128^3 tile
    grid.fill((4088, 4088, 4080), (4095, 4095, 4087), 0.6, active=True)      # an active 8^3 tile
    grid.fill((4080, 4080, 4088), (4087, 4087, 4095), 0.3, active=False)     # an inactive 8^3 tile
    # leaves whose inactive voxels hold values other than the background, as node-mask compression
    # stores them: one other value (flag 2), two (flag 5), more than two (flag 6, all values saved)
    access = grid.getAccessor()
    for origin, values in (((4104, 4096, 4080), (0.2, 0.2)), ((4096, 4096, 4080), (0.2, 0.3)),
                           ((4096, 4104, 4080), (0.1, 0.2, 0.3))):
        grid.fill(origin, tuple(o + 7 for o in origin), 0.4, active=True)
        for n, value in enumerate(values):
            access.setValueOff((origin[0] + n, origin[1] + 2 * n, origin[2] + 3 * n), value)
    grid.transform = vdb.createLinearTransform([[0.5, 0, 0, 0], [0, 0.5, 0, 0], [0, 0, 0.5, 0],
                                                [-2048.0, -2048.0, -2040.0, 1]])
    return grid


def cloud(shape=(24, 20, 16), seed=3, name="cloud"):
    """Noise of class unknown, which OpenVDB may zip (it never zips a fog volume)."""
    return grid_from(noise(shape, seed), (1, 2, 3), name, fog=False)


def scaled():
    """Non-uniform scale and a translation."""
    grid = grid_from(noise((20, 12, 16), 4), (3, 5, 7), "density")
    grid.transform = vdb.createLinearTransform([[0.25, 0, 0, 0], [0, 0.5, 0, 0], [0, 0, 2.0, 0],
                                                [10.0, -3.0, 100.0, 1]])
    return grid


def reference(path, folder):
    """The dense values over the active box as OpenVDB reads the file back, and the box."""
    names = [g.name for g in vdb.readAllGridMetadata(path)]
    grid = vdb.read(path, "density" if "density" in names else names[0])
    (i0, j0, k0), (i1, j1, k1) = grid.evalActiveVoxelBoundingBox()
    dtype = np.float64 if grid.valueTypeName == "double" else np.float32
    dense = np.zeros((i1 - i0 + 1, j1 - j0 + 1, k1 - k0 + 1), dtype=dtype)
    grid.copyToArray(dense, ijk=(i0, j0, k0))
    corners = [grid.transform.indexToWorld((i0 + a * (i1 - i0 + 1) - 0.5, j0 + a * (j1 - j0 + 1) - 0.5,
                                            k0 + a * (k1 - k0 + 1) - 0.5)) for a in (0, 1)]
    lower, upper = np.minimum(*corners).tolist(), np.maximum(*corners).tolist()
    stem = os.path.splitext(path)[0]
    np.save(stem + ".npy", dense)
    with open(stem + ".json", "w") as f:
        json.dump({"grid": grid.name, "type": grid.valueTypeName, "index_min": [i0, j0, k0],
                   "index_max": [i1, j1, k1], "lower": lower, "upper": upper,
                   "transform": grid.transform.typeName, "half": bool(grid.saveFloatAsHalf)}, f, indent=1)
        f.write("\n")
    print(f"{os.path.relpath(path)}: {os.path.getsize(path)} bytes, {dense.shape} {grid.valueTypeName}, "
          f"{grid.transform.typeName}, {grid.leafCount()} leaves")


def resaver(workdir):
    """The path of the compiled RESAVE program, or None without g++ and the OpenVDB headers."""
    if not shutil.which("g++"):
        return None
    source = os.path.join(workdir, "resave.cpp")
    with open(source, "w") as f:
        f.write(RESAVE)
    exe = os.path.join(workdir, "resave")
    done = subprocess.run(["g++", "-std=c++17", "-O1", source, "-o", exe, "-lopenvdb", "-ltbb", "-lImath"],
                          capture_output=True, text=True)
    if done.returncode:
        print("write_vdb_fixtures: no C++ re-saver (zlib, uncompressed and double files skipped):",
              done.stderr.strip().splitlines()[:1])
        return None
    return exe


def main(argv):
    big = cumulus_path = None
    if "--big" in argv:
        i = argv.index("--big")
        big = argv[i + 1]
        del argv[i:i + 2]
    if "--cumulus" in argv:
        i = argv.index("--cumulus")
        cumulus_path = argv[i + 1]
        del argv[i:i + 2]
    folder = os.path.abspath(argv[0] if argv else DEFAULT)
    os.makedirs(folder, exist_ok=True)
    print(f"OpenVDB {'.'.join(map(str, vdb.LIBRARY_VERSION))}, file format {vdb.FILE_FORMAT_VERSION}")
    out = lambda name: os.path.join(folder, name)  # noqa: E731
    written = []

    def save(name, grids):
        vdb.write(out(name), grids=grids if isinstance(grids, list) else [grids])
        written.append(name)

    save("sphere_blosc.vdb", sphere())
    save("tiles_blosc.vdb", tiles())
    half = cloud()
    half.saveFloatAsHalf = True
    save("cloud_half.vdb", half)
    save("scaled_translated.vdb", scaled())
    # two grids in one file: the reader picks one by name
    save("two_grids.vdb", [cloud((10, 10, 10), 5, "temperature"), cloud((16, 12, 8), 6, "density")])

    with tempfile.TemporaryDirectory() as work:
        exe = resaver(work)
        if exe:
            for name, source, flags, extra in (("tiles_zlib.vdb", "tiles_blosc.vdb", 3, []),
                                               ("cloud_zlib_nomask.vdb", "two_grids.vdb", 1, []),
                                               ("cloud_raw.vdb", "scaled_translated.vdb", 0, []),
                                               ("tiles_double.vdb", "tiles_blosc.vdb", 6, ["double"])):
                src = out(source)
                if name == "tiles_zlib.vdb":  # OpenVDB never zips a fog volume: save it as class unknown
                    grid = vdb.read(src, "density")
                    grid.gridClass = vdb.GridClass.UNKNOWN
                    src = os.path.join(work, "unknown.vdb")
                    vdb.write(src, grids=[grid])
                subprocess.run([exe, src, out(name), str(flags)] + extra, check=True)
                written.append(name)
        if big:
            stem = os.path.splitext(big)[0]
            os.makedirs(os.path.dirname(os.path.abspath(big)), exist_ok=True)
            grid = grid_from(noise((128, 128, 128), 7), (0, 0, 0), "density", fog=False)
            vdb.write(big, grids=[grid])
            grid.saveFloatAsHalf = True
            vdb.write(stem + "_half.vdb", grids=[grid])
            bigs = [big, stem + "_half.vdb"]
            if exe:
                for suffix, flags in (("_zlib", 3), ("_raw", 0)):
                    subprocess.run([exe, big, stem + suffix + ".vdb", str(flags)], check=True)
                    bigs.append(stem + suffix + ".vdb")
            for path in bigs:
                print(f"{path}: {os.path.getsize(path)} bytes, 128^3 noise, {grid.leafCount()} leaves")
        if cumulus_path:
            os.makedirs(os.path.dirname(os.path.abspath(cumulus_path)), exist_ok=True)
            grid = grid_from(cumulus(), (0, 0, 0), "density")
            vdb.write(cumulus_path, grids=[grid])
            print(f"{cumulus_path}: {os.path.getsize(cumulus_path)} bytes, 128^3 cumulus, {grid.leafCount()} leaves")

    for name in written:
        if name not in SAME:
            reference(out(name), folder)
    for name, twin in SAME.items():
        if name not in written:
            continue
        if name != "tiles_double.vdb":  # pyopenvdb reads no double grids; the others OpenVDB checks here
            again = os.path.join(folder, ".again.vdb")
            shutil.copyfile(out(name), again)
            reference(again, folder)
            same = np.array_equal(np.load(os.path.join(folder, ".again.npy")), np.load(out(twin + ".npy")))
            for ext in (".vdb", ".npy", ".json"):
                os.remove(os.path.join(folder, ".again" + ext))
            assert same, f"{name}: OpenVDB reads other values than {twin}.npy"
        print(f"{name}: {os.path.getsize(out(name))} bytes, the values of {twin}.vdb")

    # files the reader refuses, each small: another grid type, a level set, a rotated transform
    vec = vdb.Vec3SGrid()
    vec.copyFromArray(np.ones((2, 2, 2, 3), dtype=np.float32), ijk=(0, 0, 0))
    vec.name = "velocity"
    vdb.write(out("refuse_vec3s.vdb"), grids=[vec])
    vdb.write(out("refuse_level_set.vdb"), grids=[vdb.createLevelSetSphere(2.0, voxelSize=0.5)])
    rotated = grid_from(fog_sphere(2), (0, 0, 0), "density")
    c, s = np.cos(0.3), np.sin(0.3)
    rotated.transform = vdb.createLinearTransform([[c, s, 0, 0], [-s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
    vdb.write(out("refuse_rotated.vdb"), grids=[rotated])
    total = sum(os.path.getsize(os.path.join(folder, n)) for n in os.listdir(folder))
    print(f"{folder}: {len(os.listdir(folder))} files, {total} bytes")


if __name__ == "__main__":
    main(sys.argv[1:])
