"""Planned multiple-scattering paths (``render.ms_spp`` auto) against their promise: on
validation.accuracy.approximate's six report scenes, the relative RMSE of the planned image against a converged
reference, relative to the scattered light (the reference's own noise subtracted), beside the renderer's own
estimate of it and the preset's target, with the time and the paths per pixel the plan chose.

Per scene (64 x 48 unless --size, ambient removed, the report's references of ``--paths`` paths per pixel,
seed 0; approximate.reference caches them in validation/results/approximate/): the planned render at each
``--quality`` (seed 1), its estimate (RenderResult.estimated: the paths' standard errors over the frame's
scattered light) and its true error (approximate.rel_error). The ratio estimate / true must lie within 0.5-2.
The time is the whole render_frame call, kernels loaded, process CPU and wall.

    python -m validation.accuracy.ms_promise [--size 64] [--paths 2048] [--quality draft default] [--no-csv]
"""
from __future__ import annotations

import time

import numpy as np

from cloudmeta.renderer.frame import render_frame
from validation.accuracy.approximate import FIT, REPORT, reference, rel_error, scene_of
from validation.common import RESULTS, parse, parser, run_main, with_settings, write_csv


def main(argv=None):
    ap = parser(__doc__, no_csv=True)
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--paths", type=int, default=2048, help="paths per pixel of the references")
    ap.add_argument("--quality", nargs="+", default=["draft"])
    ap.add_argument("--scenes", nargs="+", default=list(REPORT), choices=list(REPORT) + list(FIT),
                    help="the report's six (default) or the approximate mode's four fitting scenes (held out here)")
    args, _ = parse(ap, argv)
    rows = []
    for name in args.scenes:
        path = {**REPORT, **FIT}[name]
        u, se, bt, _ = reference(name, path, args.size, args.paths)
        render_frame(with_settings(scene_of(path, 4, "multiple"), ms_spp=1), progress=False)  # kernels loaded
        for quality in args.quality:
            scene = with_settings(scene_of(path, args.size, "multiple"), quality=quality, ms_spp=None)
            wall, cpu = time.perf_counter(), time.process_time()
            result = render_frame(scene, progress=False, seed=1)
            wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
            true = rel_error(result.image[..., :3].astype(np.float64), u, se, bt)
            h, w = scene.image.height, scene.image.width
            row = dict(scene=name, quality=quality, target=result.settings.paths_target,
                       estimated=round(result.estimated, 5), true=round(true, 5),
                       ratio=round(result.estimated / true, 3) if true > 0 else float("nan"),
                       paths=round(result.plan.mean_paths(h, w), 1), max_paths=int(result.plan.paths.max()),
                       cpu=round(cpu, 2), wall=round(wall, 2))
            rows.append(row)
            print("  ".join(f"{k} {v}" for k, v in row.items()), flush=True)
    if not args.no_csv:
        write_csv(RESULTS / f"ms_promise_{args.size}.csv", rows)
    return dict(rows=rows)


if __name__ == "__main__":
    run_main(main)
