"""Writes hand.csv: a right hand of 94 metaballs with ellipsoid fingers (the paper's hand has 94), deterministic.

Units are centimetres. The hand stands upright, fingers along +z from the wrist at z = 0, its back towards
-y (the camera of hand.yaml) and its palm towards +y; the thumb is on the -x side. It is built as:

- palm: 5 x 4 flattened ellipsoids (20), narrower towards the wrist and thicker in the middle columns:
  a slab about 8.7 wide, 11 long and 2.9 thick; 4 more at the wrist (a short stub of forearm), 4 for the
  ball of the thumb and 2 for the heel of the little finger on the palm side: 30;
- four fingers of 3 phalanges each, every phalanx 3 ellipsoids along the bone (long radius along it, the
  thin one across the finger's back), a knuckle sphere (weight 0.8) on the back of each of the 3 joints
  and a pad at the tip (weight 0.8): 4 x 13 = 52;
- the thumb: metacarpal and 2 phalanges, 3 ellipsoids each, 2 joint knuckles and a tip pad: 12.

The fingers spread a little and curl towards the palm, the more so from index to little finger, like a
hand at rest; the thumb leaves the palm at about 45 degrees. No randomness: the numbers below are the
whole recipe. hand.yaml draws it with wyvill6 at T = 0.3, every weight 1 but the knuckles and pads.

Run from the repository root: python scenes/make_hand.py [OUTDIR]
"""
import numpy as np

from shapes import ellipsoid, out_dir, sphere, unit, write_balls

BACK = np.array([0.0, -1.0, 0.0])  # the back of the hand faces -y
#: a straight chain of ellipsoids with cross radius c, a third of a bone apart, has its isosurface (T = 0.3,
#: hand.yaml's threshold) about 1.36 c across: a finger of "diameter" t gets cross radii CROSS * t and is
#: about 1.1 t thick
CROSS = 0.82
#: per finger (index, middle, ring, little): base knuckle x and z, spread angle (deg, + towards +x),
#: phalanx lengths, finger diameter at its base, curl at each joint (deg, towards the palm)
FINGERS = (
    (-2.85, 9.6, -11.0, (4.3, 2.5, 2.1), 1.65, (6.0, 12.0, 10.0)),
    (-0.95, 10.0, -2.5, (4.7, 2.9, 2.3), 1.70, (8.0, 14.0, 12.0)),
    (0.95, 9.8, 6.0, (4.4, 2.7, 2.2), 1.62, (11.0, 17.0, 14.0)),
    (2.8, 9.1, 15.0, (3.4, 2.1, 1.9), 1.45, (15.0, 20.0, 16.0)),
)


def rotate(v, axis, degrees):
    """``v`` rotated about ``axis`` by ``degrees`` (Rodrigues)."""
    k = unit(axis)
    a = np.radians(degrees)
    return v * np.cos(a) + np.cross(k, v) * np.sin(a) + k * np.dot(k, v) * (1 - np.cos(a))


def digit(base, direction, lengths, thickness, curls, knuckle_first=True):
    """Rows of one finger (or the thumb's chain): 3 ellipsoids per bone, knuckles, a tip pad.

    ``direction`` is the first bone's axis; each joint turns the next bone by its curl towards the palm.
    Each bone is 8 % thinner than the one before.
    """
    rows = []
    d = unit(direction)
    side = unit(np.cross(d, BACK))  # the axis the finger curls about
    p = np.asarray(base, dtype=np.float64)
    for k, (length, curl) in enumerate(zip(lengths, curls)):
        d = unit(rotate(d, side, -curl))  # curl towards the palm (+y)
        normal = unit(BACK - np.dot(BACK, d) * d)
        t = thickness * (1.0 - 0.08 * k)
        if k > 0 or knuckle_first:  # a knuckle on the back of the joint
            rows.append(sphere(p + 0.28 * t * normal, 0.62 * t, weight=0.8))
        for s in (1 / 6, 3 / 6, 5 / 6):
            rows.append(ellipsoid(p + s * length * d, d, normal, (0.62 * length, CROSS * t, 0.95 * CROSS * t)))
        p = p + length * d
    # the pad of the tip, a little towards the palm
    rows.append(sphere(p - 0.3 * thickness * d - 0.12 * thickness * normal, 0.62 * thickness, weight=0.8))
    return rows


def hand():
    rows = []
    # palm: 5 columns across x (narrower at the wrist), 4 rows along z; thicker in the middle columns
    for z in (2.0, 4.2, 6.4, 8.6):
        half = 2.2 + 0.75 * (z - 2.0) / 6.6
        for x in np.linspace(-half, half, 5):
            ry = 2.1 - 0.4 * (x / half) ** 2
            rows.append(ellipsoid((x, 0.0, z), (0, 0, 1), BACK, (3.6, 2.6, ry)))
    # wrist and a stub of forearm
    for x in (-1.1, 1.1):
        for z in (-1.6, 0.2):
            rows.append(ellipsoid((x, 0.1, z), (0, 0, 1), BACK, (2.8, 2.8, 2.0)))
    # ball of the thumb (thenar) on the palm side and the heel of the little finger (hypothenar)
    for x, y, z, r in ((-2.4, 0.8, 2.0, 1.9), (-2.7, 0.9, 3.5, 1.9), (-1.6, 1.0, 2.6, 1.7), (-2.9, 0.6, 5.0, 1.6)):
        rows.append(sphere((x, y, z), r))
    for x, y, z, r in ((2.6, 0.7, 2.6, 1.8), (2.8, 0.6, 4.6, 1.7)):
        rows.append(sphere((x, y, z), r))
    # four fingers
    for x, z, spread, lengths, thickness, curls in FINGERS:
        direction = rotate(np.array([0.0, 0.0, 1.0]), -BACK, spread)
        rows += digit((x, 0.0, z), direction, lengths, thickness, curls)
    # the thumb: from the ball of the thumb out towards -x, up, and a little towards the palm side
    direction = unit((-0.72, 0.25, 0.65))
    rows += digit((-2.6, 0.6, 2.2), direction, (4.0, 3.1, 2.6), 2.15, (0.0, 16.0, 18.0), knuckle_first=False)
    return rows


if __name__ == "__main__":
    folder = out_dir()
    balls = write_balls(folder / "hand.csv", hand())
    print(f"wrote {len(balls)} balls to {folder / 'hand.csv'}")
