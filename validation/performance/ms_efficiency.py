"""Variance x time of multiple-scattering estimators: checkouts (or settings) alternating on one thread.

For each case (scenes/cumulus.yaml front-lit and scenes/cumulus_backlit.yaml back-lit, ambient removed so
that the sky lights them, as the multiple mode requires), each estimator renders the Monte Carlo part
(renderer.multiple.render_multiple) at ``--size`` squared with ``--paths`` paths per pixel in a fresh
process on ONE thread (NUMBA_NUM_THREADS=1), its kernels loaded outside the clock; the estimators
alternate ``--rounds`` times. An estimator is ``DIR`` (a checkout, as it renders by default) or
``DIR:N`` (a checkout that knows ``render.track_from``, with track_from N; N = 1000000001 keeps every flight
exact). Per estimator: the median time and its spread, the image's variance (the mean over pixels and
channels of the squared standard error of the pixel means: the same every round, the seeds being fixed)
and the efficiency 1 / (variance x time), relative to the first estimator.

    python -m validation.performance.ms_efficiency OLD NEW[:N] ... [--size 64] [--paths 64] [--rounds 3]

Every checkout must have its kernels compiled (a multiple-scattering render of each once).
"""
from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import textwrap
from pathlib import Path

from validation.common import parse, parser, run_main

CASES = {"front": "scenes/cumulus.yaml", "back": "scenes/cumulus_backlit.yaml"}

_RUN = textwrap.dedent("""
    import json, sys, time
    from dataclasses import replace
    import numpy as np
    import cloudmeta as cm
    from cloudmeta.renderer.multiple import render_multiple
    path, size, paths, track_from, out = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4], sys.argv[5]
    def scene(w):
        s = cm.load_scene(path, width=w, height=w)
        settings = dict(scattering="multiple", ms_spp=paths)
        if track_from != "default":
            settings["track_from"] = int(track_from)
        return replace(s, ambient=None, render=replace(s.render, **settings))
    render_multiple(scene(4))
    s = scene(size)
    t0 = time.perf_counter()
    mean, err = render_multiple(s)
    seconds = time.perf_counter() - t0
    json.dump(dict(seconds=seconds, variance=float(np.mean(err ** 2)), mean=float(mean.mean())), open(out, "w"))
""")


def run_one(checkout, track_from, case, size, paths, out):
    env = dict(os.environ, NUMBA_NUM_THREADS="1", PYTHONPATH=str(checkout))
    scene = Path(checkout) / CASES[case]
    subprocess.run([sys.executable, "-c", _RUN, str(scene), str(size), str(paths), track_from, str(out)],
                   check=True, env=env, cwd=checkout)
    return json.loads(Path(out).read_text())


def main(argv=None, quick=False):
    ap = parser(__doc__)
    ap.add_argument("estimators", nargs="+", help="DIR or DIR:TRACK_FROM, the first one the reference")
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--paths", type=int, default=64)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    args, _ = parse(ap, argv, quick)
    estimators = []
    for spec in args.estimators:
        path, _, tf = spec.partition(":")
        estimators.append((spec, Path(path).resolve(), tf or "default"))
    tmp = Path(os.environ.get("TMPDIR", "/tmp")) / f"ms_efficiency_{os.getpid()}.json"
    rows = []
    for case in args.cases:
        runs = {spec: [] for spec, _, _ in estimators}
        for _ in range(args.rounds):
            for spec, path, tf in estimators:
                runs[spec].append(run_one(path, tf, case, args.size, args.paths, tmp))
        first = None
        print(f"{case}: {args.size}^2, {args.paths} paths per pixel, one thread, {args.rounds} rounds")
        for spec, _, _ in estimators:
            times = [r["seconds"] for r in runs[spec]]
            t = statistics.median(times)
            var = runs[spec][-1]["variance"]
            eff = 1.0 / (var * t)
            first = first or (t, var, eff)
            rows.append(dict(case=case, estimator=spec, seconds=t, t_min=min(times), t_max=max(times), variance=var,
                             mean=runs[spec][-1]["mean"], efficiency=eff / first[2]))
            print(f"  {spec:40s} {t:7.2f} s ({min(times):.2f}-{max(times):.2f})  variance {var:.3e}  "
                  f"mean {runs[spec][-1]['mean']:.5f}  time {first[0] / t:5.2f}x  variance {first[1] / var:5.2f}x  "
                  f"variance x time {eff / first[2]:5.2f}x", flush=True)
    tmp.unlink(missing_ok=True)
    return dict(rows=rows)


if __name__ == "__main__":
    run_main(main)
