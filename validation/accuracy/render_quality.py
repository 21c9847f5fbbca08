"""Run time against error of the renderer's quality settings.

For each scene, renders every quality preset (draft, default, fine) and the tightest setting
(``reference``), and prints per setting the wall time and the relative RMSE against the reference:

    rel. RMSE = sqrt(mean over pixels and RGB of (L - L_ref)^2) / sqrt(mean of L_ref^2)

It also checks that the reference itself has converged, by rendering a smaller image at a setting
tighter still (``--check-size``). Writes validation/results/render_quality.csv and a Pareto plot
render_quality.png (time against error).

    python -m validation.accuracy.render_quality [--size 512] [--scenes scenes/cumulus.yaml ...] [--quick]
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

import cloudmeta as cm
from validation.common import ROOT, parse, parser, pyplot, rel_rmse, run_main, save_figure, with_settings, write_results

PRESETS = ("draft", "default", "fine")
#: tighter than ``reference``: used only to show that the reference has converged
ULTRA = dict(quality="reference", tolerance=1e-8, max_tau=0.05, cutoff=0.0)
#: ULTRA's longest step, as a fraction of the scene's diagonal (reference: 1/128)
ULTRA_LENGTH = 1 / 512


def timed_render(scene):
    start = time.perf_counter()
    img = cm.render(scene, progress=False)
    return img, time.perf_counter() - start


def run_scene(path, size, check_size):
    scene = cm.load_scene(path, width=size, height=size)
    cm.render(cm.load_scene(path, width=8, height=8), progress=False)  # compile (or load the cache) first
    ref, t_ref = timed_render(with_settings(scene, quality="reference"))
    rows = []
    for preset in PRESETS:
        img, t = timed_render(with_settings(scene, quality=preset))
        rows.append(dict(scene=Path(path).stem, size=size, setting=preset, seconds=t, rel_rmse=rel_rmse(img, ref),
                         max_abs=float(np.abs(img[..., :3] - ref[..., :3]).max())))
    rows.append(dict(scene=Path(path).stem, size=size, setting="reference", seconds=t_ref, rel_rmse=0.0, max_abs=0.0))
    small = cm.load_scene(path, width=check_size, height=check_size)
    ref_small, _ = timed_render(with_settings(small, quality="reference"))
    lo, hi = small.bbox()
    ultra, _ = timed_render(with_settings(small, **ULTRA, max_length=ULTRA_LENGTH * float(np.linalg.norm(hi - lo))))
    rows.append(dict(scene=Path(path).stem, size=check_size, setting="reference vs tighter", seconds=float("nan"),
                     rel_rmse=rel_rmse(ref_small, ultra), max_abs=float(np.abs(ref_small - ultra)[..., :3].max())))
    return rows


def plot(rows, out):
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6, 4))
    for scene in dict.fromkeys(r["scene"] for r in rows):
        pts = [r for r in rows if r["scene"] == scene and r["setting"] in PRESETS]
        ax.plot([r["seconds"] for r in pts], [r["rel_rmse"] for r in pts], "o-", label=scene)
        for r in pts:
            ax.annotate(r["setting"], (r["seconds"], r["rel_rmse"]), textcoords="offset points", xytext=(4, 4),
                        fontsize=8)
    ax.axhline(1e-3, color="grey", ls="--", lw=0.8)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("wall time [s] (2 cores)")
    ax.set_ylabel("relative RMSE vs reference")
    ax.set_title("cloudmeta: time against error")
    ax.legend()
    save_figure(fig, out)


def main(argv=None, quick=False):
    ap = parser(__doc__, quick="small images, for a test")
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--check-size", type=int, default=96)
    ap.add_argument("--scenes", nargs="+", default=[str(ROOT / "scenes" / "cumulus.yaml")])
    args, quick = parse(ap, argv, quick)
    size, check = (48, 24) if quick else (args.size, args.check_size)
    rows = [r for s in args.scenes for r in run_scene(s, size, check)]
    print(f"{'scene':18s} {'size':>5s} {'setting':22s} {'time [s]':>9s} {'rel RMSE':>10s} {'max abs':>10s}")
    for r in rows:
        print(f"{r['scene']:18s} {r['size']:5d} {r['setting']:22s} {r['seconds']:9.2f} {r['rel_rmse']:10.2e} "
              f"{r['max_abs']:10.2e}")
    default_ok = all(r["rel_rmse"] < 1e-3 for r in rows if r["setting"] == "default")
    print(f"default setting below 1e-3 relative RMSE on every scene: {'PASS' if default_ok else 'FAIL'}")
    if not quick:
        write_results("render_quality", rows, plot)
    return dict(rows=rows, passed=default_ok)


if __name__ == "__main__":
    run_main(main)
