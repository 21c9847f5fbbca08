"""The approximate mode's shared method (docs/approximate.md, "Shared"), measured on the six report scenes.

At ``--size`` (default 512 wide) each scene renders at each ``--quality`` with ``method: shared`` (whole frame,
both cores, seed 1; the tails planned to the preset's target); its error is the mode's own estimate
(renderer.approximate.approximation_error: 512 cloud pixels against unbiased paths; no converged reference exists
at this size), with the tails' noise part of it (the error channels' RMS: the tails' noise and the quadrature's)
beside it; the time is ``render_frame(error=True)``'s, the estimate included. With ``--check`` the same at 64 wide against the references of
validation.accuracy.approximate (2,048 paths, their noise subtracted): the true error beside the estimate.

With ``--planned`` the unbiased paths of ``scattering: multiple`` planned to those presets (their own estimate,
RenderResult.estimated) and the octaves (their measured approximation error) are timed too, with ``--grid`` the grid
method at those presets (its measured approximation error), and the rows are
written to validation/results/ms_shared_SIZE.csv with a plot of estimated error against time per scene
(ms_shared_SIZE.png): estimates, not errors against references, which do not exist at this size.

    python -m validation.accuracy.ms_shared [--size 512] [--quality draft default] [--scenes ...] [--check]
        [--planned draft] [--grid default] [--skip-shared] [--merge] [--cache N]
"""
from __future__ import annotations

import time

import numpy as np

import cloudmeta as cm
from validation.accuracy.approximate import FIT, REPORT, background_times_t, reference, rel_error, scene_of
from validation.common import (RESULTS, finish_time_error, parse, parser, pyplot, read_csv, run_main, with_settings,
                               write_csv)


#: the report scenes and the fitting scenes of validation.accuracy.approximate (the latter played no part in choosing
#: the shared method's settings)
SCENES = {**REPORT, **FIT}


def measure(name, size, quality, seed=1, cache=None):
    """One scene at one quality, rendered with ``error=True`` (the time includes the estimate): a dict of its time,
    the estimated error (renderer.approximate.approximation_error) and the noise the error channels hold (the
    tails' and the quadrature's), relative to the scattered light. cache: render.shared.cache (None: the
    preset's)."""
    s = with_settings(scene_of(SCENES[name], size, "approximate", method="shared"), quality=quality,
                      shared=None if cache is None else (None, None, cache))
    t0 = time.perf_counter()
    result = cm.render_frame(s, progress=False, seed=seed, error=True)
    seconds = time.perf_counter() - t0
    h, w = s.image.height, s.image.width
    image = result.image.astype(np.float64)
    scattered = float((image[..., :3] - background_times_t(s, image)).mean())
    noise = float(np.sqrt(np.mean(result.error.astype(np.float64) ** 2))) / scattered
    est = result.approximation
    tails = getattr(result.plan, "tails", None)  # planned (renderer.shared.plan_tails) per coarsest sample ray
    return dict(scene=name, size=f"{w}x{h}", quality=quality, seconds=seconds, estimated=est.rel_rmse,
                est_se=est.stderr, noise=noise, tails=tails, image=image)


def measure_other(name, size, how, seed=1):
    """The planned unbiased paths at a preset (how = "planned draft", ...), the octaves ("octaves") or the grid
    method at a preset ("grid default", ...): their time and estimated error (the plan's estimate; the octaves' and
    the grid's measured approximation error, with its standard error, the time including it)."""
    if how == "octaves":
        s = with_settings(scene_of(SCENES[name], size, "approximate"), quality="default")
    elif how.startswith("grid"):
        s = with_settings(scene_of(SCENES[name], size, "approximate", method="grid"), quality=how.split()[1])
    else:
        s = with_settings(scene_of(SCENES[name], size, "multiple"), quality=how.split()[1])
    approximate = not how.startswith("planned")
    t0 = time.perf_counter()
    result = cm.render_frame(s, progress=False, seed=seed, error=approximate)
    seconds = time.perf_counter() - t0
    est = result.approximation.rel_rmse if approximate else result.estimated
    est_se = result.approximation.stderr if approximate else 0.0
    w, h = s.image.width, s.image.height
    return dict(scene=name, size=f"{w}x{h}", quality=how, seconds=seconds, estimated=est, est_se=est_se,
                noise=np.nan, tails=None)


def plot(rows, out, size):
    plt = pyplot()
    names = list(dict.fromkeys(r["scene"] for r in rows))
    cols = min(3, len(names))
    fig, axes = plt.subplots(-(-len(names) // cols), cols, figsize=(4 * cols, 3.5 * -(-len(names) // cols)),
                             sharex=True, sharey=True, squeeze=False)
    for ax, name in zip(axes.flat, names):
        mine = [r for r in rows if r["scene"] == name]
        shared = [r for r in mine if not r["quality"].startswith(("planned", "octaves", "grid"))]
        # an estimate that did not rise above its own paths' noise (0 +- inf) has no point to draw
        resolved = [np.isfinite(float(r["est_se"])) and float(r["estimated"]) > 0.0 for r in shared]
        drawn = [r for r, ok in zip(shared, resolved) if ok]
        ax.errorbar([r["seconds"] for r in drawn], [r["estimated"] for r in drawn],
                    yerr=[r["est_se"] for r in drawn], fmt="o-", label="approximate, shared")
        for r, ok in zip(shared, resolved):
            if not ok:
                ax.annotate(f"{r['quality']}: not resolved\n({float(r['seconds']):.0f} s)", (float(r["seconds"]), 0.022),
                            fontsize=7, ha="right")
        planned = [r for r in mine if r["quality"].startswith("planned")]
        ax.plot([r["seconds"] for r in planned], [r["estimated"] for r in planned], "P-", markersize=9,
                label="multiple, planned paths")
        octaves = [r for r in mine if r["quality"] == "octaves"]
        ax.plot([r["seconds"] for r in octaves], [r["estimated"] for r in octaves], "^", markersize=9,
                label="approximate, octaves")
        for target in (0.10, 0.03):  # `draft`'s and `default`'s targets
            ax.axhline(target, color="0.6", linestyle=":", linewidth=1)
        grid = [r for r in mine if r["quality"].startswith("grid")]
        ax.errorbar([r["seconds"] for r in grid], [r["estimated"] for r in grid], yerr=[r["est_se"] for r in grid],
                    fmt="s--", markersize=7, label="approximate, grid")
    finish_time_error(fig, axes, names, "estimated relative RMSE",
                      f"Time against estimated error, {size} px wide (each method's own estimate)", out)


def main(argv=None):
    ap = parser(__doc__)
    ap.add_argument("--scenes", nargs="+", default=list(REPORT), choices=list(SCENES),
                    help="the six report scenes by default; the approximate mode's four fitting scenes (FIT) too")
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--quality", nargs="+", default=["draft"])
    ap.add_argument("--check", action="store_true", help="at 64 wide against the converged references")
    ap.add_argument("--cache", type=int, default=None, help="render.shared.cache: the order the tails trace up to "
                    "before they read the cache (0: no cache; default: the preset's)")
    ap.add_argument("--planned", nargs="*", default=[], help="also the planned paths at these presets, the octaves, "
                    "and a CSV and plot")
    ap.add_argument("--grid", nargs="*", default=[], help="also the grid method at these presets, the octaves, "
                    "and a CSV and plot")
    ap.add_argument("--skip-shared", action="store_true", help="only the other methods (with --planned or "
                    "--grid)")
    ap.add_argument("--merge", action="store_true", help="keep the CSV's rows of other scenes and methods: this "
                    "run's rows replace those of the same scene and method")
    args, _ = parse(ap, argv)
    rows = []
    size = 64 if args.check else args.size
    for name in args.scenes:
        for quality in [] if args.skip_shared else args.quality:
            r = measure(name, size, quality, cache=args.cache)
            line = (f"{name:14s} {r['size']:>8s} {quality:8s} {r['seconds']:7.1f} s"
                    f"  estimated {r['estimated']:.3f} +- {r['est_se']:.3f} (tails' noise {r['noise']:.3f}, "
                    f"{r['tails']} tails planned)")
            if args.check:
                u, se, bt, _ = reference(name, SCENES[name], 64, 2048)
                r["true"] = rel_error(r["image"][..., :3], u, se, bt)
                line += f"  true {r['true']:.3f}"
            print(line, flush=True)
            rows.append({k: v for k, v in r.items() if k != "image"})
        others = ["octaves"] + [f"planned {q}" for q in args.planned] + [f"grid {q}" for q in args.grid]
        for how in others if args.planned or args.grid else []:
            r = measure_other(name, size, how)
            print(f"{name:14s} {r['size']:>8s} {how:16s} {r['seconds']:7.1f} s  estimated {r['estimated']:.3f}"
                  + (f" +- {r['est_se']:.3f}" if r["est_se"] else ""), flush=True)
            rows.append(r)
        if args.planned or args.grid:  # after every scene, so that a long run stopped keeps what it measured
            _write(rows, size, args.merge)
    return dict(rows=rows)


def _write(rows, size, merge):
    """ms_shared_SIZE.csv and .png of ``rows``; with ``merge`` the CSV's rows of other scenes and methods kept."""
    out = RESULTS / f"ms_shared_{size}.csv"
    if merge and out.exists():
        mine = {(r["scene"], r["quality"]) for r in rows}
        kept = [r for r in read_csv(out, floats=("seconds", "estimated", "est_se", "noise"))
                if (r["scene"], r["quality"]) not in mine]
        rows = sorted(kept + rows, key=lambda r: list(SCENES).index(r["scene"]))
    write_csv(out, rows)
    plot(rows, RESULTS / f"ms_shared_{size}.png", size)


if __name__ == "__main__":
    run_main(main)
