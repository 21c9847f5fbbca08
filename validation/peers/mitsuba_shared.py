"""The shared method of `scattering: approximate` against Mitsuba 3.8 at equal time: total error, Mitsuba's voxel
bias included, against a converged reference.

For each scene (by default the front-, back- and side-lit cumulus of the report scenes,
validation/accuracy/ms_shared.py), square-cropped to SIZE x SIZE pixels' worth of its aspect, every pixel
box-filtered by 16 stratified camera rays (``image.spp`` 16: Mitsuba's ``box`` filter integrates the pixel too):

1. The reference: cloudmeta ``scattering: multiple`` at quality ``fine`` with ``--ref-paths`` paths per pixel,
   two seeds; U their mean, its per-pixel noise variance (A1 - A2)^2 / 4.
2. For each budget (seconds of CPU time per thread: wall time on an idle machine), alternated, ``--seeds``
   seeds each:
   - cloudmeta's shared method with ``render.shared: {stride, tails}`` fixed, for each stride of ``--strides``:
     the tails that make a render take about the budget (mitsuba_peer.calibrate); the cache of the deep orders as
     its preset (``draft``) decides, or none (``STRIDE:0``: the cache's photons are a fixed cost);
   - Mitsuba ``volpath`` on the voxelised field (``--grid`` voxels along the longest side,
     mitsuba_peer.mitsuba_scene), its spp calibrated the same way.
3. With ``--presets``, the shared method at those presets with its tails planned, with its own estimate of its
   error (``render_frame(error=True)``): the estimate against the true error.
4. Each render's total error: the relative RMSE against U over the scattered light (the mean of U less the
   background seen through the media), the reference's noise subtracted (validation.accuracy.approximate
   rel_error); the RMS over the seeds. Mitsuba's includes its voxel bias; cloudmeta's its sharing's and cache's
   bias and the tails' noise.

    python -m validation.peers.mitsuba_shared [--size 128] [--budgets 5 30] [--strides 2 4 4:0] [--seeds 4]
        [--presets draft] [--ref-paths 4096] [--scenes cumulus_front cumulus_back cumulus_side]

Writes validation/results/mitsuba/shared_SIZE.csv (keeping an earlier run's rows of other scenes, budgets and
presets). Without mitsuba it says how to install it and exits 0.
"""
from __future__ import annotations

import argparse
import math
import time
from dataclasses import replace

import numpy as np

from validation.accuracy.approximate import background_times_t, rel_error, scene_of
from validation.common import RESULTS, read_csv, run_main, with_settings, write_csv
from validation.peers.mitsuba_peer import (INSTALL, calibrate, clocks, cloudmeta_render, import_mitsuba, mitsuba_render,
                                           mitsuba_scene, since, voxelise)

#: camera rays per pixel (a 4 x 4 stratified box filter, as Mitsuba's box filter integrates the pixel)
SPP = 16


def _scene(name, size, scattering, **settings):
    from validation.accuracy.ms_shared import SCENES
    s = scene_of(SCENES[name], size, scattering, method="shared")
    s = replace(s, image=replace(s.image, spp=SPP))
    return with_settings(s, **settings)


def reference(name, size, paths):
    """(U, its per-pixel noise variance, the background seen through the media, seconds): two seeds of
    ``paths`` unbiased paths a pixel (cached in results/mitsuba/shared_ref_NAME_SIZE_PATHS.npz)."""
    import cloudmeta as cm
    f = RESULTS / "mitsuba" / f"shared_ref_{name}_{size}_{paths}.npz"
    if f.exists():
        z = np.load(f)
        return z["u"], z["var"], z["bt"], float(z["seconds"])
    s = _scene(name, size, "multiple", quality="fine", ms_spp=paths)
    t0 = time.perf_counter()
    halves = [cloudmeta_render(s, 5000 + k)[0] for k in range(2)]
    seconds = time.perf_counter() - t0
    single = cm.render(with_settings(s, scattering="single"), progress=False)
    bt = background_times_t(s, single)
    u = 0.5 * (halves[0] + halves[1])
    var = (halves[0] - halves[1]) ** 2 / 4.0
    f.parent.mkdir(parents=True, exist_ok=True)
    np.savez(f, u=u, var=var, bt=bt, seconds=seconds)
    return u, var, bt, seconds


def total_error(images, u, var, bt):
    """The RMS over the renders of their relative RMSE against U over the scattered light, U's noise
    subtracted."""
    se = np.sqrt(var)
    return math.sqrt(float(np.mean([rel_error(a, u, se, bt) ** 2 for a in images])))


def _preset(name, size, preset, u, var, bt):
    """The shared method at a preset with its tails planned: its time with the estimate, its total error against
    the reference and its own estimate of it (render_frame(error=True))."""
    import cloudmeta as cm
    s = _scene(name, size, "approximate", quality=preset)
    t0 = clocks()
    r = cm.render_frame(s, progress=False, seed=1, error=True)
    wall, _ = since(t0)
    err = total_error([r.image[..., :3].astype(np.float64)], u, var, bt)
    e = r.approximation
    row = dict(scene=name, size=size, budget_s="", method=f"shared {preset}, planned", samples=r.plan.tails,
               fixed_s="", cpu_s_per_thread="", cpu_spread="", wall_s=round(wall, 2), total_error=round(err, 5),
               error_at_budget="", estimate=round(e.rel_rmse, 5), estimate_stderr=round(e.stderr, 5))
    ratio = f" ({e.rel_rmse / err:.2f}x)" if err > 0.0 else " (the error is under the reference's noise)"
    print(f"  {preset}: {wall:.1f} s wall with the estimate, total error {err:.4f}, estimated {e.rel_rmse:.4f} +- "
          f"{e.stderr:.4f}{ratio}", flush=True)
    return row


def _earlier(out, args):
    """The rows of an earlier run that this one does not redo (other scenes, budgets or presets)."""
    if not out.exists():
        return []
    redo = {str(b) for b in args.budgets}
    presets = {f"shared {p}, planned" for p in args.presets}
    return [r for r in read_csv(out) if r["scene"] not in args.scenes
            or (r["budget_s"] and r["budget_s"] not in redo) or (not r["budget_s"] and r["method"] not in presets)]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", type=int, default=128, help="pixels along the image's longer side")
    ap.add_argument("--budgets", type=float, nargs="*", default=[5.0, 30.0], help="seconds (CPU time per thread)")
    ap.add_argument("--presets", nargs="*", default=["draft"],
                    help="also the shared method at these presets, planned, with its own estimate (--error)")
    ap.add_argument("--strides", nargs="+", default=["2", "4", "4:0"],
                    help="the shared method's sample ray strides; STRIDE:0 without the cache of the deep orders")
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--ref-paths", type=int, default=4096, help="the reference's paths a pixel, per half")
    ap.add_argument("--grid", type=int, default=256, help="Mitsuba's voxels along the longest side")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--scenes", nargs="+", default=["cumulus_front", "cumulus_back", "cumulus_side"])
    args = ap.parse_args(argv)
    mi = import_mitsuba(args.threads)
    if mi is None:
        print(INSTALL)
        return dict(passed=True, skipped=True)
    out = RESULTS / "mitsuba" / f"shared_{args.size}.csv"
    rows = []
    kept = _earlier(out, args)
    for name in args.scenes:
        u, var, bt, ref_s = reference(name, args.size, args.ref_paths)
        scattered = float(np.mean(u - bt))
        print(f"{name}: reference {ref_s:.0f} s, its noise {math.sqrt(float(np.mean(var))) / scattered:.4f} of the "
              f"scattered light", flush=True)
        base = _scene(name, args.size, "approximate", quality="draft")
        for preset in args.presets:
            rows.append(_preset(name, args.size, preset, u, var, bt))
            write_csv(out, kept + rows)
        if not args.budgets:
            continue
        ms = mitsuba_scene(mi, base, voxelise(base, args.grid), base.render.max_order + 1)
        mitsuba_render(mi, ms, 1, 77)  # untimed: Mitsuba's first render compiles its kernels
        cloudmeta_render(with_settings(base, shared=(4, 64, None)), 77)  # untimed: numba's kernels load
        for budget in args.budgets:
            runs = {}
            for variant in args.strides:
                stride, _, no_cache = variant.partition(":")
                stride, cache = int(stride), (0 if no_cache else None)

                def cm_cpu(n, stride=stride, cache=cache):
                    return cloudmeta_render(with_settings(base, shared=(stride, int(n), cache)), 77)[2] / args.threads
                n, _, fixed = calibrate(cm_cpu, budget, 64, 1 << 20)
                key = f"shared stride {stride}" + (" no cache" if cache == 0 else "")
                runs[key] = (n, fixed, lambda seed, n=n, stride=stride, cache=cache: cloudmeta_render(
                    with_settings(base, shared=(stride, n, cache)), seed))
            n, _, fixed = calibrate(lambda k: mitsuba_render(mi, ms, int(k), 77)[2] / args.threads, budget, 16, 1 << 20)
            runs["mitsuba"] = (n, fixed, lambda seed, n=n: mitsuba_render(mi, ms, n, seed))
            images = {k: [] for k in runs}
            cpu = {k: [] for k in runs}
            wall = {k: [] for k in runs}
            for seed in range(args.seeds):
                for key, (_, _, run) in runs.items():
                    img, w, c = run(seed)
                    images[key].append(img)
                    wall[key].append(w)
                    cpu[key].append(c / args.threads)
            for key, (n, fixed, _) in runs.items():
                err = total_error(images[key], u, var, bt)
                t = float(np.median(cpu[key]))
                row = dict(scene=name, size=args.size, budget_s=budget, method=key, samples=n, fixed_s=round(fixed, 2),
                           cpu_s_per_thread=round(t, 2), cpu_spread=round(float(np.ptp(cpu[key])), 2),
                           wall_s=round(float(np.median(wall[key])), 2), total_error=round(err, 5),
                           # error^2 x time = const for the noise only: a guide where the run missed its budget
                           error_at_budget=round(err * math.sqrt(t / budget), 5))
                rows.append(row)
                print("  " + "  ".join(f"{k} {v}" for k, v in row.items() if k not in ("scene", "size")), flush=True)
            cm_best = min(r["error_at_budget"] for r in rows if r["scene"] == name and r["budget_s"] == budget
                          and r["method"] != "mitsuba")
            mi_err = next(r["error_at_budget"] for r in rows if r["scene"] == name and r["budget_s"] == budget
                          and r["method"] == "mitsuba")
            print(f"  {name} at {budget:g} s: Mitsuba's total error / cloudmeta's best {mi_err / cm_best:.2f}x",
                  flush=True)
            write_csv(out, kept + rows)
    return dict(passed=True, rows=rows)


if __name__ == "__main__":
    run_main(main)
