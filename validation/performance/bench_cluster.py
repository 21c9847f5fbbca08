"""The cost of a Dask cluster: an animation rendered on a 2-worker local cluster against the same frames
rendered in this one process, side by side (alternating), with the frames checked bit-identical.

    python -m validation.performance.bench_cluster [--scene scenes/merging_clouds.yaml] [--frames 24]
        [--size 256] [--quality draft] [--repeats 3] [--workers 2]

Three figures per repeat: this process alone (numba on every core); the cluster with a client started
beforehand and its workers warmed (the cluster's own overhead: task and pixel transfer, per-task scene
loading, the split of cores between processes); and the cluster as the CLI's --workers runs it (start-up and
shut-down of the worker processes included). Overheads are relative to this process, medians over the
repeats with the spread (min..max). On a shared machine the figures are noisy: compare the ratios.
"""
from __future__ import annotations

import logging
import os
import statistics
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

import cloudmeta as cm
from cloudmeta.api.cluster import render_frames
from validation.common import ROOT, parse, parser, run_main


def timed(fn):
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start


def main(argv=None):
    p = parser(__doc__)
    p.add_argument("--scene", default=str(ROOT / "scenes" / "merging_clouds.yaml"))
    p.add_argument("--frames", type=int, default=24)
    p.add_argument("--size", type=int, default=256)
    p.add_argument("--quality", default="draft")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--workers", type=int, default=2)
    args, _ = parse(p, argv)
    from distributed import Client, LocalCluster
    warnings.filterwarnings("ignore", message="Port .* is already in use", category=UserWarning)

    frames = range(args.frames)
    load_before = os.getloadavg()[0]
    common = dict(width=args.size, height=args.size, render={"quality": args.quality}, overwrite=True,
                  progress=False)
    env = {"PYTHONPATH": str(ROOT)}  # the workers import this checkout's cloudmeta
    with tempfile.TemporaryDirectory() as tmp:
        out = {k: Path(tmp) / k for k in ("local", "client", "cli")}
        for folder in out.values():
            folder.mkdir()
        pattern = lambda k: out[k] / "f_{frame:04d}.exr"  # noqa: E731
        # warm up: this process's kernels, then the cluster's workers (numba's on-disk cache, shared)
        render_frames(args.scene, [0], pattern("local"), **common)
        os.environ["PYTHONPATH"] = str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")
        times = {"local": [], "client": [], "cli": []}
        with LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                          dashboard_address=None, silence_logs=logging.ERROR, env=env) as cluster, \
                Client(cluster) as client:
            render_frames(args.scene, range(args.workers), pattern("client"), client=client, **common)
            for _ in range(args.repeats):
                times["local"].append(timed(lambda: render_frames(args.scene, frames, pattern("local"), **common)))
                times["client"].append(timed(lambda: render_frames(args.scene, frames, pattern("client"),
                                                                   client=client, **common)))
                times["cli"].append(timed(lambda: render_frames(args.scene, frames, pattern("cli"),
                                                                workers=args.workers, **common)))
        same = all(np.array_equal(cm.read_exr(out["local"] / f"f_{f:04d}.exr")[0],
                                  cm.read_exr(out[k] / f"f_{f:04d}.exr")[0]) for f in frames for k in ("client", "cli"))
    local = statistics.median(times["local"])
    print(f"{args.frames} frames of {Path(args.scene).name} at {args.size} x {args.size}, quality {args.quality}, "
          f"{os.cpu_count()} cores, {args.repeats} repeats (alternating), load average {load_before:.1f} before, "
          f"{os.getloadavg()[0]:.1f} after")
    print(f"{'run':<46}{'median s':>10}{'min..max s':>16}{'s / frame':>11}{'overhead':>10}")
    names = {"local": "this process (numba threads on every core)",
             "client": f"local cluster, {args.workers} workers, started before",
             "cli": f"local cluster, {args.workers} workers, start-up included"}
    for k, label in names.items():
        med = statistics.median(times[k])
        print(f"{label:<46}{med:>10.2f}{f'{min(times[k]):.2f}..{max(times[k]):.2f}':>16}{med / args.frames:>11.3f}"
              f"{(med - local) / local * 100:>+9.1f}%")
    print(f"frames bit-identical between this process and the cluster: {same}")
    return dict(times=times, identical=same, passed=same)


if __name__ == "__main__":
    run_main(main)
