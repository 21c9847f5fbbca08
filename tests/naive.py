"""Slow, obviously correct numpy references for every kernel. They share no code with cloudmeta's
kernels: Bernstein values come from the textbook basis sum, curves from solving the interpolation system,
roots from numpy.roots on a power form in a local variable, integrals from numpy's polynomial integration."""
import math

import numpy as np
from numpy.polynomial import polynomial as P


def bernstein_basis(n, i, s):
    return math.comb(n, i) * s ** i * (1.0 - s) ** (n - i)


def bernstein_eval(c, s):
    n = len(c) - 1
    return sum(c[i] * bernstein_basis(n, i, s) for i in range(n + 1))


def fit_bernstein(f, n):
    """Control values of the degree-n polynomial f on [0, 1] by interpolation at n+1 points."""
    x = 0.5 - 0.5 * np.cos(np.pi * (np.arange(n + 1) + 0.5) / (n + 1))
    m = np.array([[bernstein_basis(n, i, xk) for i in range(n + 1)] for xk in x])
    return np.linalg.solve(m, np.array([f(xk) for xk in x]))


def subdivide(c, s0, s1):
    return fit_bernstein(lambda x: bernstein_eval(c, s0 + x * (s1 - s0)), len(c) - 1)


def falloff(kernel, u, b=4.0):
    u = np.asarray(u, dtype=float)
    out = np.zeros_like(u)
    m = u < 1.0
    v = u[m]
    if kernel == "wyvill6":
        out[m] = 1 - 22 / 9 * v + 17 / 9 * v ** 2 - 4 / 9 * v ** 3
    elif kernel == "murakami4":
        out[m] = (1 - v) ** 2
    elif kernel == "nishimura":
        out[m] = np.where(v <= 1 / 9, 1 - 3 * v, 1.5 * (1 - np.sqrt(v)) ** 2)
    else:
        out[m] = np.exp(-b * v)
    return out


def kernel_poly(kernel):
    """k(u) in the power basis of u, for the polynomial kernels."""
    return {"wyvill6": [1, -22 / 9, 17 / 9, -4 / 9], "murakami4": [1, -2, 1]}[kernel]


def control_values(kernel, a, q=1.0):
    return fit_bernstein(lambda s: q * falloff(kernel, 1 - 4 * a * s * (1 - s)), 6)


def chord_sphere(o, d, c, r):
    """Textbook: B = (c - o).d, C = |c - o|^2 - R^2, D = B^2 - C; a = D / R^2."""
    b = np.dot(c - o, d)
    cc = np.dot(c - o, c - o) - r * r
    disc = b * b - cc
    if disc <= 0:
        return None
    return b - math.sqrt(disc), b + math.sqrt(disc), disc / (r * r)


def unit_frame(radii, rotation):
    return rotation.T / np.asarray(radii)[:, None]


def chord_ellipsoid(o, d, c, radii, rotation):
    """docs/model.md §2: A = |d'|^2, B = -o'.d', C = |o'|^2 - 1, D = B^2 - A C, a = D / A."""
    m = unit_frame(radii, rotation)
    op, dp = m @ (o - c), m @ d
    A, B, C = dp @ dp, -op @ dp, op @ op - 1.0
    D = B * B - A * C
    if D <= 0:
        return None
    return (B - math.sqrt(D)) / A, (B + math.sqrt(D)) / A, D / A


def field(blob, points):
    points = np.atleast_2d(points)
    u = np.einsum("nij,pnj->pni", blob.frames, points[:, None, :] - blob.centers[None]) ** 2
    return (falloff(blob.kernel, u.sum(axis=2), blob.blobbiness) * blob.weights[None]).sum(axis=1)


def _ball_u_poly(blob, i, o, d, ta):
    """u_i(t) as a power series in x = t - ta (local variable, so the coefficients stay well scaled)."""
    m = blob.frames[i]
    p0 = m @ (o + ta * d - blob.centers[i])
    p1 = m @ d
    return np.array([p0 @ p0, 2 * p0 @ p1, p1 @ p1])


def ray_pieces(blob, o, d, t_max=np.inf):
    """The ray's field as power-series pieces: list of (ta, tb, coeffs of F in x = t - ta)."""
    ends = []
    for i in range(len(blob)):
        ch = chord_ellipsoid(o, d, blob.centers[i], blob.radii[i], blob.rotations[i])
        if ch is not None:
            ends.append((ch[0], ch[1], i))
    bps = sorted({0.0, *(e[0] for e in ends), *(e[1] for e in ends)})
    bps = [t for t in bps if 0.0 <= t <= t_max] + ([t_max] if np.isfinite(t_max) else [])
    pieces = []
    k = kernel_poly(blob.kernel)
    for ta, tb in zip(bps[:-1], bps[1:]):
        if tb <= ta:
            continue
        active = [i for (t0, t1, i) in ends if t0 <= ta and t1 >= tb]
        if not active:
            continue
        f = np.zeros(1)
        for i in active:
            u = _ball_u_poly(blob, i, o, d, ta)
            ki = np.zeros(1)
            upow = np.ones(1)
            for coef in k:
                ki = P.polyadd(ki, coef * upow)
                upow = P.polymul(upow, u)
            f = P.polyadd(f, blob.weights[i] * ki)
        pieces.append((ta, tb, f))
    return pieces


def _real_roots_in(poly, length):
    """Real roots of a power-series polynomial in [0, length], polished by Newton steps."""
    poly = np.trim_zeros(np.asarray(poly, dtype=float), "b")
    if len(poly) < 2:
        return []
    cand = np.roots(poly[::-1])
    out = []
    dpoly = P.polyder(poly)
    for z in cand:
        if abs(z.imag) > 1e-6 * max(1.0, length):
            continue
        x = z.real
        for _ in range(4):
            dv = P.polyval(x, dpoly)
            if dv != 0:
                x -= P.polyval(x, poly) / dv
        if -1e-12 * length <= x <= length * (1 + 1e-12):
            out.append(min(max(x, 0.0), length))
    return sorted(out)


def crossings(blob, o, d, t_max=np.inf):
    """t where F - T changes sign along the ray (sign checked just around each candidate)."""
    o = np.asarray(o, float)
    d = np.asarray(d, float) / np.linalg.norm(d)
    out = []
    for ta, tb, f in ray_pieces(blob, o, d, t_max):
        g = P.polysub(f, [blob.threshold])
        w = tb - ta
        for x in _real_roots_in(g, w):
            h = 1e-7 * w
            lo, hi = P.polyval(max(x - h, 0), g), P.polyval(min(x + h, w), g)
            if (lo >= 0) != (hi >= 0):
                out.append(ta + x)
    out = np.array(sorted(out))
    # a root exactly at a piece boundary is found from both sides
    if len(out) > 1:
        keep = np.concatenate([[True], np.diff(out) > 1e-12])
        out = out[keep]
    return out


def optical_depth(blob, o, d, t_max=np.inf, density="field", scale=1.0):
    """Exact integral of sigma_t by numpy polynomial integration between consecutive crossings."""
    o = np.asarray(o, float)
    d = np.asarray(d, float) / np.linalg.norm(d)
    tau = 0.0
    for ta, tb, f in ray_pieces(blob, o, d, t_max):
        g = P.polysub(f, [blob.threshold])
        w = tb - ta
        cuts = [0.0] + _real_roots_in(g, w) + [w]
        for x0, x1 in zip(cuts[:-1], cuts[1:]):
            if x1 <= x0 or P.polyval(0.5 * (x0 + x1), g) < 0:
                continue
            rho = {"field": f, "excess": g, "uniform": np.ones(1)}[density]
            anti = P.polyint(rho)
            tau += P.polyval(x1, anti) - P.polyval(x0, anti)
    return scale * tau


def hull_crossing(c):
    """Where the convex hull of (i/n, c_i) meets 0: min and max over all segments between points of
    opposite sign, and points on the axis (None when nowhere)."""
    n = len(c) - 1
    xs = [i / n for i in range(n + 1) if c[i] == 0]
    for i in range(n + 1):
        for j in range(i + 1, n + 1):
            if c[i] * c[j] < 0:
                xs.append((i + (j - i) * c[i] / (c[i] - c[j])) / n)
    return (min(xs), max(xs)) if xs else None



def first_hit(field, threshold, origins, directions, t0, t1, step):
    """Per ray, the first t in [t0, t1] where field(o + t d) >= threshold, by brute force: samples every
    ``step``, then bisection (60 halvings, to the spacing of doubles) between the last sample outside
    and the first inside; inf where no sample is inside. ``field`` maps (N, 3) points to (N,) values. An
    inside part shorter than ``step`` can be stepped over: use a step far below the features of the field."""
    o = np.asarray(origins, float)
    d = np.asarray(directions, float)
    d = d / np.linalg.norm(d, axis=1)[:, None]
    ts = np.linspace(t0, t1, int(math.ceil((t1 - t0) / step)) + 1)
    lo = np.full(len(o), np.nan)
    hi = np.full(len(o), np.inf)
    for r in range(len(o)):
        inside = field(o[r] + ts[:, None] * d[r]) >= threshold
        k = int(np.argmax(inside))
        if inside[k]:
            lo[r], hi[r] = ts[max(k - 1, 0)], ts[k]
    bracket = np.flatnonzero(np.isfinite(hi) & (hi > lo))
    for _ in range(60):
        mid = 0.5 * (lo[bracket] + hi[bracket])
        inside = field(o[bracket] + mid[:, None] * d[bracket]) >= threshold
        hi[bracket] = np.where(inside, mid, hi[bracket])
        lo[bracket] = np.where(inside, lo[bracket], mid)
    return hi


def phase(kind, cos_theta, g1=0.0, g2=0.0, w=1.0):
    """docs/model.md §4's phase functions, by name, straight from the formulas."""
    def hg(g):
        return (1 - g * g) / (4 * math.pi * (1 + g * g - 2 * g * cos_theta) ** 1.5)
    if kind == "isotropic":
        return 1 / (4 * math.pi) + 0 * cos_theta
    if kind == "hg":
        return hg(g1)
    if kind == "double_hg":
        return w * hg(g1) + (1 - w) * hg(g2)
    if kind == "rayleigh":
        return 3 / (16 * math.pi) * (1 + cos_theta * cos_theta)
    raise ValueError(kind)


def lagrange(x, k, y):
    """The k-th Lagrange basis polynomial of the nodes x at y."""
    return np.prod([(y - x[j]) / (x[k] - x[j]) for j in range(len(x)) if j != k], axis=0)


def exp_weights(h, x, n_fine=200):
    """int_0^h e^-t L_k(t / h) dt for every k, by a fine Gauss-Legendre rule on [0, h]."""
    y, w = np.polynomial.legendre.leggauss(n_fine)
    t = 0.5 * h * (y + 1.0)
    return np.array([0.5 * h * np.sum(w * np.exp(-t) * lagrange(x, k, t / h)) for k in range(len(x))])


# --- walks: the BVH, the cell grid, the media along a ray ------------------------------------------------

def boxes_on_ray(bounds, o, d, tmin=0.0, tmax=np.inf):
    """Indices of the boxes bounds (N, 6) = [lo, hi] that the ray o + t d meets for some t in [tmin, tmax]:
    the slab test on every box, one after the other (what a BVH walk must return at least)."""
    o, d = np.asarray(o, float), np.asarray(d, float)
    lo_t = np.full(len(bounds), tmin, float)
    hi_t = np.full(len(bounds), tmax, float)
    for c in range(3):
        lo, hi = bounds[:, c], bounds[:, 3 + c]
        if d[c] == 0.0:
            outside = (o[c] < lo) | (o[c] > hi)
            hi_t[outside] = -np.inf
            continue
        a, b = (lo - o[c]) / d[c], (hi - o[c]) / d[c]
        lo_t = np.maximum(lo_t, np.minimum(a, b))
        hi_t = np.minimum(hi_t, np.maximum(a, b))
    return np.flatnonzero(lo_t <= hi_t)


def boxes_holding(bounds, x):
    """Indices of the boxes that hold the point x (bounds included)."""
    return np.flatnonzero(np.all((bounds[:, :3] <= x) & (x <= bounds[:, 3:]), axis=1))


def bin_balls(bounds, pad, origin, size, dims):
    """{cell: [ball, ...]} of every ball's padded box over a grid of dims cells of side ``size`` from
    ``origin``, cell c = i + nx (j + ny k), indices clamped to the grid, lists in ball order."""
    cells = {}
    for b, box in enumerate(bounds):
        lo = np.clip(np.floor((box[:3] - pad - origin) / size), 0, np.asarray(dims) - 1).astype(int)
        hi = np.clip(np.floor((box[3:] + pad - origin) / size), 0, np.asarray(dims) - 1).astype(int)
        for k in range(lo[2], hi[2] + 1):
            for j in range(lo[1], hi[1] + 1):
                for i in range(lo[0], hi[0] + 1):
                    cells.setdefault(i + dims[0] * (j + dims[1] * k), []).append(b)
    return cells


def media_optical_depth(media, o, d, t_max=np.inf):
    """tau along o + t d through several media [(blob, density mode, scale)], each by optical_depth."""
    return sum(optical_depth(blob, o, d, t_max, mode, scale) for blob, mode, scale in media)
