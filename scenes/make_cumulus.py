"""Writes cumulus.csv: a 77-ball cumulus (the paper's cloud has 77 metaballs), deterministic.

A flat base of wide, squashed balls and a cauliflower top of smaller ones heaped towards the middle.
Run from the repository root: python scenes/make_cumulus.py [OUTDIR]
"""
import sys
from pathlib import Path

import numpy as np


def cumulus(n=77, seed=7):
    rng = np.random.default_rng(seed)
    rows = []
    # base: 22 ellipsoids flattened in z, spread along x
    for _ in range(22):
        x, y = rng.uniform(-4.2, 4.2), rng.uniform(-1.6, 1.6)
        r = rng.uniform(1.4, 1.9)
        rows.append((x, y, rng.uniform(0.3, 0.7), r, r * rng.uniform(0.8, 1.0), r * 0.55, 0, 0, rng.uniform(0, 180),
                     rng.uniform(0.9, 1.1)))
    # body and towers: spheres, higher and smaller towards the top, pulled to the middle
    while len(rows) < n:
        h = rng.uniform(0.0, 1.0) ** 0.8
        spread = 3.8 * (1 - 0.65 * h)
        x, y = rng.normal(0, spread / 2), rng.normal(0, 0.9 * (1 - 0.5 * h))
        if abs(x) > 4.5:
            continue
        r = 1.7 - 0.9 * h + rng.uniform(-0.15, 0.15)
        rows.append((x, y, 0.9 + 4.2 * h, r, r, r, 0, 0, 0, rng.uniform(0.9, 1.15)))
    return np.array(rows)


if __name__ == "__main__":
    here = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parent
    balls = cumulus()
    np.savetxt(here / "cumulus.csv", balls, delimiter=",", fmt="%.4f", header="x,y,z,rx,ry,rz,ax,ay,az,weight",
               comments="")
    print(f"wrote {len(balls)} balls to {here / 'cumulus.csv'}")
