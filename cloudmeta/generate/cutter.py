"""The flat base: the cutter, one flat ball of large negative weight under z = 0 that overwhelms every
positive ball there (docs/generate.md, Flat base)."""
from __future__ import annotations

import math

import numpy as np

from .field import _Field, _solve_u
from .params import CUTTER_WEIGHT, THRESHOLD


def _base_field_bound(c, r, a, q, tag, depth, n=40):
    """A bound on the field of the positive balls below the base (what the cutter must overcome there):
    the largest value sampled on n x n points across the cloud's footprint at z = 0, -depth/3 and
    -2 depth/3, times 1.5, plus T."""
    f = _Field()
    for level in np.unique(tag):
        i = np.flatnonzero((tag == level) & (q > 0))
        f.add(c[i], r[i], a[i], q[i])
    lo, hi = c[:, :2].min(axis=0), c[:, :2].max(axis=0)
    xs, ys = np.linspace(lo[0], hi[0], n), np.linspace(lo[1], hi[1], n)
    x, y = [v.ravel() for v in np.meshgrid(xs, ys, indexing="ij")]
    pts = np.concatenate([np.stack([x, y, np.full_like(x, z)], 1) for z in (0.0, -depth / 3, -2 * depth / 3)])
    return 1.5 * float(max(f(pts).max(), 0.0)) + THRESHOLD


def _cutter(c, half, depth, field_bound):
    """The base cutter: (x, y, z, rx, ry, rz, weight). A flat ellipsoid under z = 0 of weight -CUTTER_WEIGHT.
    Where its field exceeds field_bound, no positive ball can bring F up to T; that region (an ellipsoid
    u <= u_b of the cutter's frame) is placed to contain the whole part of the positive supports below
    z = 0: their footprint there lies inside the ellipse (x / ex)^2 + (y / ey)^2 <= 1 at z = 0, and no
    deeper than ``depth``. The cutter is 4 times as wide as that footprint and 1.3 times as deep, so the
    top of the cut region dips by only ~(1/16)/2 x 1.3 depth between the centre and the footprint's edge,
    and the cut lies between z = 0 and the top of the cutter's support, ~0.06 x depth above: the base is
    flat."""
    below = c[:, 2] - half[:, 2] < 0
    if not np.any(below):
        below = np.ones(len(c), bool)
    ex = np.max(np.abs(c[below, 0]) + half[below, 0])
    ey = np.max(np.abs(c[below, 1]) + half[below, 1])
    # scale the footprint ellipse so that every support's box lies inside it
    fx, fy = np.abs(c[below, 0]) + half[below, 0], np.abs(c[below, 1]) + half[below, 1]
    grow = float(np.max(np.sqrt((fx / ex) ** 2 + (fy / ey) ** 2)))
    ex, ey = ex * grow, ey * grow
    ax, ay = 4.0 * ex, 4.0 * ey
    depth = max(depth, 1e-3)
    hz = 1.3 * depth
    # u_b: CUTTER_WEIGHT k(u_b) = field_bound
    u_b = float(_solve_u(min(field_bound / CUTTER_WEIGHT, 0.5)))
    # the ellipsoid u = u_b passes through the footprint's edge at z = 0: (1/4)^2 + (z0 / hz)^2 = u_b
    z0 = -hz * math.sqrt(max(u_b - 1.0 / 16.0, 1e-6))
    return np.array([0.0, 0.0, z0, ax, ay, hz, -CUTTER_WEIGHT])
