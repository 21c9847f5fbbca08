"""Render cost against ball count: a generated cumulus of fixed size and shape at 10^3 .. 10^5 (10^6) balls,
the same image, camera and light, single scattering at ``default``.

For each ball count, in a process of its own (so that its peak memory is its own): the generation time, the
scene's load (CSV parsing and validation), the BVH build (``pack_scene``), the render, and the process's
peak resident memory; plus the balls a camera ray meets (its BVH candidates and overlapping chords, on a
sample of the image's rays), the quantity the cost per pixel follows. Every count is rendered ``--repeats``
times, the counts alternating round by round; medians and spreads (min-max) are printed, written to
validation/results/scale.csv and plotted to validation/results/scale.png.

    python -m validation.performance.scale [--balls 1000 10000 100000] [--size 512] [--repeats 3] [--kind cumulus]
"""
from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from validation.common import RESULTS, ROOT, parse, parser, run_main, write_csv

CHILD = r"""
import json, resource, sys, time
from dataclasses import replace
import numpy as np
import cloudmeta as cm
from cloudmeta.generate import generate, write_scene
from cloudmeta.renderer.pack import pack_scene
kind, n, size, folder, camera_from = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4], sys.argv[5]
t0 = time.perf_counter()
cloud = generate(kind, balls=n, seed=1)
t_gen = time.perf_counter() - t0
yaml_path = f"{folder}/{kind}_{n}.yaml"
write_scene(cloud, yaml_path, width=size, height=size, overwrite=True)
t0 = time.perf_counter()
scene = cm.load_scene(yaml_path)
t_load = time.perf_counter() - t0
ref = cm.load_scene(camera_from)  # the same camera, image and lights for every ball count
scene = replace(scene, camera=ref.camera, image=replace(ref.image, width=size, height=size), lights=ref.lights,
                background=ref.background, ambient=ref.ambient)
t0 = time.perf_counter()
packed = pack_scene(scene, 0)
t_pack = time.perf_counter() - t0
t0 = time.perf_counter()
img = cm.render(scene, progress=False)
t_render = time.perf_counter() - t0
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
print(json.dumps(dict(balls=len(scene.media[0].blob), generate=t_gen, load=t_load, pack=t_pack, render=t_render,
                      peak_mb=peak, mean=float(img[..., :3].mean()), cover=float((img[..., 3] > 0.01).mean()))))
"""


def run_one(kind, n, size, folder, camera_from):
    out = subprocess.run([sys.executable, "-c", CHILD, kind, str(n), str(size), folder, camera_from],
                         capture_output=True, text=True, cwd=ROOT)
    if out.returncode != 0:
        raise RuntimeError(out.stderr[-2000:])
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None, quick=False):
    ap = parser(__doc__, no_csv=True)
    ap.add_argument("--balls", type=int, nargs="+", default=[1000, 10000, 100000])
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--kind", default="cumulus")
    args, quick = parse(ap, argv, quick)
    from cloudmeta.generate import generate, write_scene
    with tempfile.TemporaryDirectory() as folder:
        # the camera and light of the smallest cloud frame every count (the shape is the same at every count)
        camera_from = f"{folder}/frame.yaml"
        write_scene(generate(args.kind, balls=min(args.balls), seed=1), camera_from, width=args.size,
                    height=args.size)
        runs = {n: [] for n in args.balls}
        for _ in range(args.repeats):
            for n in args.balls:
                runs[n].append(run_one(args.kind, n, args.size, folder, camera_from))
                r = runs[n][-1]
                print(f"  {n:>8} balls: generate {r['generate']:.2f} s, load {r['load']:.2f} s, pack (BVH) "
                      f"{r['pack']:.2f} s, render {r['render']:.2f} s, peak {r['peak_mb']:.0f} MB", flush=True)
    rows = []
    base = None
    for n in args.balls:
        med = {k: float(np.median([r[k] for r in runs[n]])) for k in ("generate", "load", "pack", "render", "peak_mb")}
        spread = {k: (min(r[k] for r in runs[n]), max(r[k] for r in runs[n])) for k in ("render",)}
        base = med["render"] if base is None else base
        rows.append(dict(balls=runs[n][0]["balls"], generate_s=f"{med['generate']:.2f}", load_s=f"{med['load']:.2f}",
                         pack_s=f"{med['pack']:.2f}", render_s=f"{med['render']:.2f}",
                         render_min=f"{spread['render'][0]:.2f}", render_max=f"{spread['render'][1]:.2f}",
                         render_ratio=f"{med['render'] / base:.2f}", peak_mb=f"{med['peak_mb']:.0f}",
                         mean=f"{runs[n][0]['mean']:.4f}", cover=f"{runs[n][0]['cover']:.3f}"))
        print(f"{n:>8} balls: render {med['render']:.2f} s (min {spread['render'][0]:.2f}, max "
              f"{spread['render'][1]:.2f}; {med['render'] / base:.2f}x the smallest), BVH/pack {med['pack']:.2f} s, "
              f"load {med['load']:.2f} s, generate {med['generate']:.2f} s, peak {med['peak_mb']:.0f} MB")
    if not args.no_csv and not quick:
        write_csv(RESULTS / "scale.csv", rows)
        plot(rows, RESULTS / "scale.png")
    return {"rows": rows}


def plot(rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    n = [int(r["balls"]) for r in rows]
    fig, ax = plt.subplots(figsize=(5.5, 3.6), dpi=120)
    for key, label in (("render_s", "render (512 x 512)"), ("pack_s", "pack + BVH build"), ("load_s", "load (CSV)"),
                       ("generate_s", "generate")):
        ax.loglog(n, [float(r[key]) for r in rows], "o-", label=label)
    ax.set_xlabel("balls")
    ax.set_ylabel("seconds (median)")
    ax.set_title("A generated cumulus: cost against ball count")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


if __name__ == "__main__":
    run_main(main)
