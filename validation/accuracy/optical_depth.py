"""Optical depth of every kernel, density mode and ball shape against adaptive quadrature, on random scenes
of 1 to 2,000 balls.

For each kernel (wyvill6, murakami4, nishimura, blinn), density mode (field, excess, uniform) and shape
(spheres, rotated ellipsoids), random blobs of 1, 3, 10, 100 and 2,000 balls (two of each size but 1: all
weights positive, and some negative) are crossed by random rays from outside (half aimed at a ball);
cm.optical_depth is compared with the reference of validation/accuracy/optical_depth_vs_quadrature.py
(scipy.integrate.quad of sigma_t on the plain numpy field of docs/model.md §1, between break points: chord ends,
the engine's roots and independently found roots), whose functions are imported here. On a big blob the
reference only sees the balls the ray meets (the others are 0 on the ray), which keeps quad affordable.

Every kernel is traceable: nishimura and blinn are checked like the others, against quad with roots found
on a fine sampling refined by brentq (these kernels are not polynomials on a chord). A kernel the engine
could not trace (cm.optical_depth raising cloudmeta.InputError) would be listed as "not traceable yet"
rather than left out.

    python -m validation.accuracy.optical_depth [--rays-per-blob 16] [--seed 2] [--quick]

Requirement: relative error below 1e-9 on every ray with a positive reference (and |tau| <= 1e-12 where
the reference is 0). Writes validation/results/optical_depth.csv (per case), optical_depth_sizes.csv
(per scene size) and optical_depth.png.
"""
from __future__ import annotations

import itertools
import time
import warnings

import numpy as np
from scipy.integrate import IntegrationWarning, quad
from scipy.optimize import brentq

import cloudmeta as cm
from validation.accuracy.optical_depth_vs_quadrature import PlainBlob, random_rays, reference_ray
from validation.common import RESULTS, parse, parser, print_head, pyplot, run_main, save_figure, write_csv

REL_LIMIT = 1e-9
ZERO_ABS_LIMIT = 1e-12
KERNELS = ("wyvill6", "murakami4", "nishimura", "blinn")
DENSITIES = ("field", "excess", "uniform")
SHAPES = ("spheres", "ellipsoids")
SIZES = (1, 3, 10, 100, 2000)
QUICK_SIZES = (1, 10, 200)
BLOBBINESS = 4.0


class AnyKernelBlob(PlainBlob):
    """PlainBlob with every kernel of docs/model.md §1 (the imported reference knows the two polynomial ones)."""

    def k(self, u):
        if self.kernel in ("wyvill6", "murakami4"):
            return super().k(u)
        inside = u < 1.0
        if self.kernel == "nishimura":
            val = np.where(u <= 1.0 / 9.0, 1.0 - 3.0 * u, 1.5 * (1.0 - np.sqrt(np.clip(u, 0.0, None))) ** 2)
        else:
            val = np.exp(-BLOBBINESS * u)
        return np.where(inside, val, 0.0)

    def field_many(self, xs):
        """(M,) F at the points xs (M, 3), vectorised: the same sum as ``field`` point by point."""
        p = np.einsum("nij,mnj->mni", self.m, xs[:, None, :] - self.centers[None, :, :])
        return self.k(np.einsum("mni,mni->mn", p, p)) @ self.weights


def restricted(plain, idx):
    """The same blob with only the balls ``idx`` (those the ray meets: the others are 0 on the ray)."""
    sub = object.__new__(type(plain))
    sub.centers, sub.m, sub.weights = plain.centers[idx], plain.m[idx], plain.weights[idx]
    sub.kernel, sub.threshold = plain.kernel, plain.threshold
    return sub


def random_blob(rng, n, kernel, shape, negative):
    """n balls in a box whose size keeps the overlap alike for every n (as optical_depth_vs_quadrature)."""
    half = 1.1 * (max(n, 5) / 5.0) ** (1.0 / 3.0)
    centers = rng.uniform(-half, half, (n, 3))
    if shape == "spheres":
        radii = rng.uniform(0.5, 2.0, n)
        radii3, angles = np.repeat(radii[:, None], 3, axis=1), None
    else:
        rmax = rng.uniform(1.0, 2.0, n)
        radii3 = rng.permuted(np.stack([rmax, rng.uniform(np.maximum(0.5, rmax / 4), rmax),
                                        rng.uniform(np.maximum(0.5, rmax / 4), rmax)], axis=1), axis=1)
        radii, angles = radii3, rng.uniform(-180.0, 180.0, (n, 3))
    w = rng.uniform(0.5, 1.5, n)
    if negative and n > 1:
        neg = rng.random(n) < 0.3
        neg[rng.integers(n)] = True
        w[neg] = -rng.uniform(0.2, 1.2, neg.sum())
    threshold = float(rng.uniform(0.25, 0.6))
    blob = cm.Blob(centers, radii, w, kernel=kernel, threshold=threshold, rotations=angles, blobbiness=BLOBBINESS)
    plain = AnyKernelBlob(centers, radii3, angles, w, kernel, threshold)
    return blob, plain, half


def reference_generic(plain, o, d, mode, scale, engine_roots):
    """quad of sigma_t for a non-polynomial kernel: break points at chord ends, engine roots, the nishimura
    kink (u = 1/9) and roots found on a fine sampling of every chord interval, refined by brentq."""
    from validation.accuracy.optical_depth_vs_quadrature import sigma_t
    t0, t1, hit, (A, b, c0) = plain.chords(o, d)
    ends = np.unique(np.concatenate([t0[hit], t1[hit]]))
    if len(ends) == 0:
        return 0.0
    extra = []
    if plain.kernel == "nishimura":  # u(t) = A t^2 + 2 b t + c0 = 1/9
        for i in np.flatnonzero(hit):
            disc = b[i] ** 2 - A[i] * (c0[i] - 1.0 / 9.0)
            if disc > 0:
                extra += [(-b[i] - np.sqrt(disc)) / A[i], (-b[i] + np.sqrt(disc)) / A[i]]
    g = lambda t: plain.field(o + t * d) - plain.threshold  # noqa: E731
    for ta, tb in zip(ends[:-1], ends[1:]):
        s = np.linspace(ta, tb, 401)
        v = plain.field_many(o + s[:, None] * d) - plain.threshold  # brackets; brentq refines with g
        for k in np.flatnonzero((v[:-1] >= 0) != (v[1:] >= 0)):
            extra.append(brentq(g, s[k], s[k + 1], xtol=1e-15, rtol=8.9e-16))
    breaks = np.unique(np.concatenate([ends, np.asarray(engine_roots, float), extra]))
    total = 0.0
    for ta, tb in zip(breaks[:-1], breaks[1:]):
        if tb > ta and np.any(hit & (t0 < tb) & (t1 > ta)):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", IntegrationWarning)
                total += quad(lambda t: sigma_t(plain, o, d, t, mode, scale), ta, tb, epsabs=0.0, epsrel=1e-13,
                              limit=200)[0]
    return float(total)


def traceable(kernel):
    """True if cm.optical_depth accepts the kernel; the engine's message otherwise."""
    blob = cm.Blob([[0.0, 0.0, 0.0]], [1.0], [1.0], kernel=kernel)
    try:
        cm.optical_depth(blob, [[-3.0, 0.0, 0.0]], [[1.0, 0.0, 0.0]])
    except cm.InputError as exc:
        return str(exc)
    return True


def aimed_rays(rng, m, half, centers):
    """random_rays (from outside, at random points of the box), half of them re-aimed at a random ball's
    centre (jittered) so that most rays meet the blob."""
    o, d = random_rays(rng, m, half)
    k = rng.random(m) < 0.5
    tgt = centers[rng.integers(len(centers), size=k.sum())] + rng.uniform(-0.4, 0.4, (k.sum(), 3))
    d[k] = tgt - o[k]
    d[k] /= np.linalg.norm(d[k], axis=1)[:, None]
    return o, d


def run_case(rng, case, sizes, rays_per_blob):
    kernel, density, shape = case
    rows = []
    for n, negative in itertools.product(sizes, (False, True)):
        if negative and n == 1:
            continue
        blob, plain, half = random_blob(rng, n, kernel, shape, negative=negative)
        m = max(4, rays_per_blob // 2) if n >= 1000 else rays_per_blob
        o, d = aimed_rays(rng, m, half, blob.centers)
        scale = float(rng.uniform(0.5, 3.0))
        tau = cm.optical_depth(blob, o, d, density=density, scale=scale)
        eroots = cm.roots(blob, o, d)
        for r in range(m):
            t0, t1, hit, _ = plain.chords(o[r], d[r])
            sub = restricted(plain, np.flatnonzero(hit))
            if kernel in ("wyvill6", "murakami4"):
                ref = reference_ray(sub, o[r], d[r], density, scale, eroots[r])[0]
            else:
                ref = reference_generic(sub, o[r], d[r], density, scale, eroots[r])
            err = abs(tau[r] - ref)
            rows.append(dict(kernel=kernel, density=density, shape=shape, n_balls=n, balls_on_ray=int(hit.sum()),
                             negative=negative, tau=float(tau[r]), ref=ref, abs_err=err, zero_ref=ref == 0.0,
                             rel_err=err / ref if ref != 0.0 else np.nan, finite=bool(np.isfinite(tau[r]))))
    return rows


def summarise(rows):
    rel = np.array([r["rel_err"] for r in rows if not r["zero_ref"]])
    zero = np.array([r["abs_err"] for r in rows if r["zero_ref"]])
    ok = (bool(np.all(rel < REL_LIMIT)) if len(rel) else True) and \
         (bool(np.all(zero <= ZERO_ABS_LIMIT)) if len(zero) else True) and all(r["finite"] for r in rows)
    return dict(rays=len(rows), hit=len(rel), zero=len(zero),
                max_rel=float(rel.max()) if len(rel) else 0.0, median_rel=float(np.median(rel)) if len(rel) else 0.0,
                max_zero_abs=float(zero.max()) if len(zero) else 0.0,
                max_balls_on_ray=max((r["balls_on_ray"] for r in rows), default=0), passed=ok)


def plot(rows, per_case, out):
    plt = pyplot()
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 5), gridspec_kw=dict(width_ratios=[1.1, 1]))
    labels, mx, md, colours = [], [], [], []
    for case, s in per_case.items():
        labels.append("/".join(case) + ("" if s.get("status") != "not traceable yet" else "  (not traceable yet)"))
        mx.append(s["max_rel"] if s.get("rays") else np.nan)
        md.append(s["median_rel"] if s.get("rays") else np.nan)
        colours.append("C0" if case[0] == "wyvill6" else "C1" if case[0] == "murakami4" else "grey")
    y = np.arange(len(labels))
    tiny = 1e-18
    ax1.scatter(np.maximum(np.nan_to_num(mx, nan=tiny), tiny), y, marker="o", c=colours, label="max")
    ax1.scatter(np.maximum(np.nan_to_num(md, nan=tiny), tiny), y, marker="|", c=colours, s=120, label="median")
    for k, v in enumerate(mx):
        if not np.isfinite(v):
            ax1.annotate("not traceable yet", (2e-18, y[k]), fontsize=6, va="center", color="grey")
    ax1.axvline(REL_LIMIT, color="k", ls="--", lw=0.8)
    ax1.set_xscale("log")
    ax1.set_xlim(1e-18, 1e-6)
    ax1.set_yticks(y)
    ax1.set_yticklabels(labels, fontsize=6)
    ax1.invert_yaxis()
    ax1.set_xlabel("relative error (o: max, |: median); dashed: 1e-9")
    ax1.set_title("per case: kernel / density / shape", fontsize=9)
    jit = np.random.default_rng(0)
    for kernel, colour in (("wyvill6", "C0"), ("murakami4", "C1"), ("nishimura", "C2"), ("blinn", "C3")):
        pts = [r for r in rows if r["kernel"] == kernel and not r["zero_ref"]]
        if pts:
            n = np.array([r["n_balls"] for r in pts]) * np.exp(jit.normal(0, 0.08, len(pts)))
            ax2.scatter(n, np.maximum([r["rel_err"] for r in pts], tiny), s=6, alpha=0.5, color=colour, label=kernel)
    ax2.axhline(REL_LIMIT, color="k", ls="--", lw=0.8)
    ax2.set_xscale("log")
    ax2.set_yscale("log")
    ax2.set_ylim(1e-18, 1e-6)
    ax2.set_xlabel("balls in the scene")
    ax2.set_ylabel("relative error of tau, per ray (0 shown at 1e-18)")
    ax2.set_title("every ray, against the scene's size", fontsize=9)
    ax2.legend(fontsize=8)
    fig.suptitle("cloudmeta.optical_depth against scipy quad of the plain field")
    save_figure(fig, out)


def main(argv=None, quick=False):
    ap = parser(__doc__, quick="smaller scenes and fewer rays, for the test")
    ap.add_argument("--rays-per-blob", type=int, default=None, help="rays per blob (default 16; 4 quick; half on "
                                                                     "the 2,000-ball blobs)")
    ap.add_argument("--seed", type=int, default=2)
    args, quick = parse(ap, argv, quick)
    rays = args.rays_per_blob or (4 if quick else 16)
    sizes = QUICK_SIZES if quick else SIZES
    rng = np.random.default_rng(args.seed)
    start = time.perf_counter()
    status = {k: traceable(k) for k in KERNELS}
    rows, per_case = [], {}
    for case in itertools.product(KERNELS, DENSITIES, SHAPES):
        if status[case[0]] is not True:
            per_case[case] = dict(rays=0, hit=0, zero=0, max_rel=np.nan, median_rel=np.nan, max_zero_abs=np.nan,
                                  max_balls_on_ray=0, passed=True, status="not traceable yet")
            continue
        case_rows = run_case(rng, case, sizes, rays)
        rows += case_rows
        per_case[case] = dict(summarise(case_rows), status="checked")
    overall = summarise(rows)
    by_size = {n: summarise([r for r in rows if r["n_balls"] == n]) for n in sizes}
    elapsed = time.perf_counter() - start

    print("Optical depth: cm.optical_depth against scipy quad of the plain field (docs/model.md §1, §4)")
    print(f"scenes of {', '.join(map(str, sizes))} balls per case (positive weights; and with negative ones); "
          f"{rays} rays per scene ({max(4, rays // 2)} on scenes of 1,000+)\n")
    head = (f"{'kernel':10s} {'density':8s} {'shape':10s} {'rays':>5s} {'hit':>4s} {'max rel':>9s} {'median rel':>10s} "
            f"{'max|tau| (0)':>12s} {'balls/ray':>9s}  result")
    print_head(head)
    for case, s in per_case.items():
        if s["status"] != "checked":
            print(f"{case[0]:10s} {case[1]:8s} {case[2]:10s} {'-':>5s} {'-':>4s} {'-':>9s} {'-':>10s} {'-':>12s} "
                  f"{'-':>9s}  not traceable yet")
            continue
        print(f"{case[0]:10s} {case[1]:8s} {case[2]:10s} {s['rays']:5d} {s['hit']:4d} {s['max_rel']:9.2e} "
              f"{s['median_rel']:10.2e} {s['max_zero_abs']:12.1e} {s['max_balls_on_ray']:9d}  "
              f"{'PASS' if s['passed'] else 'FAIL'}")
    print("-" * len(head))
    print(f"{'all':30s} {overall['rays']:5d} {overall['hit']:4d} {overall['max_rel']:9.2e} "
          f"{overall['median_rel']:10.2e} {overall['max_zero_abs']:12.1e} {overall['max_balls_on_ray']:9d}  "
          f"{'PASS' if overall['passed'] else 'FAIL'}")
    print("\nby scene size:")
    for n, s in by_size.items():
        print(f"  {n:5d} balls: {s['rays']:5d} rays, max rel {s['max_rel']:.2e}, median rel {s['median_rel']:.2e}, "
              f"up to {s['max_balls_on_ray']} balls on a ray")
    untraced = [k for k, v in status.items() if v is not True]
    if untraced:
        print(f"not traceable yet: {', '.join(untraced)} (cm.optical_depth raises InputError: "
              f"{status[untraced[0]]!r})")
    print(f"\n{'PASS' if overall['passed'] else 'FAIL'}: max relative error {overall['max_rel']:.2e} (limit "
          f"{REL_LIMIT:g}) over {overall['hit']} rays; max |tau| on {overall['zero']} zero-reference rays "
          f"{overall['max_zero_abs']:.1e} (limit {ZERO_ABS_LIMIT:g})   [{elapsed:.1f} s]")
    if not quick:
        keys = ["rays", "hit", "zero", "max_rel", "median_rel", "max_zero_abs", "max_balls_on_ray", "passed", "status"]
        write_csv("optical_depth.csv", [list(case) + [s[k] for k in keys] for case, s in per_case.items()]
                  + [["all", "", ""] + [overall.get(k, "") for k in keys]], ["kernel", "density", "shape"] + keys)
        write_csv("optical_depth_sizes.csv", [[n] + [s[k] for k in keys[:-1]] for n, s in by_size.items()],
                  ["n_balls"] + keys[:-1])
        plot(rows, per_case, RESULTS / "optical_depth.png")
        print(f"wrote {RESULTS / 'optical_depth.csv'}, optical_depth_sizes.csv and optical_depth.png")
    return dict(passed=overall["passed"], max_rel_err=overall["max_rel"], median_rel_err=overall["median_rel"],
                rays=overall["rays"], per_case=per_case, by_size=by_size, not_traceable=untraced, seconds=elapsed)


if __name__ == "__main__":
    run_main(main)
