"""The fit's error against the number of balls (docs/fit.md): a procedural noise cloud (cloudmeta.fit.procedural,
not made of metaballs) of SIZE^3 voxels, fitted with each ball budget; printed as a table of the density's
relative L2 error on the grid, the optical depth's relative RMSE along 10^4 random rays (exact tau of the balls
against the grid's trilinear interpolant), and the fit's time: process CPU time (time.process_time, which the
other processes on a shared machine do not inflate) and wall time.

    python -m validation.accuracy.fit_error                         # 128^3, 10^3 and 10^4 balls
    python -m validation.accuracy.fit_error --balls 1000 10000 20000 100000
    python -m validation.accuracy.fit_error --size 256 --balls 100000
    python -m validation.accuracy.fit_error --octaves 7                # noise down to the voxel
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from cloudmeta.fit import fit_volume
from cloudmeta.fit.error import RAYS
from cloudmeta.fit.procedural import noise_cloud


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=128, help="voxels a side (default 128)")
    ap.add_argument("--balls", type=int, nargs="+", default=[1000, 10000])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--octaves", type=int, default=5, help="noise octaves from 4 cells a side (default 5: the "
                                                           "finest 2 voxels wide at 128^3; 7: down to the voxel)")
    ap.add_argument("--rays", type=int, default=RAYS)
    args = ap.parse_args(argv)
    n = args.size
    t0 = time.process_time()
    density, lower, upper = noise_cloud((n, n, n), seed=args.seed, octaves=args.octaves, coverage=0.7,
                                          peak=20.0, size=1.0)
    print(f"cloud: {n}^3 voxels, {int((density > 0).sum()):,} occupied ({100 * (density > 0).mean():.1f} %), "
          f"{args.octaves} octaves, seed {args.seed}, made in {time.process_time() - t0:.1f} s CPU")
    print("| balls asked | balls | density L2 error | optical-depth rel. RMSE "
          f"({args.rays:,} rays) | fit CPU s | fit wall s | errors CPU s |")
    print("|---|---|---|---|---|---|---|")
    for balls in args.balls:
        c0, w0 = time.process_time(), time.perf_counter()
        r = fit_volume((density, lower, upper), balls=balls, rays=args.rays, progress=False)
        c1, w1 = time.process_time(), time.perf_counter()
        print(f"| {balls:,} | {len(r):,} | {r.errors['density']:.4f} | {r.errors['depth']:.4f} | "
              f"{r.cpu_seconds:.1f} | {r.seconds:.1f} | {c1 - c0 - r.cpu_seconds:.1f} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
