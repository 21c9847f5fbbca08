"""Adversarial cases for the ray engine (and a few renders): no crash, no NaN/inf, agreement with a reference.

Every case is a ray (or an image) of a deliberately hard configuration. It FAILS if the engine raises, if
any output is not finite, or if its error exceeds the criterion of its category. References:

- ``exact``: the field on the ray rebuilt in 50-digit arithmetic (mpmath) from the very same float inputs
  (centres, frames = S^-1 Q^T, weights, origin, direction): per chord interval, F - T is an exact polynomial
  in t, its real roots come from mpmath.polyroots, and the inside length and the optical depth are exact
  integrals. For a single sphere the inside length is closed-form: 2 sqrt(r_iso^2 - p^2), with p the
  distance of the (float) ray from the (float) centre computed in mpmath and r_iso = R sqrt(u_T), k(u_T) = T.
- ``plain``: validation/references/plain.py (numpy power form, companion-matrix roots; ~1e-13 relative), used where
  an mpmath reference would be too slow (many balls).

Criteria (docs/model.md §3 and docs/model_notes.md), with tol_t the engine's root tolerance (1e-9 x the blob's
bounding-box diagonal, or as passed), n = 1 + the number of roots (engine or reference, the larger), and
sigma = scale x max(T, 1) the density at a crossing (an upper bound: field mode has T there, uniform 1):

- optical depth: |tau - tau_ref| <= 1e-9 tau_ref + sigma n (tol_t + x)
- inside length: |L - L_ref| <= n (tol_t + x)
  where x is 0, except far from the origin (x = 8 eps |coordinates|: the coordinates' own rounding moves
  a root by that much before any computation).
- tangent rays (a single sphere, exact length): |L - L_exact| <= tol_t + 2 sqrt(2 delta / |F''|): the bound of
  docs/model_notes.md (the square-root amplification of the engine's touch level delta = ROUND_F x sum|q k|).
- tangent rays to a composite surface: the same bound in its general form, |L - L_exact| <= tol_t +
  2 sqrt(2 delta / |F''|), delta = 4e-16 x sum_i |q_i k_i| at the touching point (one rounding of F's
  terms) and F'' the second derivative of F along the ray there (for one sphere this is the notes' bound
  within 10 %).
- thresholds just below the maximum (T = q (1 - delta)): the inside segment is 2 R sqrt(u_T); its
  length is as sensitive as a tangency, so the same general bound holds, with F'' = 2 |k'(0)| q / R^2 at
  the centre: |L - L_exact| <= tol_t + 2 R sqrt(2 x 4e-16 / (2 x 22/9)).
- renders: finite, alpha in [0, 1]; the far scene (1e6 from the origin) against the same scene at the
  origin, both at the reference quality: relative RMSE <= 1e-6 (positional rounding ~1e-10 of the scene
  size moves roots and nodes by that much; 1e-6 also covers the float32 image); the camera inside the
  cloud at the default quality against the reference quality: <= 1e-3 (the default's promise).

    python -m validation.accuracy.stability [--quick] [--seed 5]

Writes validation/results/stability.csv (per category), stability_cases.csv (every case) and
stability.png (worst error / tolerance per category).
"""
from __future__ import annotations

import inspect
import math
import tempfile
import textwrap
import time
import traceback
from pathlib import Path

import mpmath as mp
import numpy as np

import cloudmeta as cm
from cloudmeta.kernels.sweep import NOISE
from validation.common import (RESULTS, ROOT, parse, parser, print_head, pyplot, rel_rmse, run_main, save_figure,
                               with_settings, write_csv)
from validation.references import plain as P

EPS = np.finfo(float).eps
DPS = 50
ROUND_F = 8 * NOISE  # the engine's touch level, 64 eps (T + sum |c|), is at most 8 x 64 eps x sum|q k| here
                    # (docs/model_notes.md)


# --- exact references (mpmath, from the float inputs) ---------------------------------------------------------

_KV = {"wyvill6": (0, 0, mp.mpf(5) / 9, mp.mpf(4) / 9), "murakami4": (0, 0, 1)}


def _pmul(a, b):
    out = [mp.mpf(0)] * (len(a) + len(b) - 1)
    for i, x in enumerate(a):
        for j, y in enumerate(b):
            out[i + j] += x * y
    return out


#: mpmath >= 1.4 takes coefficients lowest power first (asc=True) and deprecates the old order
_ASCENDING = "asc" in inspect.signature(mp.polyroots).parameters


def _mp_polyroots(coeffs, **kw):
    """mpmath.polyroots of coefficients given highest power first, in either mpmath's convention."""
    if _ASCENDING:
        return mp.polyroots(list(coeffs)[::-1], asc=True, **kw)
    return mp.polyroots(coeffs, **kw)


def _polyroots(coeffs):
    """All complex roots (mpmath); clusters (double roots) converge slowly: retry with more precision."""
    for steps, extra in ((600, 3 * DPS), (3000, 8 * DPS)):
        try:
            return _mp_polyroots(coeffs, maxsteps=steps, extraprec=extra)
        except mp.libmp.NoConvergence:
            continue
    return _mp_polyroots(coeffs, maxsteps=3000, extraprec=8 * DPS, error=True)[0]


def exact_ray(blob, o, d, mode="field", scale=1.0, t_max=None):
    """(inside length, tau, number of roots) on the ray o + t d, t in [0, t_max], in DPS-digit arithmetic.

    The ray is the float (o, d) as given; t is measured in units of |d| (the engine normalises d: pass
    directions whose float norm is exactly 1)."""
    with mp.workdps(DPS):
        O = [mp.mpf(float(x)) for x in o]
        D = [mp.mpf(float(x)) for x in d]
        tm = mp.inf if t_max is None else mp.mpf(float(t_max))
        chords = []
        for i in range(len(blob)):
            M, c, w = blob.frames[i], blob.centers[i], float(blob.weights[i])
            if w == 0.0:
                continue
            p = [sum(mp.mpf(float(M[r, k])) * (O[k] - mp.mpf(float(c[k]))) for k in range(3)) for r in range(3)]
            q = [sum(mp.mpf(float(M[r, k])) * D[k] for k in range(3)) for r in range(3)]
            A = sum(x * x for x in q)
            b = sum(x * y for x, y in zip(p, q))
            C = sum(x * x for x in p)
            disc = b * b - A * (C - 1)
            if disc <= 0:
                continue
            s = mp.sqrt(disc)
            t0, t1 = (-b - s) / A, (-b + s) / A
            if t1 <= 0 or t0 >= tm:
                continue
            chords.append((max(t0, mp.mpf(0)), min(t1, tm), A, b, C, mp.mpf(w)))
        ends = sorted(set([ch[0] for ch in chords] + [ch[1] for ch in chords]))
        T = mp.mpf(float(blob.threshold))
        length, tau, n_roots = mp.mpf(0), mp.mpf(0), 0
        was_inside = False
        for ta, tb in zip(ends[:-1], ends[1:]):
            act = [ch for ch in chords if ch[0] <= ta and ch[1] >= tb]
            if not act:
                was_inside = False
                continue
            F = [mp.mpf(0)] * 7
            for (_, _, A, b, C, w) in act:  # v = 1 - u(ta + x), k as a polynomial in v (docs/model.md §1)
                v = [1 - (A * ta * ta + 2 * b * ta + C), -(2 * A * ta + 2 * b), -A]
                vp = [mp.mpf(1)]
                for coef in _KV[blob.kernel]:
                    if coef:
                        for j, x in enumerate(vp):
                            F[j] += w * coef * x
                    vp = _pmul(vp, v)
            g = list(F)
            g[0] -= T
            while len(g) > 1 and g[-1] == 0:
                g.pop()
            wdt = tb - ta
            rts = []
            if len(g) > 1:
                for z in _polyroots(g[::-1]):
                    if abs(mp.im(z)) <= mp.mpf(10) ** (-DPS // 2) * (1 + abs(z)) and 0 < mp.re(z) < wdt:
                        rts.append(mp.re(z))
            rts = sorted(rts)
            cuts = [mp.mpf(0)] + rts + [wdt]
            gv = lambda x: sum(cf * x ** j for j, cf in enumerate(g))  # noqa: E731
            rho = {"field": F, "excess": g, "uniform": [mp.mpf(1)]}[mode]
            anti = lambda x: sum(cf * x ** (j + 1) / (j + 1) for j, cf in enumerate(rho))  # noqa: E731
            for a_, b_ in zip(cuts[:-1], cuts[1:]):
                inside = b_ > a_ and gv((a_ + b_) / 2) >= 0
                if b_ > a_:
                    if inside != was_inside and (ta + a_) > 0:
                        n_roots += 1
                    was_inside = inside
                if inside:
                    length += b_ - a_
                    tau += anti(b_) - anti(a_)
        return float(length), float(scale * tau), n_roots


def sphere_exact_length(center, R, q, T, kernel, o, d):
    """Closed form for one sphere: 2 sqrt(r_T^2 - p^2) (in units of |d|), with k(r_T^2 / R^2) = T / q."""
    with mp.workdps(DPS):
        tq = mp.mpf(float(T)) / mp.mpf(float(q))
        if kernel == "wyvill6":
            f = lambda u: (1 - u) ** 2 * (1 - 4 * u / 9) - tq  # noqa: E731
            guess = 9 * (1 - tq) / 22 if tq > 0.99 else mp.mpf(0.25)
        else:
            f = lambda u: (1 - u) ** 2 - tq  # noqa: E731
            guess = 1 - mp.sqrt(tq)
        u_t = mp.findroot(f, guess) if kernel == "wyvill6" else 1 - mp.sqrt(tq)
        r2 = mp.mpf(float(R)) ** 2 * u_t
        O = [mp.mpf(float(x)) for x in o]
        D = [mp.mpf(float(x)) for x in d]
        C = [mp.mpf(float(x)) for x in center]
        w = [C[i] - O[i] for i in range(3)]
        dd = sum(x * x for x in D)
        wd = sum(w[i] * D[i] for i in range(3))
        p2 = sum(x * x for x in w) - wd * wd / dd
        length = 2 * mp.sqrt(r2 - p2) / mp.sqrt(dd) if r2 > p2 else mp.mpf(0)
        return float(length), float(mp.sqrt(r2))


# --- helpers ----------------------------------------------------------------------------------------------------

def unit_exact(v):
    """v normalised, or None if the float norm of the result is not exactly 1 (then the engine's own
    normalisation would move the ray by an ulp and the exact reference would describe another ray)."""
    v = np.asarray(v, float)
    v = v / np.linalg.norm(v)
    return v if np.linalg.norm(v) == 1.0 else None


def random_unit(rng, perp_to=None):
    while True:
        v = rng.normal(size=3)
        if perp_to is not None:
            v = v - np.dot(v, perp_to) * perp_to
        u = unit_exact(v)
        if u is not None:
            return u


def engine(blob, o, d, mode="field", scale=1.0, tolerance=1e-9, t_max=np.inf):
    """tau, roots, segments of the engine for rays (N, 3); raises what the engine raises."""
    o, d = np.atleast_2d(o), np.atleast_2d(d)
    tau = cm.optical_depth(blob, o, d, t_max=t_max, density=mode, scale=scale, tolerance=tolerance)
    roots = cm.roots(blob, o, d, t_max=t_max, tolerance=tolerance)
    segs = cm.segments(blob, o, d, t_max=t_max, tolerance=tolerance)
    return tau, roots, segs


def seg_length(s):
    return float(np.sum(s[:, 1] - s[:, 0])) if len(s) else 0.0


def plain_of(blob, mode="field", scale=1.0):
    """The plain model of a cm.Blob: the same float centres, frames and weights."""
    return P.Medium(np.array(blob.centers), np.array(blob.frames), np.array(blob.weights), kernel=blob.kernel,
                    threshold=blob.threshold, mode=mode, scale=scale)


class Cases:
    """Collects every case: category, label, error, tolerance, status."""

    def __init__(self):
        self.rows = []

    def add(self, cat, label, err, tol, status=None, ref="exact", note=""):
        if status is None:
            status = "ok" if (np.isfinite(err) and err <= tol) else ("nonfinite" if not np.isfinite(err) else "FAIL")
        self.rows.append(dict(category=cat, case=label, error=float(err), tolerance=float(tol),
                              ratio=float(err / tol) if tol > 0 and np.isfinite(err) else float("inf"),
                              status=status, reference=ref, note=note))

    def crash(self, cat, label, exc):
        self.rows.append(dict(category=cat, case=label, error=float("nan"), tolerance=float("nan"),
                              ratio=float("inf"), status="CRASH", reference="-",
                              note=f"{type(exc).__name__}: {exc}".replace("\n", " ")[:300]))

    def length(self, cat, label, blob, o, d, exact, bound):
        """One ray's inside length against ``exact()`` (the reference, computed only when the engine did not
        raise): a case within ``bound``."""
        try:
            segs = cm.segments(blob, o[None], d[None])[0]
        except Exception as exc:  # noqa: BLE001 - a crash is a result here
            self.crash(cat, label, exc)
            return
        length = exact()
        if not np.all(np.isfinite(segs)):
            self.add(cat, label, float("inf"), bound, status="nonfinite")
            return
        self.add(cat, label, abs(seg_length(segs) - length), bound,
                 note=f"exact length {length:.3e}, engine {seg_length(segs):.3e}")

    def compare(self, cat, label, blob, o, d, mode="field", scale=1.0, tolerance=1e-9, extra=0.0, ref="exact",
                t_max=None):
        """Engine against the reference on rays o, d (N, 3): one case per ray (tau and inside length)."""
        try:
            tau, roots, segs = engine(blob, o, d, mode, scale, tolerance, np.inf if t_max is None else t_max)
        except Exception as exc:  # noqa: BLE001 - a crash is a result here
            self.crash(cat, label, exc)
            return
        tol_t = tolerance * blob.diagonal
        sigma = scale * max(blob.threshold, 1.0)
        plain = plain_of(blob, mode, scale) if ref == "plain" else None
        for k in range(len(o)):
            if not (np.isfinite(tau[k]) and np.all(np.isfinite(roots[k])) and np.all(np.isfinite(segs[k]))):
                self.add(cat, f"{label} #{k}", float("inf"), 1.0, status="nonfinite", ref=ref)
                continue
            if ref == "exact":
                L_ref, tau_ref, n_ref = exact_ray(blob, o[k], d[k], mode, scale, t_max)
            else:
                ps = P.segments(plain, o[k], d[k], t_max)
                L_ref = seg_length(ps)
                tau_ref = float(P.optical_depth(plain, o[k][None], d[k][None], None if t_max is None else [t_max])[0])
                n_ref = 2 * len(ps)
            n = 1 + max(len(roots[k]), n_ref)
            tol_tau = 1e-9 * abs(tau_ref) + sigma * n * (tol_t + extra)
            tol_len = n * (tol_t + extra)
            err_tau, err_len = abs(tau[k] - tau_ref), abs(seg_length(segs[k]) - L_ref)
            # one case per ray: the worse of the two, as a fraction of its own tolerance
            if err_tau / tol_tau >= err_len / tol_len:
                self.add(cat, f"{label} #{k} (tau)", err_tau, tol_tau, ref=ref)
            else:
                self.add(cat, f"{label} #{k} (length)", err_len, tol_len, ref=ref)


# --- the categories ---------------------------------------------------------------------------------------------

def tangent_single(cs, rng, quick):
    """Rays at distance r (1 - e) from the centre of one sphere's isosurface of radius r (exact length)."""
    cat = "tangent rays, one sphere"
    es = [1e-3, 1e-6, 1e-9, 1e-12, 1e-13, 3e-14, 1e-14, 3e-15, 1e-15, 1e-16, 0.0, -1e-16, -1e-14, -1e-9, -1e-3]
    n_dir = 2 if quick else 6
    for kernel, T, R, q in (("wyvill6", 0.5, 1.3, 1.0), ("murakami4", 0.3, 0.7, 0.8)):
        c = np.array([0.3, -0.2, 0.1])
        blob = cm.Blob([c], [R], [q], kernel=kernel, threshold=T)
        tol_t = 1e-9 * blob.diagonal
        _, r_iso = sphere_exact_length(c, R, q, T, kernel, c - 3 * R * np.array([1.0, 0, 0]), [1.0, 0, 0])
        bound = tol_t + 2 * r_iso * math.sqrt(ROUND_F)
        for e in es:
            for _ in range(n_dir):
                d = random_unit(rng)
                e1 = random_unit(rng, perp_to=d)
                o = c + r_iso * (1 - e) * e1 - 3 * R * d
                cs.length(cat, f"{kernel} e={e:g}", blob, o, d,
                          lambda: sphere_exact_length(c, R, q, T, kernel, o, d)[0], bound)


def _field_terms(blob, x):
    """F, sum |q k|, gradient and Hessian at x (float, docs/model.md §1; wyvill6 and murakami4)."""
    F, S = 0.0, 0.0
    grad, hess = np.zeros(3), np.zeros((3, 3))
    for c, M, q in zip(blob.centers, blob.frames, blob.weights):
        y = M @ (x - c)
        u = y @ y
        if u >= 1.0:
            continue
        v = 1.0 - u
        if blob.kernel == "wyvill6":
            k, dk, d2k = v * v * (1 - 4 * u / 9), -22 / 9 + 34 / 9 * u - 12 / 9 * u * u, 34 / 9 - 24 / 9 * u
        else:
            k, dk, d2k = v * v, -2 * v, 2.0
        G = M.T @ M
        du = 2 * G @ (x - c)
        F += q * k
        S += abs(q * k)
        grad += q * dk * du
        hess += q * (d2k * np.outer(du, du) + dk * 2 * G)
    return F, S, grad, hess


def tangent_composite(cs, rng, quick):
    """Rays tangent to the isosurface of overlapping balls at a point found by bisection (exact length)."""
    cat = "tangent rays, composite surface"
    es = [1e-3, 1e-6, 1e-9, 1e-12, 1e-14, 1e-16, 0.0, -1e-16, -1e-12, -1e-6]
    n_blobs, n_pts = (1, 1) if quick else (3, 2)
    for b in range(n_blobs):
        n = 4
        centers = rng.uniform(-0.8, 0.8, (n, 3))
        blob = cm.Blob(centers, rng.uniform(0.9, 1.4, n), rng.uniform(0.8, 1.2, n),
                       kernel=("wyvill6", "murakami4")[b % 2], threshold=0.5)
        tol_t = 1e-9 * blob.diagonal
        for _ in range(n_pts):
            # a point on F = T: bisection from the centroid (inside) outwards along a random direction
            start = centers.mean(axis=0)
            if _field_terms(blob, start)[0] <= blob.threshold:
                start = centers[0]
            u = random_unit(rng)
            lo, hi = 0.0, 0.1
            while _field_terms(blob, start + hi * u)[0] > blob.threshold:
                lo, hi = hi, hi + 0.1
            for _ in range(200):
                mid = 0.5 * (lo + hi)
                if mid in (lo, hi):
                    break
                if _field_terms(blob, start + mid * u)[0] > blob.threshold:
                    lo = mid
                else:
                    hi = mid
            x0 = start + lo * u
            _, S, grad, hess = _field_terms(blob, x0)
            nrm = grad / np.linalg.norm(grad)  # towards higher F: inwards
            d = random_unit(rng, perp_to=nrm)
            f2 = abs(d @ hess @ d)
            bound = tol_t + 2 * math.sqrt(2 * ROUND_F * S / f2)
            for e in es:
                o = x0 + e * nrm - 4.0 * d
                cs.length(cat, f"blob {b} e={e:g}", blob, o, d, lambda: exact_ray(blob, o, d)[0], bound)


def near_max_threshold(cs, rng, quick):
    """T = q (1 - delta): the inside region is a tiny ball around the centre (exact length)."""
    cat = "threshold just below the maximum"
    deltas = [1e-2, 1e-4, 1e-6, 1e-8, 1e-10, 1e-12, 1e-13, 3e-14, 1e-14, 3e-15, 1e-15]
    n_dir = 2 if quick else 5
    R, q = 1.3, 1.0
    c = np.array([0.3, -0.2, 0.1])
    for delta in deltas:
        T = q * (1 - delta)
        blob = cm.Blob([c], [R], [q], threshold=T)
        tol_t = 1e-9 * blob.diagonal
        bound = tol_t + 2 * R * math.sqrt(2 * ROUND_F * q / (2 * 22 / 9 * q))
        for k in range(n_dir):
            d = random_unit(rng)
            o = c - 3 * R * d
            if k % 2:  # off-centre, half the inside radius
                _, r_t = sphere_exact_length(c, R, q, T, "wyvill6", o, d)
                o = o + 0.5 * r_t * random_unit(rng, perp_to=d)
            cs.length(cat, f"delta={delta:g}", blob, o, d,
                      lambda: sphere_exact_length(c, R, q, T, "wyvill6", o, d)[0], bound)


def grazing_support(cs, rng, quick):
    """Rays at distance R (1 - e) from a ball's centre (its chord shrinks to nothing, D -> 0) that also
    cross a neighbour's inside; spheres and an ellipsoid."""
    cat = "grazing a ball's support"
    es = [1e-2, 1e-6, 1e-10, 1e-14, 1e-16, 0.0, -1e-16, -1e-10]
    n_dir = 1 if quick else 3
    for shape in ("sphere", "ellipsoid"):
        cA, cB = np.array([0.0, 0.0, 0.0]), np.array([1.2, 0.1, -0.1])
        if shape == "sphere":
            blob = cm.Blob([cA, cB], [1.0, 1.0], [1.0, 0.9], threshold=0.5)
        else:
            blob = cm.Blob([cA, cB], [[1.0, 1.0, 1.0], [1.5, 0.7, 0.9]], [1.0, 0.9], threshold=0.5,
                           rotations=[[0, 0, 0], [20, 30, 40]])
        for e in es:
            for _ in range(n_dir):
                d = random_unit(rng)
                # the line through A's centre region that grazes B's support: in B's unit frame, put the
                # line at distance (1 - e) from the origin
                M = blob.frames[1]
                dp = M @ d
                perp = M @ (cA - cB)
                perp = perp - (perp @ dp) / (dp @ dp) * dp
                perp /= np.linalg.norm(perp)
                o = cB + np.linalg.solve(M, (1 - e) * perp) - 4.0 * d
                cs.compare(cat, f"{shape} e={e:g}", blob, o[None], d[None])


def coincident_centres(cs, rng, quick):
    cat = "coincident centres"
    c = np.array([0.2, 0.1, -0.3])
    setups = {
        "5 equal balls": cm.Blob(np.repeat(c[None], 5, 0), [1.0] * 5, [0.2] * 5, threshold=0.5),
        "radii 0.5..2": cm.Blob(np.repeat(c[None], 4, 0), [0.5, 1.0, 1.5, 2.0], [0.4, 0.3, 0.3, 0.2],
                                threshold=0.5),
        "ellipsoids, 3 rotations": cm.Blob(np.repeat(c[None], 3, 0), [[2.0, 0.6, 0.6]] * 3, [0.5] * 3,
                                           rotations=[[0, 0, 0], [0, 0, 60], [0, 0, 120]], threshold=0.5),
        "pairs + neighbours": cm.Blob(np.array([c, c, c + [1, 0, 0], c + [1, 0, 0], c + [0, 1.0, 0.5]]),
                                      [1.0, 1.0, 1.2, 1.2, 0.8], [0.5, 0.5, 0.6, 0.4, 1.0], threshold=0.5,
                                      kernel="murakami4"),
    }
    n_rays = 3 if quick else 10
    for name, blob in setups.items():
        o, d = [], []
        for k in range(n_rays):
            dd = random_unit(rng)
            target = c if k == 0 else c + rng.uniform(-0.6, 0.6, 3)
            o.append(target - 5.0 * dd)
            d.append(dd)
        cs.compare(cat, name, blob, np.array(o), np.array(d), mode=("field", "excess", "uniform")[len(o) % 3])


def radii_range(cs, rng, quick):
    """Radii from 1e-4 to 1e4 in one blob; at the default tolerance and at 1e-15 of the diagonal."""
    cat = "radii 1e-4 .. 1e4 in one scene"
    radii = np.array([1e4, 3e3, 1e3, 1e2, 10.0, 1.0, 0.1, 1e-2, 1e-3, 1e-4])
    # the big ones nested around the origin; the small ones in a row outside the big supports
    centers = np.zeros((len(radii), 3))
    centers[:4] = [[0, 0, 0], [2e3, 0, 0], [-1e3, 5e2, 0], [0, 9e2, 1e2]]
    centers[4:] = np.array([[1.2e4 + 40 * k, 0, 0] for k in range(6)])
    centers[4:, 1] = rng.uniform(-1, 1, 6) * 1e-6
    blob = cm.Blob(centers, radii, np.ones(len(radii)), threshold=0.5)
    n_rays = 2 if quick else 6
    for tol_rel in (1e-9, 1e-15):
        extra = 8 * EPS * 1.3e4  # positions carry 1e-12 of rounding at 1.2e4: a tight tolerance cannot beat it
        for i, (c, r) in enumerate(zip(centers, radii)):
            if quick and i % 3:
                continue
            o, d = [], []
            for k in range(n_rays):
                dd = random_unit(rng)
                o.append(c + rng.uniform(-0.3, 0.3, 3) * r - 3 * r * dd)
                d.append(dd)
            cs.compare(cat, f"tol {tol_rel:g}, ball R={r:g}", blob, np.array(o), np.array(d), tolerance=tol_rel,
                       extra=extra if tol_rel < 1e-9 else 0.0)


def cancelling_weights(cs, rng, quick):
    """+q and -q at the same centre and radius: their curves cancel exactly."""
    cat = "negative weights that cancel exactly"
    c1, c2 = np.array([0.0, 0.0, 0.0]), np.array([0.9, 0.2, 0.0])
    setups = {
        "cancelling pair alone": cm.Blob([c1, c1], [1.0, 1.0], [1.0, -1.0], threshold=0.3),
        "cancelling pair + ball": cm.Blob([c1, c1, c2], [1.0, 1.0, 1.2], [1.0, -1.0, 1.0], threshold=0.3),
        "two pairs, ellipsoids": cm.Blob([c1, c1, c2, c2, c1 + 0.5], [[1.5, 0.5, 0.8]] * 4 + [[1.0, 1.0, 1.0]],
                                         [0.7, -0.7, 1.3, -1.3, 1.0], threshold=0.3,
                                         rotations=[[10, 20, 30]] * 2 + [[0, 45, 0]] * 2 + [[0, 0, 0]]),
        "carving to zero": cm.Blob([c1, c1, c2], [1.0, 1.0, 1.0], [1.0, -2.0, 1.0], threshold=0.3),
    }
    n_rays = 3 if quick else 10
    for name, blob in setups.items():
        o, d = [], []
        for k in range(n_rays):
            dd = random_unit(rng)
            o.append(rng.uniform(-0.5, 1.0, 3) - 5 * dd)
            d.append(dd)
        cs.compare(cat, name, blob, np.array(o), np.array(d))


def aspect_1000(cs, rng, quick):
    """Needles (10, 0.01, 0.01) and pancakes (10, 10, 0.01), rotated, crossing each other."""
    cat = "ellipsoids with aspect ratio 1000"
    n = 6
    radii = np.array([[10, 0.01, 0.01], [10, 10, 0.01]] * (n // 2), float)
    rot = rng.uniform(-180, 180, (n, 3))
    centers = rng.uniform(-0.005, 0.005, (n, 3))
    blob = cm.Blob(centers, radii, rng.uniform(0.8, 1.2, n), rotations=rot, threshold=0.5)
    n_rays = 6 if quick else 30
    o, d = [], []
    for k in range(n_rays):
        dd = random_unit(rng)
        if k % 3 == 0:  # nearly in the plane of a pancake
            normal = blob.rotations[1][:, 2]
            dd = random_unit(rng, perp_to=normal)
            dd = unit_exact(dd + 1e-4 * normal) if unit_exact(dd + 1e-4 * normal) is not None else dd
        o.append(rng.uniform(-0.005, 0.005, 3) - 15 * dd)
        d.append(dd)
    cs.compare(cat, "needles and pancakes", blob, np.array(o), np.array(d), ref="plain")


def far_away(cs, rng, quick):
    """The same blob and rays near the origin and shifted by ~1e6 (exact reference on the shifted floats)."""
    cat = "scene 1e6 from the origin"
    n = 8
    centers = rng.uniform(-1.5, 1.5, (n, 3))
    radii = rng.uniform(0.8, 1.6, (n, 3))
    rot = rng.uniform(-90, 90, (n, 3))
    w = rng.uniform(0.7, 1.2, n)
    n_rays = 4 if quick else 12
    dirs = np.array([random_unit(rng) for _ in range(n_rays)])
    tgt = rng.uniform(-1.0, 1.0, (n_rays, 3))
    for shift in (np.array([1e6, -2e6, 1.5e6]), np.array([-3e6, 1e6, 2e6])):
        blob = cm.Blob(centers + shift, radii, w, rotations=rot, threshold=0.5)
        o = tgt + shift - 6 * dirs
        extra = 8 * EPS * np.abs(shift).max()
        cs.compare(cat, f"shift {shift.tolist()}", blob, o, dirs, extra=extra)


def inside_start(cs, rng, quick):
    """Rays whose origin is inside a ball's support, inside the isosurface, at a centre, on the surface."""
    cat = "rays starting inside a ball"
    n = 5
    centers = rng.uniform(-1, 1, (n, 3))
    blob = cm.Blob(centers, rng.uniform(1.0, 1.5, n), rng.uniform(0.8, 1.2, n), threshold=0.5,
                   kernel="murakami4")
    n_rays = 4 if quick else 16
    o = [centers[0].copy(), centers[1].copy()]
    o += [rng.uniform(-1.5, 1.5, 3) for _ in range(n_rays - 2)]
    d = [random_unit(rng) for _ in o]
    cs.compare(cat, "random origins", blob, np.array(o), np.array(d), mode="excess", scale=2.0)
    # an origin on the isosurface of one sphere (a root at t = 0 or nearly)
    c = np.array([0.0, 0.0, 0.0])
    one = cm.Blob([c], [1.0], [1.0], threshold=0.5)
    _, r_iso = sphere_exact_length(c, 1.0, 1.0, 0.5, "wyvill6", c - 3 * np.array([1.0, 0, 0]), [1.0, 0, 0])
    o2, d2 = [], []
    for _ in range(3 if quick else 8):
        u = random_unit(rng)
        o2.append(c + r_iso * u)
        dd = random_unit(rng)
        d2.append(dd)
    cs.compare(cat, "origin on the isosurface", one, np.array(o2), np.array(d2), mode="uniform")


def crossing_at_chord_end(cs, rng, quick):
    """Rays that cross one ball's isosurface exactly where they leave another ball's support: ball A alone
    has its isosurface at |x| = r_T (0.5 for wyvill6, R = 1, T = 0.5), and ball B's support touches it at
    x* = (r_T, 0, 0), so a composite interval of the ray starts at the crossing itself (F - T = 0 there,
    to rounding)."""
    cat = "crossing at another ball's chord end"
    n_rays = 4 if quick else 16
    A = np.zeros(3)
    for RB, qB in ((1.0, 0.7), (0.8, -0.5)):
        cB = np.array([0.5 + RB, 0.0, 0.0])
        blob = cm.Blob([A, cB], [1.0, RB], [1.0, qB], threshold=0.5)
        xs = np.array([0.5, 0.0, 0.0])
        o, d = [], []
        while len(d) < n_rays:
            dd = random_unit(rng)
            if dd[0] > -0.05:
                dd = -dd
            if dd[0] > -0.05:
                continue
            o.append(xs - 3 * dd)
            d.append(dd)
        cs.compare(cat, f"R_B={RB} q_B={qB}", blob, np.array(o), np.array(d))


def many_balls(cs, rng, quick):
    """100,000 balls in a slab 120 x 120 x 6: every ray crosses hundreds of chords."""
    cat = "100,000 balls"
    n = 20_000 if quick else 100_000
    side = 120.0 * math.sqrt(n / 100_000)
    centers = np.stack([rng.uniform(-side / 2, side / 2, n), rng.uniform(-side / 2, side / 2, n),
                        rng.uniform(-3, 3, n)], axis=1)
    blob = cm.Blob(centers, rng.uniform(0.6, 1.6, n), rng.uniform(0.8, 1.2, n), threshold=0.5)
    n_rays = 200 if quick else 2000
    o = np.column_stack([rng.uniform(-side / 2.5, side / 2.5, n_rays), np.full(n_rays, -side / 2 - 5),
                         rng.uniform(-2.5, 2.5, n_rays)])
    d = np.column_stack([rng.normal(0, 0.2, n_rays), np.ones(n_rays), rng.normal(0, 0.01, n_rays)])
    d /= np.linalg.norm(d, axis=1)[:, None]
    t0 = time.perf_counter()
    try:
        tau = cm.optical_depth(blob, o, d)
    except Exception as exc:  # noqa: BLE001
        cs.crash(cat, f"{n} balls, {n_rays} rays", exc)
        return None
    secs = time.perf_counter() - t0
    bad = int(np.sum(~np.isfinite(tau)))
    cs.add(cat, f"{n} balls: {n_rays} rays finite", float(bad), 0.5, status="ok" if bad == 0 else "nonfinite",
           ref="-", note=f"{secs:.2f} s for {n_rays} rays (BVH build included)")
    k = 10 if quick else 40
    cs.compare(cat, f"{n} balls", blob, o[:k], d[:k], ref="plain")
    return dict(balls=n, rays=n_rays, seconds=secs)


# --- renders ------------------------------------------------------------------------------------------------------

def renders(cs, quick):
    cat = "renders"
    size = 8 if quick else 16
    cum = ROOT / "scenes" / "cumulus.yaml"
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        # far away: the cumulus and its camera shifted by 1e6, against the original
        shift = np.array([1e6, -1e6, 1e6])
        data = np.genfromtxt(ROOT / "scenes" / "cumulus.csv", delimiter=",", names=True)
        cols = list(data.dtype.names)
        arr = np.array([list(r) for r in data])
        arr[:, :3] += shift
        np.savetxt(tmp / "far.csv", arr, delimiter=",", fmt="%.10f", header=",".join(cols), comments="")
        text = (cum.read_text().replace("balls_file: cumulus.csv", f"balls_file: {tmp / 'far.csv'}")
                .replace("position: [0, -22, 2.2], look_at: [0, 0, 2.4]",
                         f"position: [{shift[0]}, {shift[1] - 22}, {shift[2] + 2.2}], "
                         f"look_at: [{shift[0]}, {shift[1]}, {shift[2] + 2.4}]"))
        assert "far.csv" in text and str(shift[0]) in text
        (tmp / "far.yaml").write_text(text)
        try:
            near = cm.render(with_settings(cm.load_scene(cum, width=size, height=size), quality="reference"),
                             progress=False)
            far = cm.render(with_settings(cm.load_scene(tmp / "far.yaml", width=size, height=size),
                                         quality="reference"), progress=False)
            ok = bool(np.all(np.isfinite(far)))
            cs.add(cat, "cumulus 1e6 from the origin vs at the origin (reference quality)",
                   rel_rmse(far, near) if ok else float("inf"), 1e-6, ref="same scene at the origin")
        except Exception as exc:  # noqa: BLE001
            cs.crash(cat, "cumulus 1e6 from the origin", exc)
        # the camera inside the cloud (at a ball's centre)
        inside = cum.read_text().replace("position: [0, -22, 2.2], look_at: [0, 0, 2.4]",
                                         "position: [0.0382, 0.1712, 0.6171], look_at: [3, 2, 2.4]")
        inside = inside.replace("balls_file: cumulus.csv", f"balls_file: {ROOT / 'scenes' / 'cumulus.csv'}")
        (tmp / "inside.yaml").write_text(inside)
        try:
            s = cm.load_scene(tmp / "inside.yaml", width=size, height=size)
            ref = cm.render(with_settings(s, quality="reference"), progress=False)
            img = cm.render(with_settings(s, quality="default"), progress=False)
            ok = bool(np.all(np.isfinite(img)) and np.all(np.isfinite(ref)))
            ok_alpha = bool(np.all((img[..., 3] >= 0) & (img[..., 3] <= 1)))
            cs.add(cat, "camera inside the cumulus: default vs reference",
                   rel_rmse(img, ref) if ok and ok_alpha else float("inf"), 1e-3, ref="reference quality")
        except Exception as exc:  # noqa: BLE001
            cs.crash(cat, "camera inside the cumulus", exc)
        # a blob of 100,000 balls in a scene
        rng = np.random.default_rng(3)
        n = 20_000 if quick else 100_000
        side = 120.0 * math.sqrt(n / 100_000)
        balls = np.column_stack([rng.uniform(-side / 2, side / 2, n), rng.uniform(-side / 2, side / 2, n),
                                 rng.uniform(-3, 3, n), rng.uniform(0.6, 1.6, n), rng.uniform(0.8, 1.2, n)])
        np.savetxt(tmp / "many.csv", balls, delimiter=",", fmt="%.6f", header="x,y,z,radius,weight", comments="")
        (tmp / "many.yaml").write_text(textwrap.dedent(f"""\
            image: {{width: {size}, height: {size}}}
            camera: {{position: [0, {-side}, 40], look_at: [0, 0, 0], up: [0, 0, 1], fov: 50}}
            background: [0.2, 0.3, 0.6]
            lights: [{{type: directional, direction: [0.3, 0.2, 0.9], irradiance: 3.0}}]
            media:
              - {{kernel: wyvill6, threshold: 0.5, density: {{mode: field, scale: 0.5}}, albedo: 0.9,
                 phase: {{type: hg, g: 0.5}}, balls_file: many.csv}}
            render: {{quality: draft}}
            """))
        try:
            t0 = time.perf_counter()
            img = cm.render(cm.load_scene(tmp / "many.yaml"), progress=False)
            secs = time.perf_counter() - t0
            ok = bool(np.all(np.isfinite(img)) and np.all((img[..., 3] >= 0) & (img[..., 3] <= 1)))
            cs.add(cat, f"{n} balls, {size}x{size} draft render finite", 0.0 if ok else float("inf"), 0.5,
                   ref="-", note=f"{secs:.1f} s")
        except Exception as exc:  # noqa: BLE001
            cs.crash(cat, f"{n} balls render", exc)


CATEGORIES = (tangent_single, tangent_composite, near_max_threshold, grazing_support, coincident_centres,
              radii_range, cancelling_weights, aspect_1000, far_away, inside_start, crossing_at_chord_end, many_balls)


def summarise(rows):
    out = {}
    for r in rows:
        s = out.setdefault(r["category"], dict(cases=0, failures=0, worst_ratio=0.0, worst_error=0.0, worst_case=""))
        s["cases"] += 1
        if r["status"] != "ok":
            s["failures"] += 1
        ratio = r["ratio"] if np.isfinite(r["ratio"]) else np.inf
        if ratio >= s["worst_ratio"]:
            s["worst_ratio"], s["worst_error"], s["worst_case"] = ratio, r["error"], r["case"]
    return out


def plot(summary, out):
    plt = pyplot()
    names = list(summary)
    ratios = [min(max(summary[n]["worst_ratio"], 1e-12), 1e6) for n in names]
    colours = ["C3" if summary[n]["failures"] else "C0" for n in names]
    fig, ax = plt.subplots(figsize=(8, 0.45 * len(names) + 1.5))
    ax.barh(range(len(names)), ratios, color=colours)
    ax.set_yticks(range(len(names)))
    ax.set_yticklabels([f"{n} ({summary[n]['failures']}/{summary[n]['cases']} failed)" for n in names], fontsize=8)
    ax.axvline(1.0, color="k", lw=0.8, ls="--")
    ax.set_xscale("log")
    ax.invert_yaxis()
    ax.set_xlabel("worst error / its tolerance (dashed: the criterion)")
    ax.set_title("cloudmeta: adversarial cases (red: categories with failures)")
    save_figure(fig, out)


def main(argv=None, quick=False):
    ap = parser(__doc__, quick="fewer rays per category, 20,000 instead of 100,000 balls")
    ap.add_argument("--seed", type=int, default=5)
    ap.add_argument("--no-renders", action="store_true")
    args, quick = parse(ap, argv, quick)
    rng = np.random.default_rng(args.seed)
    cs = Cases()
    start = time.perf_counter()
    timings = {}
    for fn in CATEGORIES:
        t0 = time.perf_counter()
        try:
            fn(cs, rng, quick)
        except Exception as exc:  # noqa: BLE001 - a crash of the harness is reported, not hidden
            cs.crash(fn.__name__, "harness", exc)
            traceback.print_exc()
        timings[fn.__name__] = time.perf_counter() - t0
    if not args.no_renders:
        t0 = time.perf_counter()
        renders(cs, quick)
        timings["renders"] = time.perf_counter() - t0
    elapsed = time.perf_counter() - start
    summary = summarise(cs.rows)
    print("Stability: adversarial cases (criteria in the docstring: python -m validation.accuracy.stability --help)\n")
    head = f"{'category':38s} {'cases':>5s} {'fail':>5s} {'worst err/tol':>13s} {'worst error':>11s}  worst case"
    print_head(head)
    for name, s in summary.items():
        print(f"{name:38s} {s['cases']:5d} {s['failures']:5d} {s['worst_ratio']:13.2e} {s['worst_error']:11.2e}  "
              f"{s['worst_case']}")
    total = dict(cases=sum(s["cases"] for s in summary.values()), failures=sum(s["failures"] for s in summary.values()))
    worst = max(summary.values(), key=lambda s: s["worst_ratio"])
    print("-" * len(head))
    print(f"{'all':38s} {total['cases']:5d} {total['failures']:5d} {worst['worst_ratio']:13.2e}")
    fails = [r for r in cs.rows if r["status"] != "ok"]
    if fails:
        print(f"\n{len(fails)} failing cases (first 20):")
        for r in fails[:20]:
            print(f"  [{r['status']}] {r['category']}: {r['case']}: error {r['error']:.3e} > tolerance "
                  f"{r['tolerance']:.3e}  {r['note']}")
    passed = total["failures"] == 0
    print(f"\n{'PASS' if passed else 'FAIL'}: {total['cases']} cases, {total['failures']} failures, worst error "
          f"{worst['worst_ratio']:.2e} x its tolerance   [{elapsed:.1f} s]")
    if not quick:
        write_csv("stability.csv", [dict(category=name, **s) for name, s in summary.items()])
        write_csv("stability_cases.csv", cs.rows)
        plot(summary, RESULTS / "stability.png")
        print(f"wrote {RESULTS / 'stability.csv'}, stability_cases.csv and stability.png")
    return dict(passed=passed, cases=total["cases"], failures=total["failures"], worst_ratio=worst["worst_ratio"],
                summary=summary, failing=fails, seconds=elapsed, timings=timings)


if __name__ == "__main__":
    run_main(main)
