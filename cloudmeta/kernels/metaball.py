"""One metaball on a ray: its chord, its Bernstein control values, and its falloff at a point.

MODEL.md §1-2. A ball is a centre c and a frame M = S^-1 Q^T with u(x) = |M (x - c)|^2.
"""
import math

import numpy as np
from numba import njit

from ..config import NJIT

WYVILL6 = 0
MURAKAMI4 = 1
NISHIMURA = 2
BLINN = 3


@njit(**NJIT)
def chord(o, d, center, frame):
    """The ray's chord through the ball's support u < 1: returns (t0, t1, a), a = 1 - min u on the line.

    a <= 0 means the line misses (or only touches) the support. In the unit frame o' = M (o - c),
    d' = M d, u(t) = A t^2 + 2 (o'.d') t + |o'|^2 with A = |d'|^2. a is computed as 1 - |o' + t_m d'|^2 at
    the closest point t_m rather than as B^2 - A C, which cancels catastrophically far from the ball.
    """
    ox = o[0] - center[0]
    oy = o[1] - center[1]
    oz = o[2] - center[2]
    px = frame[0, 0] * ox + frame[0, 1] * oy + frame[0, 2] * oz
    py = frame[1, 0] * ox + frame[1, 1] * oy + frame[1, 2] * oz
    pz = frame[2, 0] * ox + frame[2, 1] * oy + frame[2, 2] * oz
    dx = frame[0, 0] * d[0] + frame[0, 1] * d[1] + frame[0, 2] * d[2]
    dy = frame[1, 0] * d[0] + frame[1, 1] * d[1] + frame[1, 2] * d[2]
    dz = frame[2, 0] * d[0] + frame[2, 1] * d[1] + frame[2, 2] * d[2]
    A = dx * dx + dy * dy + dz * dz
    tm = -(px * dx + py * dy + pz * dz) / A
    qx = px + tm * dx
    qy = py + tm * dy
    qz = pz + tm * dz
    a = 1.0 - (qx * qx + qy * qy + qz * qz)
    if a <= 0.0:
        return tm, tm, a
    h = math.sqrt(a / A)
    return tm - h, tm + h, a


@njit(**NJIT)
def control_values(kernel, a, q, out):
    """Degree-6 Bernstein control values of q k(u(s)) on the chord, u(s) = 1 - 4 a s (1 - s) (eq. 11).

    wyvill6: exact, with MODEL.md's erratum (d_3 = 8 a^2 (8a + 5) / 45, the paper drops the 8).
    murakami4: exactly (0, 0, 8/3 a^2, 0, 0) at degree 4 (eq. 18), elevated twice to degree 6.
    """
    for i in range(7):
        out[i] = 0.0
    a2 = a * a
    if kernel == WYVILL6:
        e = q * 16.0 / 27.0 * a2
        out[2] = e
        out[3] = q * 8.0 * a2 * (8.0 * a + 5.0) / 45.0
        out[4] = e
    else:  # MURAKAMI4: m = 8/3 a^2 at degree 4; elevated 4 -> 5 -> 6 it becomes (2/5, 3/5, 2/5) m
        m = q * 8.0 / 3.0 * a2
        out[2] = 0.4 * m
        out[3] = 0.6 * m
        out[4] = 0.4 * m


@njit(**NJIT)
def falloff(kernel, u, blobbiness):
    """k(u) of MODEL.md §1 (0 for u >= 1)."""
    if u >= 1.0:
        return 0.0
    if kernel == WYVILL6:
        v = 1.0 - u
        return v * v * (1.0 - 4.0 * u / 9.0)
    if kernel == MURAKAMI4:
        v = 1.0 - u
        return v * v
    if kernel == NISHIMURA:
        if u <= 1.0 / 9.0:
            return 1.0 - 3.0 * u
        v = 1.0 - math.sqrt(u)
        return 1.5 * v * v
    return math.exp(-blobbiness * u)


@njit(**NJIT)
def unit_distance2(x, center, frame):
    """u(x) = |M (x - c)|^2."""
    ox = x[0] - center[0]
    oy = x[1] - center[1]
    oz = x[2] - center[2]
    px = frame[0, 0] * ox + frame[0, 1] * oy + frame[0, 2] * oz
    py = frame[1, 0] * ox + frame[1, 1] * oy + frame[1, 2] * oz
    pz = frame[2, 0] * ox + frame[2, 1] * oy + frame[2, 2] * oz
    return px * px + py * py + pz * pz
