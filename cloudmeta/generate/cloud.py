"""``generate``: the Cloud it returns and the levels built in order (body, puffs, fray and erosion,
scale and stretch, cutter, density)."""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field as dc_field
from types import MappingProxyType
from typing import Mapping

import numpy as np

from ..scene.blob import rotation_matrix
from .cutter import _base_field_bound, _cutter
from .field import _Field, _grid_for, iso_u
from .params import (CUTTER, EROSION, FADE, FADE_WEIGHT, KERNEL, THRESHOLD, _check_args,
                     _check_params)
from .puffs import _Level, _exposed_area, _level, _puff_level
from .shapes import _body_cumulonimbus, _body_cumulus, _body_stratocumulus, _body_tower, _default_body


@dataclass(frozen=True)
class Cloud:
    """A generated cloud.

    balls : (N, 10) float64, read-only: x, y, z, rx, ry, rz, ax, ay, az, weight (ellipsoids, radii along the
        columns of Q = Rz(az) Ry(ay) Rx(ax), angles in degrees): the rows of its balls file.
    levels : (N,) int8: 0 the body, 1 .. the puff levels, -1 the base cutter, -2 the erosion balls,
        -3 the base fade.
    kind, seed, size : the arguments of ``generate``; params : every kind parameter, defaults resolved.
    medium : the suggested medium settings (kernel, threshold, density, albedo, phase), scene-file keys.
    base : z of the flat base (the condensation level): F < T everywhere below it.
    depth : no positive ball's support reaches further than this below the base.
    extent : ((x0, y0, z0), (x1, y1, z1)) a box around the visible cloud (F >= T), for framing a camera.
    seconds : how long ``generate`` took.
    """
    kind: str
    seed: int
    size: float
    balls: np.ndarray
    levels: np.ndarray
    params: Mapping
    medium: Mapping
    base: float
    depth: float
    extent: tuple
    seconds: float = dc_field(default=0.0, compare=False)

    def __len__(self):
        return len(self.balls)

    def field(self, points):
        """(M,) F(x) of the whole cloud at the points (M, 3): numpy, for checks and figures."""
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        f = _Field()
        b = self.balls
        for level in np.unique(self.levels):
            i = np.flatnonzero(self.levels == level)
            f.add(b[i, :3], b[i, 3:6], b[i, 6:9], b[i, 9])
        return f(points)


def generate(kind, balls=3000, seed=1, size=10.0, **params):
    """A deterministic cloud of exactly ``balls`` metaballs (docs/generate.md).

    kind : ``cumulus``, ``stratocumulus``, ``tower`` or ``cumulonimbus``.
    balls : the number of balls, from 8 to 2**22 (the cutter and any erosion balls included).
    seed : any integer from 0 to 2**63 - 1; the same seed gives the same cloud.
    size : the cloud's horizontal extent along x, in scene units (the base is at z = 0, centred on x = y = 0).
    params : the kind's parameters (``PARAMETERS[kind]``; each with its unit, default and range).
    Raises InputError for a bad argument.
    """
    start = time.perf_counter()
    n_balls, seed, size = _check_args(kind, balls, seed, size)
    p = _check_params(kind, params)
    rng = np.random.default_rng(seed)
    fade = p["base_fade"] > 0 and n_balls >= 200
    n_special = 1 + fade                                      # the cutter and the base-fade ball
    n_erosion = int(round(p["erosion"] * n_balls)) if n_balls >= 200 else 0
    n_free = n_balls - n_special - n_erosion
    n0 = p["body"] if p["body"] is not None else _default_body(kind, p, n_free)
    n0 = min(n0, n_free)

    # level 0, in units of size = 1
    if kind == "cumulus":
        body = _body_cumulus(rng, p, n0)
    elif kind == "tower":
        body = _body_tower(rng, p, n0)
    elif kind == "cumulonimbus":
        body = _body_cumulonimbus(rng, p, n0)
    else:
        body = _body_stratocumulus(rng, p, n0)
        if len(body) > n_free:  # the cells decide the body's count (the puffs take any balls left)
            body = _level(body.c[:n_free], body.r[:n_free], body.a[:n_free], body.q[:n_free])
    n0 = len(body)
    levels = [body]
    flat = p["flatness"] if kind == "stratocumulus" else 1.0
    ratio = p["ratio"]
    spacing = p["spacing"]
    spread = (p["size_spread"], p["size_power"]) if p["size_spread"] > 1.0 else None
    budget = n_free - n0
    erosion = None
    plan = []
    while budget > 0 or (n_erosion and erosion is None):
        parent = levels[-1]
        k = len(levels)
        r_parent = float(np.mean(parent.r.max(axis=1)))
        field = _grid_for(levels, 0.45 * r_parent)
        area, choice = _exposed_area(rng, field, parent)
        rho = 0.5 * ratio * r_parent                               # iso-radius of a puff of weight 1
        per = 0.866 * spacing ** 2                                  # area a puff takes, / rho^2
        n_here = int(math.ceil(area / (per * rho ** 2)))
        n_next = area * 1.3 / (per * (0.8 * rho) ** 2)              # the least a further level would need
        last = k + 1 >= p["levels"] or n_here + n_next > budget
        if last:
            n_here = budget
            ratio_here = float(np.clip(math.sqrt(area / (per * max(n_here, 1))) / (0.5 * r_parent), 0.15, 0.8))
        else:
            ratio_here = ratio
        push = p["push"] if not last else 0.5 * p["push"]
        if k == 1 and not last and p["push_first"] is not None:
            push = p["push_first"]
        plan.append((n_here, round(ratio_here, 4)))
        if last and p["fray"] > 0 and n_here >= 4:
            n_fray = int(round(p["fray"] * n_here))
            solid = _puff_level(rng, field, parent, n_here - n_fray, ratio_here, 1.0, p["bias"], push, spacing, flat,
                                choice=choice, spread=spread)
            loose = _puff_level(rng, field, parent, n_fray, 0.8 * ratio_here, p["fray_weight"], p["bias"] + 0.3,
                                (0.9, p["fray_reach"], 2.0), 0.0, flat, choice=choice, spread=spread)
            lev = _Level(np.concatenate([solid.c, loose.c]), np.concatenate([solid.r, loose.r]),
                         np.concatenate([solid.a, loose.a]), np.concatenate([solid.q, loose.q]))
        else:
            lev = _puff_level(rng, field, parent, n_here, ratio_here, 1.0, p["bias"], push, spacing, flat,
                              choice=choice, spread=spread)
            # how many puffs each one carries on the next level: half alike, half Pareto, so that a few
            # puffs carry most of the finer levels and the depth of the hierarchy varies over the cloud,
            # but none stays bare (a bare puff pushed out reads as a smooth bead); mean 1, as the level's
            # count is planned on its exposed area
            vigor = (1.0 - rng.uniform(0.0, 1.0, len(lev))) ** (-1.0 / p["depth_power"]) - 1.0
            lev.w = 0.5 + 0.5 * vigor / max(float(vigor.mean()), 1e-12)
        if last and n_erosion:  # small negative balls in the crevices among the last puffs
            erosion = _puff_level(rng, field, parent, n_erosion, 1.1 * ratio_here, 1.0, p["bias"], -0.3,
                                  0.0, flat, choice=choice, spread=spread)
            erosion.q[:] = -0.6
        if len(lev):
            levels.append(lev)
        budget -= n_here
    if not n_erosion:
        erosion = None
    assert erosion is None or len(erosion) == n_erosion
    # the positive balls reach at most `depth` below z = 0; the cutter covers them there
    all_levels = levels + ([erosion] if erosion is not None else [])
    c = np.concatenate([lv.c for lv in all_levels])
    r = np.concatenate([lv.r for lv in all_levels])
    a = np.concatenate([lv.a for lv in all_levels])
    q = np.concatenate([lv.q for lv in all_levels])
    tag = np.concatenate([np.full(len(lv), i, np.int8) for i, lv in enumerate(levels)]
                         + ([np.full(n_erosion, EROSION, np.int8)] if erosion is not None else []))
    if fade:  # the base fade: a wide flat ball of negative weight centred on z = 0, as deep as the fade layer
        positive = q > 0
        top = float(np.max(c[positive, 2] + np.sqrt(iso_u(q[positive])) * r[positive, 2]))
        reach = np.max(np.abs(c[positive, :2]) + r[positive, :2], axis=0)
        c = np.concatenate([c, [[0.5 * (c[positive, 0].max() + c[positive, 0].min()),
                                 0.5 * (c[positive, 1].max() + c[positive, 1].min()), 0.0]]])
        r = np.concatenate([r, [[4.0 * reach[0], 4.0 * reach[1], p["base_fade"] * top]]])
        a = np.concatenate([a, np.zeros((1, 3))])
        q = np.concatenate([q, [FADE_WEIGHT]])
        tag = np.concatenate([tag, [FADE]]).astype(np.int8)
    half = np.sqrt(np.einsum("nkj,nj->nk", rotation_matrix(a) ** 2, r ** 2))  # half-widths of the supports
    # measure the visible cloud; scale it so that its extent along x is 1, centred on x = y = 0
    everything = _Field()
    for level in np.unique(tag):
        i = np.flatnonzero(tag == level)
        everything.add(c[i], r[i], a[i], q[i])
    lo, hi = _extent(everything, c, half, q)
    k = 1.0 / (hi[0] - lo[0])
    shift = np.array([0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.0])
    c, r, half = (c - shift) * k, r * k, half * k
    lo, hi = (lo - shift) * k, (hi - shift) * k
    # then stretch it along z to the height asked for (an affine map of the whole field: every ball is
    # turned about z alone, so its third radius lies along z)
    stretch = float(np.clip(p["height_ratio" if kind != "stratocumulus" else "thickness"] / hi[2], 0.5, 2.0))
    c[:, 2] *= stretch
    r[:, 2] *= stretch
    half[:, 2] *= stretch
    hi[2] *= stretch
    # the density: rays along x are the same in the unscaled cloud (field ``everything``), at the heights
    # before the stretch; lengths grew by k, so the density shrinks by k for the same optical depth
    scale = _density_scale(everything, lo / k + shift, np.array([hi[0], hi[1], hi[2] / stretch]) / k + shift,
                           p["optical_depth"]) / k

    # the positive balls reach at most `depth` below z = 0; the cutter covers them there
    positive = q > 0
    depth = float(max(0.0, np.max((half[:, 2] - c[:, 2])[positive])))
    cutter = _cutter(c[positive], half[positive], depth, _base_field_bound(c, r, a, q, tag, depth))
    c = np.concatenate([c, cutter[None, :3]])
    r = np.concatenate([r, cutter[None, 3:6]])
    a = np.concatenate([a, np.zeros((1, 3))])
    q = np.concatenate([q, [cutter[6]]])
    tag = np.concatenate([tag, [CUTTER]]).astype(np.int8)
    assert len(c) == n_balls, (len(c), n_balls)

    out = np.concatenate([c * size, r * size, a, q[:, None]], axis=1)
    out.setflags(write=False)
    tag.setflags(write=False)
    medium = {"kernel": KERNEL, "threshold": THRESHOLD, "density": {"mode": "excess", "scale": float(scale / size)},
              "albedo": 0.98, "phase": {"type": "double_hg", "g1": 0.75, "g2": -0.3, "w": 0.85}}
    params_out = dict(p)
    params_out["body"] = n0
    params_out["levels"] = len(levels)
    params_out["plan"] = tuple(plan)
    params_out["stretch"] = round(stretch, 4)
    return Cloud(kind=kind, seed=seed, size=size, balls=out, levels=tag, params=MappingProxyType(params_out),
                 medium=MappingProxyType(medium), base=0.0, depth=depth * size,
                 extent=(tuple((lo * size).tolist()), tuple((hi * size).tolist())),
                 seconds=time.perf_counter() - start)


def _extent(field, c, half, q, samples=7):
    """The box of the visible cloud (F >= T) above the base. Along each of +-x, +-y and +z, only the balls
    whose supports reach beyond the farthest own iso-surface can hold the extreme: the field is sampled
    on the axis of each of them, out to its support (to within 1/8 of a support radius)."""
    positive = q > THRESHOLD
    s = np.sqrt(iso_u(q))[:, None]
    reach_iso = np.concatenate([c + s * half, -(c - s * half)], axis=1)[positive]     # (n, 6)
    reach_sup = np.concatenate([c + half, -(c - half)], axis=1)[positive]
    cp, hp = c[positive], half[positive]
    ts = np.linspace(0.0, 1.0, samples)
    lo, hi = np.zeros(3), np.zeros(3)
    for axis in range(6):
        k, sign = axis % 3, (1.0 if axis < 3 else -1.0)
        if axis == 5:  # the base: the cut at z = 0
            lo[2] = 0.0
            continue
        bound = reach_iso[:, axis].max()
        cand = np.flatnonzero(reach_sup[:, axis] > bound)
        if len(cand) > 96:  # the 96 that reach farthest: the extreme lies among them
            cand = cand[np.argsort(-reach_sup[cand, axis], kind="stable")[:96]]
        best = bound
        if len(cand):
            pts = np.repeat(cp[cand], samples, axis=0)
            off = (hp[cand, k][:, None] * ts[None, :]).ravel()
            pts[:, k] += sign * off
            inside = field(pts) >= THRESHOLD
            if np.any(inside):
                best = max(best, float(np.max(sign * pts[inside, k])))
        if sign > 0:
            hi[k] = best
        else:
            lo[k] = -best
    return lo, hi


def _density_scale(field, lo, hi, optical_depth, n=601):
    """density.scale (in the units of ``field``) so that the most opaque of five horizontal rays along x
    through the cloud's middle (y at the middle of the box lo..hi, z at 0.2, 0.35, 0.5, 0.65 and 0.8 of
    its height) has the target optical depth, with the excess density rho = F - T."""
    xs = np.linspace(lo[0] - 0.05 * (hi[0] - lo[0]), hi[0] + 0.05 * (hi[0] - lo[0]), n)
    y = 0.5 * (lo[1] + hi[1])
    best = 0.0
    for f in (0.2, 0.35, 0.5, 0.65, 0.8):
        z = lo[2] + f * (hi[2] - lo[2])
        pts = np.stack([xs, np.full_like(xs, y), np.full_like(xs, z)], 1)
        best = max(best, float(np.sum(np.maximum(field(pts) - THRESHOLD, 0.0)) * (xs[1] - xs[0])))
    return optical_depth / max(best, 1e-12)
