"""Helpers the scene generators (make_*.py) share: ellipsoid orientations and the balls CSV.

A row is (x, y, z, rx, ry, rz, ax, ay, az, weight), the 10-column layout of a balls file (docs/model.md §9):
radii rx, ry, rz along the columns of Q = Rz(az) Ry(ay) Rx(ax), angles in degrees.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

HEADER = "x,y,z,rx,ry,rz,ax,ay,az,weight"


def unit(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def euler_xyz(q):
    """[ax, ay, az] in degrees with Q = Rz(az) Ry(ay) Rx(ax) (docs/model.md §9) for a rotation matrix ``q``."""
    ay = -np.arcsin(np.clip(q[2, 0], -1.0, 1.0))
    if abs(q[2, 0]) < 1.0 - 1e-12:
        ax = np.arctan2(q[2, 1], q[2, 2])
        az = np.arctan2(q[1, 0], q[0, 0])
    else:  # gimbal lock: az is free, put everything in ax
        ax = np.arctan2(-q[1, 2], q[1, 1])
        az = 0.0
    return np.degrees([ax, ay, az])


def ellipsoid(center, long_axis, normal, radii, weight=1.0):
    """A row for an ellipsoid with radii (along ``long_axis``, across it, along ``normal``); ``normal`` is
    made perpendicular to ``long_axis`` first. E.g. a flat finger bone: long axis along the finger, the
    third radius (the thin one) along the back-of-hand normal."""
    e1 = unit(long_axis)
    e3 = unit(np.asarray(normal, dtype=np.float64) - np.dot(normal, e1) * e1)
    e2 = np.cross(e3, e1)
    q = np.stack([e1, e2, e3], axis=1)  # columns: the ellipsoid's axes
    return (*np.asarray(center, dtype=np.float64), *radii, *euler_xyz(q), weight)


def sphere(center, radius, weight=1.0):
    return (*np.asarray(center, dtype=np.float64), radius, radius, radius, 0.0, 0.0, 0.0, weight)


def write_balls(path, rows):
    """Write ``rows`` as a balls CSV (4 decimals: what the scene renders is the file, not the floats)."""
    balls = np.array(rows, dtype=np.float64).reshape(-1, 10)
    balls[np.abs(balls) < 5e-5] = 0.0  # no "-0.0000"
    np.savetxt(path, balls, delimiter=",", fmt="%.4f", header=HEADER, comments="")
    return balls


def out_dir(argv=None):
    """The folder to write into: the first command-line argument, else this folder (scenes/)."""
    argv = sys.argv[1:] if argv is None else argv
    return Path(argv[0]) if argv else Path(__file__).parent
