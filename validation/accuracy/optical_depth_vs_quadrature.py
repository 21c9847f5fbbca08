"""cloudmeta.optical_depth (exact, Bernstein means) against adaptive quadrature of the plain field.

Random blobs (5-40 balls in a box; spheres or rotated ellipsoids; positive or some negative weights;
wyvill6 or murakami4) and random rays from outside aimed at random points of the box. For every ray the
reference is scipy.integrate.quad of sigma_t(t) = scale * rho(F(x(t))) (docs/model.md §4), where F is evaluated
here by plain numpy from docs/model.md §1 (not cm.field; rotations from scipy's Rotation, not the engine's). The
integral is taken piece by piece between break points: every chord end (plain sphere/ellipsoid formula),
every root reported by cm.roots, and every root found here independently (power-form polynomial of F on
each chord interval, refined by brentq on the plain field), so that the integrand is a smooth polynomial
on every piece.

    python -m validation.accuracy.optical_depth_vs_quadrature [--rays 3000] [--seed 1] [--quick]

Requirement: max relative error below 1e-9 on every ray; rays whose reference is 0 must give
tau = 0 to 1e-12 absolute. Writes validation/results/optical_depth_vs_quadrature.csv (per case) and, with
--per-ray-csv, optical_depth_vs_quadrature_rays.csv (every ray, to reproduce any of them).
"""
from __future__ import annotations

import itertools
import time
import warnings

from validation.common import cache_note, fresh_kernels_when_run, parse, parser, print_head, run_main, write_csv

fresh_kernels_when_run(__name__)  # before cloudmeta is imported

import numpy as np
from numpy.polynomial import Polynomial
from scipy.integrate import IntegrationWarning, quad
from scipy.optimize import brentq
from scipy.spatial.transform import Rotation

import cloudmeta as cm

REL_LIMIT = 1e-9      # the requirement on every ray
ZERO_ABS_LIMIT = 1e-12  # rays whose reference is 0
TINY = 1e-300
SLIVER = 1e-10          # pieces narrower than this (in t) are integrated by the midpoint rule

KERNELS = ("wyvill6", "murakami4")
SHAPES = ("spheres", "ellipsoids")
WEIGHTS = ("positive", "negative")
DENSITIES = ("field", "excess", "uniform")

#: k(u) in power form, for u < 1 (docs/model.md §1)
K_POWER = {"wyvill6": Polynomial([1.0, -22.0 / 9.0, 17.0 / 9.0, -4.0 / 9.0]),
           "murakami4": Polynomial([1.0, -2.0, 1.0])}


# --- the plain model (docs/model.md §1), independent of the engine -----------------------------------------------

class PlainBlob:
    """The same balls as a cm.Blob, with u_i(x) = |S^-1 Q^T (x - c)|^2 computed here."""

    def __init__(self, centers, radii3, angles, weights, kernel, threshold):
        self.centers = np.asarray(centers, dtype=np.float64)
        q = (np.broadcast_to(np.eye(3), (len(centers), 3, 3)) if angles is None
             else Rotation.from_euler("xyz", angles, degrees=True).as_matrix())  # Q = Rz Ry Rx
        self.m = np.transpose(q, (0, 2, 1)) / np.asarray(radii3)[:, :, None]  # S^-1 Q^T
        self.weights = np.asarray(weights, dtype=np.float64)
        self.kernel = kernel
        self.threshold = float(threshold)

    def k(self, u):
        inside = u < 1.0
        v = np.where(inside, 1.0 - u, 0.0)
        if self.kernel == "wyvill6":
            return np.where(inside, v * v * (1.0 - 4.0 * u / 9.0), 0.0)
        return np.where(inside, v * v, 0.0)

    def field(self, x):
        p = np.einsum("nij,nj->ni", self.m, x[None, :] - self.centers)
        return float(np.dot(self.weights, self.k(np.einsum("ni,ni->n", p, p))))

    def ray_quadratics(self, o, d):
        """Per ball, u(t) = A t^2 + 2 b t + c0 along the ray (A = |d'|^2, b = o'.d', c0 = |o'|^2)."""
        op = np.einsum("nij,nj->ni", self.m, o[None, :] - self.centers)
        dp = self.m @ d
        return np.einsum("ni,ni->n", dp, dp), np.einsum("ni,ni->n", op, dp), np.einsum("ni,ni->n", op, op)

    def chords(self, o, d):
        """(t0, t1) of every ball the ray meets: A = |d'|^2, B = -o'.d', C = |o'|^2 - 1, D = B^2 - A C."""
        A, b, c0 = self.ray_quadratics(o, d)
        B, C = -b, c0 - 1.0
        D = B * B - A * C
        hit = D > 0.0
        sq = np.sqrt(np.where(hit, D, 0.0))
        return (B - sq) / A, (B + sq) / A, hit, (A, b, c0)


def sigma_t(blob, o, d, t, mode, scale):
    f = blob.field(o + t * d)
    if f < blob.threshold:
        return 0.0
    if mode == "field":
        return scale * f
    if mode == "excess":
        return scale * (f - blob.threshold)
    return scale


def independent_roots(blob, o, d, ta, tb, active, quad_coeffs):
    """Crossings of F = T in (ta, tb), where the balls ``active`` cover the whole interval: F is then a
    polynomial in s = (t - ta) / (tb - ta); its real roots, each refined by brentq on the plain field."""
    A, b, c0 = quad_coeffs
    w = tb - ta
    poly = Polynomial([-blob.threshold])
    for i in active:
        u = Polynomial([A[i] * ta * ta + 2 * b[i] * ta + c0[i], (2 * A[i] * ta + 2 * b[i]) * w, A[i] * w * w])
        poly = poly + blob.weights[i] * K_POWER[blob.kernel](u)
    if poly.degree() < 1 or np.all(poly.coef[1:] == 0):
        return []
    g = lambda s: blob.field(o + (ta + s * w) * d) - blob.threshold
    found = []
    for r in poly.roots():
        if abs(r.imag) > 1e-6 or not (-1e-7 <= r.real <= 1 + 1e-7):
            continue
        for h in (1e-9, 1e-7, 1e-5):
            lo, hi = max(r.real - h, 0.0), min(r.real + h, 1.0)
            if lo < hi and (g(lo) >= 0) != (g(hi) >= 0):
                s = brentq(g, lo, hi, xtol=1e-16, rtol=8.9e-16, maxiter=200)
                found.append(ta + s * w)
                break
    found.sort()
    return [t for k, t in enumerate(found) if k == 0 or t - found[k - 1] > 1e-13 * max(1.0, abs(t))]


def reference_ray(blob, o, d, mode, scale, engine_roots):
    """quad of sigma_t between break points; also returns the independently found roots."""
    t0, t1, hit, qc = blob.chords(o, d)
    ends = np.unique(np.concatenate([t0[hit], t1[hit]]))
    if len(ends) == 0:
        return 0.0, [], 0
    if ends[0] < 0:
        raise RuntimeError("ray origin inside a ball's support: the generator must start rays outside")
    my_roots = []
    for ta, tb in zip(ends[:-1], ends[1:]):
        active = np.flatnonzero(hit & (t0 <= ta) & (t1 >= tb))
        if len(active):
            my_roots += independent_roots(blob, o, d, ta, tb, active, qc)
    breaks = np.unique(np.concatenate([ends, np.asarray(engine_roots, dtype=np.float64), my_roots]))
    total = 0.0
    n_warn = 0
    for ta, tb in zip(breaks[:-1], breaks[1:]):
        if not np.any(hit & (t0 < tb) & (t1 > ta)):
            continue  # no ball on this piece: F = 0 < T, rho = 0
        if tb - ta < SLIVER:
            # a sliver between two estimates of one root (engine vs plain, ~1e-15 apart): quad only warns
            # about its own round-off there; sigma_t is smooth inside it, the midpoint rule is exact enough
            total += (tb - ta) * sigma_t(blob, o, d, 0.5 * (ta + tb), mode, scale)
            continue
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", IntegrationWarning)
            val, _ = quad(lambda t: sigma_t(blob, o, d, t, mode, scale), ta, tb, epsabs=0.0, epsrel=1e-13,
                          limit=200)
        n_warn += sum(issubclass(c.category, IntegrationWarning) for c in caught)
        total += val
    return float(total), my_roots, n_warn


# --- random scenes --------------------------------------------------------------------------------------------

def random_case_blob(rng, kernel, shape, weights_kind):
    n = int(rng.integers(5, 41))
    half = 1.1 * (n / 5.0) ** (1.0 / 3.0)  # box half-width: similar overlap whatever n
    centers = rng.uniform(-half, half, (n, 3))
    if shape == "spheres":
        radii = rng.uniform(0.5, 2.0, n)
        radii3 = np.repeat(radii[:, None], 3, axis=1)
        angles = None
    else:
        rmax = rng.uniform(1.0, 2.0, n)
        radii3 = np.stack([rmax, rng.uniform(np.maximum(0.5, rmax / 4), rmax),
                           rng.uniform(np.maximum(0.5, rmax / 4), rmax)], axis=1)
        radii3 = rng.permuted(radii3, axis=1)  # aspect up to 4, longest axis anywhere
        radii = radii3
        angles = rng.uniform(-180.0, 180.0, (n, 3))
    w = rng.uniform(0.5, 1.5, n)
    if weights_kind == "negative":
        neg = rng.random(n) < 0.3
        neg[rng.integers(n)] = True  # at least one
        w[neg] = -rng.uniform(0.2, 1.2, neg.sum())
    threshold = float(rng.uniform(0.25, 0.6))
    blob = cm.Blob(centers, radii, w, kernel=kernel, threshold=threshold, rotations=angles)
    plain = PlainBlob(centers, radii3, angles, w, kernel, threshold)
    return blob, plain, half


def random_rays(rng, n, half):
    """From a sphere well outside every support, aimed at random points of the box."""
    dist = half * np.sqrt(3.0) + 2.0 + rng.uniform(0.5, 5.0, n)
    o = rng.normal(size=(n, 3))
    o *= (dist / np.linalg.norm(o, axis=1))[:, None]
    d = rng.uniform(-half, half, (n, 3)) - o
    return o, d / np.linalg.norm(d, axis=1)[:, None]


# --- the run --------------------------------------------------------------------------------------------------

def run_case(rng, case, n_rays, rays_per_blob):
    kernel, shape, weights_kind, mode = case
    rows = []
    done = 0
    b = 0
    while done < n_rays:
        m = min(rays_per_blob, n_rays - done)
        blob, plain, half = random_case_blob(rng, kernel, shape, weights_kind)
        o, d = random_rays(rng, m, half)
        scale = float(rng.uniform(0.5, 3.0))
        tau = cm.optical_depth(blob, o, d, density=mode, scale=scale)
        eroots = cm.roots(blob, o, d)
        for r in range(m):
            ref, my_roots, n_warn = reference_ray(plain, o[r], d[r], mode, scale, eroots[r])
            err = abs(tau[r] - ref)
            er = eroots[r]
            root_diff = (float(np.max(np.abs(er - np.asarray(my_roots)))) if len(er) == len(my_roots) and len(er)
                         else (0.0 if len(er) == len(my_roots) else np.inf))
            rows.append(dict(kernel=kernel, shape=shape, weights=weights_kind, density=mode, blob=b, ray=r,
                             n_balls=len(blob), threshold=blob.threshold, scale=scale,
                             origin=o[r].tolist(), direction=d[r].tolist(),
                             tau=float(tau[r]), ref=ref, abs_err=err, zero_ref=ref == 0.0,
                             rel_err=err / max(ref, TINY) if ref != 0.0 else np.nan,
                             n_roots_engine=len(er), n_roots_plain=len(my_roots), root_diff=root_diff,
                             quad_warnings=n_warn))
        done += m
        b += 1
    return rows


def summarise(rows):
    rel = np.array([r["rel_err"] for r in rows if not r["zero_ref"]])
    zero_abs = np.array([r["abs_err"] for r in rows if r["zero_ref"]])
    rd = np.array([r["root_diff"] for r in rows])
    ok_rel = bool(np.all(rel < REL_LIMIT)) if len(rel) else True
    ok_zero = bool(np.all(zero_abs <= ZERO_ABS_LIMIT)) if len(zero_abs) else True
    return dict(rays=len(rows), hit=len(rel), zero=len(zero_abs),
                max_rel=float(rel.max()) if len(rel) else 0.0,
                median_rel=float(np.median(rel)) if len(rel) else 0.0,
                max_zero_abs=float(zero_abs.max()) if len(zero_abs) else 0.0,
                root_count_mismatch=int(np.sum(~np.isfinite(rd))),
                max_root_diff=float(rd[np.isfinite(rd)].max()) if np.any(np.isfinite(rd)) else 0.0,
                quad_warnings=int(sum(r["quad_warnings"] for r in rows)),
                passed=ok_rel and ok_zero)


def print_table(per_case, overall, file=None):
    head = (f"{'kernel':<10} {'shape':<10} {'weights':<8} {'density':<8} {'rays':>5} {'hit':>5} {'max rel':>9} "
            f"{'median rel':>10} {'zero-ref':>8} {'max abs(0)':>10} {'roots #!=':>9} {'max dt root':>11} "
            f"{'quadW':>5}  result")
    print_head(head, file)
    for case, s in list(per_case.items()) + [(("overall", "", "", ""), overall)]:
        print(f"{case[0]:<10} {case[1]:<10} {case[2]:<8} {case[3]:<8} {s['rays']:>5} {s['hit']:>5} "
              f"{s['max_rel']:>9.2e} {s['median_rel']:>10.2e} {s['zero']:>8} {s['max_zero_abs']:>10.1e} "
              f"{s['root_count_mismatch']:>9} {s['max_root_diff']:>11.1e} {s['quad_warnings']:>5}  "
              f"{'PASS' if s['passed'] else 'FAIL'}", file=file)


def main(argv=None, quick=False):
    ap = parser(__doc__, quick="about 200 rays", no_csv=True)
    ap.add_argument("--rays", type=int, default=None, help="rays in total (default 3000; 200 with --quick)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--per-ray-csv", action="store_true",
                    help="also write every ray (origin, direction, tau, reference) to *_rays.csv (large)")
    args, quick = parse(ap, argv, quick)
    write = not (args.no_csv or quick)  # quick runs (tests) leave the full run's results alone
    total = args.rays if args.rays is not None else (200 if quick else 3000)
    cases = list(itertools.product(KERNELS, SHAPES, WEIGHTS, DENSITIES))
    per = [total // len(cases) + (1 if k < total % len(cases) else 0) for k in range(len(cases))]
    rng = np.random.default_rng(args.seed)
    t_start = time.perf_counter()
    rows, per_case = [], {}
    for case, n in zip(cases, per):
        case_rows = run_case(rng, case, n, rays_per_blob=25) if n else []
        rows += case_rows
        per_case[case] = summarise(case_rows)
    overall = summarise(rows)
    elapsed = time.perf_counter() - t_start

    print("Optical depth: cm.optical_depth vs scipy quad of the plain field (docs/model.md §4)")
    print(cache_note())
    print(f"{len(rows)} rays, seed {args.seed}; requirement: relative error < {REL_LIMIT:g} on every ray, "
          f"|tau| <= {ZERO_ABS_LIMIT:g} where the reference is 0\n")
    print_table(per_case, overall)
    print("\nhit: rays with reference tau > 0; zero-ref: rays with reference 0 (their error is absolute, "
          "'max abs(0)');\nroots #!=: rays where cm.roots and the independent roots differ in number; "
          "max dt root: largest |t_engine - t_plain|;\nquadW: scipy IntegrationWarnings.")
    hit_rows = [r for r in rows if not r["zero_ref"]]
    if hit_rows:
        worst = max(hit_rows, key=lambda r: r["rel_err"])
        print(f"\nworst ray: {worst['kernel']}/{worst['shape']}/{worst['weights']}/{worst['density']} "
              f"blob {worst['blob']} ray {worst['ray']}: tau = {worst['tau']!r}, ref = {worst['ref']!r}, "
              f"rel err = {worst['rel_err']:.2e}")
    print(f"\n{'PASS' if overall['passed'] else 'FAIL'}: max relative error {overall['max_rel']:.2e} "
          f"(limit {REL_LIMIT:g}) over {overall['hit']} rays; max |tau| on {overall['zero']} zero-reference "
          f"rays {overall['max_zero_abs']:.1e} (limit {ZERO_ABS_LIMIT:g})   [{elapsed:.1f} s]")

    if write:
        keys = list(overall)
        write_csv("optical_depth_vs_quadrature.csv",
                  [list(case) + [s[k] for k in keys]
                   for case, s in list(per_case.items()) + [(("overall", "", "", ""), overall)]],
                  ["kernel", "shape", "weights", "density"] + keys)
    if args.per_ray_csv and write:
        write_csv("optical_depth_vs_quadrature_rays.csv", rows)
    return dict(rays=overall["rays"], max_rel_err=overall["max_rel"], median_rel_err=overall["median_rel"],
                max_zero_abs_err=overall["max_zero_abs"], zero_ref_rays=overall["zero"],
                root_count_mismatch=overall["root_count_mismatch"], max_root_diff=overall["max_root_diff"],
                passed=overall["passed"], per_case=per_case, seconds=elapsed)


if __name__ == "__main__":
    run_main(main)
