"""Denoised multiple scattering (``denoise=True``, renderer.denoise) against converged unbiased multiple
scattering: how far a denoised image at 16 and 64 paths per pixel is from the truth, next to the raw one's.

Scenes: validation.accuracy.approximate's REPORT scenes (front-, back- and side-lit cumulus, the bank, a deck
under a low sun, small wispy puffs), 64 x 48 unless --size, ambient removed. Reference per scene: single
scattering at ``fine`` plus ``--paths`` paths per pixel (seed 0; cached with approximate's references).
The test images use seed 1, so their paths are independent of the reference's. Error relative to the
scattered light, the reference's own variance subtracted (approximate.rel_error). Variants: the raw image,
OIDN guided by the albedo (what ``denoise=True`` does), and by the albedo and the normal.

    python -m validation.accuracy.denoise [--size 64] [--paths 1024] [--spp 16 64] [--scenes ...] [--no-csv]
"""
from __future__ import annotations

import time

import numpy as np

import cloudmeta as cm
from cloudmeta.renderer.denoise import aux_images, denoise_paths, require_denoiser
from cloudmeta.renderer.multiple import render_multiple
from cloudmeta.renderer.pack import pack_scene
from validation.accuracy.approximate import REPORT, reference, rel_error, scene_of
from validation.common import RESULTS, parse, parser, run_main, with_settings, write_csv


def main(argv=None):
    ap = parser(__doc__, no_csv=True)
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--paths", type=int, default=1024, help="paths per pixel of the references")
    ap.add_argument("--spp", type=int, nargs="+", default=[16, 64], help="paths per pixel of the test images")
    ap.add_argument("--scenes", nargs="+", choices=sorted(REPORT), default=list(REPORT))
    args, _ = parse(ap, argv)
    rows = []
    print(f"{'scene':<14} {'paths':>5} {'raw':>8} {'albedo':>9} {'albedo+normal':>14} {'paths s':>8} {'OIDN s':>7}")
    for name in args.scenes:
        path = REPORT[name]
        u, se, bt, _ = reference(name, path, args.size, args.paths)
        s = with_settings(scene_of(path, args.size, "multiple"), quality="fine")
        pyoidn = require_denoiser(s)
        single_rgba = cm.render(with_settings(s, scattering="single"), progress=False).astype(np.float64)
        single, alpha = single_rgba[..., :3], single_rgba[..., 3]
        window = ((0, s.image.height), (0, s.image.width))
        albedo, normal = aux_images(s, pack_scene(s, 1), window)
        for n in args.spp:
            t0 = time.perf_counter()
            mean, _ = render_multiple(s, paths=n, seed=1)
            t_raw = time.perf_counter() - t0
            t0 = time.perf_counter()
            alb = denoise_paths(pyoidn, mean, albedo, None, alpha)
            t_dn = time.perf_counter() - t0
            full = denoise_paths(pyoidn, mean, albedo, normal, alpha)
            e_raw, e_full, e_alb = (rel_error(single + m, u, se, bt) for m in (mean, full, alb))
            print(f"{name:<14} {n:>5} {e_raw:>8.4f} {e_alb:>9.4f} {e_full:>14.4f} {t_raw:>8.2f} {t_dn:>7.2f}",
                  flush=True)
            rows.append(dict(scene=name, paths=n, raw=round(e_raw, 5), albedo=round(e_alb, 5),
                             albedo_normal=round(e_full, 5), paths_s=round(t_raw, 3), oidn_s=round(t_dn, 3)))
    if not args.no_csv:
        write_csv(RESULTS / f"denoise_{args.size}.csv", rows)
    return dict(rows=rows)


if __name__ == "__main__":
    run_main(main)
