"""A plain numpy model of metaball media (docs/model.md §1-§4), written for validation only.

It shares no code with the engine (no Bernstein form, no de Casteljau, no Bézier clipping, no numba): on a
ray, between consecutive chord ends, the field of the balls on the ray is a polynomial in power form of a
local variable s in [0, 1]. Each ball contributes q k(u(s)) with v = 1 - u(s) = a - A (x0 + s w)^2 (a = 1 -
min u on the line, A = |d'|^2, x0 = distance of the interval's start from the closest point): wyvill6 is
k = (1 - u)^2 (1 - 4u/9) = 5/9 v^2 + 4/9 v^3 and murakami4 is k = v^2 (docs/model.md §1). The roots of F - T on
an interval are the real eigenvalues in [0, 1] of the companion matrix (numpy, batched over every interval
of every ray at once), polished by Newton on the power form; an interval is skipped only when a rigorous
bound (samples and the derivative's bound) shows F - T has no zero on it. Inside pieces are the parts of
an interval between consecutive roots where F - T >= 0 at the midpoint, and the optical depth of a piece is
the power-form antiderivative of scale * rho (exact).

Everything is vectorised over rays: ``pieces`` takes (K, 3) origins and directions and returns flat arrays
of pieces, so that a validation script can trace tens of thousands of shadow rays at once.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

#: k(v), v = 1 - u, in powers of v (docs/model.md §1: wyvill6 = (1-u)^2 (1 - 4u/9), murakami4 = (1-u)^2)
K_OF_V = {"wyvill6": np.array([0.0, 0.0, 5.0 / 9.0, 4.0 / 9.0]), "murakami4": np.array([0.0, 0.0, 1.0])}
#: degree in s of the field on an interval
DEGREE = {"wyvill6": 6, "murakami4": 4}
#: rays x balls per vectorised block (memory)
BLOCK = 400_000
#: samples per interval for the no-root bound
N_SAMPLES = 17


def frames_of(radii3, angles_deg):
    """S^-1 Q^T per ball, Q = Rz(az) Ry(ay) Rx(ax) (docs/model.md §9) from scipy's extrinsic 'xyz' Euler angles."""
    radii3 = np.asarray(radii3, dtype=np.float64)
    n = len(radii3)
    q = (np.broadcast_to(np.eye(3), (n, 3, 3)) if angles_deg is None
         else Rotation.from_euler("xyz", np.asarray(angles_deg, dtype=np.float64), degrees=True).as_matrix())
    return np.ascontiguousarray(np.transpose(q, (0, 2, 1)) / radii3[:, :, None])


@dataclass
class Medium:
    """One blob with its density (docs/model.md §4); albedo and phase are carried for the radiance reference."""
    centers: np.ndarray          # (N, 3)
    frames: np.ndarray           # (N, 3, 3) = S^-1 Q^T
    weights: np.ndarray          # (N,)
    kernel: str = "wyvill6"
    threshold: float = 0.5
    mode: str = "field"
    scale: float = 1.0
    albedo: float = 1.0
    phase: tuple = ("isotropic",)

    @classmethod
    def build(cls, centers, radii, weights, angles=None, **kw):
        centers = np.asarray(centers, dtype=np.float64).reshape(-1, 3)
        radii = np.asarray(radii, dtype=np.float64)
        radii3 = np.repeat(radii.reshape(-1, 1), 3, axis=1) if radii.ndim <= 1 else radii
        w = np.broadcast_to(np.asarray(weights, dtype=np.float64), (len(centers),)).copy()
        return cls(centers, frames_of(radii3, angles), w, **kw)

    def field(self, points):
        """F at (P, 3) points, straight from docs/model.md §1."""
        p = np.einsum("nij,pnj->pni", self.frames, np.asarray(points, np.float64)[:, None, :] - self.centers[None])
        u = np.einsum("pni,pni->pn", p, p)
        v = np.where(u < 1.0, 1.0 - u, 0.0)
        k = v * v * (5.0 / 9.0 + 4.0 / 9.0 * v) if self.kernel == "wyvill6" else v * v
        return k @ self.weights


# --- power-form helpers ----------------------------------------------------------------------------------------

def polyval(c, s):
    """Horner, row-wise: c (..., n+1) lowest power first, s broadcastable to c[..., 0]."""
    out = np.zeros(np.broadcast_shapes(c.shape[:-1], np.shape(s)))
    for j in range(c.shape[-1] - 1, -1, -1):
        out = out * s + c[..., j]
    return out


def polyder(c):
    return c[..., 1:] * np.arange(1, c.shape[-1])


def antideriv(c):
    """P with P(0) = 0, P' = c (one more coefficient)."""
    out = np.zeros(c.shape[:-1] + (c.shape[-1] + 1,))
    out[..., 1:] = c / np.arange(1, c.shape[-1] + 1)
    return out


def polymul(a, b):
    out = np.zeros(np.broadcast_shapes(a.shape[:-1], b.shape[:-1]) + (a.shape[-1] + b.shape[-1] - 1,))
    for i in range(a.shape[-1]):
        out[..., i:i + b.shape[-1]] += a[..., i:i + 1] * b
    return out


def real_roots_01(g):
    """Sorted real roots in [0, 1] of each row of g (power form), as an (n, deg) array padded with nan.

    Companion-matrix eigenvalues (batched), then Newton on g itself. Rows whose leading coefficient is
    negligible are solved with their degree reduced (numpy.roots, one by one)."""
    n, m = g.shape
    deg = m - 1
    out = np.full((n, deg), np.nan)
    if n == 0:
        return out
    mag = np.abs(g).max(axis=1)
    full = np.abs(g[:, -1]) > 1e-12 * mag
    cand = np.full((n, deg), np.nan + 0j)
    if np.any(full):
        gf = g[full]
        comp = np.zeros((len(gf), deg, deg))
        comp[:, np.arange(1, deg), np.arange(deg - 1)] = 1.0
        comp[:, :, -1] = -gf[:, :-1] / gf[:, -1:]
        cand[full] = np.linalg.eigvals(comp)
    for r in np.flatnonzero(~full):
        c = g[r].copy()
        while len(c) > 1 and abs(c[-1]) <= 1e-12 * mag[r]:
            c = c[:-1]
        if len(c) >= 2:
            z = np.roots(c[::-1])
            cand[r, :len(z)] = z
    x = np.where(np.abs(cand.imag) <= 1e-6, cand.real, np.nan)
    x = np.where((x > -1e-3) & (x < 1.001), x, np.nan)
    dg = polyder(g)
    for _ in range(4):  # Newton on the undeflated polynomial
        f = polyval(g[:, None, :], x)
        fp = polyval(dg[:, None, :], x)
        step = np.where(fp != 0.0, f / np.where(fp != 0.0, fp, 1.0), 0.0)
        x = np.where(np.abs(step) < 1e-2, x - step, x)
    x = np.where((x >= -1e-12) & (x <= 1 + 1e-12), np.clip(x, 0.0, 1.0), np.nan)
    out[:] = np.sort(x, axis=1)  # nan last
    return out


# --- rays through one medium ------------------------------------------------------------------------------------

@dataclass
class Pieces:
    """Inside pieces of one medium on many rays: on piece p, sigma_t(t) = polyval(coef[p], (t - ta[p]) / w[p])
    for t in [ta + sa w, ta + sb w]."""
    ray: np.ndarray
    ta: np.ndarray
    w: np.ndarray
    sa: np.ndarray
    sb: np.ndarray
    coef: np.ndarray

    @property
    def t0(self):
        return self.ta + self.sa * self.w

    @property
    def t1(self):
        return self.ta + self.sb * self.w

    def tau(self):
        """Optical depth of each piece."""
        P = antideriv(self.coef)
        return self.w * (polyval(P, self.sb) - polyval(P, self.sa))


def _chords(med, O, D, tmax):
    """Hits (ray, ball) of the rays' supports, chords clipped to [0, tmax], and the local quantities."""
    K, N = len(O), len(med.centers)
    rows = max(1, BLOCK // max(N, 1))
    parts = []
    for k0 in range(0, K, rows):
        o, d = O[k0:k0 + rows], D[k0:k0 + rows]
        op = np.einsum("nij,knj->kni", med.frames, o[:, None, :] - med.centers[None])
        dp = np.einsum("nij,kj->kni", med.frames, d)
        A = np.einsum("kni,kni->kn", dp, dp)
        tm = -np.einsum("kni,kni->kn", op, dp) / A
        q = op + tm[:, :, None] * dp
        a = 1.0 - np.einsum("kni,kni->kn", q, q)     # 1 - min u on the line (exact form, no B^2 - AC)
        half = np.sqrt(np.where(a > 0, a, 0.0) / A)
        t0, t1 = tm - half, tm + half
        hit = (a > 0) & (t1 > 0.0) & (t0 < tmax[k0:k0 + rows, None]) & (med.weights[None] != 0.0)
        kk, ii = np.nonzero(hit)
        parts.append((kk + k0, ii, t0[kk, ii], t1[kk, ii], tm[kk, ii], a[kk, ii], A[kk, ii]))
    return [np.concatenate([p[j] for p in parts]) for j in range(7)]


def pieces(med, O, D, tmax=None):
    """Every inside piece of ``med`` on the rays O + t D, t in [0, tmax] (D unit, tmax (K,) or None)."""
    O = np.atleast_2d(np.asarray(O, np.float64))
    D = np.atleast_2d(np.asarray(D, np.float64))
    K = len(O)
    tmax = np.full(K, np.inf) if tmax is None else np.broadcast_to(np.asarray(tmax, np.float64), (K,))
    kk, ii, t0, t1, tm, a, A = _chords(med, O, D, tmax)
    empty = Pieces(*(np.zeros(0) for _ in range(5)), np.zeros((0, DEGREE[med.kernel] + 1)))
    if len(kk) == 0:
        return empty
    t0 = np.maximum(t0, 0.0)
    t1 = np.minimum(t1, tmax[kk])
    H = len(kk)
    # every chord end, sorted by ray then t; intervals between consecutive ends of one ray
    vals = np.concatenate([t0, t1])
    rays = np.concatenate([kk, kk])
    order = np.lexsort((vals, rays))
    sv, sr = vals[order], rays[order]
    pos = np.empty(2 * H, np.int64)
    pos[order] = np.arange(2 * H)
    p0, p1 = pos[:H], pos[H:]             # sorted positions of each chord's start and end
    # (chord, interval) pairs: chord h covers the intervals starting at sorted positions p0 .. p1 - 1
    cnt = p1 - p0
    h_of = np.repeat(np.arange(H), cnt)
    j_of = p0[h_of] + (np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt))
    ta, tb = sv[j_of], sv[j_of + 1]
    keep = tb > ta
    h_of, j_of, ta, tb = h_of[keep], j_of[keep], ta[keep], tb[keep]
    w = tb - ta
    # v(s) = 1 - u = a - A (x0 + s w)^2, x0 = ta - tm
    x0 = ta - tm[h_of]
    Ah = A[h_of]
    v = np.stack([a[h_of] - Ah * x0 * x0, -2.0 * Ah * x0 * w, -Ah * w * w], axis=1)
    kv = K_OF_V[med.kernel]
    contrib = np.zeros((len(h_of), DEGREE[med.kernel] + 1))
    vp = np.ones((len(h_of), 1))
    for c in kv:
        if c != 0.0:
            contrib[:, :vp.shape[1]] += c * vp
        vp = polymul(vp, v)
    contrib *= med.weights[ii[h_of]][:, None]
    uniq, iv = np.unique(j_of, return_inverse=True)
    F = np.zeros((len(uniq), contrib.shape[1]))
    np.add.at(F, iv, contrib)
    iv_ray, iv_ta, iv_w = sr[uniq], sv[uniq], sv[uniq + 1] - sv[uniq]
    g = F.copy()
    g[:, 0] -= med.threshold
    # rigorous no-root test: |g(s)| > L h / 2 at every sample (L bounds |g'| on [0, 1], h the spacing)
    s = np.linspace(0.0, 1.0, N_SAMPLES)
    G = polyval(g[:, None, :], s[None, :])
    L = (np.abs(g[:, 1:]) * np.arange(1, g.shape[1])).sum(axis=1)
    may = np.any(np.abs(G) <= L[:, None] * (0.5 / (N_SAMPLES - 1)) * (1 + 1e-12) + 1e-300, axis=1)
    cuts = np.full((len(uniq), g.shape[1] + 1), 1.0)
    cuts[:, 0] = 0.0
    if np.any(may):
        r = real_roots_01(g[may])
        cuts[may, 1:-1] = np.where(np.isnan(r), 1.0, r)
    cuts.sort(axis=1)
    sa, sb = cuts[:, :-1], cuts[:, 1:]
    mid = polyval(g[:, None, :], 0.5 * (sa + sb))
    inside = (sb > sa) & (mid >= 0.0)
    pi, pj = np.nonzero(inside)
    if med.mode == "field":
        rho = F
    elif med.mode == "excess":
        rho = g
    else:
        rho = np.zeros_like(F)
        rho[:, 0] = 1.0
    return Pieces(iv_ray[pi], iv_ta[pi], iv_w[pi], sa[pi, pj], sb[pi, pj], med.scale * rho[pi])


def optical_depth(media, O, D, tmax=None):
    """(K,) tau along the rays through every medium (their sigma_t add)."""
    O = np.atleast_2d(np.asarray(O, np.float64))
    tau = np.zeros(len(O))
    for med in media if isinstance(media, (list, tuple)) else [media]:
        p = pieces(med, O, D, tmax)
        np.add.at(tau, p.ray.astype(np.int64), p.tau())
    return tau


def segments(med, o, d, tmax=None, join=1e-12):
    """Inside intervals [t0, t1] of one ray, adjacent pieces joined."""
    p = pieces(med, np.asarray(o)[None], np.asarray(d)[None], None if tmax is None else [tmax])
    order = np.argsort(p.t0)
    out = []
    for t0, t1 in zip(p.t0[order], p.t1[order]):
        if out and t0 - out[-1][1] <= join * max(1.0, abs(t0)):
            out[-1][1] = max(out[-1][1], t1)
        else:
            out.append([t0, t1])
    return np.array(out).reshape(-1, 2)
