"""The true error of every quality preset on the accuracy suite (scenes/suite/), and its time.

Renders every suite scene (64 x 48, spp 1) at draft, default and fine with exact shadow rays, and at
default and draft with ``shadows: map`` (384 texels, the renderer's default), and measures against the
scene's converged reference (validation/accuracy/suite_references.py's cache, ``quality: reference``; run that
script first, or this one computes the missing references itself):

    rel. RMSE = sqrt(mean over pixels and RGB of (L - L_ref)^2) / sqrt(mean over pixels and RGB of L_ref^2)

over the whole image (validation/common.py's ``rel_rmse``); the same relative to the scattered light
only, sqrt(mean (L - L_ref)^2) / sqrt(mean S_ref^2) with S_ref = L_ref - L_bg T_ref (a bright sky covering
much of the frame makes the first measure up to 17x smaller on this suite); and the worst pixel's relative error,
max over pixels of max_c |L - L_ref| / max_c L_ref. Each setting is checked against its preset's target:
draft 3e-3, default 1e-3, fine 3e-4 (a map row against the target of its quality). "floor" is the
reference's own error (against the tighter setting): a figure is meaningful only well above it.

Time: wall seconds per render, the median of ``--repeat`` renders (3) after a warm-up, on the machine that
runs it (the project's: 2 cores, shared, so expect noise; compare times within one run only).

    python -m validation.accuracy.suite_accuracy [--scenes NAME ...] [--settings draft default ...] [--repeat 3]
        [--replot]

Writes validation/results/suite_accuracy.csv and suite_accuracy.png (time against error: one curve per
setting over the whole suite, and one per scene across the presets). Exit status 0 only if every setting
meets its target on every scene (it is a measurement of a promise the presets do not keep yet).
"""
from __future__ import annotations

import time

import numpy as np

import cloudmeta as cm
from validation.accuracy import suite_references
from validation.common import RESULTS, parse, parser, pyplot, read_csv, run_main, save_figure, write_results
from validation.references import suite as S

#: label -> (render settings, the target it is held to)
SETTINGS = {
    "draft": (dict(quality="draft"), S.TARGETS["draft"]),
    "default": (dict(quality="default"), S.TARGETS["default"]),
    "fine": (dict(quality="fine"), S.TARGETS["fine"]),
    "default + map": (dict(quality="default", shadows="map"), S.TARGETS["default"]),
    "draft + map": (dict(quality="draft", shadows="map"), S.TARGETS["draft"]),
}


def timed(scene, repeat):
    times, img = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        img = cm.render(scene, progress=False)
        times.append(time.perf_counter() - t0)
    return np.asarray(img, np.float64), float(np.median(times)), float(np.min(times)), float(np.max(times))


def run_scene(path, repeat, labels=tuple(SETTINGS)):
    name = path.stem
    ref, _, meta = suite_references.current(path)
    scene = cm.load_scene(path)
    small = cm.load_scene(path, width=8, height=6)
    for label in labels:  # warm-up: compile or load every code path outside the timings
        cm.render(S.with_settings(small, **SETTINGS[label][0]), progress=False)
    rows = []
    for label in labels:
        settings, target = SETTINGS[label]
        img, t, t_min, t_max = timed(S.with_settings(scene, **settings), repeat)
        err = S.rel_rmse(img, ref)
        err_s = S.rel_rmse_scattered(img, ref, scene.background)
        worst, at = S.worst_pixel(img, ref)
        rows.append(dict(scene=name, setting=label, seconds=t, seconds_min=t_min, seconds_max=t_max,
                         rel_rmse=err, rel_rmse_scattered=err_s, meets_scattered=bool(err_s <= target),
                         worst_pixel=worst, worst_row=at[0], worst_col=at[1], target=target,
                         meets=bool(err <= target), floor=meta["ref_vs_tighter"], reference_s=meta["reference_s"],
                         finite=bool(np.all(np.isfinite(img)))))
    return rows


def table(rows, key="rel_rmse", meets="meets"):
    """The scene x setting table of errors, marked '!' where a target is missed."""
    labels = list(dict.fromkeys(r["setting"] for r in rows))
    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    by = {(r["scene"], r["setting"]): r for r in rows}
    lines = [f"{'scene':22s} " + " ".join(f"{lab:>15s}" for lab in labels) + f" {'floor':>8s}"]
    lines.append("-" * len(lines[0]))
    for s in scenes:
        cells = []
        for lab in labels:
            r = by[(s, lab)]
            cells.append(f"{r[key]:8.1e}{'!' if not r[meets] else ' '}{r['seconds']:5.2f}s")
        lines.append(f"{s:22s} " + " ".join(f"{c:>15s}" for c in cells) + f" {by[(s, labels[0])]['floor']:8.1e}")
    lines.append("-" * len(lines[0]))
    miss = [sum(not by[(s, lab)][meets] for s in scenes) for lab in labels]
    lines.append(f"{'misses its target':22s} " + " ".join(f"{f'{m} of {len(scenes)}':>15s}" for m in miss))
    worst = [max(by[(s, lab)][key] for s in scenes) for lab in labels]
    lines.append(f"{'worst rel. RMSE':22s} " + " ".join(f"{w:15.1e}" for w in worst))
    med = [float(np.median([by[(s, lab)][key] for s in scenes])) for lab in labels]
    lines.append(f"{'median rel. RMSE':22s} " + " ".join(f"{m:15.1e}" for m in med))
    total = [sum(by[(s, lab)]["seconds"] for s in scenes) for lab in labels]
    lines.append(f"{'suite time [s]':22s} " + " ".join(f"{t:15.2f}" for t in total))
    return "\n".join(lines)


def worst_table(rows):
    labels = list(dict.fromkeys(r["setting"] for r in rows))
    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    by = {(r["scene"], r["setting"]): r for r in rows}
    lines = [f"{'worst pixel rel. err':22s} " + " ".join(f"{lab:>13s}" for lab in labels)]
    for s in scenes:
        lines.append(f"{s:22s} " + " ".join(f"{by[(s, lab)]['worst_pixel']:13.1e}" for lab in labels))
    return "\n".join(lines)


def plot(rows, out):
    plt = pyplot()
    labels = list(dict.fromkeys(r["setting"] for r in rows))
    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(13, 5.2), sharey=True)
    for k, lab in enumerate(labels):
        pts = [r for r in rows if r["setting"] == lab]
        marker = "s" if "map" in lab else "o"
        ax1.plot([r["seconds"] for r in pts], [r["rel_rmse_scattered"] for r in pts], marker, color=f"C{k}", ms=3.5,
                 mfc="none", alpha=0.8)
        # the suite as a whole: mean time per render against the worst and the median scene
        t = float(np.mean([r["seconds"] for r in pts]))
        errs = [r["rel_rmse_scattered"] for r in pts]
        ax1.plot([t, t], [float(np.median(errs)), max(errs)], marker + "-", color=f"C{k}", ms=7, lw=2,
                 label=f"{lab} (target {SETTINGS[lab][1]:g})")
    for k, t in enumerate(S.TARGETS.values()):
        ax1.axhline(t, color=f"C{k}", ls="--", lw=0.8)
        ax2.axhline(t, color=f"C{k}", ls="--", lw=0.8)
    ax1.set_title("per setting: every scene (open), and the suite: mean time vs median and worst scene (bar);\n"
                  "dashed: the targets (draft, default, fine)", fontsize=9)
    exact = ("draft", "default", "fine")
    for k, s in enumerate(scenes):
        pts = [next(r for r in rows if r["scene"] == s and r["setting"] == lab) for lab in exact if lab in labels]
        ax2.plot([r["seconds"] for r in pts], [r["rel_rmse_scattered"] for r in pts], "o-", color=plt.cm.tab20(k % 20),
                 lw=0.9, ms=3, label=s)
        floor = pts[0]["floor"]
        ax2.plot([pts[-1]["seconds"]], [floor], "x", color=plt.cm.tab20(k % 20), ms=4)
    ax2.set_title("per scene: draft -> default -> fine (x: the reference's own error)", fontsize=9)
    for ax in (ax1, ax2):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("wall time per render [s], 64 x 48 pixels (2 shared cores)")
    ax1.set_ylabel("RMSE against the converged reference / its mean scattered radiance")
    ax1.legend(fontsize=7, loc="lower left")
    ax2.legend(fontsize=6, loc="lower left", ncol=2)
    fig.suptitle("cloudmeta accuracy suite (scenes/suite/): time against true error of the presets", fontsize=10)
    save_figure(fig, out)


def read_rows(path=RESULTS / "suite_accuracy.csv"):
    """Rows of a suite_accuracy.csv, typed (to redraw the plot without rendering again)."""
    return read_csv(path, floats=("seconds", "seconds_min", "seconds_max", "rel_rmse", "rel_rmse_scattered",
                                  "worst_pixel", "target", "floor", "reference_s"),
                    ints=("worst_row", "worst_col"), bools=("meets", "meets_scattered", "finite"))


def main(argv=None, quick=False):
    ap = parser(__doc__)
    ap.add_argument("--scenes", nargs="+", default=None, help="scene names (default: the whole suite)")
    ap.add_argument("--repeat", type=int, default=3, help="renders per setting; the median time is quoted")
    ap.add_argument("--replot", action="store_true", help="redraw the plot from the CSV, render nothing")
    ap.add_argument("--settings", nargs="+", default=list(SETTINGS), choices=list(SETTINGS),
                    help="the settings to measure (default: all; the CSV and plot are written only for all)")
    args, _ = parse(ap, argv)
    if args.replot:
        rows = read_rows()
        plot(rows, RESULTS / "suite_accuracy.png")
        print(table(rows, "rel_rmse_scattered", "meets_scattered"))
        return dict(rows=rows, passed=all(r["meets_scattered"] for r in rows))
    paths = [p for p in S.scene_paths() if args.scenes is None or p.stem in args.scenes]
    start = time.perf_counter()
    rows = []
    for p in paths:
        rows += run_scene(p, args.repeat, args.settings)
        print(f"  {p.stem}: " + ", ".join(f"{r['setting']} {r['rel_rmse_scattered']:.1e}"
                                          for r in rows[-len(args.settings):]), flush=True)
    elapsed = time.perf_counter() - start
    print(f"\nAccuracy suite: RMSE against the converged reference over its mean scattered radiance (the presets' "
          f"measure), and median time per render "
          f"(64 x 48, spp 1; '!' misses the target: draft {S.TARGETS['draft']:g}, default "
          f"{S.TARGETS['default']:g}, fine {S.TARGETS['fine']:g}; map rows: the target of their quality)\n")
    print(table(rows, "rel_rmse_scattered", "meets_scattered"))
    print("\nThe same relative to the whole image (sqrt(mean L_ref^2): a bright sky dilutes the error; "
          "the older measure, for comparison):\n")
    print(table(rows))
    print()
    print(worst_table(rows))
    passed = all(r["meets_scattered"] and r["finite"] for r in rows)
    print(f"\nfloor: the reference's own error (rel. RMSE against the tighter setting).\n"
          f"{'PASS' if passed else 'FAIL'}: every setting at or below its target on every scene; every image "
          f"finite ({'yes' if all(r['finite'] for r in rows) else 'NO'})   [{elapsed:.1f} s]")
    if args.scenes is None and args.settings == list(SETTINGS):
        write_results("suite_accuracy", rows, plot)
    return dict(rows=rows, passed=passed, seconds=elapsed)


if __name__ == "__main__":
    run_main(main)
