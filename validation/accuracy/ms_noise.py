"""Where the unbiased paths' noise comes from: per order kept, per pixel's opacity, in the worst pixels.

Renders the Monte Carlo part of scenes/generated_cumulus.yaml (``scattering: multiple``, its sky lighting the
cloud) at ``--size`` squared with ``--paths`` paths per pixel, once per ``--orders`` value of ``max_order``,
and prints per run: the frame's mean multiply scattered radiance, the variance of one path (the mean over
pixels and channels of paths x the squared standard error), their ratio as a relative standard deviation
(cv), the paths per pixel that a 10 % relative RMSE of that light would need with equal paths everywhere
(cv^2 / 0.1^2), and how the variance and the light split over the pixels' alpha and into the 1 % of pixels
with the most variance. Process CPU of each Monte Carlo render, kernels loaded.

    python -m validation.accuracy.ms_noise [--size 48] [--paths 64] [--orders 2 3 4 8 16 64]
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

import cloudmeta as cm
from cloudmeta.renderer.frame import render_frame
from cloudmeta.renderer.multiple import render_multiple
from validation.common import parse, parser, run_main, with_settings

SCENE = Path(__file__).resolve().parents[2] / "scenes" / "generated_cumulus.yaml"
ALPHA_BINS = ((0.0, 0.5), (0.5, 0.9), (0.9, 0.99), (0.99, 1.01))


def main(argv=None):
    ap = parser(__doc__)
    ap.add_argument("--size", type=int, default=48)
    ap.add_argument("--paths", type=int, default=64)
    ap.add_argument("--orders", type=int, nargs="+", default=[2, 3, 4, 8, 16, 64])
    args, _ = parse(ap, argv)
    base = with_settings(cm.load_scene(SCENE, width=args.size, height=args.size), scattering="single",
                         quality="draft")
    alpha = render_frame(base, progress=False).image[..., 3]
    rows = []
    for order in args.orders:
        scene = with_settings(base, scattering="multiple", ms_spp=args.paths, max_order=order)
        render_multiple(with_settings(scene, ms_spp=1), progress=False)  # kernels loaded outside the clock
        t0 = time.process_time()
        mean, stderr = render_multiple(scene, progress=False)
        cpu = time.process_time() - t0
        var = stderr ** 2 * args.paths
        cv = float(np.sqrt(var.mean()) / mean.mean())
        v_px, m_px = var.mean(-1), mean.mean(-1)
        top = np.sort(v_px.ravel())[::-1]
        top_share = float(top[:max(1, top.size // 100)].sum() / top.sum())
        print(f"max_order {order:3d}: light {mean.mean():.4f}  variance a path {var.mean():.4f}  cv {cv:.2f}  "
              f"paths a pixel for 10 % {cv * cv / 0.01:6.0f}  worst 1 % of pixels {top_share:.2f} of the variance  "
              f"CPU {cpu:.2f} s", flush=True)
        for lo, hi in ALPHA_BINS:
            inside = (alpha >= lo) & (alpha < hi)
            if inside.any():
                print(f"    alpha {lo:.2f}-{min(hi, 1.0):.2f}: {inside.sum():5d} pixels, "
                      f"{v_px[inside].sum() / v_px.sum():.2f} of the variance, "
                      f"{m_px[inside].sum() / m_px.sum():.2f} of the light")
        rows.append(dict(max_order=order, light=float(mean.mean()), variance=float(var.mean()), cv=cv,
                         top_share=top_share, cpu=cpu))
    return dict(rows=rows)


if __name__ == "__main__":
    run_main(main)
