"""Puffs on the exposed surface of their parents: spots found along rays from a parent, the exposed
area, and blue-noise spacing (a vectorised greedy maximal set over close pairs)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..scene.blob import rotation_matrix
from .field import _CHUNK_PAIRS, _OFFSETS, iso_u
from .params import THRESHOLD


@dataclass
class _Level:
    c: np.ndarray       # (n, 3) centres
    r: np.ndarray       # (n, 3) radii
    a: np.ndarray       # (n, 3) angles, degrees
    q: np.ndarray       # (n,) weights
    w: np.ndarray = None  # (n,) how many puffs a ball takes, relative to its exposed area (default 1)

    def puffiness(self):
        return np.ones(len(self.c)) if self.w is None else self.w

    def __len__(self):
        return len(self.c)


def _level(c, r, a, q):
    c = np.asarray(c, np.float64).reshape(-1, 3)
    r = np.asarray(r, np.float64).reshape(-1, 3)
    a = np.zeros_like(c) if a is None else np.asarray(a, np.float64).reshape(-1, 3)
    return _Level(c, r, a, np.broadcast_to(np.asarray(q, np.float64), (len(c),)).copy())


def _unit(v):
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _surface_along(field, origin, d, t_start, t_stop, step):
    """Along each ray origin + t d, from t_start outwards in steps of ``step`` up to t_stop (the parent's
    support): t where the field first falls below T (linear between the samples), nan where it does not
    fall below T before t_stop (the spot is buried), and the field at the last sample. Only the rays still
    inside are sampled again."""
    t_in = t_start.copy()
    f_in = field(origin + t_start[:, None] * d)
    t_cross = np.where(f_in < THRESHOLD, t_start, np.nan)
    active = np.flatnonzero(f_in >= THRESHOLD)
    last = f_in.copy()
    j = 0
    while len(active) and j < 64:
        j += 1
        t = t_in[active] + step[active]
        f = field(origin[active] + t[:, None] * d[active])
        last[active] = f
        out = f < THRESHOLD
        hit = active[out]
        frac = np.clip((f_in[hit] - THRESHOLD) / np.maximum(f_in[hit] - f[out], 1e-12), 0.0, 1.0)
        t_cross[hit] = t_in[hit] + frac * (t[out] - t_in[hit])
        keep = ~out & (t < t_stop[active])
        t_in[active[keep]] = t[keep]
        f_in[active[keep]] = f[keep]
        active = active[keep]
    return t_cross, last


def _power_law(rng, m, spread, power):
    """m factors from p(x) ~ x^-power on [1/sqrt(spread), sqrt(spread)], scaled so that the mean of x^2 is 1
    (the puffs' mean area is the one a level's count was planned for)."""
    lo, hi = 1.0 / math.sqrt(spread), math.sqrt(spread)
    if spread <= 1.0:
        return np.ones(m)
    u = rng.uniform(0.0, 1.0, m)
    if abs(power - 1.0) < 1e-9:
        x = lo * (hi / lo) ** u
        mean2 = (hi ** 2 - lo ** 2) / (2.0 * math.log(hi / lo))
    else:
        e = 1.0 - power
        x = (lo ** e + u * (hi ** e - lo ** e)) ** (1.0 / e)
        # E[x^2] = int x^(2 - power) / int x^-power over [lo, hi]
        e3 = 3.0 - power
        num = (hi ** e3 - lo ** e3) / e3 if abs(e3) > 1e-9 else math.log(hi / lo)
        mean2 = num / ((hi ** e - lo ** e) / e)
    return x / math.sqrt(mean2)


def _pareto_range(rng, m, top, a):
    """m draws from p(x) ~ x^-a on [1, top]."""
    u = rng.uniform(0.0, 1.0, m)
    if abs(a - 1.0) < 1e-9:
        return top ** u
    e = 1.0 - a
    return (1.0 + u * (top ** e - 1.0)) ** (1.0 / e)


def _spots(rng, field, parent, m, ratio, weight, bias, push=0.0, base_floor=0.0, jitter=0.15, choice=None,
           spread=None):
    """m candidate puffs on the surface F = T of the levels in ``field``, each on the exposed part of a ball
    of ``parent`` (chosen at random, in proportion to ``choice`` where given): along a random direction
    d from the parent's centre (biased upwards by ``bias``), from the parent's own iso-surface outwards, at
    the point where the field of the levels so far falls to T, if it does within the parent's support
    (else the spot is buried under other balls). ``push`` moves the centre outwards along d by that many of
    the puff's own iso-radii (a tuple (lo, hi, a): drawn per puff from lo to hi, a power law of exponent a). Sizes are ``ratio`` x the parent's, +-``jitter``, or with ``spread`` = (S, a)
    ``ratio`` x the parents' mean times a factor from a power law p ~ x^-a over a range of S (_power_law). Returns (centres, support radii, exposed:
    bool, parent indices)."""
    s_child = math.sqrt(float(iso_u(weight))) if weight > THRESHOLD else 0.5
    u_par = iso_u(parent.q)
    u_par = np.where(u_par > 0, u_par, 0.25)
    m_par = rotation_matrix(parent.a).transpose(0, 2, 1) / parent.r[:, :, None]
    if choice is not None and np.sum(choice) > 0:  # parents in proportion to these weights
        cum = np.cumsum(choice)
        pi = np.minimum(np.searchsorted(cum / cum[-1], rng.uniform(0, 1, m), "right"), len(parent) - 1)
    else:
        pi = rng.integers(0, len(parent), m)
    d = _unit(rng.normal(size=(m, 3)))
    if bias:
        d[:, 2] += bias
        d = _unit(d)
    if spread is None:
        size = parent.r[pi].max(axis=1) * ratio * (1.0 + jitter * rng.uniform(-1, 1, m))
    else:
        # relative to the parents' mean size, not each parent's own: the spread does not compound from
        # level to level (the levels overlap in size instead, and the grids of cells stay fine)
        size = float(np.mean(parent.r.max(axis=1))) * ratio * _power_law(rng, m, *spread)
    md = np.linalg.norm(np.einsum("mij,mj->mi", m_par[pi], d), axis=1)
    t_sup = 1.0 / md                                # the parent's support along d
    t_iso = np.sqrt(u_par[pi]) * t_sup              # its own iso-surface
    t_cross, _ = _surface_along(field, parent.c[pi], d, t_iso, t_sup, 0.6 * size)
    exposed = ~np.isnan(t_cross)
    t_cross = np.where(exposed, t_cross, t_iso)
    if isinstance(push, tuple):  # (lo, hi, a): from lo to hi, most near lo (p ~ x^-a on 1 .. hi - lo + 1)
        lo, hi, a = push
        push = lo - 1.0 + _pareto_range(rng, m, hi - lo + 1.0, a)
    centre = parent.c[pi] + (np.maximum(t_cross, t_iso) + push * s_child * size)[:, None] * d
    exposed &= centre[:, 2] >= base_floor
    return centre, size, exposed, pi


def _area(radii):
    """Surface area of ellipsoids with these radii (n, 3) (Knud Thomsen's approximation, within 1.1 %)."""
    p = 1.6075
    a, b, c = (radii[:, 0] ** p, radii[:, 1] ** p, radii[:, 2] ** p)
    return 4 * np.pi * ((a * b + a * c + b * c) / 3.0) ** (1.0 / p)


def _exposed_area(rng, field, parent, samples=4000):
    """(area, weights): the area of the surface F = T that the balls of ``parent`` hold (their
    iso-ellipsoids' area times the part of it found exposed, sampled), and per parent a weight for
    drawing the puffs' parents: its area times the part of it found exposed (smoothed)."""
    u_par = iso_u(parent.q)
    area = _area(parent.r * np.sqrt(np.where(u_par > 0, u_par, 0.25))[:, None])
    puffy = parent.puffiness()
    _, _, exposed, pi = _spots(rng, field, parent, samples, 0.5, 1.0, 0.0, choice=area * puffy)
    tried = np.bincount(pi, minlength=len(parent))
    hits = np.bincount(pi, weights=exposed, minlength=len(parent))
    total = float((area * puffy).sum()) * max(np.count_nonzero(exposed) / samples, 1.0 / samples)
    return total, area * puffy * (hits + 0.25) / (tried + 1.0)


#: the cell itself and the 13 neighbours that come after it: each pair of cells met once
_HALF = np.array([o for o in _OFFSETS.tolist() if tuple(o) >= (0, 0, 0)], dtype=np.int64)


def _close_pairs(points, reach):
    """(i, j) with i < j of the points closer than reach_i + reach_j, through a grid of cells as wide as
    the largest such distance (each pair of neighbouring cells visited once)."""
    h = 2.0 * float(reach.max()) * 1.0000001
    cells = np.floor(points / h).astype(np.int64)
    lo = cells.min(axis=0) - 1
    dims = cells.max(axis=0) - lo + 2
    cells -= lo
    keys = (cells[:, 0] * dims[1] + cells[:, 1]) * dims[2] + cells[:, 2]
    order = np.argsort(keys, kind="stable")
    skeys = keys[order]
    out_i, out_j = [], []
    step = max(1, _CHUNK_PAIRS // 32)
    n_off = len(_HALF)
    for s in range(0, len(points), step):
        idx = np.arange(s, min(s + step, len(points)))
        nb = cells[idx, None, :] + _HALF[None, :, :]
        nkeys = (nb[..., 0] * dims[1] + nb[..., 1]) * dims[2] + nb[..., 2]
        start = np.searchsorted(skeys, nkeys, "left").ravel()
        count = (np.searchsorted(skeys, nkeys, "right").ravel() - start)
        total = int(count.sum())
        if not total:
            continue
        qi = np.repeat(np.repeat(idx, n_off), count)
        first = np.cumsum(count) - count
        other = order[np.arange(total) - np.repeat(first - start, count)]
        same = np.repeat(np.tile(np.arange(n_off) == 0, len(idx)), count)   # offset (0, 0, 0): the cell itself
        keep = ~same | (other > qi)
        qi, other = qi[keep], other[keep]
        d = points[qi] - points[other]
        close = np.einsum("ij,ij->i", d, d) < (reach[qi] + reach[other]) ** 2
        a, b = qi[close], other[close]
        out_i.append(np.minimum(a, b))
        out_j.append(np.maximum(a, b))
    if not out_i:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    return np.concatenate(out_i), np.concatenate(out_j)


def _spaced(points, reach):
    """The greedy maximal set of points, in their order, no two closer than the sum of their reaches
    (blue noise): a point is kept when no earlier kept point is too close. Computed in rounds (a point
    decides once every earlier point near it has), vectorised. Returns a bool mask."""
    i, j = _close_pairs(points, reach)          # i < j: i comes first
    n = len(points)
    undecided = np.ones(n, bool)
    kept = np.zeros(n, bool)
    for _ in range(10000):
        if not undecided.any():
            break
        live = undecided[i] & undecided[j]
        waits = np.zeros(n, bool)
        waits[j[live]] = True                   # an earlier point near it is still undecided
        new = undecided & ~waits
        kept |= new
        undecided &= ~new
        drop = np.zeros(n, bool)
        drop[j[new[i]]] = True                  # too close to a point just kept
        undecided &= ~drop
        i, j = i[undecided[i] & undecided[j]], j[undecided[i] & undecided[j]]
    return kept


#: levels of more puffs than this are not spaced (their puffs are small texture; spacing costs time)
_MAX_SPACED = 25000


def _puff_level(rng, field, parent, n, ratio, weight, bias, push, spacing, flatness=1.0, jitter=0.15,
                choice=None, spread=None):
    """Exactly n puffs of one level on the exposed surface of ``parent``'s balls, spaced (blue noise): no
    two closer than ``spacing`` x their visible radius (spacing 0, or n > _MAX_SPACED: not spaced). With a
    ``spread`` of sizes the candidates are spaced by octave of size, largest first, so the small ones fill
    the gaps between the large (a packing whose sizes follow the power law down to the smallest).
    Candidates are drawn in at most two rounds; where the exposed surface cannot hold n at that spacing,
    the remaining puffs go to the first of the rest (closer together)."""
    if n <= 0:
        return _level(np.zeros((0, 3)), np.zeros((0, 3)), None, weight)
    s_child = math.sqrt(float(iso_u(weight))) if weight > THRESHOLD else 0.5
    spaced = spacing > 0 and n <= _MAX_SPACED
    pts, size = np.zeros((0, 3)), np.zeros(0)
    kept = np.zeros(0, bool)
    rate = 0.5
    for round_ in range(2 if spaced else 4):
        need = n - (np.count_nonzero(kept) if spaced else len(pts))
        if need <= 0:
            break
        m = int((1.6 if spaced else 1.05) * need / max(rate, 0.05)) + 16
        c, r, exposed, _ = _spots(rng, field, parent, m, ratio, weight, bias, push, jitter=jitter, choice=choice,
                                  spread=spread)
        rate = max(np.count_nonzero(exposed) / m, 0.02)
        if spaced:
            c, r = c[exposed], r[exposed]
            if spread is not None:  # by octave of size, largest first (in random order within an octave:
                # fully sorted, the spacing's rounds would follow long chains of neighbours)
                order = np.argsort(np.floor(-np.log2(r / r.max())), kind="stable")
                c, r = c[order], r[order]
            pts = np.concatenate([pts[kept], c, pts[~kept]])  # the kept ones keep their precedence
            size = np.concatenate([size[kept], r, size[~kept]])
            kept = _spaced(pts, 0.5 * spacing * s_child * size) if len(pts) else kept
        else:
            pts, size = np.concatenate([pts, c[exposed]]), np.concatenate([size, r[exposed]])
            kept = np.ones(len(pts), bool)
    take = np.flatnonzero(kept)[:n]
    c_out, r_out = pts[take], size[take]
    if len(take) < n:  # the surface is full at this spacing: the rest go between, in candidate order
        extra = np.flatnonzero(~kept)[:n - len(take)]
        c_out = np.concatenate([c_out, pts[extra]])
        r_out = np.concatenate([r_out, size[extra]])
    if len(c_out) < n:  # too little exposed surface (never with a sane body): repeat what there is
        if len(c_out):
            reps = np.arange(n) % len(c_out)
            c_out, r_out = c_out[reps], r_out[reps]
        else:
            c_out = np.repeat(parent.c[:1], n, 0)
            r_out = np.full(n, parent.r.max() * ratio)
    radii = np.stack([r_out, r_out, r_out * flatness], axis=1)
    angles = np.zeros_like(c_out)
    if flatness != 1.0:
        angles[:, 2] = rng.uniform(0.0, 180.0, n)  # a flattened puff: its wider axes turned about z
    return _level(c_out, radii, angles, weight)
