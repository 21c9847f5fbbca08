"""The approximate mode's shared method (docs/approximate.md, "Shared"), measured on the six report scenes.

At ``--size`` (default 512 wide) each scene renders at each ``--quality`` with ``method: shared`` (whole frame,
both cores, seed 1); its error is the mode's own estimate (renderer.approximate.approximation_error: 128 cloud
pixels against unbiased paths; no converged reference exists at this size), with the tails'
noise part of it (the error channels' RMS: the tails' noise and the quadrature's) beside it; the time is
``render_frame(error=True)``'s, the estimate included. With ``--check`` the same at 64 wide against the references of
validation.accuracy.approximate (2,048 paths, their noise subtracted): the true error beside the estimate.

    python -m validation.accuracy.ms_shared [--size 512] [--quality draft default] [--scenes ...] [--check]
"""
from __future__ import annotations

import time

import numpy as np

import cloudmeta as cm
from validation.accuracy.approximate import REPORT, background_times_t, reference, rel_error, scene_of
from validation.common import parse, parser, run_main, with_settings


def measure(name, size, quality, seed=1):
    """One scene at one quality, rendered with ``error=True`` (the time includes the estimate): a dict of its time,
    the estimated error (renderer.approximate.approximation_error) and the noise the error channels hold (the
    tails' and the quadrature's), relative to the scattered light."""
    s = with_settings(scene_of(REPORT[name], size, "approximate", method="shared"), quality=quality)
    t0 = time.perf_counter()
    result = cm.render_frame(s, progress=False, seed=seed, error=True)
    seconds = time.perf_counter() - t0
    h, w = s.image.height, s.image.width
    image = result.image.astype(np.float64)
    scattered = float((image[..., :3] - background_times_t(s, image)).mean())
    noise = float(np.sqrt(np.mean(result.error.astype(np.float64) ** 2))) / scattered
    est = result.approximation
    return dict(scene=name, size=f"{w}x{h}", quality=quality, seconds=seconds, estimated=est.rel_rmse,
                est_se=est.stderr, noise=noise, image=image)


def main(argv=None):
    ap = parser(__doc__)
    ap.add_argument("--scenes", nargs="+", default=list(REPORT), choices=list(REPORT))
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--quality", nargs="+", default=["draft"])
    ap.add_argument("--check", action="store_true", help="at 64 wide against the converged references")
    args, _ = parse(ap, argv)
    rows = []
    size = 64 if args.check else args.size
    for name in args.scenes:
        for quality in args.quality:
            r = measure(name, size, quality)
            line = (f"{name:14s} {r['size']:>8s} {quality:8s} {r['seconds']:7.1f} s"
                    f"  estimated {r['estimated']:.3f} +- {r['est_se']:.3f} (tails' noise {r['noise']:.3f})")
            if args.check:
                u, se, bt, _ = reference(name, REPORT[name], 64, 2048)
                r["true"] = rel_error(r["image"][..., :3], u, se, bt)
                line += f"  true {r['true']:.3f}"
            print(line, flush=True)
            rows.append({k: v for k, v in r.items() if k != "image"})
    return dict(rows=rows)


if __name__ == "__main__":
    run_main(main)
