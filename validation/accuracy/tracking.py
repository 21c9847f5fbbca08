"""Tracked flights against exact ones: the multiple-scattering image of the cumulus, front- and back-lit,
with flights tracked from vertex 2 (the default) and with every flight exact, 4 seeds x 1024 paths per
pixel each; the two are independent unbiased estimates of one image.

Measured (docs/benchmarks.md; the design: docs/multiple_scattering.md): the difference of the image means in units of
its standard error (requirement |z| <= 3), and the RMS over 4 x 4-pixel blocks of the blocks' z-scores
(requirement <= 1.15: the standard errors are honest and no block is biased). The standard errors come from
the spread of the seeds' images, not from the paths' own estimates.

    python -m validation.accuracy.tracking [--quick] [--size 48] [--paths 1024] [--seeds 4]

Writes validation/results/tracking.csv (full runs only).
"""
from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from validation.common import fresh_kernels_when_run, parse, parser, run_main, write_csv

fresh_kernels_when_run(__name__)

import cloudmeta as cm  # noqa: E402
from cloudmeta.renderer.multiple import render_multiple  # noqa: E402
from validation.common import ROOT  # noqa: E402

#: every flight exact: a first tracked vertex beyond any max_order
EXACT = 10 ** 9 + 1
BLOCK = 4


def images(scene, track_from, seeds, paths):
    """The seeds' Monte Carlo images (seeds x H x W x 3) and the seconds they took."""
    scene = replace(scene, render=replace(scene.render, track_from=track_from))
    t0 = time.perf_counter()
    out = np.stack([render_multiple(scene, paths=paths, seed=s)[0] for s in range(seeds)])
    return out, time.perf_counter() - t0


def compare(a, b):
    """(z of the image means, RMS of the blocks' z): a and b are seeds x H x W x 3 stacks."""
    def mean_and_var(x, axes):
        per_seed = x.mean(axis=axes)
        return per_seed.mean(axis=0), per_seed.var(axis=0, ddof=1) / x.shape[0]
    ma, va = mean_and_var(a, (1, 2, 3))
    mb, vb = mean_and_var(b, (1, 2, 3))
    z_image = float((ma - mb) / np.sqrt(va + vb))
    s, h, w, _ = a.shape
    hb, wb = h // BLOCK, w // BLOCK

    def blocks(x):
        return x[:, :hb * BLOCK, :wb * BLOCK].reshape(s, hb, BLOCK, wb, BLOCK, 3).mean(axis=(2, 4, 5))
    ba, bb = blocks(a), blocks(b)
    va_b = ba.var(axis=0, ddof=1) / s
    vb_b = bb.var(axis=0, ddof=1) / s
    lit = (va_b + vb_b) > 0
    z_blocks = (ba.mean(axis=0) - bb.mean(axis=0))[lit] / np.sqrt(va_b + vb_b)[lit]
    return z_image, float(np.sqrt(np.mean(z_blocks ** 2))), int(lit.sum())


def main(argv=None, quick=False):
    ap = parser(__doc__, quick="16^2 pixels, 64 paths, 2 seeds: a smoke run, no verdict on the figures")
    ap.add_argument("--size", type=int, default=48)
    ap.add_argument("--paths", type=int, default=1024)
    ap.add_argument("--seeds", type=int, default=4)
    args, quick = parse(ap, argv, quick)
    size, paths, seeds = (16, 64, 2) if quick else (args.size, args.paths, args.seeds)
    rows = []
    for name in ("cumulus", "cumulus_backlit"):
        scene = cm.load_scene(ROOT / "scenes" / f"{name}.yaml", width=size, height=size)
        scene = replace(scene, ambient=None, render=replace(scene.render, scattering="multiple"))
        small = replace(scene, image=replace(scene.image, width=4, height=4))
        for track_from in (2, EXACT):  # the kernels load (or compile) outside the clock
            images(small, track_from, 1, 4)
        tracked, t_tracked = images(scene, 2, seeds, paths)
        exact, t_exact = images(scene, EXACT, seeds, paths)
        z_image, z_rms, n_blocks = compare(tracked, exact)
        rows.append(dict(scene=name, size=size, paths=paths, seeds=seeds, mean_tracked=float(tracked.mean()),
                         mean_exact=float(exact.mean()), z_image=z_image, z_block_rms=z_rms, blocks=n_blocks,
                         t_tracked=t_tracked, t_exact=t_exact))
        print(f"  {name:16s} {size}^2, {seeds} x {paths} paths: mean tracked {tracked.mean():.5f}, exact "
              f"{exact.mean():.5f}, z {z_image:+.2f}; block z RMS {z_rms:.3f} over {n_blocks} blocks; "
              f"{t_tracked:.0f} s against {t_exact:.0f} s", flush=True)
    passed = quick or all(abs(r["z_image"]) <= 3.0 and r["z_block_rms"] <= 1.15 for r in rows)
    if not quick:
        write_csv("tracking.csv", rows)
    print("passed" if passed else "FAILED")
    return dict(passed=passed, rows=rows)


if __name__ == "__main__":
    run_main(main)
