"""Writes dense_1000.csv and dense_1000.yaml: a stratocumulus bank of 1,200 metaballs, deterministic (seed 11).

A sheet of cloud cells about 70 x 46 units with gaps between them: each cell is a cluster of wide,
flattened ellipsoids at the base (z ~ 2) under a cauliflower of smaller spheres whose tops rise towards
the cell's middle. The cells sit on a jittered grid and vary in size, so that the bank breaks up into
rolls and holes as stratocumulus does. Seen from an aircraft above the bank in dense_1000.yaml.

Run from the repository root: python scenes/make_dense.py [OUTDIR]
"""
import sys
from pathlib import Path

import numpy as np

N_BALLS = 1200
SCENE = """\
# A broken stratocumulus bank of 1,200 metaballs (dense_1000.csv, made by scenes/make_dense.py) seen from
# an aircraft above it, the sun 40 degrees up behind the bank; the benchmark scene of
# validation/performance/time_vs_error.py (256 x 256 at the default quality: 4-10 s on 2 cores).
# Render: cloudmeta render scenes/dense_1000.yaml --png dense_1000.png
image: {width: 256, height: 256, spp: 1}
camera: {position: [0, -44, 24], look_at: [0, -2, 1.0], up: [0, 0, 1], fov: 44}
background: [0.16, 0.30, 0.62]
ambient: [0.08, 0.11, 0.18]
lights:
  - {type: directional, direction: [0.45, 0.5, 0.55], irradiance: 12.0, color: {temperature: 5000}}
media:
  - name: stratocumulus
    kernel: wyvill6
    threshold: 0.3
    density: {mode: field, scale: 1.0}
    albedo: 0.96
    phase: {type: hg, g: 0.6}
    balls_file: dense_1000.csv
render: {quality: default}
output: {path: dense_1000.exr, png: dense_1000.png, exposure: 0.0}
"""


def dense(n=N_BALLS, seed=11):
    rng = np.random.default_rng(seed)
    # cell centres: a jittered 8 x 5 grid, spacing ~9 units, some cells smaller than others
    gx, gy = np.meshgrid(np.linspace(-30, 30, 8), np.linspace(-18, 18, 5))
    cells = np.stack([gx.ravel(), gy.ravel()], axis=1) + rng.uniform(-2.0, 2.0, (gx.size, 2))
    size = rng.uniform(0.7, 1.0, len(cells))
    weight = size / size.sum()
    rows = []
    n_base = int(0.4 * n)
    for k in range(n):
        c = rng.choice(len(cells), p=weight)
        cx, cy = cells[c]
        spread = 5.4 * size[c]
        r_off = spread * np.sqrt(rng.uniform(0.0, 1.0))  # uniform over the cell's disc
        phi = rng.uniform(0.0, 2 * np.pi)
        x, y = cx + r_off * np.cos(phi), cy + 0.85 * r_off * np.sin(phi)
        rim = r_off / spread  # 0 in the middle of the cell, 1 at its edge
        if k < n_base:  # base: flattened ellipsoids, long axis anywhere in the horizontal plane
            a = rng.uniform(2.2, 3.0) * (0.7 + 0.3 * size[c])
            rows.append((x, y, rng.uniform(1.8, 2.3), a, a * rng.uniform(0.7, 1.0), a * rng.uniform(0.35, 0.45),
                         0.0, 0.0, rng.uniform(0.0, 180.0), rng.uniform(0.9, 1.1)))
        else:  # tops: spheres, higher and bigger towards the middle of the cell
            r = (1.5 - 0.6 * rim) * size[c] + rng.uniform(-0.15, 0.15)
            z = 2.6 + 2.2 * size[c] * (1.0 - rim ** 2) * rng.uniform(0.6, 1.0)
            rows.append((x, y, z, r, r, r, 0.0, 0.0, 0.0, rng.uniform(0.85, 1.1)))
    return np.array(rows)


if __name__ == "__main__":
    here = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parent
    balls = dense()
    np.savetxt(here / "dense_1000.csv", balls, delimiter=",", fmt="%.4f", header="x,y,z,rx,ry,rz,ax,ay,az,weight",
               comments="")
    (here / "dense_1000.yaml").write_text(SCENE)
    print(f"wrote {len(balls)} balls to {here / 'dense_1000.csv'}, and {here / 'dense_1000.yaml'}")
