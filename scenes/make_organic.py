"""Writes organic.csv: a soft, stomach-like sac of 190 metaballs (the paper's stomach has 190), deterministic
(seed 5).

The sac follows a J-shaped centre line in the xz plane (Catmull-Rom through the control points below): a
rounded fundus at the top left, a wide body that bends through the greater curvature at the bottom, a
narrowing antrum rising to the right, a pinched pylorus and a short duodenum; an oesophagus comes down
from above into the top of the lesser curvature. Units are arbitrary (the sac is about 11 wide, 12 high).

- centre line: balls 0.3 of their radius apart, radius R = rho / 0.70 where rho is the tube radius wanted
  there (a straight chain of unit spheres 0.3 apart has its isosurface at 0.70 with wyvill6, weight 1,
  T = 0.5); the sac is flattened front to back by using ellipsoids 0.85 as deep;
- the oesophagus: a second, thin centre line into the sac;
- folds: as many smaller balls as make 190 in all, just inside the surface of the wide part (tube radius
  > 1.1), flattened against it (weight 0.55), which make the surface gently lumpy;
- a pit: 4 negative balls (weight -1.2) carve a round crater into the front of the body (towards -y, the
  camera of organic.yaml).

Run from the repository root: python scenes/make_organic.py [OUTDIR]
"""
import numpy as np

from shapes import ellipsoid, out_dir, sphere, write_balls

#: chain of unit spheres 0.3 apart (wyvill6, T = 0.5): isosurface radius 0.70
ISO = 0.70
SPACING = 0.3
DEPTH = 0.85  # front-to-back radius / in-plane radius
#: the sac's centre line (x, z) and tube radius there
SAC = np.array([
    (-2.1, 8.5, 1.6), (-3.2, 6.9, 2.4), (-2.6, 4.6, 2.5), (-1.9, 2.6, 2.4), (-0.6, 1.0, 2.1),
    (1.2, 0.5, 1.6), (2.8, 1.2, 1.15), (3.9, 2.6, 0.8), (4.5, 3.8, 0.55), (5.2, 4.6, 0.6), (6.3, 4.8, 0.6),
    (7.2, 4.2, 0.55),
])
#: the oesophagus, from above into the top of the lesser curvature
GULLET = np.array([(1.4, 12.4, 0.6), (0.4, 11.4, 0.65), (-0.5, 9.8, 0.75), (-1.2, 8.0, 0.9)])
N_BALLS = 190
PIT = ((-2.0, 4.3, 1.2), (-1.6, 3.8, 1.0), (-2.4, 3.9, 1.0), (-2.0, 3.4, 0.9))  # (x, z, radius)


def catmull_rom(points, samples=2000):
    """``samples`` points (samples, k) on the uniform Catmull-Rom spline through ``points`` (n, k)."""
    p = np.vstack([2 * points[0] - points[1], points, 2 * points[-1] - points[-2]])
    t = np.linspace(0, len(points) - 1, samples)
    i = np.minimum(t.astype(int), len(points) - 2)
    u = (t - i)[:, None]
    p0, p1, p2, p3 = p[i], p[i + 1], p[i + 2], p[i + 3]
    return 0.5 * ((2 * p1) + (-p0 + p2) * u + (2 * p0 - 5 * p1 + 4 * p2 - p3) * u ** 2
                  + (-p0 + 3 * p1 - 3 * p2 + p3) * u ** 3)


def tube(control):
    """(centres (m, 3), tangents (m, 3), tube radii (m,)) of stations along a centre line, each the
    ball spacing (SPACING x its ball radius) from the one before."""
    curve = catmull_rom(control)
    xz, rho = curve[:, :2], curve[:, 2]
    centres = np.column_stack([xz[:, 0], np.zeros(len(xz)), xz[:, 1]])
    steps = np.linalg.norm(np.diff(centres, axis=0), axis=1)
    arc = np.r_[0.0, np.cumsum(steps)]
    picked, s = [], 0.0
    while s <= arc[-1]:
        k = int(np.searchsorted(arc, s).clip(0, len(arc) - 1))
        picked.append(k)
        s += SPACING * rho[k] / ISO
    picked = np.array(picked)
    tangents = np.gradient(centres, axis=0)[picked]
    return centres[picked], tangents / np.linalg.norm(tangents, axis=1)[:, None], rho[picked]


def chain(control):
    centres, tangents, rho = tube(control)
    r = rho / ISO
    return [ellipsoid(c, (0.0, 1.0, 0.0), t, (DEPTH * ri, ri, ri)) for c, t, ri in zip(centres, tangents, r)]


def organic(seed=5):
    rng = np.random.default_rng(seed)
    rows = chain(SAC) + chain(GULLET)
    # folds on the wide part of the sac (tube radius > 1.1): a point on the tube's surface, pulled in a little
    centres, tangents, rho = tube(SAC)
    wide = np.flatnonzero(rho > 1.1)
    for _ in range(N_BALLS - len(rows) - len(PIT)):
        k = rng.choice(wide)
        t = tangents[k]
        side = np.cross(t, (0.0, 1.0, 0.0))
        phi = rng.uniform(0, 2 * np.pi)
        radial = np.cos(phi) * side + DEPTH * np.sin(phi) * np.array([0.0, 1.0, 0.0])
        along = rng.uniform(-0.5, 0.5) * SPACING * rho[k] / ISO
        centre = centres[k] + 0.78 * rho[k] * radial + along * t
        r = rho[k] * rng.uniform(0.42, 0.58)
        rows.append(ellipsoid(centre, t, radial, (1.6 * r, r, 0.8 * r), weight=0.55))
    # the pit: centred on the front of the body, whose tube radius there is about 2.45
    for x, z, r in PIT:
        rows.append(sphere((x, -DEPTH * 2.45, z), r, weight=-1.2))
    return rows


if __name__ == "__main__":
    folder = out_dir()
    balls = write_balls(folder / "organic.csv", organic())
    print(f"wrote {len(balls)} balls to {folder / 'organic.csv'}")
