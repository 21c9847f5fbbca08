"""The worked numbers of Nishita & Nakamae, recomputed with cloudmeta's kernels (docs/model.md §1-3).

Every row is an expected value (from the paper, or from a formula of docs/model.md) against what the engine's
kernels give. The expected values are derived here independently: control values by interpolating the
kernel k(u(s)) itself at Bernstein nodes, roots by brentq on the plain field.

    python -m validation.accuracy.paper_examples    # from the repository root

Writes validation/results/paper_examples.csv.
"""
from __future__ import annotations

from math import comb

from validation.common import cache_note, fresh_kernels_when_run, parse, parser, print_head, run_main, write_csv

fresh_kernels_when_run(__name__)  # before cloudmeta is imported

import numpy as np
from scipy.optimize import brentq

import cloudmeta as cm
from cloudmeta.kernels.bernstein import elevate, subdivide
from cloudmeta.kernels.clipping import STACK_DEPTH, clip_roots
from cloudmeta.kernels.metaball import MURAKAMI4, WYVILL6, control_values


# --- independent helpers (plain numpy, from the formulas of docs/model.md) -------------------------------------

def k_wyvill6(u):
    u = np.asarray(u, dtype=np.float64)
    return np.where(u < 1.0, (1.0 - u) ** 2 * (1.0 - 4.0 * u / 9.0), 0.0)


def k_murakami4(u):
    u = np.asarray(u, dtype=np.float64)
    return np.where(u < 1.0, (1.0 - u) ** 2, 0.0)


def bernstein_matrix(n, s):
    """M[j, i] = B_i^n(s_j)."""
    s = np.asarray(s, dtype=np.float64)[:, None]
    i = np.arange(n + 1)[None, :]
    return np.array([comb(n, k) for k in range(n + 1)])[None, :] * s ** i * (1.0 - s) ** (n - i)


def bernstein_value(c, s):
    c = np.asarray(c, dtype=np.float64)
    return bernstein_matrix(len(c) - 1, np.atleast_1d(s)) @ c


def interpolate_bernstein(f, n):
    """Control values of the degree-n polynomial that interpolates f at n + 1 Chebyshev nodes of [0, 1]."""
    s = 0.5 - 0.5 * np.cos(np.pi * (np.arange(n + 1) + 0.5) / (n + 1))
    return np.linalg.solve(bernstein_matrix(n, s), f(s))


def elevate_numpy(c):
    n = len(c) - 1
    out = np.empty(n + 2)
    out[0], out[-1] = c[0], c[-1]
    for i in range(1, n + 1):
        out[i] = i / (n + 1) * c[i - 1] + (1 - i / (n + 1)) * c[i]
    return out


def engine_control_values(kernel_id, a, q=1.0):
    out = np.empty(7)
    control_values(kernel_id, a, q, out)
    return out


def engine_subdivide(c, s0, s1):
    out = np.empty(7)
    subdivide(np.ascontiguousarray(c, dtype=np.float64), s0, s1, out)
    return out


def engine_clip_roots(g, tol_s=1e-12, eps_g=0.0):
    st_lo, st_hi = np.empty(STACK_DEPTH), np.empty(STACK_DEPTH)
    st_c = np.empty((STACK_DEPTH, 7))
    roots, rising = np.empty(16), np.empty(16, np.bool_)
    n = clip_roots(np.ascontiguousarray(g, dtype=np.float64), tol_s, eps_g, st_lo, st_hi, st_c, roots, rising)
    return roots[:n].copy(), rising[:n].copy()


# --- the checks -------------------------------------------------------------------------------------------

class Checks:
    def __init__(self):
        self.rows = []

    def add(self, name, expected, got, tol):
        expected, got = float(expected), float(got)
        diff = abs(got - expected)
        self.rows.append(dict(check=name, expected=expected, got=got, diff=diff, tol=tol, ok=bool(diff <= tol)))

    def vector(self, name, expected, got, tol):
        """One row for a vector: its worst component (index shown), all components within tol."""
        expected, got = np.asarray(expected, dtype=np.float64), np.asarray(got, dtype=np.float64)
        i = int(np.argmax(np.abs(got - expected)))
        self.add(f"{name} (worst of {len(got)}: [{i}])", expected[i], got[i], tol)


def wyvill6_control_values(ch):
    """d = (0, 0, 16/27 a^2, 8 a^2 (8a + 5)/45, 16/27 a^2, 0, 0): 0.59, 2.31 for a = 1; d_3 = 0.4 for a = 0.5."""
    for a in (1.0, 0.5):
        got = engine_control_values(WYVILL6, a)
        formula = np.array([0, 0, 16 / 27 * a * a, 8 * a * a * (8 * a + 5) / 45, 16 / 27 * a * a, 0, 0])
        ch.vector(f"wyvill6 a={a:g} d (docs/model.md formula)", formula, got, 1e-15)
        # the same curve, independently: interpolate k(u(s)), u = 1 - 4 a s (1 - s), at 7 nodes
        interp = interpolate_bernstein(lambda s: k_wyvill6(1 - 4 * a * s * (1 - s)), 6)
        ch.vector(f"wyvill6 a={a:g} d (interpolated k)", interp, got, 1e-12)
    got1, got05 = engine_control_values(WYVILL6, 1.0), engine_control_values(WYVILL6, 0.5)
    ch.add("wyvill6 a=1 d_2 vs paper 0.59", 0.59, got1[2], 0.005)
    ch.add("wyvill6 a=1 d_3 vs paper 2.31", 2.31, got1[3], 0.005)
    ch.add("wyvill6 a=1 d_3 = 8*13/45", 8 * 13 / 45, got1[3], 1e-15)
    ch.add("wyvill6 a=0.5 d_3 vs paper 0.4", 0.4, got05[3], 1e-15)
    # a wider spread of a: the Bernstein form equals the kernel on the chord
    s = np.linspace(0, 1, 101)
    worst = 0.0
    for a in np.linspace(0.01, 1.0, 50):
        c = engine_control_values(WYVILL6, a)
        worst = max(worst, np.abs(bernstein_value(c, s) - k_wyvill6(1 - 4 * a * s * (1 - s))).max())
    ch.add("wyvill6 max |B(s) - k(u(s))|, 50 a x 101 s", 0.0, worst, 1e-14)


def murakami4_control_values(ch):
    """Degree 4: (0, 0, 8/3 a^2, 0, 0) (eq. 18); degree 6 after two elevations: (0, 0, 2/5, 3/5, 2/5, 0, 0) m."""
    worst = 0.0
    s = np.linspace(0, 1, 101)
    for a in (1.0, 0.5, 0.25):
        m = 8 / 3 * a * a
        deg4 = interpolate_bernstein(lambda s: k_murakami4(1 - 4 * a * s * (1 - s)), 4)
        ch.vector(f"murakami4 a={a:g} degree-4 d (interpolated k vs 8/3 a^2)", [0, 0, m, 0, 0], deg4, 1e-12)
        deg6_expected = elevate_numpy(elevate_numpy(np.array([0, 0, m, 0, 0.0])))
        got = engine_control_values(MURAKAMI4, a)
        ch.vector(f"murakami4 a={a:g} degree-6 d (elevated twice)", deg6_expected, got, 1e-15)
        # the engine's own elevate gives the same
        e5, e6 = np.empty(6), np.empty(7)
        elevate(np.array([0, 0, m, 0, 0.0]), e5)
        elevate(e5, e6)
        ch.vector(f"murakami4 a={a:g} bernstein.elevate x2 vs control_values", e6, got, 1e-15)
    for a in np.linspace(0.01, 1.0, 50):
        c = engine_control_values(MURAKAMI4, a)
        worst = max(worst, np.abs(bernstein_value(c, s) - k_murakami4(1 - 4 * a * s * (1 - s))).max())
    ch.add("murakami4 max |B(s) - k(u(s))|, 50 a x 101 s", 0.0, worst, 1e-14)


FIG5_A = (0.15, 0.12, 0.09, 0.05, 0.02, 0.0, 0.0)
FIG5_B = (0.0, 0.0, 0.15, 0.51, 0.84, 1.0, 1.0)


def fig5(ch, out):
    """Ball A (a = 0.5) on t in [2, 5], ball B (a = 1) on t in [4, 6], q = 1, T = 0.5: root t = 4.4624."""
    dA = engine_control_values(WYVILL6, 0.5)
    dB = engine_control_values(WYVILL6, 1.0)
    cA = engine_subdivide(dA, 2 / 3, 1.0)  # [4, 5] is s in [2/3, 1] of [2, 5]
    cB = engine_subdivide(dB, 0.0, 0.5)    # [4, 5] is s in [0, 1/2] of [4, 6]
    out["fig5_A"], out["fig5_B"] = cA, cB
    ch.vector("Fig.5 A on [4,5] vs paper (2 decimals)", FIG5_A, cA, 0.005)
    ch.vector("Fig.5 B on [4,5] vs paper (2 decimals)", FIG5_B, cB, 0.005)
    # exact: the cut curves are the kernel on [4, 5]
    for name, c, a, t0, t1 in (("A", cA, 0.5, 2.0, 5.0), ("B", cB, 1.0, 4.0, 6.0)):
        interp = interpolate_bernstein(
            lambda s: k_wyvill6(1 - 4 * a * ((4 + s) - t0) / (t1 - t0) * (1 - ((4 + s) - t0) / (t1 - t0))), 6)
        ch.vector(f"Fig.5 {name} on [4,5] vs interpolated k (exact)", interp, c, 1e-12)
    g = cA + cB - 0.5
    roots, rising = engine_clip_roots(g)
    out["fig5_clip_roots"] = roots
    ch.add("Fig.5 clip_roots: number of roots on [4,5]", 1, len(roots), 0)
    s_clip = roots[0] if len(roots) else np.nan
    s_poly = brentq(lambda s: bernstein_value(g, s)[0], 0.0, 1.0, xtol=1e-15, rtol=8.9e-16)
    t_field = brentq(lambda t: float(k_wyvill6(1 - 4 * 0.5 * (t - 2) / 3 * (1 - (t - 2) / 3))
                                     + k_wyvill6(1 - 4 * 1.0 * (t - 4) / 2 * (1 - (t - 4) / 2))) - 0.5,
                     4.0, 5.0, xtol=1e-15, rtol=8.9e-16)
    out.update(fig5_s_clip=s_clip, fig5_s_brentq=s_poly, fig5_t_field=t_field)
    ch.add("Fig.5 root s vs paper 0.4624", 0.4624, s_clip, 1e-4)
    ch.add("Fig.5 root t vs paper 4.4624", 4.4624, 4.0 + s_clip, 1e-4)
    ch.add("Fig.5 root s: clip_roots vs brentq on the composite", s_poly, s_clip, 1e-12)
    ch.add("Fig.5 root t: brentq on the plain field", t_field, 4.0 + s_clip, 1e-12)
    ch.add("Fig.5 clip_roots: rising (enters the blob)", 1, float(rising[0]) if len(rising) else 0, 0)

    # the same configuration as a real Blob: the ray x(t) = (t, 0, 0). A sphere of radius R whose centre is
    # at distance p from the line has a = D / R^2 = 1 - p^2 / R^2 and half-chord sqrt(D).
    # A: chord [2, 5] (half 1.5), a = 0.5 -> R^2 = 1.5^2 / 0.5 = 4.5, p = 1.5, centre (3.5, 1.5, 0)
    # B: chord [4, 6] (half 1.0), a = 1   -> R = 1, p = 0, centre (5, 0, 0)
    blob = cm.Blob([[3.5, 1.5, 0.0], [5.0, 0.0, 0.0]], [np.sqrt(4.5), 1.0], weights=1.0, kernel="wyvill6",
                   threshold=0.5)
    r = cm.roots(blob, [0.0, 0.0, 0.0], [1.0, 0.0, 0.0])[0]
    out["fig5_blob_roots"] = r
    ch.add("Fig.5 Blob: number of roots on the ray", 2, len(r), 0)
    ch.add("Fig.5 Blob: cm.roots entry t vs clip_roots", 4.0 + s_clip, r[0] if len(r) else np.nan, 1e-12)
    ch.add("Fig.5 Blob: cm.roots entry t vs plain-field brentq", t_field, r[0] if len(r) else np.nan, 1e-12)
    # after t = 5 only B is on the ray: it leaves B's isosurface at 5 + R/2 = 5.5
    ch.add("Fig.5 Blob: cm.roots exit t = 5 + R_B/2", 5.5, r[1] if len(r) > 1 else np.nan, 1e-12)


def half_radius(ch, out):
    """T = 0.5, wyvill6: k(1/4) = (3/4)^2 (1 - 1/9) = 1/2, so one ball's isosurface is at R/2."""
    ch.add("wyvill6 k(1/4) = 1/2", 0.5, float(k_wyvill6(0.25)), 1e-16)
    ch.add("engine control values: B(1/2 +- 1/4) on a central chord", 0.5,
           bernstein_value(engine_control_values(WYVILL6, 1.0), 0.25)[0], 1e-15)
    rng = np.random.default_rng(5)
    worst = 0.0
    cases = []
    for R in (0.3, 1.0, 2.0, 7.5):
        for _ in range(5):
            center = rng.uniform(-5, 5, 3)
            direction = rng.normal(size=3)
            direction /= np.linalg.norm(direction)
            dist = R + rng.uniform(0.5, 20.0)
            origin = center - dist * direction
            r = cm.roots(cm.Blob([center], [R], threshold=0.5), origin, direction)[0]
            expected = np.array([dist - R / 2, dist + R / 2])
            if len(r) != 2:
                worst = np.inf
            else:
                worst = max(worst, np.abs(r - expected).max())
            cases.append((R, dist, r))
    out["half_radius_cases"] = cases
    ch.add("sphere, ray through centre: max |t - (L +- R/2)|, 20 rays", 0.0, worst, 1e-12)
    # an ellipsoid along each of its axes: the isosurface is the ellipsoid with half the radii
    radii = np.array([2.0, 1.0, 0.5])
    rot = np.array([30.0, -20.0, 75.0])
    blob = cm.Blob([[1.0, 2.0, 3.0]], [radii], rotations=[rot], threshold=0.5)
    q = blob.rotations[0]
    worst = 0.0
    for k in range(3):
        axis = q[:, k]
        origin = blob.centers[0] - 10.0 * axis
        r = cm.roots(blob, origin, axis)[0]
        expected = np.array([10.0 - radii[k] / 2, 10.0 + radii[k] / 2])
        worst = max(worst, np.abs(r - expected).max() if len(r) == 2 else np.inf)
    ch.add("rotated ellipsoid, rays along its 3 axes: max |t - (L +- r_k/2)|", 0.0, worst, 1e-12)


def print_table(rows, file=None):
    w = max(len(r["check"]) for r in rows)
    head = f"{'check':<{w}}  {'expected':>20}  {'got':>20}  {'|diff|':>9}  {'tol':>7}  ok"
    print_head(head, file)
    for r in rows:
        print(f"{r['check']:<{w}}  {r['expected']:>20.15g}  {r['got']:>20.15g}  {r['diff']:>9.2e}  "
              f"{r['tol']:>7.0e}  {'ok' if r['ok'] else 'FAIL'}", file=file)


def main(argv=None, quick=False):
    args, quick = parse(parser(__doc__, quick="same checks (they are all fast)", no_csv=True), argv, quick)
    write = not (args.no_csv or quick)  # quick runs (tests) leave the full run's results alone
    ch = Checks()
    out = {}
    wyvill6_control_values(ch)
    murakami4_control_values(ch)
    fig5(ch, out)
    half_radius(ch, out)
    print("Paper examples (Nishita & Nakamae; docs/model.md §1-3)\n")
    print(cache_note() + "\n")
    print_table(ch.rows)
    print("\nFig. 5 composite on [4, 5] (exact values):")
    print("  A (a=0.5, s in [2/3, 1]):", np.array2string(out["fig5_A"], precision=6))
    print("  B (a=1,   s in [0, 1/2]):", np.array2string(out["fig5_B"], precision=6))
    print("  A rounded:", np.round(out["fig5_A"], 2), " paper:", FIG5_A)
    print("  B rounded:", np.round(out["fig5_B"], 2), " paper:", FIG5_B)
    print(f"  root: s = {out['fig5_s_clip']:.15f} (clip_roots), {out['fig5_s_brentq']:.15f} (brentq); "
          f"t = {4 + out['fig5_s_clip']:.10f}; cm.roots on the Blob: {out['fig5_blob_roots']}")
    n_fail = sum(not r["ok"] for r in ch.rows)
    print(f"\n{len(ch.rows)} checks, {n_fail} failed: {'PASS' if n_fail == 0 else 'FAIL'}")
    if write:
        write_csv("paper_examples.csv", ch.rows, ["check", "expected", "got", "diff", "tol", "ok"])
    return dict(rows=ch.rows, n_checks=len(ch.rows), n_failed=n_fail, passed=n_fail == 0,
                fig5_root_s=float(out["fig5_s_clip"]), fig5_root_t=float(4 + out["fig5_s_clip"]),
                fig5_blob_roots=out["fig5_blob_roots"], fig5_A=out["fig5_A"], fig5_B=out["fig5_B"])


if __name__ == "__main__":
    run_main(main)
