"""Root finding per interval: Bézier clipping against Laguerre's method and a companion-matrix solver.

Three solvers find the real roots in [0, 1] of g = F - T, a degree-6 Bernstein polynomial:

- Bézier clipping: the engine's ``cloudmeta.kernels.clipping.clip_roots`` (convex hull, subdivision);
- Laguerre's method: validation/references/laguerre.py (power form, all complex roots with deflation, polished), as in
  the paper's Table 1;
- companion matrix: the power form's companion matrix, its eigenvalues by LAPACK (numpy.linalg.eigvals
  inside numba), the real ones in [0, 1] polished by two Newton steps and kept where |g| is at rounding
  level; numpy.roots (plain Python, one call per interval) is timed alongside for scale.

Intervals: the paper's (a = 1 on its whole chord, d = (0, 0, 0.59, 2.31, 0.59, 0, 0), T = -0.2, 0.5, 1.2:
validation/accuracy/root_finding_table.py, imported), four with a simple root near one end (NEAR_END), and random
composited intervals like the engine's: 1 to 5 balls' curves (cloudmeta.kernels.metaball.control_values,
random a and weights, some negative, wyvill6 or murakami4) on random chords that all cover a random interval,
each cut to it (cloudmeta.kernels.bernstein.subdivide) and added, minus a threshold (45 % chosen on the curve,
so that most intervals hold roots; 10 % at the curve's largest value, a touch: a double root where it is
interior). Time per interval: the best of several timings of a numba loop over all intervals of a group, after
warm-up. Iterations per root: clipping steps (a Python mirror of clip_roots's loop,
validation/accuracy/root_finding_table.clipping_steps) and Laguerre iterations (search + polish, over the degree's
complex roots).

    python -m validation.accuracy.root_finding [--intervals 3000] [--runs 5] [--tol 1e-9] [--quick]

Requirement: the three solvers agree on the roots (count, and positions to 1e-7) on every interval whose
roots are simple (|g'| at every root above 1e-3 of max |g|; tangencies are counted apart: clipping drops a
touch on purpose); clipping is faster than Laguerre on every group. Writes validation/results/root_finding.csv
and root_finding.png.
"""
from __future__ import annotations

import math
import time

import numpy as np
from numba import njit

from cloudmeta.kernels.bernstein import subdivide
from cloudmeta.kernels.clipping import clip_roots
from cloudmeta.kernels.metaball import MURAKAMI4, WYVILL6, control_values
from validation.accuracy.root_finding_table import D_PAPER, THRESHOLDS, clipping_scratch, clipping_steps
from validation.common import parse, parser, print_head, pyplot, run_main, save_figure, write_results
from validation.references.laguerre import bernstein_to_power, laguerre_roots, scratch as laguerre_scratch

#: intervals with a simple root near one end (found by this script's random search, and built by hand):
#: clipping converges onto the root from one side there
NEAR_END = np.array([
    [-0.0017490108556571515, 0.018314448580663445, 0.03615174477914662, 0.0074840482259058705,
     -0.08019612095467155, -0.20762489299992476, -0.32376704850891813],   # roots 0.0146110, 0.3827860
    [-1e-10, 0.3, 0.5, 0.4, 0.1, -0.2, -0.4],                              # roots 5.6e-11, 0.7217220
    [-0.4, -0.2, 0.1, 0.4, 0.5, 0.3, -1e-10],                              # its mirror: 0.2782780, 1 - 5.6e-11
    [1e-10, -0.3, -0.5, -0.4, -0.1, 0.2, 0.4],                             # sign flipped: 5.6e-11, 0.7217220
])
AGREE = 1e-7        # roots of the three solvers agree to this (in s)
SIMPLE = 1e-3       # a root is simple if |g'| there exceeds this fraction of max |g| (control values)


# --- the companion-matrix solver (numba) ----------------------------------------------------------------------

@njit(cache=True, nogil=True, error_model="numpy")
def companion_roots(c, apow, comp, out):
    """Real roots in [0, 1] of the Bernstein polynomial c via its power form's companion matrix; sorted
    into out, returns their number."""
    bernstein_to_power(c, apow)
    m = c.shape[0] - 1
    big = 0.0
    for k in range(m + 1):
        big = max(big, abs(apow[k]))
    while m > 0 and abs(apow[m]) <= 1e-14 * big:
        m -= 1
    if m == 0:
        return 0
    a = comp[:m, :m]
    a[:, :] = 0.0
    for i in range(1, m):
        a[i, i - 1] = 1.0
    for i in range(m):
        a[i, m - 1] = -apow[i] / apow[m]
    ev = np.linalg.eigvals(a.astype(np.complex128))  # complex: numba refuses a real matrix with complex eigenvalues
    n_out = 0
    for z in ev:
        if abs(z.imag) > 1e-7 or z.real < -1e-7 or z.real > 1.0 + 1e-7:
            continue
        x = z.real
        for it in range(3):  # Newton on the power form (small steps only: near a double root g' ~ 0)
            p = apow[m]
            dp = 0.0
            for k in range(m - 1, -1, -1):
                dp = dp * x + p
                p = p * x + apow[k]
            if it == 2:
                break
            if dp != 0.0 and abs(p / dp) <= 1e-6:
                x -= p / dp
        if abs(p) > 1e-9 * big:  # not a root of the real polynomial (a spurious eigenvalue)
            continue
        x = min(max(x, 0.0), 1.0)
        k = n_out
        while k > 0 and out[k - 1] > x:
            out[k] = out[k - 1]
            k -= 1
        out[k] = x
        n_out += 1
    return n_out


def companion_scratch():
    return np.empty(7), np.empty((6, 6)), np.empty(8)


# --- timing loops over a group of intervals (not cached: they inline the engine's clip_roots) ---------------------

@njit(cache=False, nogil=True, error_model="numpy")
def _loop_clip(G, tol, reps, st_lo, st_hi, st_c, roots, rising):
    acc = 0.0
    for _ in range(reps):
        for i in range(G.shape[0]):
            acc += clip_roots(G[i], tol, 0.0, st_lo, st_hi, st_c, roots, rising)
    return acc


@njit(cache=False, nogil=True, error_model="numpy")
def _loop_laguerre(G, tol, reps, apow, ad, aorig, zroots, out):
    acc = 0.0
    for _ in range(reps):
        for i in range(G.shape[0]):
            n, its, m = laguerre_roots(G[i], tol, apow, ad, aorig, zroots, out)
            acc += n
    return acc


@njit(cache=False, nogil=True, error_model="numpy")
def _loop_companion(G, tol, reps, apow, comp, out):
    acc = 0.0
    for _ in range(reps):
        for i in range(G.shape[0]):
            acc += companion_roots(G[i], apow, comp, out)
    return acc


def time_group(G, tol, runs, min_seconds=0.05):
    """ns per interval of each numba solver on the group G: best of ``runs`` timings."""
    jobs = {"clipping": (_loop_clip, clipping_scratch()), "laguerre": (_loop_laguerre, laguerre_scratch()),
            "companion": (_loop_companion, companion_scratch())}
    for fn, s in jobs.values():  # warm-up (compiles)
        fn(G[:1], tol, 1, *s)
    reps = {}
    for name, (fn, s) in jobs.items():  # calibrate: enough reps for min_seconds per timing
        t0 = time.perf_counter()
        fn(G, tol, 1, *s)
        dt = max(time.perf_counter() - t0, 1e-7)
        reps[name] = max(1, int(min_seconds / dt))
    best = {name: np.inf for name in jobs}
    for _ in range(runs):
        for name, (fn, s) in jobs.items():
            t0 = time.perf_counter()
            fn(G, tol, reps[name], *s)
            best[name] = min(best[name], (time.perf_counter() - t0) / (reps[name] * len(G)))
    return {k: v * 1e9 for k, v in best.items()}


def time_numpy_roots(G, runs=3):
    """µs per interval of numpy.roots on the power form (plain Python, conversion included)."""
    n = G.shape[1] - 1
    conv = np.zeros((n + 1, n + 1))  # power coefficients = conv @ bernstein control values
    for i in range(n + 1):
        for j in range(n - i + 1):
            conv[i + j, i] = math.comb(n, i) * math.comb(n - i, j) * (-1) ** j
    best = np.inf
    for _ in range(runs):
        t0 = time.perf_counter()
        for g in G:
            p = conv @ g
            r = np.roots(p[::-1])
            r = r[(np.abs(r.imag) <= 1e-7) & (r.real >= 0) & (r.real <= 1)]
        best = min(best, time.perf_counter() - t0)
    return best / len(G) * 1e6


# --- the intervals ----------------------------------------------------------------------------------------------

def random_intervals(rng, n):
    """n composited intervals: (n, 7) control values of g = F - T, the number of curves in each, and which
    ones touch their threshold (T = the curve's largest value: a double root where it is interior)."""
    G = np.empty((n, 7))
    ks = rng.integers(1, 6, n)
    touch = np.zeros(n, bool)
    cv, part = np.empty(7), np.empty(7)
    for i in range(n):
        ta, tb = np.sort(rng.uniform(0.0, 1.0, 2))
        if tb - ta < 1e-3:
            tb = ta + 1e-3
        kernel = WYVILL6 if rng.random() < 0.7 else MURAKAMI4
        f = np.zeros(7)
        for _ in range(ks[i]):
            t0 = ta - rng.uniform(0.0, 1.0)
            t1 = tb + rng.uniform(0.0, 1.0)
            a = rng.uniform(0.05, 1.0)
            q = rng.uniform(0.5, 1.5) if rng.random() < 0.8 else -rng.uniform(0.2, 1.0)
            control_values(kernel, a, q, cv)
            subdivide(cv, (ta - t0) / (t1 - t0), (tb - t0) / (t1 - t0), part)
            f += part
        u = rng.random()
        T = _max_value(f) if u < 0.1 else None
        if T is not None:  # the curve's largest value, where it is interior: a touch (double root)
            touch[i] = True
        elif u < 0.55:  # a threshold on the curve: most such intervals hold a root
            T = _bernstein(f, rng.uniform(0.0, 1.0))
        else:
            T = rng.uniform(0.1, 1.2)
        G[i] = f - T
    return G, ks, touch


def _bernstein(c, s):
    n = len(c) - 1
    return float(sum(c[j] * math.comb(n, j) * s ** j * (1 - s) ** (n - j) for j in range(n + 1)))


_GRID = np.linspace(0.0, 1.0, 2001)
_GRID_BASIS = np.array([[math.comb(6, j) * x ** j * (1 - x) ** (6 - j) for j in range(7)] for x in _GRID])


def _max_value(c):
    """The curve's largest value on [0, 1] if it lies inside (a fine grid, then golden-section search)."""
    s = _GRID
    v = _GRID_BASIS @ c
    k = int(np.argmax(v))
    if k in (0, 2000):
        return None  # the largest value is at an end: no touch there
    lo, hi = s[max(k - 1, 0)], s[min(k + 1, 2000)]
    g = (math.sqrt(5) - 1) / 2
    for _ in range(80):
        a, b = hi - g * (hi - lo), lo + g * (hi - lo)
        if _bernstein(c, a) > _bernstein(c, b):
            hi = b
        else:
            lo = a
    return max(_bernstein(c, 0.5 * (lo + hi)), v[k])


def bernstein_derivative_at(c, s):
    n = len(c) - 1
    d = n * np.diff(c)
    return float(sum(d[j] * math.comb(n - 1, j) * s ** j * (1 - s) ** (n - 1 - j) for j in range(n)))


def solve_all(G, tol):
    """Roots of every interval by the three solvers, with clipping steps and Laguerre iterations."""
    cs, ls, ks = clipping_scratch(), laguerre_scratch(), companion_scratch()
    out = []
    for g in G:
        g = np.ascontiguousarray(g)
        n = clip_roots(g, tol, 0.0, *cs)
        r_clip = cs[3][:n].copy()
        n, its, m = laguerre_roots(g, tol, *ls)
        r_lag = ls[4][:n].copy()
        n = companion_roots(g, *ks)
        r_comp = ks[2][:n].copy()
        steps, _ = clipping_steps(g, tol)
        scale = np.abs(g).max()
        simple = all(abs(bernstein_derivative_at(g, r)) > SIMPLE * scale for r in r_comp) and \
            all(abs(bernstein_derivative_at(g, r)) > SIMPLE * scale for r in r_lag)
        out.append(dict(clip=r_clip, lag=r_lag, comp=r_comp, steps=steps, lag_its=its, degree=m, simple=simple))
    return out


def agree(a, b):
    return len(a) == len(b) and (len(a) == 0 or float(np.abs(a - b).max()) <= AGREE)


def group_row(name, G, sol, tol, runs, numpy_too=True):
    t = time_group(np.ascontiguousarray(G), tol, runs)
    simple = [s for s in sol if s["simple"]]
    n_roots = sum(len(s["comp"]) for s in sol)
    n_clip_roots = sum(len(s["clip"]) for s in sol)
    diffs = [float(np.abs(s[k] - s["comp"]).max()) for s in simple for k in ("clip", "lag")
             if len(s["comp"]) and agree(s[k], s["comp"])]
    return dict(group=name, intervals=len(G), roots=n_roots, tangent_intervals=len(sol) - len(simple),
                clip_ns=t["clipping"], laguerre_ns=t["laguerre"], companion_ns=t["companion"],
                numpy_roots_us=time_numpy_roots(G) if numpy_too else float("nan"),
                clip_steps_per_interval=float(np.mean([s["steps"] for s in sol])),
                clip_steps_per_root=(sum(s["steps"] for s in sol if len(s["clip"])) / n_clip_roots
                                     if n_clip_roots else float("nan")),
                laguerre_its_per_root=float(sum(s["lag_its"] for s in sol) / max(1, sum(s["degree"] for s in sol))),
                clip_vs_companion_mismatch=sum(not agree(s["clip"], s["comp"]) for s in simple),
                laguerre_vs_companion_mismatch=sum(not agree(s["lag"], s["comp"]) for s in simple),
                tangent_mismatch=sum(not agree(s["clip"], s["comp"]) for s in sol if not s["simple"]),
                max_root_diff=max(diffs) if diffs else 0.0)


def plot(rows, out):
    plt = pyplot()
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 4.5))
    x = np.arange(len(rows))
    wdt = 0.27
    for k, (key, label) in enumerate((("clip_ns", "Bézier clipping"), ("laguerre_ns", "Laguerre"),
                                      ("companion_ns", "companion matrix (LAPACK)"))):
        ax1.bar(x + (k - 1) * wdt, [r[key] for r in rows], wdt, label=label)
    ax1.set_yscale("log")
    ax1.set_xticks(x)
    ax1.set_xticklabels([r["group"] for r in rows], rotation=30, ha="right", fontsize=7)
    ax1.set_ylabel("ns per interval (numba, best of runs)")
    ax1.set_title("time per interval")
    ax1.legend(fontsize=8)
    ax2.bar(x - 0.27, [r["clip_steps_per_interval"] for r in rows], 0.27, label="clipping steps per interval")
    ax2.bar(x, np.nan_to_num([r["clip_steps_per_root"] for r in rows]), 0.27, label="clipping steps per root")
    ax2.bar(x + 0.27, [r["laguerre_its_per_root"] for r in rows], 0.27, label="Laguerre iterations per root")
    ax2.set_xticks(x)
    ax2.set_xticklabels([r["group"] for r in rows], rotation=30, ha="right", fontsize=7)
    ax2.set_title("iterations (no bar for 'per root': the group has no roots)")
    ax2.legend(fontsize=8)
    save_figure(fig, out)


def main(argv=None, quick=False):
    ap = parser(__doc__, quick="150 intervals, one timing")
    ap.add_argument("--intervals", type=int, default=None, help="random intervals (default 3000; 150 quick)")
    ap.add_argument("--runs", type=int, default=None,
                    help="timings per solver and group, best kept (default 5; 1 quick)")
    ap.add_argument("--tol", type=float, default=1e-9, help="root tolerance in s (default 1e-9)")
    ap.add_argument("--seed", type=int, default=4)
    args, quick = parse(ap, argv, quick)
    n = args.intervals or (150 if quick else 3000)
    runs = args.runs or (1 if quick else 5)
    tol = args.tol
    start = time.perf_counter()
    rng = np.random.default_rng(args.seed)
    rows = []
    for T in THRESHOLDS:
        g = (D_PAPER - T)[None, :]
        rows.append(group_row(f"paper T={T}", g, solve_all(g, tol), tol, runs))
    near = solve_all(NEAR_END, tol)
    rows.append(group_row("roots near an end", NEAR_END, near, tol, runs))
    G, ks, touch = random_intervals(rng, n)
    sol = solve_all(G, tol)
    nroots = np.array([len(s["comp"]) for s in sol])
    groups = [("random, 0 roots", (nroots == 0) & ~touch), ("random, 1 root", (nroots == 1) & ~touch),
              ("random, 2+ roots", (nroots >= 2) & ~touch), ("random, T = max", touch),
              ("random, 1 curve", ks == 1), ("random, 4-5 curves", ks >= 4), ("random, all", np.ones(n, bool))]
    for name, sel in groups:
        if np.any(sel):
            idx = np.flatnonzero(sel)
            rows.append(group_row(name, G[idx], [sol[i] for i in idx], tol, runs))
    elapsed = time.perf_counter() - start

    print("Root finding per interval: Bézier clipping vs Laguerre vs companion matrix (degree 6, tol "
          f"{tol:g} in s)\n")
    head = (f"{'group':20s} {'ivals':>5s} {'roots':>5s} {'clip ns':>8s} {'Lag ns':>8s} {'comp ns':>8s} "
            f"{'np.roots us':>11s} {'Lag/clip':>8s} {'clip st/iv':>10s} {'clip st/root':>12s} {'Lag it/root':>11s} "
            f"{'mismatch':>8s} {'tangent':>7s} {'max dr':>8s}")
    print_head(head)
    for r in rows:
        print(f"{r['group']:20s} {r['intervals']:5d} {r['roots']:5d} {r['clip_ns']:8.1f} {r['laguerre_ns']:8.1f} "
              f"{r['companion_ns']:8.1f} {r['numpy_roots_us']:11.1f} {r['laguerre_ns'] / r['clip_ns']:7.1f}x "
              f"{r['clip_steps_per_interval']:10.2f} {r['clip_steps_per_root']:12.2f} "
              f"{r['laguerre_its_per_root']:11.2f} "
              f"{r['clip_vs_companion_mismatch'] + r['laguerre_vs_companion_mismatch']:8d} "
              f"{r['tangent_intervals']:7d} {r['max_root_diff']:8.1e}")
    print("\nclip st/iv: clipping steps per interval (1 = the convex-hull test alone); clip st/root: steps of the "
          "intervals with roots per root;\nLag it/root: Laguerre iterations per (complex) root of the power form; "
          "mismatch: intervals with simple roots where clipping or\nLaguerre disagree with the companion solver "
          f"(count, or a root off by more than {AGREE:g}); tangent: intervals with a near-double root\n"
          f"(|g'| <= {SIMPLE:g} max|g|), excluded from the mismatch count (clipping drops touches on purpose); "
          "max dr: largest root difference.")
    every = list(zip(NEAR_END, near)) + list(zip(G, sol))
    bad, seen = [], set()
    for g, s in every:
        if s["simple"] and not (agree(s["clip"], s["comp"]) and agree(s["lag"], s["comp"])) and tuple(g) not in seen:
            seen.add(tuple(g))
            bad.append((g, s))
    if bad:
        print(f"\nintervals with simple roots where the solvers disagree ({len(bad)} distinct; first 6):")
        for g, s in bad[:6]:
            print(f"  g = [{', '.join(repr(float(x)) for x in g)}]\n    clipping {s['clip'].tolist()}, "
                  f"Laguerre {s['lag'].tolist()}, companion {s['comp'].tolist()}")
    mismatch = sum(r["clip_vs_companion_mismatch"] + r["laguerre_vs_companion_mismatch"] for r in rows
                   if r["group"] != "random, all" and not r["group"].startswith("random, 1 curve")
                   and not r["group"].startswith("random, 4"))
    faster = all(r["clip_ns"] < r["laguerre_ns"] for r in rows)
    passed = mismatch == 0 and faster
    print(f"\n{'PASS' if passed else 'FAIL'}: solvers agree on every interval with simple roots "
          f"({'yes' if mismatch == 0 else f'NO: {mismatch}'}); clipping faster than Laguerre on every group "
          f"({'yes' if faster else 'NO'})   [{elapsed:.1f} s]")
    if not quick:
        write_results("root_finding", rows, plot)
    return dict(rows=rows, passed=passed, mismatches=mismatch, seconds=elapsed)


if __name__ == "__main__":
    run_main(main)
