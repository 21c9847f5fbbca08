"""Wall time against error for every quality setting of the renderer: the figure to choose settings by.

For the 77-ball cumulus (scenes/cumulus.yaml) and a 1,200-ball stratocumulus bank (scenes/dense_1000.yaml,
made by scenes/make_dense.py), renders each setting and measures its wall time and its relative RMSE
against the ``reference`` setting of the same image, relative to the scattered light (the presets' measure,
docs/error_estimate.md):

    rel. RMSE = sqrt(mean over pixels and RGB of (L - L_ref)^2) / mean over pixels and RGB of S_ref

(S_ref: the reference less the background seen through the media). Settings: the presets draft, default,
fine (exact shadow rays, calibrated on the frame: renderer.calibrate); ``default`` with ``calibrate: false``
(the preset's fixed settings, as before the calibration) and with ``shadows: hybrid``; shadow maps
(``shadows: map``) at the default quality with 128, 384 (the renderer's default) and 1024 texels per side,
and at draft with 384.
The ``reference`` itself is checked on a small image against a setting tighter still (``vs tighter``: the
check setting of validation/accuracy/render_quality.py), so that its own error shows the floor under every other
figure. The Pareto curve (settings that no other
setting beats in both time and error) is drawn in validation/results/time_vs_error.png.

    python -m validation.performance.time_vs_error [--size 256] [--check-size 64] [--scenes ...] [--quick]

Times are wall-clock seconds on the machine that runs it (the project's: 2 cores, shared), one render
each after a warm-up, so expect some noise. Requirement: the default quality below 1e-3 relative RMSE on
every scene, every image finite. Reuses validation/accuracy/render_quality.py's ULTRA.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

import cloudmeta as cm
from validation.accuracy import render_quality
from validation.common import (RESULTS, ROOT, parse, parser, print_head, pyplot, read_csv, run_main, save_figure,
                               with_settings, write_results)
from validation.references.suite import rel_rmse_scattered

SCENES = (ROOT / "scenes" / "cumulus.yaml", ROOT / "scenes" / "dense_1000.yaml")
#: label -> render settings (``reference`` is the baseline and comes first)
SETTINGS = {
    "reference": dict(quality="reference"),
    "draft": dict(quality="draft"),
    "default": dict(quality="default"),
    "fine": dict(quality="fine"),
    "default, not calibrated": dict(quality="default", calibrate=False),
    "default + hybrid": dict(quality="default", shadows="hybrid"),
    "default + map 128": dict(quality="default", shadows="map", shadow_map=128),
    "default + map 384": dict(quality="default", shadows="map", shadow_map=384),
    "default + map 1024": dict(quality="default", shadows="map", shadow_map=1024),
    "draft + map 384": dict(quality="draft", shadows="map", shadow_map=384),
}
QUICK_SETTINGS = ("reference", "draft", "default", "default + map 128")
DEFAULT_BOUND = 1e-3


def timed(scene):
    t0 = time.perf_counter()
    img = cm.render(scene, progress=False)
    return np.asarray(img, np.float64), time.perf_counter() - t0


def tighter(scene):
    """validation/accuracy/render_quality.py's check setting, tighter than ``reference`` (ULTRA, and its step length
    where that script defines one)."""
    extra = {}
    if hasattr(render_quality, "ULTRA_LENGTH"):
        lo, hi = scene.bbox()
        extra["max_length"] = render_quality.ULTRA_LENGTH * float(np.linalg.norm(hi - lo))
    return with_settings(scene, **{**render_quality.ULTRA, **extra})


def pareto(rows):
    """The rows that no other row beats in both time and error (ties kept)."""
    front = []
    best = np.inf
    for r in sorted(rows, key=lambda r: (r["seconds"], r["rel_rmse"])):
        if r["rel_rmse"] < best:
            front.append(r)
            best = r["rel_rmse"]
    return front


def run_scene(path, size, check_size, labels):
    name = Path(path).stem
    # warm-up: compile (or load from the cache) everything a setting may use, outside the timings
    small = cm.load_scene(path, width=8, height=8)
    cm.render(small, progress=False)
    cm.render(with_settings(small, shadows="map", shadow_map=16), progress=False)
    scene = cm.load_scene(path, width=size, height=size, spp=1)
    rows = []
    ref = None
    for label in labels:
        img, t = timed(with_settings(scene, **SETTINGS[label]))
        finite = bool(np.all(np.isfinite(img)))
        if ref is None:
            ref = img
        rows.append(dict(scene=name, size=size, setting=label, seconds=t,
                         rel_rmse=rel_rmse_scattered(img, ref, scene.background),
                         max_abs=float(np.abs(img[..., :3] - ref[..., :3]).max()), finite=finite))
    check = cm.load_scene(path, width=check_size, height=check_size, spp=1)
    r_small, _ = timed(with_settings(check, quality="reference"))
    ultra, _ = timed(tighter(check))
    rows.append(dict(scene=name, size=check_size, setting="reference vs tighter", seconds=float("nan"),
                     rel_rmse=rel_rmse_scattered(r_small, ultra, check.background), max_abs=float(np.abs(r_small - ultra)[..., :3].max()),
                     finite=bool(np.all(np.isfinite(r_small)))))
    for r in pareto([r for r in rows if r["setting"] not in ("reference", "reference vs tighter")]):
        r["pareto"] = True
    for r in rows:
        r.setdefault("pareto", False)
    return rows


def plot(rows, out):
    """One panel per scene: every setting (time, error), the Pareto front, the reference's time and its own
    error, and the default's promise."""
    plt = pyplot()
    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    fig, axes = plt.subplots(1, len(scenes), figsize=(6.2 * len(scenes), 4.8), sharey=True, squeeze=False)
    panels = []  # (axes, the scene's settings): labelled once every panel's limits are fixed
    for k, (ax, scene) in enumerate(zip(axes[0], scenes)):
        colour = f"C{k}"
        pts = sorted([r for r in rows if r["scene"] == scene
                      and r["setting"] not in ("reference", "reference vs tighter")], key=lambda r: r["seconds"])
        panels.append((ax, pts))
        front = [r for r in pts if r["pareto"]]
        ax.plot([r["seconds"] for r in front], [r["rel_rmse"] for r in front], "-", color=colour, lw=1.2,
                label="Pareto front")
        for r in pts:
            marker = "s" if "map" in r["setting"] else "o"
            ax.plot(r["seconds"], r["rel_rmse"], marker, color=colour, mfc=colour if r["pareto"] else "none")
        ref = [r for r in rows if r["scene"] == scene and r["setting"] == "reference"][0]
        ax.axvline(ref["seconds"], color=colour, ls=":", lw=0.8)
        ax.annotate(f"reference: {ref['seconds']:.0f} s", (ref["seconds"], 0.97), xycoords=("data", "axes fraction"),
                    rotation=90, fontsize=7, color=colour, ha="right", va="top")
        floor = [r for r in rows if r["scene"] == scene and r["setting"] == "reference vs tighter"][0]
        ax.axhline(floor["rel_rmse"], color=colour, ls="-.", lw=0.6, label="the reference's own error")
        ax.axhline(DEFAULT_BOUND, color="grey", ls="--", lw=0.8, label="1e-3: the default's promise")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(f"wall time [s], {ref['size']} x {ref['size']} pixels (2 cores)")
        ax.set_title(scene, fontsize=10)
        ax.legend(fontsize=7, loc="lower left")
    fig.canvas.draw()  # the axes' limits and scales fixed: the labels are placed in display space
    for ax, pts in panels:
        place_labels(ax, [(r["seconds"], r["rel_rmse"]) for r in pts], [r["setting"] for r in pts], fontsize=7)
    axes[0][0].set_ylabel("RMSE against the reference setting / mean scattered radiance")
    fig.suptitle("cloudmeta: time against error (circles: exact shadow rays, squares: shadow maps; "
                 "filled: on the Pareto front)", fontsize=9)
    save_figure(fig, out, dpi=130)


#: where a label may sit, in points from its marker (right, left, above, below, then the diagonals)
LABEL_OFFSETS = ((6, -3), (-6, -3), (0, 7), (0, -13), (6, 6), (-6, 6), (6, -12), (-6, -12), (10, 14), (-10, 14),
                 (10, -20), (-10, -20))


def place_labels(ax, points, labels, fontsize):
    """Annotate each point with its label at the first of LABEL_OFFSETS whose box overlaps no label placed
    before it, no marker and no panel edge (else the least overlapping); boxes estimated from the font size."""
    to_px = ax.figure.dpi / 72.0
    xy = [ax.transData.transform(p) for p in points]
    bounds = ax.bbox.extents
    marks = [(x - 4 * to_px, y - 4 * to_px, x + 4 * to_px, y + 4 * to_px) for x, y in xy]
    placed = []

    def overlap(a, b):
        return max(0.0, min(a[2], b[2]) - max(a[0], b[0])) * max(0.0, min(a[3], b[3]) - max(a[1], b[1]))

    for (x, y), text, point in sorted(zip(xy, labels, points), key=lambda q: q[0][0]):
        w, h = 0.52 * fontsize * len(text) * to_px, fontsize * to_px
        best = None
        for dx, dy in LABEL_OFFSETS:
            x0 = x + dx * to_px - (w if dx < 0 else (w / 2 if dx == 0 else 0.0))
            y0 = y + dy * to_px
            box = (x0, y0, x0 + w, y0 + h)
            cost = sum(overlap(box, b) for b in placed + marks)
            cost += w * h * (box[0] < bounds[0] or box[2] > bounds[2] or box[1] < bounds[1] or box[3] > bounds[3])
            if best is None or cost < best[0]:
                best = (cost, dx, dy, box)
            if cost == 0.0:
                break
        _, dx, dy, box = best
        placed.append(box)
        ax.annotate(text, point, textcoords="offset points", xytext=(dx, dy), fontsize=fontsize, color="k",
                    ha="right" if dx < 0 else ("center" if dx == 0 else "left"), va="bottom")


def read_rows(path=RESULTS / "time_vs_error.csv"):
    """Rows of a time_vs_error.csv, typed (to redraw the plot without rendering again)."""
    return read_csv(path, floats=("seconds", "rel_rmse", "max_abs"), ints=("size",), bools=("finite", "pareto"))


def main(argv=None, quick=False):
    ap = parser(__doc__, quick="small images and fewer settings, for the test")
    ap.add_argument("--size", type=int, default=None, help="image side in pixels (default 256; 20 quick)")
    ap.add_argument("--check-size", type=int, default=None, help="image side of the reference check (default 64)")
    ap.add_argument("--scenes", nargs="+", default=[str(s) for s in SCENES])
    args, quick = parse(ap, argv, quick)
    size = args.size or (20 if quick else 256)
    check = args.check_size or (10 if quick else 64)
    labels = QUICK_SETTINGS if quick else tuple(SETTINGS)
    start = time.perf_counter()
    rows = [r for s in args.scenes for r in run_scene(s, size, check, labels)]
    elapsed = time.perf_counter() - start
    print(f"Time against error, {size} x {size} pixels (relative RMSE against the reference setting)\n")
    head = f"{'scene':12s} {'size':>5s} {'setting':22s} {'time [s]':>9s} {'x ref':>6s} {'rel RMSE':>10s} " \
           f"{'max abs':>9s} {'Pareto':>6s}"
    print_head(head)
    for r in rows:
        ref_t = [q["seconds"] for q in rows if q["scene"] == r["scene"] and q["setting"] == "reference"][0]
        speed = "" if not np.isfinite(r["seconds"]) else f"{r['seconds'] / ref_t:6.3f}"
        print(f"{r['scene']:12s} {r['size']:5d} {r['setting']:22s} {r['seconds']:9.2f} {speed:>6s} "
              f"{r['rel_rmse']:10.2e} {r['max_abs']:9.2e} {'*' if r['pareto'] else '':>6s}")
    ok_default = all(r["rel_rmse"] < DEFAULT_BOUND for r in rows if r["setting"] == "default")
    ok_finite = all(r["finite"] for r in rows)
    passed = ok_default and ok_finite
    print("\nx ref: time as a fraction of the reference setting's; Pareto: on the time/error front;\n"
          "reference vs tighter: the reference setting's own error on a small image (against render_quality's "
          "tighter check setting).")
    print(f"{'PASS' if passed else 'FAIL'}: default below {DEFAULT_BOUND:g} relative RMSE on every scene "
          f"({'yes' if ok_default else 'NO'}), every image finite ({'yes' if ok_finite else 'NO'})   "
          f"[{elapsed:.1f} s]")
    if not quick:
        write_results("time_vs_error", rows, plot)
    return dict(rows=rows, passed=passed, seconds=elapsed)


if __name__ == "__main__":
    run_main(main)
