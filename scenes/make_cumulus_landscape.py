"""Writes cumulus_landscape.csv: rolling hills of 400 large, flattened metaballs under the cumulus of
cumulus.csv (which cumulus_landscape.yaml reuses as it is); deterministic (seed 13).

The hills cover x in [-70, 70], y in [-45, 85] (the cloud sits over the origin, its base at z = 0): a
jittered 20 x 19 grid of flattened ellipsoids (horizontal radii 10.5 to 12, vertical 3.2 to 3.8, about
0.6 of their radius apart) whose tops follow a smooth height field: ground about z = -12 (-9 under the
cloud), swells of +-3.8, a ridge far behind the cloud rising 4.5 higher (it hides the ground's far edge
from the camera) and a hill on the near left. 20 more, smaller balls make knolls on the slopes.

Run from the repository root: python scenes/make_cumulus_landscape.py [OUTDIR]
"""
import numpy as np

from shapes import ellipsoid, out_dir, write_balls

N_BALLS = 400


def height(x, y):
    """Ground height at (x, y)."""
    return (-12.0 + 2.6 * np.sin(0.08 * x + 1.0) * np.cos(0.06 * y) + 1.2 * np.sin(0.05 * y - 0.04 * x + 0.5)
            + 4.5 / (1.0 + np.exp(-(y - 60.0) / 6.0)) * (0.8 + 0.2 * np.sin(0.09 * x))
            + 5.0 * np.exp(-((x + 30.0) ** 2 + (y + 10.0) ** 2) / 250.0))


def landscape(seed=13):
    rng = np.random.default_rng(seed)
    rows = []
    for y in np.linspace(-45, 85, 19):
        for x in np.linspace(-70, 70, 20):
            x1, y1 = x + rng.uniform(-1.5, 1.5), y + rng.uniform(-1.5, 1.5)
            a, c = rng.uniform(10.5, 12.0), rng.uniform(3.2, 3.8)
            phi = rng.uniform(0.0, np.pi)
            # a sheet of such balls has its top about 0.6 c above their centres
            rows.append(ellipsoid((x1, y1, height(x1, y1) - 0.6 * c), (np.cos(phi), np.sin(phi), 0.0), (0, 0, 1),
                                  (a, a * rng.uniform(0.8, 1.0), c)))
    while len(rows) < N_BALLS:  # knolls
        x, y = rng.uniform(-50, 50), rng.uniform(-20, 55)
        r = rng.uniform(3.0, 5.0)
        phi = rng.uniform(0.0, np.pi)
        rows.append(ellipsoid((x, y, height(x, y) - 0.2 * r), (np.cos(phi), np.sin(phi), 0.0), (0, 0, 1),
                              (1.4 * r, r, 0.6 * r)))
    return rows


if __name__ == "__main__":
    folder = out_dir()
    balls = write_balls(folder / "cumulus_landscape.csv", landscape())
    print(f"wrote {len(balls)} balls to {folder / 'cumulus_landscape.csv'}")
