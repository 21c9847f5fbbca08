"""Writes creature_whale.csv and creature_floor.csv: a killer-whale-like creature over a bumpy sea floor,
the stand-in for the paper's killer whale (890 balls) on a sea floor (740 balls); deterministic (seed 3).

Units are about half a metre: the whale is 12 long, its snout towards +x, swimming 3 to 4 above the floor.

The whale (867 balls):
- body (468): 52 rings along a gently S-curved spine, each ring a centre ball and 8 balls around it (offset
  0.6 rho, radius 0.6 rho; the centre radius 0.9 rho), rings 0.3 rho apart, where rho is the body radius
  wanted there divided by 0.94 (a straight tube built so has its isosurface at 0.94 of rho, ripple 1 %,
  wyvill6, T = 0.5); the radius swells from a blunt snout to 1.25 at 40 % of the length and narrows to a
  tail stock flattened from side to side;
- dorsal fin, two pectoral flippers and two flukes (388): sheets of flattened ellipsoids 0.45 of their
  in-plane radius r apart, inset 0.62 r from the outline (a sheet so built ends 0.62 r past its last
  centres and is 1.35 times the thin radius thick);
- a blowhole and the line of the mouth: 11 negative balls (CSG).

The floor (900 balls): a jittered 24 x 22 grid of wide, flattened ellipsoids (528) whose tops follow a
smooth height field (two rolling swells, a ridge behind the whale), 152 boulders heaped in 7 clusters
and 220 pebbles. It is about 68 x 64, larger than the view of creature.yaml, whose haze hides its far
edge.

Run from the repository root: python scenes/make_creature.py [OUTDIR]
"""
import numpy as np

from shapes import ellipsoid, out_dir, sphere, unit, write_balls

LENGTH = 12.0
FLOOR_BALLS = 900
#: body radius (wanted isosurface) against s, the fraction of the length from the snout
PROFILE_S = (0.0, 0.02, 0.06, 0.12, 0.22, 0.40, 0.55, 0.68, 0.80, 0.90, 0.96, 1.0)
PROFILE_R = (0.25, 0.55, 0.78, 0.95, 1.12, 1.25, 1.15, 0.92, 0.62, 0.40, 0.30, 0.24)
#: width / height of the cross-section against s: round, then a tail stock flattened sideways
WIDTH_S = (0.0, 0.55, 0.80, 0.92, 1.0)
WIDTH_R = (1.0, 0.95, 0.72, 0.55, 0.6)
TUBE_ISO = 0.94  # a straight tube of rings: isosurface at 0.94 rho
SHEET_EDGE = 0.62  # a sheet ends this many in-plane radii past its outermost centres
SHEET_THICK = 1.35  # a sheet's isosurface is this many thin radii thick


def spine(s):
    """Point on the spine at fraction s from the snout (snout at +x)."""
    x = LENGTH * (0.5 - s)
    z = 4.4 + 0.35 * np.sin(np.pi * (s - 0.15)) - 0.55 * s ** 3  # head a little down, tail lifting then lower
    y = 0.35 * np.sin(2.0 * np.pi * s)  # a slight sideways bend, as in a stroke
    return np.array([x, y, z])


def spine_frame(s, ds=1e-3):
    """(tangent towards the tail, side (+y-ish), up (+z-ish)) at s."""
    t = unit(spine(s + ds) - spine(s - ds))
    up = unit(np.array([0.0, 0.0, 1.0]) - t[2] * t)
    return t, np.cross(up, t), up


def body():
    rows = []
    s = 0.0
    k = 0
    while s <= 1.0:
        rho = np.interp(s, PROFILE_S, PROFILE_R) / TUBE_ISO
        w = np.interp(s, WIDTH_S, WIDTH_R)
        c = spine(s)
        t, side, up = spine_frame(s)
        rows.append(ellipsoid(c, t, up, (0.9 * rho, w * 0.9 * rho, 0.9 * rho)))
        for j in range(8):
            a = 2 * np.pi * (j + 0.5 * (k % 2)) / 8
            offset = 0.6 * rho * (w * np.cos(a) * side + np.sin(a) * up)
            rows.append(ellipsoid(c + offset, t, up, (0.6 * rho, w * 0.6 * rho, 0.6 * rho)))
        s += 0.3 * rho / LENGTH
        k += 1
    return rows


def fin(origin, chord_axis, span_axis, length, lead, trail, thickness, r0, r1):
    """A fin of span ``length``: rows of flattened ellipsoids across the chord, the rows 0.45 r apart.

    ``lead``, ``trail`` map the span fraction v to the chord coordinates of the outline; the in-plane radius
    r tapers from r0 at the root to r1 at the tip and the isosurface thickness from ``thickness`` to half
    of it. Centres are inset SHEET_EDGE r from the outline, the last row SHEET_EDGE r1 from the tip.
    """
    u_axis, v_axis = unit(chord_axis), unit(span_axis)
    normal = np.cross(u_axis, v_axis)
    out = []
    along, end = 0.0, length - SHEET_EDGE * r1
    while along <= end + 1e-9:
        v = along / length
        r = r0 + (r1 - r0) * v
        t = thickness * (1.0 - 0.5 * v) / SHEET_THICK
        a, b = lead(v) + SHEET_EDGE * r, trail(v) - SHEET_EDGE * r
        us = [0.5 * (a + b)] if b <= a else np.linspace(a, b, int(np.ceil((b - a) / (0.45 * r))) + 1)
        for u in us:
            out.append(ellipsoid(origin + u * u_axis + along * v_axis, u_axis, normal, (r, r, t)))
        along += 0.45 * r
    return out


def whale():
    rows = body()
    # dorsal fin: tall, swept back; chord along the tail direction, span up
    s0 = 0.42
    t, side, up = spine_frame(s0)
    root = spine(s0) + 0.75 * np.interp(s0, PROFILE_S, PROFILE_R) * up
    rows += fin(root, t, unit(up + 0.25 * t), 3.0,
                lambda v: -1.0 + 1.45 * v ** 0.8, lambda v: 1.6 - 1.45 * v, 0.5, 0.6, 0.28)
    # pectoral flippers: paddles, down, out and back from low on the sides behind the head
    s0 = 0.22
    t, side, up = spine_frame(s0)
    rho = np.interp(s0, PROFILE_S, PROFILE_R)
    for sign in (1.0, -1.0):
        root = spine(s0) + rho * (0.55 * sign * side - 0.6 * up)
        span = unit(0.45 * t + 0.75 * sign * side - 0.55 * up)
        chord = unit(t - np.dot(t, span) * span)
        rows += fin(root, chord, span, 2.4, lambda v: -0.45 - 0.35 * np.sin(np.pi * v ** 0.9),
                    lambda v: 0.55 + 0.2 * np.sin(np.pi * v) - 0.4 * v ** 3, 0.4, 0.45, 0.32)
    # flukes: horizontal, swept back from the tail stock, with pointed tips
    s0 = 0.975
    t, side, up = spine_frame(s0)
    for sign in (1.0, -1.0):
        span = unit(0.6 * t + sign * side)
        chord = unit(t - np.dot(t, span) * span)
        rows += fin(spine(s0) - 0.1 * t, chord, span, 3.0, lambda v: -1.0 + 0.3 * v + 0.6 * v ** 2,
                    lambda v: 0.95 - 0.35 * v - 0.55 * v ** 2, 0.4, 0.55, 0.26)
    # blowhole: a small negative ball on top of the head
    t, side, up = spine_frame(0.16)
    rows.append(sphere(spine(0.16) + 0.98 * np.interp(0.16, PROFILE_S, PROFILE_R) * up, 0.32, weight=-1.0))
    # the mouth: a line of negative balls low on each side, from near the snout back
    for s in np.linspace(0.025, 0.11, 5):
        t, side, up = spine_frame(s)
        rho = np.interp(s, PROFILE_S, PROFILE_R)
        for sign in (1.0, -1.0):
            rows.append(sphere(spine(s) + rho * (0.95 * sign * side - 0.35 * up), 0.16 + 0.6 * s, weight=-0.8))
    return rows


def height(x, y):
    """The floor's height field: rolling swells, a ridge behind the whale, a shallow hollow under it."""
    return (0.7 * np.sin(0.19 * x + 0.4) * np.cos(0.13 * y) + 0.5 * np.sin(0.11 * y - 0.07 * x)
            + 2.2 * np.exp(-((y - 22.0) / 6.0) ** 2) * (1.0 + 0.4 * np.sin(0.23 * x))
            - 0.6 * np.exp(-((x - 1.0) ** 2 + (y - 1.0) ** 2) / 40.0))


def floor(seed=3):
    rng = np.random.default_rng(seed)
    rows = []
    xs, ys = np.linspace(-40, 20, 24), np.linspace(-12, 44, 22)
    for y in ys:
        for x in xs:
            x1, y1 = x + rng.uniform(-0.6, 0.6), y + rng.uniform(-0.6, 0.6)
            a, c = rng.uniform(3.9, 4.5), rng.uniform(1.3, 1.5)
            phi = rng.uniform(0, np.pi)
            # the sheet's top lies about 0.6 c above its centres: put it at the height field
            rows.append(ellipsoid((x1, y1, height(x1, y1) - 0.6 * c), (np.cos(phi), np.sin(phi), 0.0), (0, 0, 1),
                                  (a, a * rng.uniform(0.85, 1.0), c)))
    # boulders: heaps around a few centres
    heaps = ((-9.0, 6.0, 22), (13.0, 10.0, 30), (4.0, 18.0, 26), (-3.0, -4.0, 14), (-24.0, 4.0, 20),
             (-16.0, 20.0, 22), (-30.0, 28.0, 18))
    for hx, hy, n in heaps:
        for _ in range(n):
            d = rng.normal(0.0, 1.6, 2)
            x, y = hx + d[0], hy + d[1]
            r = rng.uniform(0.8, 1.8) * np.exp(-0.08 * (d ** 2).sum())
            rows.append(ellipsoid((x, y, height(x, y) + 0.1 * r), (rng.normal(), rng.normal(), 0.2),
                                  (0, 0, 1), (1.3 * r, r, 0.85 * r)))
    # pebbles
    while len(rows) < FLOOR_BALLS:
        x, y = rng.uniform(-36, 16), rng.uniform(-8, 40)
        r = rng.uniform(0.5, 0.9)
        rows.append(sphere((x, y, height(x, y)), r))
    return rows


if __name__ == "__main__":
    folder = out_dir()
    w = write_balls(folder / "creature_whale.csv", whale())
    f = write_balls(folder / "creature_floor.csv", floor())
    print(f"wrote {len(w)} balls to {folder / 'creature_whale.csv'} and {len(f)} to {folder / 'creature_floor.csv'}")
