"""Converged reference images of the accuracy suite (scenes/suite/), cached and cross-checked.

For every suite scene (64 x 48, spp 1):

1. the reference: ``cm.render`` at ``quality: reference`` (tolerance 1e-6, max_tau 0.1, max_length 1/128 of
   the diagonal, max_angle 0.025, cutoff 0);
2. a tighter setting still (tolerance 1e-8, max_tau 0.05, max_length 1/256, max_angle 0.0125, cutoff 0),
   to show that the reference has converged: "ref vs tighter" is their relative RMSE (validation/common.py
   defines it: over the RGB of the whole image) and the worst pixel's relative difference;
3. a cross-check of the reference against validation/accuracy/single_scattering.py's independent numpy reference
   (plain model, exact view and shadow optical depths, adaptive Gauss-Kronrod 7/15 at rtol ``--rtol``) on
   a 16 x 12 grid of the image's own pixels (every 4th row and column from 2): their relative RMSE over
   those pixels and RGB, and the worst pixel. That reference reads the YAML's geometry itself and supports
   every feature the suite uses (wyvill6 and murakami4, spheres and rotated ellipsoids, negative weights,
   the three density modes, the four phases, directional and point lights, ambient, background); it does
   not support the nishimura and blinn kernels, surfaces or spp > 1, which the suite does not use.

Images are cached as validation/reference_images/suite/NAME.npy (reference) and NAME.tighter.npy (float32, H x W x 4,
as cm.render returns them), with NAME.json (times, figures, and a fingerprint of the YAML, its balls files
and the settings) and NAME.numpy.npy (the numpy reference's pixels, (n, 3) float64 with their (row, col) in
NAME.pixels.npy). A cached scene whose fingerprint still matches is not rendered again; ``--force`` redoes it.
The whole cache is about 1.5 MB and is committed, so that the tests and later runs reuse it.

    python -m validation.accuracy.suite_references [--scenes NAME ...] [--force] [--rtol 1e-8] [--no-crosscheck]

Requirement: every reference within 1e-5 of the tighter image (relative RMSE) and within 1e-5 of the numpy
reference on the cross-checked pixels (the bounds are 30x below the tightest preset target, fine's 3e-4).
Writes validation/results/suite_references.csv.
"""
from __future__ import annotations

import json
import os
import time
from pathlib import Path

import numpy as np
import yaml

import cloudmeta as cm
from validation.accuracy import single_scattering as SS
from validation.common import RESULTS, parse, parser, print_head, rel_rmse, run_main, write_csv
from validation.references import suite as S

CONVERGED = 1e-5
AGREE = 1e-5


def grid_pixels(height, width, stride=S.STRIDE, offset=None):
    """Every ``stride``-th row and column, from ``offset`` (default stride // 2)."""
    offset = stride // 2 if offset is None else offset
    return np.array([(i, j) for i in range(offset, height, stride) for j in range(offset, width, stride)], np.int64)


def numpy_reference(path, pixels, rtol):
    """(radiance (n, 3), transmittance (n,), seconds, evaluations) of validation/accuracy/single_scattering.py's
    independent reference at the given pixels of the scene's own image size."""
    path = Path(path)
    raw = yaml.safe_load(path.read_text(encoding="utf-8"))
    scene = cm.load_scene(path)  # the colours only (the loader's conversion is not under test)
    media = SS.plain_media(raw, path.parent)
    lights = SS.Lights(raw.get("lights", []), scene)
    ambient = None if scene.ambient is None else np.asarray(scene.ambient, float)
    cam, dirs = SS.camera_rays(raw["camera"], scene.image.width, scene.image.height, pixels)
    t0 = time.perf_counter()
    view = SS.ViewRays(media, cam, dirs)
    rad, trans, n_eval = SS.reference_radiance(view, lights, ambient, np.asarray(scene.background, float), rtol)
    return rad, trans, time.perf_counter() - t0, n_eval


def tighter_vs_numpy(name):
    """Relative RMSE of the cached tighter image against the cached numpy pixels."""
    pixels = np.load(S.CACHE / f"{name}.pixels.npy")
    rad = np.load(S.CACHE / f"{name}.numpy.npy")
    got = np.load(S.CACHE / f"{name}.tighter.npy").astype(np.float64)[pixels[:, 0], pixels[:, 1], :3]
    return rel_rmse(got, rad)


def _save(path, array):
    """np.save atomically (a temporary file in the same folder, renamed into place)."""
    tmp = path.with_name(path.name + ".tmp.npy")
    np.save(tmp, array)
    os.replace(tmp, path)


def build(path, force=False, crosscheck=True, rtol=1e-8, stride=None):
    """The scene's cache entry (metadata dict), rendering and cross-checking what is missing or stale
    (``stride``: the cross-check's pixel grid; None keeps the cached one, or S.STRIDE)."""
    name = Path(path).stem
    fp = S.fingerprint(path)
    old = S.cached(name)
    meta = dict(old[2]) if old is not None and old[2].get("fingerprint") == fp and not force else {}
    S.CACHE.mkdir(parents=True, exist_ok=True)
    scene = cm.load_scene(path)
    if not meta:
        t0 = time.perf_counter()
        ref = cm.render(S.with_settings(scene, **S.REFERENCE), progress=False)
        t_ref = time.perf_counter() - t0
        t0 = time.perf_counter()
        tight = cm.render(S.tighter(scene), progress=False)
        t_tight = time.perf_counter() - t0
        worst, where = S.worst_pixel(ref, tight)
        meta = dict(scene=name, fingerprint=fp, width=scene.image.width, height=scene.image.height,
                    reference_s=t_ref, tighter_s=t_tight, ref_vs_tighter=S.rel_rmse(ref, tight),
                    ref_vs_tighter_worst_pixel=worst, ref_vs_tighter_worst_at=where,
                    finite=bool(np.all(np.isfinite(ref)) and np.all(np.isfinite(tight))))
        _save(S.CACHE / f"{name}.npy", ref)
        _save(S.CACHE / f"{name}.tighter.npy", tight)
    if crosscheck and ("numpy_rel_rmse" not in meta or meta.get("numpy_rtol") != rtol
                       or (stride is not None and meta.get("numpy_stride", S.STRIDE) != stride)):
        stride = stride or S.STRIDE
        ref = np.load(S.CACHE / f"{name}.npy").astype(np.float64)
        pixels = grid_pixels(scene.image.height, scene.image.width, stride)
        rad, trans, secs, n_eval = numpy_reference(path, pixels, rtol)
        got = ref[pixels[:, 0], pixels[:, 1]]
        pix_rel = np.abs(got[:, :3] - rad).max(axis=1) / np.maximum(rad.max(axis=1), 1e-300)
        meta.update(numpy_rtol=rtol, numpy_stride=stride, numpy_pixels=len(pixels), numpy_s=secs,
                    numpy_evals=int(n_eval),
                    numpy_rel_rmse=rel_rmse(got, rad),
                    numpy_worst_pixel=float(pix_rel.max()),
                    numpy_alpha_max_abs=float(np.abs(got[:, 3] - (1.0 - trans)).max()))
        _save(S.CACHE / f"{name}.numpy.npy", rad)
        _save(S.CACHE / f"{name}.pixels.npy", pixels)
    tmp = S.CACHE / f"{name}.json.tmp"
    tmp.write_text(json.dumps(meta, indent=1, sort_keys=True) + "\n", encoding="utf-8")
    os.replace(tmp, S.CACHE / f"{name}.json")
    return meta


def current(path):
    """(reference, tighter, metadata) of a suite scene from the cache, rendered first (without the numpy
    cross-check) where it is missing or stale."""
    entry = S.cached(Path(path).stem)
    if entry is None or entry[2].get("fingerprint") != S.fingerprint(path):
        build(path, crosscheck=False)
        entry = S.cached(Path(path).stem)
    return entry


def main(argv=None, quick=False):
    ap = parser(__doc__)
    ap.add_argument("--scenes", nargs="+", default=None, help="scene names (default: the whole suite)")
    ap.add_argument("--force", action="store_true", help="render again even where the cache is current")
    ap.add_argument("--rtol", type=float, default=1e-8, help="tolerance of the numpy reference (default 1e-8)")
    ap.add_argument("--stride", type=int, default=None,
                    help="cross-check every STRIDE-th row and column (default: as cached, or 4: 16 x 12 of 64 x 48)")
    ap.add_argument("--no-crosscheck", action="store_true", help="skip the numpy cross-check")
    args, _ = parse(ap, argv)
    paths = [p for p in S.scene_paths() if args.scenes is None or p.stem in args.scenes]
    start = time.perf_counter()
    cm.render(cm.load_scene(paths[0], width=4, height=3), progress=False)  # compile (or load the cache) first
    for p in paths:
        meta = build(p, force=args.force, crosscheck=not args.no_crosscheck, rtol=args.rtol, stride=args.stride)
        print(f"  {p.stem}: ref {meta['reference_s']:.1f} s, vs tighter {meta['ref_vs_tighter']:.2e}"
              + (f", vs numpy {meta['numpy_rel_rmse']:.2e}" if "numpy_rel_rmse" in meta else ""), flush=True)
    elapsed = time.perf_counter() - start
    rows = [S.cached(p.stem)[2] for p in S.scene_paths() if S.cached(p.stem) is not None]  # the whole cache
    print("\nAccuracy suite: converged references (cm.render, quality reference) and their checks\n")
    head = (f"{'scene':22s} {'size':>6s} {'ref s':>6s} {'tight s':>7s} {'vs tighter':>10s} {'worst px':>9s} "
            f"{'numpy px':>8s} {'vs numpy':>9s} {'worst px':>9s} {'alpha':>8s} {'numpy s':>7s} {'tight/np':>8s}"
            "  result")
    print_head(head)
    passed = True
    for m in rows:
        m["tighter_vs_numpy"] = tighter_vs_numpy(m["scene"]) if "numpy_rel_rmse" in m else float("nan")
        ok = m["finite"] and m["ref_vs_tighter"] < CONVERGED
        has = "numpy_rel_rmse" in m
        if has:
            ok = ok and m["numpy_rel_rmse"] < AGREE
        passed = passed and ok
        num = (f"{m['numpy_pixels']:8d} {m['numpy_rel_rmse']:9.2e} {m['numpy_worst_pixel']:9.2e} "
               f"{m['numpy_alpha_max_abs']:8.1e} {m['numpy_s']:7.1f} {m['tighter_vs_numpy']:8.1e}") if has else \
            f"{'-':>8s} {'-':>9s} {'-':>9s} {'-':>8s} {'-':>7s} {'-':>8s}"
        print(f"{m['scene']:22s} {m['width']:>3d}x{m['height']:<2d} {m['reference_s']:6.1f} {m['tighter_s']:7.1f} "
              f"{m['ref_vs_tighter']:10.2e} {m['ref_vs_tighter_worst_pixel']:9.2e} {num}  "
              f"{'PASS' if ok else 'FAIL'}")
    print(f"\nvs tighter: rel. RMSE of the reference against the tighter setting (whole image); vs numpy: against "
          f"the independent numpy reference (rtol {args.rtol:g}) on a grid of the image's pixels (numpy px of them); "
          "worst px: "
          "max over pixels of max_c |diff| / max_c ref; alpha: max |alpha - (1 - T)| on those pixels; tight/np: the "
          "tighter image against the numpy reference on the same pixels.")
    print(f"{'PASS' if passed else 'FAIL'}: every reference within {CONVERGED:g} of the tighter image and within "
          f"{AGREE:g} of the numpy reference   [{elapsed:.1f} s]")
    write_csv("suite_references.csv", rows, fieldnames=sorted({k for m in rows for k in m}))
    print(f"wrote {RESULTS / 'suite_references.csv'} and the cache in {S.CACHE}")
    return dict(rows=rows, passed=passed, seconds=elapsed)


if __name__ == "__main__":
    run_main(main)
