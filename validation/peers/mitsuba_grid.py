"""A voxel cloud's fit rendered by cloudmeta against Mitsuba 3.8's render of the voxel grid itself
(docs/fit.md, *Against Mitsuba's render of the grid*).

Mitsuba 3.8.0 (``pip install mitsuba==3.8.0``, variant ``llvm_ad_rgb``, as validation/peers/mitsuba_peer.py)
renders the grid as it is: a ``heterogeneous`` medium whose ``sigma_t`` is a ``gridvolume`` of the grid's
values (mi.VolumeGrid, trilinear, cell-centred: voxel i covers the i-th h of the box and holds the value at
its centre, the VoxelGrid's convention) inside a ``cube`` with a null BSDF spanning the grid's box. The
camera, the sun (its direction and linear RGB irradiance as cloudmeta computes them), the albedo and the HG
phase are the fitted scene's (cloudmeta fit writes them; mitsuba_peer.mitsuba_scene translates them).
The sky is dropped on both sides (black background, no ambient): the image is then the light the medium
scatters, nothing else, so its relative error needs no background subtracted.

    single     cloudmeta ``scattering: single`` against Mitsuba's volpath with max_depth 2 (the camera
               segment and one scattering: single scattering of the sun)
    multiple   cloudmeta ``scattering: multiple`` (``--paths`` paths per camera ray, max_order 1000) against
               volpath with max_depth -1 (unlimited)

Each renderer renders two independent halves (different seeds), A1, A2 and B1, B2; A and B are their
means. The per-pixel noise variance of a mean of two halves is estimated by (A1 - A2)^2 / 4, so

    err^2 = mean (A - B)^2 - mean (A1 - A2)^2 / 4 - mean (B1 - B2)^2 / 4

is the squared RMS difference that the noise does not explain, and the relative error is sqrt(err^2) / mean B
(B: Mitsuba's image), means over the cloud's pixels (those not 0 in one of the four images: the others see
the black background in both renderers), all three channels. The same is computed on the means of BLOCK x
BLOCK pixel blocks, whose noise is BLOCK times lower, where the multiple-scattering images are too noisy
per pixel for the subtraction to leave a steady difference. Times are process CPU time
(time.process_time, every thread's) on a machine shared with other work.

    python -m validation.peers.mitsuba_grid GRID FIT.yaml [--size 128] [--mi-spp 256] [--png docs/fit_vs_mitsuba.png]

GRID is read with cloudmeta.fit.read_grid (the grid that FIT.yaml was fitted to). Without mitsuba it says
how to install it and exits 0.
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import time
from dataclasses import replace

import numpy as np

from validation.peers.mitsuba_peer import INSTALL, MITSUBA_VERSION, VARIANT, block_means, mitsuba_scene

#: cloudmeta's max_order in multiple mode (Mitsuba: max_depth -1)
MAX_ORDER = 1000
#: block side (pixels) of the second comparison: block means have BLOCK times less noise
BLOCK = 4


def mitsuba_grid(grid):
    """((nz, ny, nx) float32 sigma_t, origin, voxel size (3,), dims (nx, ny, nz)) of a VoxelGrid, as
    mitsuba_peer.mitsuba_scene takes it (Mitsuba's data order: z slowest, x fastest)."""
    density = np.asarray(grid.density)
    sigma = np.ascontiguousarray(density.transpose(2, 1, 0), dtype=np.float32)
    dims = np.array(density.shape, dtype=np.int64)
    lower, upper = np.asarray(grid.lower, float), np.asarray(grid.upper, float)
    return sigma, lower, (upper - lower) / dims, dims


def comparison_scene(scene, size, spp, scattering, paths=None):
    """The fitted scene as compared: size x size pixels, ``spp`` stratified camera rays per pixel, black
    background, no sky, no ambient light; ``scattering`` single or multiple (``paths`` per camera ray)."""
    render = replace(scene.render, scattering=scattering)
    if scattering == "multiple":
        render = replace(render, ms_spp=int(paths), max_order=MAX_ORDER)
    image = replace(scene.image, width=size, height=size, spp=spp)
    return replace(scene, image=image, background=np.zeros(3), ambient=None, sky=None, render=render)


def _timed_images(render, seeds):
    """([render(seed)[..., :3] as float64 for each seed], their process CPU time in all)."""
    out, cpu = [], 0.0
    for seed in seeds:
        c0 = time.process_time()
        out.append(np.asarray(render(seed), np.float64)[..., :3])
        cpu += time.process_time() - c0
    return out, cpu


def cloudmeta_images(scene, seeds):
    import cloudmeta as cm
    return _timed_images(lambda seed: cm.render(scene, progress=False, seed=seed), seeds)


def mitsuba_images(mi, ms, spp, seeds):
    return _timed_images(lambda seed: np.array(mi.render(ms, spp=spp, seed=seed)), seeds)


def compare(a_halves, b_halves):
    """Relative error of A (cloudmeta) against B (Mitsuba), noise of both subtracted (module docstring)."""
    a1, a2 = a_halves
    b1, b2 = b_halves
    a, b = 0.5 * (a1 + a2), 0.5 * (b1 + b2)
    # the cloud's pixels: with a black background every other pixel is 0 in all four images
    cloud = ((np.stack([a1, a2, b1, b2]) > 0).any(axis=(0, 3)))
    a1, a2, b1, b2, a, b = (x[cloud] for x in (a1, a2, b1, b2, a, b))
    norm = float(b.mean())
    raw = float(np.mean((a - b) ** 2))
    noise_a = float(np.mean((a1 - a2) ** 2)) / 4.0
    noise_b = float(np.mean((b1 - b2) ** 2)) / 4.0
    err2 = raw - noise_a - noise_b
    return dict(rel_rmse=math.sqrt(max(err2, 0.0)) / norm, raw_rel_rmse=math.sqrt(raw) / norm,
                cm_noise=math.sqrt(noise_a) / norm, mi_noise=math.sqrt(noise_b) / norm,
                rel_mean=float(a.mean()) / norm - 1.0, mean=norm, err2_negative=err2 < 0,
                pixels=int(cloud.sum()))


def _tone(img, white):
    x = np.clip(np.asarray(img) / white, 0.0, None)
    return np.clip(x ** (1 / 2.2), 0.0, 1.0)


def _pct(res):
    return "within noise" if res["err2_negative"] else f"{res['rel_rmse']:.1%}"


def figure(rows, path):
    """A PNG, one row per (label, cloudmeta image, Mitsuba image, compare's result on pixels and on blocks):
    fit | Mitsuba | difference."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(len(rows), 3, figsize=(9.6, 3.35 * len(rows)), squeeze=False)
    for r, (label, a, b, res, blocks) in enumerate(rows):
        white = float(np.quantile(b, 0.995))
        diff = (a - b).mean(axis=2)
        lim = float(np.quantile(np.abs(diff), 0.995)) or 1.0
        panels = ((_tone(a, white), f"cloudmeta: fitted balls, {label}"),
                  (_tone(b, white), f"Mitsuba {MITSUBA_VERSION}: the voxel grid"),
                  (None, f"cloudmeta - Mitsuba; rel. RMSE, noise subtracted:\n"
                         f"pixels {_pct(res)}, {BLOCK}x{BLOCK} blocks {_pct(blocks)}"))
        for c, (img, title) in enumerate(panels):
            ax = axes[r, c]
            if img is None:
                im = ax.imshow(diff, cmap="RdBu_r", vmin=-lim, vmax=lim)
                fig.colorbar(im, ax=ax, fraction=0.046, pad=0.02)
            else:
                ax.imshow(img)
            ax.set_title(title, fontsize=9)
            ax.set_xticks([])
            ax.set_yticks([])
    fig.tight_layout()
    tmp = str(path) + ".part.png"
    fig.savefig(tmp, dpi=100)
    plt.close(fig)
    os.replace(tmp, path)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("grid", help="the voxel grid (read with cloudmeta.fit.read_grid)")
    ap.add_argument("scene", help="the scene cloudmeta fit wrote for it")
    ap.add_argument("--conversion", default=None, help="read_grid's conversion (e.g. lwc:10um:g m-3)")
    ap.add_argument("--size", type=int, default=128, help="pixels a side (default 128)")
    ap.add_argument("--mi-spp", type=int, default=256, help="Mitsuba samples per pixel per half (default 256)")
    ap.add_argument("--cm-spp", type=int, default=4, help="cloudmeta camera rays per pixel (default 4)")
    ap.add_argument("--paths", type=int, default=16, help="cloudmeta paths per camera ray, multiple mode")
    ap.add_argument("--modes", nargs="+", choices=("single", "multiple"), default=["single", "multiple"])
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--png", help="write the side-by-side figure here")
    ap.add_argument("--save", help="save the images (npz) here")
    ap.add_argument("--replot", metavar="NPZ", help="no render: the figure (--png) from images --save wrote")
    args = ap.parse_args(argv)
    if args.replot:
        saved = np.load(args.replot)
        rows = []
        for mode in args.modes:
            a, b = list(saved[f"{mode}_cloudmeta"]), list(saved[f"{mode}_mitsuba"])
            rows.append((mode, 0.5 * (a[0] + a[1]), 0.5 * (b[0] + b[1]), compare(a, b),
                         compare([block_means(x, BLOCK) for x in a], [block_means(x, BLOCK) for x in b])))
        figure(rows, args.png)
        print(f"wrote {args.png}")
        return 0
    try:
        import drjit as dr
        import mitsuba as mi
    except ImportError:
        print(INSTALL)
        return 0
    mi.set_variant(VARIANT)
    dr.set_thread_count(args.threads)
    import numba

    import cloudmeta as cm
    from cloudmeta.fit import parse_conversion, read_grid
    numba.set_num_threads(args.threads)
    grid = read_grid(args.grid, conversion=parse_conversion(args.conversion or ""))
    base = cm.load_scene(args.scene)
    vol = mitsuba_grid(grid)
    print(f"grid {args.grid}: {'x'.join(map(str, grid.density.shape))}, box {grid.lower.tolist()} .. "
          f"{grid.upper.tolist()}; fit {args.scene}: {len(base.media[0].blob.centers):,} balls; "
          f"{args.size}^2 pixels; Mitsuba {mi.__version__} {VARIANT}, {args.threads} threads", flush=True)
    rows, saved = [], {}
    for mode in args.modes:
        scene = comparison_scene(base, args.size, args.cm_spp, mode, args.paths)
        ms = mitsuba_scene(mi, scene, vol, 2 if mode == "single" else -1)
        mi.render(ms, spp=1, seed=999)  # JIT compile, untimed
        b, b_cpu = mitsuba_images(mi, ms, args.mi_spp, (1, 2))
        a, a_cpu = cloudmeta_images(scene, (1, 2))
        res = compare(a, b)
        blocks = compare([block_means(x, BLOCK) for x in a], [block_means(x, BLOCK) for x in b])
        what = "single" if mode == "single" else f"multiple, {args.paths} paths/ray"
        print(f"| {what} | {res['rel_rmse']:.2%} | {res['raw_rel_rmse']:.2%} | {res['cm_noise']:.2%} | "
              f"{res['mi_noise']:.2%} | {res['rel_mean']:+.2%} | {args.cm_spp} rays/px: {a_cpu:.1f} | "
              f"2 x {args.mi_spp} spp: {b_cpu:.1f} | {blocks['rel_rmse']:.2%} | {blocks['cm_noise']:.2%} | "
              f"{blocks['mi_noise']:.2%} |", flush=True)
        rows.append((mode, 0.5 * (a[0] + a[1]), 0.5 * (b[0] + b[1]), res, blocks))
        saved.update({f"{mode}_cloudmeta": np.stack(a), f"{mode}_mitsuba": np.stack(b)})
        del ms
    print(f"(columns: mode | rel. RMSE, noise subtracted | raw rel. RMSE | cloudmeta noise | Mitsuba noise | "
          f"mean cloudmeta / Mitsuba - 1 | cloudmeta CPU s | Mitsuba CPU s | on {BLOCK}x{BLOCK} pixel blocks: rel. RMSE, "
          "noise subtracted | cloudmeta noise | Mitsuba noise; relative to Mitsuba's mean over the cloud's pixels)")
    if args.save:
        np.savez(args.save, **saved)
    if args.png:
        figure(rows, args.png)
        print(f"wrote {args.png}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
