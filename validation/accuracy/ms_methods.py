"""Time against error for every way cloudmeta renders multiply scattered light: single
scattering, the approximate mode (octaves and grid), unbiased multiple scattering and the same denoised, on
validation.accuracy.approximate's six report scenes, against their converged references.

Per scene (64 x 48 unless --size, ambient removed; the references of approximate.py, 1,024 paths unless
--paths, seed 0): single scattering, the octaves and the grid at ``default``; multiple scattering at ``default`` with
each of ``--spp`` paths per pixel (seed 1), raw and with ``denoise=True``; the paths planned to the
``--planned`` presets' targets (seed 1). The time is the whole
render_frame call, kernels loaded; the error the relative RMSE over the mean scattered radiance, the
reference's own variance subtracted (approximate.rel_error). Prints a table, writes
validation/results/ms_methods_SIZE.csv and plots error against time per scene to ms_methods_SIZE.png.
The grid's time is nearly all its photons, which do not depend on the image size: at 512 x 512 it is
7-11x single scattering (docs/approximate.md), not the 7-180x seen at 64 x 48.

    python -m validation.accuracy.ms_methods [--size 64] [--paths 1024] [--spp 4 16 64 256]
        [--planned draft default] [--no-csv]
"""
from __future__ import annotations

import time

import numpy as np

from cloudmeta.renderer.frame import render_frame
from validation.accuracy.approximate import REPORT, reference, rel_error, scene_of
from validation.common import RESULTS, finish_time_error, parse, parser, pyplot, run_main, with_settings, write_csv


def _timed(scene, **kw):
    t0 = time.perf_counter()
    result = render_frame(scene, progress=False, **kw)
    return result.image[..., :3].astype(np.float64), time.perf_counter() - t0


def main(argv=None):
    ap = parser(__doc__, no_csv=True)
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--paths", type=int, default=1024, help="paths per pixel of the references")
    ap.add_argument("--spp", type=int, nargs="+", default=[4, 16, 64, 256])
    ap.add_argument("--planned", nargs="*", default=["draft", "default"],
                    help="quality presets whose planned paths are timed too")
    args, _ = parse(ap, argv)
    rows = []
    for name, path in REPORT.items():
        u, se, bt, _ = reference(name, path, args.size, args.paths)
        single = with_settings(scene_of(path, args.size), quality="default")
        approx = with_settings(scene_of(path, args.size, "approximate"), quality="default")
        render_frame(with_settings(scene_of(path, 4, "multiple"), ms_spp=1), progress=False)  # kernels loaded
        grid = with_settings(scene_of(path, args.size, "approximate", method="grid"), quality="default")
        runs = [("single", single, {}), ("octaves", approx, {}), ("grid", grid, {})]
        for n in args.spp:
            s = with_settings(scene_of(path, args.size, "multiple"), quality="default", ms_spp=n)
            runs += [(f"paths {n}", s, dict(seed=1)), (f"denoised {n}", s, dict(seed=1, denoise=True))]
        for q in args.planned:  # the paths planned to the preset's target (docs/multiple_scattering.md)
            runs.append((f"planned {q}", with_settings(scene_of(path, args.size, "multiple"), quality=q), dict(seed=1)))
        for method, scene, kw in runs:
            image, seconds = _timed(scene, **kw)
            err = rel_error(image, u, se, bt)
            rows.append(dict(scene=name, method=method, seconds=round(seconds, 3), error=round(err, 5)))
            print(f"{name:<14} {method:<13} {seconds:8.2f} s  error {err:.4f}", flush=True)
    if not args.no_csv:
        write_csv(RESULTS / f"ms_methods_{args.size}.csv", rows)
        plot(rows, RESULTS / f"ms_methods_{args.size}.png", args.size)
    return dict(rows=rows)


def plot(rows, out, size):
    plt = pyplot()
    names = list(dict.fromkeys(r["scene"] for r in rows))
    fig, axes = plt.subplots(2, 3, figsize=(12, 7), sharex=True, sharey=True)
    for ax, name in zip(axes.flat, names):
        mine = [r for r in rows if r["scene"] == name]
        for kind, style in (("paths", "o-"), ("denoised", "s-")):
            pts = [r for r in mine if r["method"].startswith(kind)]
            ax.plot([r["seconds"] for r in pts], [r["error"] for r in pts], style,
                    label="multiple, unbiased" if kind == "paths" else "multiple, denoised")
        for method, marker, label in (("single", "v", "single scattering"), ("octaves", "^", "approximate (octaves)"),
                                      ("grid", "D", "approximate (grid)"), ("planned draft", "P", "planned paths, draft"),
                                      ("planned default", "X", "planned paths, default")):
            r = next((r for r in mine if r["method"] == method), None)
            if r is not None:
                ax.plot([r["seconds"]], [r["error"]], marker, markersize=9, label=label)
    finish_time_error(fig, axes, names, "relative RMSE (of the scattered light)",
                      f"Multiply scattered light: time against error, {size} px wide, against converged references", out)


if __name__ == "__main__":
    run_main(main)
