"""The kinds' bodies (level 0), in units of size = 1: envelopes (a dome under turrets, a tapering
column, an anvil, a deck of cells) filled with a few large balls."""
from __future__ import annotations

import math

import numpy as np

from ..errors import InputError
from .field import iso_u
from .puffs import _Level, _level


def _greedy_fill(rng, n, points, iso_h, iso_z, cover=0.85):
    """Pick n of the candidate points (largest first, jittered), each the centre of an ellipsoid with
    horizontal iso-radius iso_h and vertical iso_z, none inside cover x an earlier pick's ellipsoid.
    Returns the indices picked (repeats allowed once the candidates run out)."""
    jitter = rng.uniform(0.7, 1.0, len(points))
    free = np.ones(len(points), bool)
    picked = []
    score = iso_h * iso_z * jitter
    for _ in range(n):  # n is the body's few balls
        s = np.where(free, score, -1.0)
        j = int(np.argmax(s))
        if s[j] < 0:
            free[:] = True
            s = np.where(free, score, -1.0)
            j = int(np.argmax(s))
        picked.append(j)
        d = points - points[j]
        inside = ((d[:, 0] ** 2 + d[:, 1] ** 2) / (cover * iso_h[j]) ** 2 + d[:, 2] ** 2 / (cover * iso_z[j]) ** 2)
        free &= inside > 1.0
    return np.array(picked, dtype=np.int64)


def _body_from_envelope(rng, n, shape_fn, box_lo, box_hi, q, r_cap, d_max, z_floor, cover=1.0, m=6000):
    """Level 0: n balls of weight q filling an envelope: ``shape_fn(points)`` gives, at candidate centres,
    the horizontal and vertical visible radii (iso-radii) a ball centred there may have (<= 0 outside).
    The balls are picked largest first (jittered), none centred inside ``cover`` x an earlier one's
    visible ellipsoid; a ball whose support would reach more than d_max below z = 0 is flattened (rz
    smaller) to stay within it."""
    pts = rng.uniform(box_lo, box_hi, (m, 3))
    pts[:, 2] = np.maximum(pts[:, 2], z_floor)
    iso_h, iso_z = shape_fn(pts)
    iso_h, iso_z = np.minimum(iso_h, r_cap), np.minimum(iso_z, r_cap)
    keep = np.minimum(iso_h, iso_z) > 0.02 * r_cap
    if not np.any(keep):
        raise InputError("the body's envelope is empty for these parameters (docs/generate.md)")
    pts, iso_h, iso_z = pts[keep], iso_h[keep], iso_z[keep]
    s = math.sqrt(float(iso_u(q)))
    rh, rz = iso_h / s, iso_z / s                         # support radii: the iso-surface touches the envelope
    rz = np.maximum(np.minimum(rz, pts[:, 2] + d_max), 0.2 * rh)  # support no deeper than d_max below the base
    pick = _greedy_fill(rng, n, pts, rh * s, rz * s, cover)
    c = pts[pick]
    r = np.stack([rh[pick], rh[pick], rz[pick]], axis=1)
    return _level(c, r, None, q)


def _turrets(rng, count, a, b, spread=(0.25, 0.45)):
    """height(x, y) in [0, 1]: the highest of ``count`` round bumps at random points of the footprint
    (semi-axes a, b), each a Gaussian as wide as ``spread`` x a: the turrets of a cumulus."""
    ang = rng.uniform(0, 2 * np.pi, count)
    rad = 0.75 * np.sqrt(rng.uniform(0, 1, count))
    cx, cy = a * rad * np.cos(ang), b * rad * np.sin(ang)
    sig = a * rng.uniform(*spread, count)
    top = rng.uniform(0.75, 1.0, count)
    top[0] = 1.0

    def height(x, y):
        d2 = (x[:, None] - cx) ** 2 + (y[:, None] - cy) ** 2
        return np.max(top * np.exp(-0.5 * d2 / sig ** 2), axis=1)
    return height


def _dome(a, b, hb, sq, lean, turret, low, taper=0.0):
    """shape_fn of a dome or column: footprint |x/a|^sq + |y/b|^sq <= 1 (x from the axis x = lean z), a
    roof at hb x (low + (1 - low) turret(x, y)), rounded at the rim (a cap of radius min(a, roof)); the
    footprint narrows by ``taper`` x z / hb upwards.
    Visible radii: the distance to the side wall or to the roof, whichever is nearer."""
    def shape(pts):
        z = pts[:, 2]
        x = pts[:, 0] - lean * z
        narrow = 1.0 - taper * np.clip(z / hb, 0.0, 1.0)
        sxy = (np.abs(x / (a * narrow)) ** sq + np.abs(pts[:, 1] / (b * narrow)) ** sq) ** (1.0 / sq)
        side = (1.0 - sxy) * min(a, b) * narrow
        top = hb * (low + (1.0 - low) * turret(x, pts[:, 1]))
        cap = np.minimum(min(a, b), top)
        roof = top - cap * (1.0 - np.sqrt(np.clip(1.0 - sxy ** 2, 0.0, None)))
        d = np.minimum(side, roof - z)
        return d, d
    return shape


def _body_cumulus(rng, p, n0):
    h = p["height_ratio"]
    a = 0.5 * 0.78            # the body's half-width: the puffs add the rest of size / 2
    b = a * p["aspect"]
    hb = 0.85 * h             # the body's height: the puffs add the rest
    shape = _dome(a, b, hb, p["squareness"], 0.0, _turrets(rng, p["turrets"], a, b), 1.0 - p["turret_height"])
    d_max = 0.12 + 0.1 * min(h, 1.0)
    return _body_from_envelope(rng, n0, shape, (-a, -b, 0.0), (a, b, hb), 1.0, r_cap=p["body_radius"],
                               d_max=d_max, z_floor=0.05 * hb, cover=p["body_cover"])


def _body_tower(rng, p, n0, width=1.0, top=None):
    h = p["height_ratio"] if top is None else top
    a = 0.5 * 0.72 * width
    b = a * p["aspect"]
    hb = (1.15 if top is None else 0.9) * h
    lean = p["lean"]
    shape = _dome(a, b, hb, p["squareness"], lean, _turrets(rng, p["turrets"], a, b), 1.0 - p["turret_height"],
                  p["taper"])
    lo = (-a + min(lean, 0.0) * hb, -b, 0.0)
    hi = (a + max(lean, 0.0) * hb, b, hb)
    return _body_from_envelope(rng, n0, shape, lo, hi, 1.0, r_cap=p["body_radius"] * width, d_max=0.25 * width,
                               z_floor=0.05 * min(hb, a), cover=p["body_cover"])


def _body_cumulonimbus(rng, p, n0):
    h = p["height_ratio"]
    tw = p["tower_width"]
    th = p["anvil_thickness"]
    n_anvil = min(max(1, int(round(0.6 * n0))), n0 - 1)  # the tower keeps at least one ball
    tower = _body_tower(rng, p, n0 - n_anvil, width=tw, top=(h - 0.9 * th) / 0.9)
    # the anvil: a flat disc of flattened balls at the top, reaching further downwind (+x)
    a = 0.5 * 0.95
    b = a * p["aspect"]
    xc = p["lean"] * (h - 0.5 * th) + 0.12 * a
    zc = h - 0.5 * th
    half = 0.5 * th

    def shape(pts):
        x, y = (pts[:, 0] - xc) / a, pts[:, 1] / b
        sxy = np.sqrt(x ** 2 + y ** 2)
        rim = (1.0 - sxy) * min(a, b)
        thick = half * np.sqrt(np.clip(1.0 - sxy ** 4, 0.0, None))  # thinner towards the rim
        iso_z = np.minimum(thick - np.abs(pts[:, 2] - zc), rim)
        return np.minimum(4.0 * iso_z, rim), iso_z
    anvil = _body_from_envelope(rng, n_anvil, shape, (xc - a, -b, zc - half), (xc + a, b, zc + half), 1.0,
                                r_cap=0.35 * a, d_max=1.0, z_floor=0.0, cover=1.0)
    w = np.concatenate([np.ones(len(tower)), np.zeros(len(anvil))])  # a smooth anvil: no puffs on it
    return _Level(np.concatenate([tower.c, anvil.c]), np.concatenate([tower.r, anvil.r]),
                  np.concatenate([tower.a, anvil.a]), np.concatenate([tower.q, anvil.q]), w)


def _smooth_noise(rng, shape, scale_cells):
    """A smooth random field on a grid of cells: a sum of random plane waves with wavelengths of about
    scale_cells cells (deterministic by the generator)."""
    ny, nx = shape
    yy, xx = np.mgrid[0:ny, 0:nx].astype(np.float64)
    out = np.zeros(shape)
    for _ in range(6):
        theta = rng.uniform(0, np.pi)
        k = 2 * np.pi / (scale_cells * rng.uniform(0.7, 1.6))
        out += np.cos(k * (np.cos(theta) * xx + np.sin(theta) * yy) + rng.uniform(0, 2 * np.pi))
    return out


def _body_stratocumulus(rng, p, n0_hint):
    nx = p["cells"]
    ny = max(1, int(round(nx * p["aspect"])))
    spacing = 1.0 / nx
    thick = 0.5 * p["thickness"]  # the cells' bodies: the puffs add about as much again
    noise = _smooth_noise(rng, (ny, nx), 3.0)
    n_cells = nx * ny
    keep = max(1, int(round(p["coverage"] * n_cells)))
    order = np.argsort(-noise.ravel(), kind="stable")[:keep]
    iy, ix = np.divmod(order, nx)
    strength = (noise.ravel()[order] - noise.min()) / max(np.ptp(noise), 1e-12)
    cx = (ix + 0.5) * spacing - 0.5 + 0.3 * spacing * rng.uniform(-1, 1, keep)
    cy = ((iy + 0.5) * spacing - 0.5 * ny * spacing) + 0.3 * spacing * rng.uniform(-1, 1, keep)
    per = max(1, int(round(n0_hint / keep))) if n0_hint else 1
    cx, cy = np.repeat(cx, per), np.repeat(cy, per)
    strength = np.repeat(strength, per)
    k = len(cx)
    if per > 1:
        cx = cx + 0.2 * spacing * rng.uniform(-1, 1, k)
        cy = cy + 0.2 * spacing * rng.uniform(-1, 1, k)
    size = spacing * (0.5 + 0.3 * strength) * rng.uniform(0.85, 1.15, k)
    height = thick * (0.6 + 0.5 * strength) * rng.uniform(0.85, 1.15, k)
    # the iso-surface of a cell spans about [0, height]: centre at height / 2, radii twice the iso-radii
    cz = 0.5 * height
    r = np.stack([size * 1.1, size * rng.uniform(0.75, 1.0, k), height], axis=1)
    a = np.zeros((k, 3))
    a[:, 2] = rng.uniform(0, 180, k)
    return _level(np.stack([cx, cy, cz], 1), r, a, 1.0)


def _default_body(kind, p, n_balls):
    if kind == "cumulus":
        n0 = 5 + 5 * p["height_ratio"]
    elif kind == "tower":
        n0 = 6 + 5 * p["height_ratio"]
    elif kind == "cumulonimbus":
        n0 = 30 + 6 * p["height_ratio"]
    else:  # a cell or two of the deck each
        n0 = 2 * p["cells"] ** 2 * p["aspect"] * p["coverage"]
    return int(max(1, min(round(n0), n_balls // 6)))
