"""The fit's error against the number of balls on four voxel clouds that no metaball made (docs/fit.md,
*Voxel clouds*), each read through cloudmeta.fit.read_grid as a user's file would be:

    noise    the procedural noise cloud of validation/accuracy/fit_error.py (128^3, 5 octaves, seed 1),
             saved as .npz
    netcdf   an LES-like liquid-water field written here to a NetCDF file with xarray: a few thermals
             (smooth blobs, wider at the top than at the base) times smoothed noise, the water content
             decaying with height above each thermal's core, in g m-3 on 128^3 voxels of 25 m with
             coordinates in m; read with conversion lwc:10um (sigma_t = 3 LWC / (2 rho_w r_e), per m)
    vdb      the 128^3 noise that validation/tools/write_vdb_fixtures.py --big writes with OpenVDB itself
             (run under /usr/bin/python3, which has pyopenvdb; written here when missing): white noise
             box-blurred three times, filling 94 % of the box; the hard case, not cloud-like
    cumulus  the 128^3 cumulus-like cloud that write_vdb_fixtures.py --cumulus writes with OpenVDB: two
             towers with flat bases and domed tops, their surfaces displaced by fractal noise, the water
             growing with height

For each cloud and ball budget: the balls, the density's relative L2 error on the grid, the optical depth's
relative RMSE along 10^4 random rays (exact tau of the balls against the grid's trilinear interpolant), and
the fit's process CPU time (time.process_time: other processes on a shared machine do not inflate it) and
wall time.

    python -m validation.accuracy.fit_clouds                              # 10^3, 10^4, 2 x 10^4 balls
    python -m validation.accuracy.fit_clouds --clouds netcdf --balls 100000
    python -m validation.accuracy.fit_clouds --write /tmp/fits            # keep the grids and fitted scenes
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from cloudmeta.fit import LiquidWater, fit_volume, read_grid
from cloudmeta.fit.error import RAYS
from cloudmeta.fit.procedural import noise_cloud

N = 128
CLOUDS = ("noise", "netcdf", "vdb", "cumulus")
WRITER = Path(__file__).resolve().parents[1] / "tools" / "write_vdb_fixtures.py"


def noise_npz(path, n=N):
    """The procedural cloud of fit_error.py, saved as the .npz that cloudmeta fit reads."""
    density, lower, upper = noise_cloud((n, n, n), seed=1, octaves=5, coverage=0.7, peak=20.0, size=1.0)
    np.savez(path, density=density, lower=lower, upper=upper)
    return path


def _smooth_noise(rng, shape, sigma):
    from scipy.ndimage import gaussian_filter
    f = gaussian_filter(rng.standard_normal(shape), sigma, mode="wrap")
    return f / f.std()


def les_field(n=N, dx=25.0, dz=25.0, base=600.0, seed=7):
    """(lwc g m-3 as (z, y, x), x, y, z voxel centres in m): an LES-like cumulus field."""
    rng = np.random.default_rng(seed)
    x = (np.arange(n) + 0.5) * dx
    y = (np.arange(n) + 0.5) * dx
    z = base + (np.arange(n) + 0.5) * dz
    Z, Y, X = np.meshgrid(z, y, x, indexing="ij")
    width = n * dx
    lwc = np.zeros((n, n, n))
    for _ in range(6):
        cx, cy = rng.uniform(0.2, 0.8, 2) * width
        top = base + rng.uniform(0.45, 0.9) * n * dz            # the thermal's top
        core = base + 0.35 * (top - base)                      # where its water is densest
        r0 = rng.uniform(0.08, 0.14) * width                   # its radius at the base
        h = np.clip((Z - base) / (top - base), 0.0, None)      # height in the thermal, 0..1
        radius = r0 * (0.7 + 0.6 * np.sqrt(np.minimum(h, 1.0)))  # a cauliflower top wider than its base
        d2 = ((X - cx) ** 2 + (Y - cy) ** 2) / radius ** 2
        vertical = np.where(Z < core, np.sin(0.5 * np.pi * np.clip((Z - base) / (core - base), 0, 1)),
                            np.exp(-2.5 * (Z - core) / (top - core)))  # decays above the core
        lwc += rng.uniform(0.6, 1.2) * np.clip(1.0 - d2, 0.0, None) ** 1.5 * vertical * (h < 1.0)
    turb = 1.0 + 0.35 * _smooth_noise(rng, lwc.shape, 3.0) + 0.15 * _smooth_noise(rng, lwc.shape, 1.0)
    lwc = lwc * turb
    lwc *= 1.5 / lwc.max()                       # at most 1.5 g m-3, a cumulus core's water content
    lwc = np.clip(lwc - 0.02, 0.0, None)         # the cloud's edge: no liquid water below 0.02 g m-3
    return lwc, x, y, z


def netcdf_file(path, n=N):
    import xarray as xr
    lwc, x, y, z = les_field(n)
    ds = xr.Dataset(
        {"lwc": (("z", "y", "x"), lwc.astype(np.float32), {"units": "g m-3", "long_name": "liquid water content"})},
        coords={"x": ("x", x, {"units": "m", "axis": "X"}), "y": ("y", y, {"units": "m", "axis": "Y"}),
                "z": ("z", z, {"units": "m", "axis": "Z", "positive": "up"})})
    tmp = str(path) + ".part"
    ds.to_netcdf(tmp)
    os.replace(tmp, path)
    return path


def vdb_file(path, option="--big"):
    """The big OpenVDB file that the writer's ``option`` writes at ``path`` (written when missing)."""
    if not Path(path).exists():
        folder = tempfile.mkdtemp(prefix="fit_clouds_vdb_")
        subprocess.run(["/usr/bin/python3", str(WRITER), folder, option, str(path)], check=True,
                       stdout=subprocess.DEVNULL)
    return path


def grid_of(name, folder):
    folder = Path(folder)
    if name == "noise":
        return read_grid(noise_npz(folder / "noise128.npz"))
    if name == "netcdf":
        return read_grid(netcdf_file(folder / "les128.nc"),
                         conversion=LiquidWater(effective_radius=10e-6, units="g m-3"))
    if name == "vdb":
        return read_grid(vdb_file(folder / "noise128.vdb"))
    if name == "cumulus":
        return read_grid(vdb_file(folder / "cumulus128.vdb", "--cumulus"))
    raise ValueError(name)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--clouds", nargs="+", choices=CLOUDS, default=list(CLOUDS))
    ap.add_argument("--balls", type=int, nargs="+", default=[1000, 10000, 20000])
    ap.add_argument("--rays", type=int, default=RAYS)
    ap.add_argument("--write", metavar="DIR", help="keep the grid files and write each fitted scene here "
                                                   "(DIR/CLOUD_BALLS.yaml)")
    args = ap.parse_args(argv)
    folder = args.write or tempfile.mkdtemp(prefix="fit_clouds_")
    os.makedirs(folder, exist_ok=True)
    print(f"| cloud | grid | occupied | balls asked | balls | density L2 error | optical-depth rel. RMSE "
          f"({args.rays:,} rays) | fit CPU s | fit wall s | errors CPU s |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name in args.clouds:
        g = grid_of(name, folder)
        occupied = int((g.density > 0).sum())
        for balls in args.balls:
            out = Path(folder) / f"{name}_{balls}.yaml" if args.write else None
            c0 = time.process_time()
            r = fit_volume(g, out, balls=balls, rays=args.rays, progress=False, overwrite=True)
            c1 = time.process_time()
            shape = "x".join(map(str, g.density.shape))
            print(f"| {name} | {shape} | {occupied:,} ({100 * occupied / g.density.size:.0f} %) | {balls:,} | "
                  f"{len(r):,} | {r.errors['density']:.4f} | {r.errors['depth']:.4f} | {r.cpu_seconds:.1f} | "
                  f"{r.seconds:.1f} | {c1 - c0 - r.cpu_seconds:.1f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
