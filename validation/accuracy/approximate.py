"""The approximate multiple-scattering mode (``render: {scattering: approximate}``) against converged unbiased
multiple scattering: fit the octaves on some scenes, report the error on others, time and error estimate.

Scenes (64 x 48 unless --size; ambient removed everywhere: in both modes the background lights the media):
- FIT: ellipsoids side-lit (HG 0.85), the carved blob side-lit (Rayleigh), the bank under a grazing sun,
  ellipsoids back-lit (double HG). The octaves (count, a, b, c) are fitted on these alone.
- REPORT: cumulus front-lit, cumulus back-lit, the shipped cumulus (side-lit from the front right), the bank
  front-lit, the deck under a low sun, the small wispy puffs. None of them is used to fit.

Unbiased reference per scene: single scattering at quality ``fine`` plus ``--paths`` Monte Carlo paths per
pixel of renderer.multiple, kept in validation/results/approximate/REF.npz (mean and standard error).
The error of an image A is relative to the scattered light:
    sqrt(mean((A - U)^2) - mean(se_U^2)) / mean(U - background * T)
(the reference's own variance is subtracted; U less the background seen through the media is the light
the approximation approximates). Printed for single scattering, the octaves and their error estimate.

    python -m validation.accuracy.approximate references [--paths 512] [--size 64]
    python -m validation.accuracy.approximate fit
    python -m validation.accuracy.approximate tune [--paths 4096]   (the grid method's cells and photons)
    python -m validation.accuracy.approximate report [--no-csv]
    python -m validation.accuracy.approximate deposits --paths 4096   (render.grid.deposit, 4 reference seeds)
    python -m validation.accuracy.approximate timing --size 512 [--repeats 3]
    python -m validation.accuracy.approximate bias --paths 16384   (where the grid misses:
        docs/approximate_grid_bias.png)
    python -m validation.accuracy.approximate levels --paths 1024 [--repeats 2]   (fewer cells and photons:
        error at --size, time at 512 x 512 against single scattering)
    python -m validation.accuracy.approximate figure --size 128 --paths 256   (docs/approximate_cumulus.png)
"""
from __future__ import annotations

import itertools
import time
from dataclasses import replace

import numpy as np

import cloudmeta as cm
from cloudmeta.renderer.approximate import approximation_error
from cloudmeta.renderer.multiple import render_multiple
from cloudmeta.renderer.pack import background_table, background_along, pack_scene, pixel_directions
from validation.common import RESULTS, ROOT, alternate, parse, parser, run_main, with_settings, write_csv

SUITE = ROOT / "scenes" / "suite"
FIT = {"ellipsoids_side": SUITE / "ellipsoids_side.yaml", "carved_side": SUITE / "carved_side.yaml",
       "bank_grazing": SUITE / "bank_grazing.yaml", "ellipsoids_back": SUITE / "ellipsoids_back.yaml"}
REPORT = {"cumulus_front": SUITE / "cumulus_front.yaml", "cumulus_back": SUITE / "cumulus_back.yaml",
          "cumulus_side": ROOT / "scenes" / "cumulus.yaml", "bank_front": SUITE / "bank_front.yaml",
          "deck_low_sun": SUITE / "deck_grazing.yaml", "wispy_puffs": SUITE / "puffs_front.yaml"}
FOLDER = RESULTS / "approximate"


def scene_of(path, size, mode="single", octaves=None, method="octaves", grid=None):
    s = cm.load_scene(path)
    h = max(1, round(size * s.image.height / s.image.width))
    s = cm.load_scene(path, width=size, height=h)
    s = replace(s, ambient=None)
    settings = dict(scattering=mode, method=method, grid=grid)
    if octaves is not None:
        settings["octaves"] = tuple(octaves)
    return with_settings(s, **settings)


def reference(name, path, size, paths):
    """(U, se, background * T) of the scene: cached in FOLDER/name.npz."""
    f = FOLDER / f"{name}_{size}_{paths}.npz"
    if f.exists():
        z = np.load(f)
        return z["u"], z["se"], z["bt"], float(z["seconds"])
    s = with_settings(scene_of(path, size, "multiple"), quality="fine")
    t0 = time.perf_counter()
    # the deterministic part alone: cm.render of the multiple-mode scene would add its own ms_spp paths too
    single = cm.render(with_settings(s, scattering="single"), progress=False)
    mean, se = render_multiple(s, paths=paths)
    seconds = time.perf_counter() - t0
    bt = background_times_t(s, single)
    FOLDER.mkdir(parents=True, exist_ok=True)
    np.savez(f, u=single[..., :3] + mean, se=se, bt=bt, seconds=seconds)
    return single[..., :3] + mean, se, bt, seconds


def background_times_t(scene, image):
    """(H, W, 3): the background seen through the media at each pixel's centre."""
    h, w = scene.image.height, scene.image.width
    cam = pack_scene(scene, 0).camera
    rows, cols = np.divmod(np.arange(h * w), w)
    bg = background_along(background_table(scene), pixel_directions(cam, rows, cols)).reshape(h, w, 3)
    return bg * (1.0 - image[..., 3:4].astype(np.float64))


def rel_error(a, u, se, bt):
    ms = max(float(np.mean((a - u) ** 2) - np.mean(se ** 2)), 0.0)
    return np.sqrt(ms) / float(np.mean(u - bt))


def approx_image(path, size, octaves=None):
    s = scene_of(path, size, "approximate", octaves)
    return s, cm.render(s, progress=False)


def references(args):
    for name, path in {**FIT, **REPORT}.items():
        u, se, bt, sec = reference(name, path, args.size, args.paths)
        noise = np.sqrt(np.mean(se ** 2)) / float(np.mean(u - bt))
        print(f"{name:16s} reference {sec:7.1f} s, its noise {noise:.2e} of the scattered light", flush=True)


def grid_error(name, path, size, paths, grid=None, seeds=(0, 1)):
    """The grid method on one scene at ``default``: (error of the first seed's image, the images' own noise
    (the RMS difference of two seeds over sqrt 2, relative to the scattered light), seconds of the first,
    the first image)."""
    u, se, bt, _ = reference(name, path, size, paths)
    s = with_settings(scene_of(path, size, "approximate", method="grid", grid=grid), quality="default")
    images, seconds, first = [], [], None
    for seed in seeds:
        t0 = time.perf_counter()
        image = cm.render(s, progress=False, seed=seed)
        seconds.append(time.perf_counter() - t0)
        first = image if first is None else first
        images.append(image[..., :3].astype(np.float64))
    scattered = float(np.mean(u - bt))
    noise = np.sqrt(np.mean((images[0] - images[1]) ** 2) / 2) / scattered if len(images) > 1 else float("nan")
    return rel_error(images[0], u, se, bt), noise, seconds[0], first


def tune(args):
    """The grid's resolution and photons on the FIT scenes alone: error and noise per setting."""
    settings = [(32, 1 << 22), (40, 1 << 23), (48, 1 << 23), (48, 1 << 24), (64, 1 << 24)]
    rows = []
    for cells, photons in settings:
        errs = []
        for name, path in FIT.items():
            err, noise, sec, _ = grid_error(name, path, args.size, args.paths, (cells, photons, "flights"))
            errs.append(err)
            rows.append(dict(cells=cells, photons=photons, scene=name, error=f"{err:.4f}", noise=f"{noise:.4f}",
                             seconds=f"{sec:.1f}"))
            print(f"cells {cells:3d} photons {photons:8d} {name:16s} error {err:.4f} noise {noise:.4f} "
                  f"({sec:.1f} s)", flush=True)
        print(f"cells {cells:3d} photons {photons:8d}: worst {max(errs):.4f}, rms {np.sqrt(np.mean(np.square(errs))):.4f}",
              flush=True)
    if not args.no_csv:
        write_csv(RESULTS / "approximate_grid_tuning.csv", rows)
    return {"rows": rows}


def fit(args):
    refs = {name: reference(name, path, args.size, args.paths) for name, path in FIT.items()}
    best = None
    grid = itertools.product((4, 8), (0.1, 0.2, 0.3, 0.5, 0.7), (0.3, 0.6, 0.85), (0.3, 0.45, 0.6, 0.75))
    for count, a, b, c in grid:
        errs = [rel_error(approx_image(FIT[n], args.size, (count, a, b, c))[1][..., :3].astype(np.float64), *refs[n][:3])
                for n in FIT]
        score = float(np.sqrt(np.mean(np.square(errs))))
        if best is None or score < best[0]:
            best = (score, (count, a, b, c), errs)
            print(f"best so far: octaves {best[1]}: rms {score:.3f} (" +
                  ", ".join(f"{n} {e:.3f}" for n, e in zip(FIT, errs)) + ")", flush=True)
    return {"octaves": best[1], "score": best[0]}


def report(args):
    rows = []
    for name, path in REPORT.items():
        u, se, bt, ref_sec = reference(name, path, args.size, args.paths)
        s1 = with_settings(scene_of(path, args.size), quality="default")
        t0 = time.perf_counter()
        single = cm.render(s1, progress=False)
        t_single = time.perf_counter() - t0
        s, _ = approx_image(path, args.size)
        t0 = time.perf_counter()
        approx = cm.render(s, progress=False)
        t_approx = time.perf_counter() - t0
        e_single = rel_error(single[..., :3].astype(np.float64), u, se, bt)
        e_approx = rel_error(approx[..., :3].astype(np.float64), u, se, bt)
        window = ((0, s.image.height), (0, s.image.width))
        est = approximation_error(s, approx.astype(np.float64), pack_scene(s, 0), window)
        sg = with_settings(scene_of(path, args.size, "approximate", method="grid"), quality="default")
        e_grid, noise_grid, t_grid, grid_img = grid_error(name, path, args.size, args.paths)
        t0 = time.perf_counter()
        est_grid = approximation_error(sg, grid_img.astype(np.float64), pack_scene(sg, 0), window)
        t_est = time.perf_counter() - t0
        noise_ref = np.sqrt(np.mean(se ** 2)) / float(np.mean(u - bt))
        rows.append(dict(scene=name, single=f"{e_single:.4f}", octaves=f"{e_approx:.4f}",
                         estimate=f"{est.rel_rmse:.4f}", estimate_se=f"{est.stderr:.4f}",
                         ratio=f"{est.rel_rmse / e_approx:.2f}", grid=f"{e_grid:.4f}", grid_noise=f"{noise_grid:.4f}",
                         grid_estimate=f"{est_grid.rel_rmse:.4f}", grid_estimate_se=f"{est_grid.stderr:.4f}",
                         grid_ratio=f"{est_grid.rel_rmse / max(e_grid, 1e-9):.2f}", reference_noise=f"{noise_ref:.4f}",
                         t_single=f"{t_single:.2f}", t_octaves=f"{t_approx:.2f}", t_grid=f"{t_grid:.2f}",
                         t_estimate=f"{t_est:.1f}", t_reference=f"{ref_sec:.0f}"))
        print(f"{name:16s} single {e_single:.3f}  octaves {e_approx:.3f} (estimate {est.rel_rmse:.3f}, "
              f"{est.rel_rmse / e_approx:.2f}x)  grid {e_grid:.4f} (its noise {noise_grid:.4f}; estimate "
              f"{est_grid.rel_rmse:.4f} +- {est_grid.stderr:.4f}, {est_grid.rel_rmse / max(e_grid, 1e-9):.2f}x)  "
              f"reference noise {noise_ref:.4f}  time single {t_single:.2f} s, octaves {t_approx:.2f} s, grid "
              f"{t_grid:.2f} s, estimate {t_est:.1f} s", flush=True)
    if not args.no_csv:
        write_csv(RESULTS / "approximate.csv", rows)
    return {"rows": rows}


def seeded_reference(name, path, size, paths, seeds=4):
    """(U, the variance of U per pixel, background * T): the reference's single scattering plus the mean of
    ``seeds`` independent runs of ``paths`` unbiased paths (seed 0 is ``reference``'s; the others are cached in
    FOLDER/name_size_paths_seedK.npz), the variance from the runs' scatter (it agreed with their standard
    errors within 6 % on the report scenes)."""
    u, se, bt, _ = reference(name, path, size, paths)
    s = with_settings(scene_of(path, size, "multiple"), quality="fine")
    single = cm.render(with_settings(s, scattering="single"), progress=False)[..., :3]
    means = [u - single]
    for seed in range(1, seeds):
        f = FOLDER / f"{name}_{size}_{paths}_seed{seed}.npz"
        if not f.exists():
            mean, se_k = render_multiple(s, paths=paths, seed=seed)
            np.savez(f, mean=mean, se=se_k)
        means.append(np.load(f)["mean"])
    m = np.array(means)
    return single + m.mean(axis=0), m.var(axis=0, ddof=1) / len(means), bt


def deposits(args):
    """The grid's deposits (render.grid.deposit: flights, collisions) on the report scenes at ``default``: error,
    the grid's own noise (two seeds) and its bias (the two seeds' mean against the reference, less both
    noises), against 4 x --paths unbiased paths."""
    rows = []
    for name, path in REPORT.items():
        u, var, bt = seeded_reference(name, path, args.size, args.paths)
        scattered = float(np.mean(u - bt))
        for where in ("flights", "collisions"):
            s = with_settings(scene_of(path, args.size, "approximate", method="grid", grid=(None, None, where)),
                              quality="default")
            images, seconds = [], []
            for seed in (0, 1):
                t0 = time.perf_counter()
                images.append(cm.render(s, progress=False, seed=seed)[..., :3].astype(np.float64))
                seconds.append(time.perf_counter() - t0)
            noise2 = np.mean((images[0] - images[1]) ** 2) / 2
            err = np.sqrt(max(np.mean((images[0] - u) ** 2) - np.mean(var), 0.0)) / scattered
            both = 0.5 * (images[0] + images[1])
            bias = np.sqrt(max(np.mean((both - u) ** 2) - np.mean(var) - noise2 / 2, 0.0)) / scattered
            rows.append(dict(scene=name, deposit=where, error=f"{err:.4f}",
                             noise=f"{np.sqrt(noise2) / scattered:.4f}", bias=f"{bias:.4f}",
                             signed=f"{np.mean(both - u) / scattered:+.4f}", seconds=f"{seconds[1]:.1f}"))
            print("  ".join(f"{k} {v}" for k, v in rows[-1].items()), flush=True)
    if not args.no_csv:
        write_csv(RESULTS / "approximate_deposits.csv", rows)
    return {"rows": rows}


def render_seconds(scene):
    """The seconds cm.render takes on the scene (``timing`` and ``levels``)."""
    t0 = time.perf_counter()
    cm.render(scene, progress=False)
    return time.perf_counter() - t0

def timing(args):
    """512 x 512 (--size 512 to get it), default quality: single scattering (the scene file as it is) against the
    approximate mode (ambient removed), the two alternating, --repeats rounds after one untimed."""
    out = {}
    for name in ("cumulus.yaml", "cumulus_backlit.yaml"):
        path = ROOT / "scenes" / name
        single = cm.load_scene(path, width=args.size, height=args.size)
        approx = with_settings(replace(single, ambient=None), scattering="approximate")
        grid = with_settings(approx, method="grid")
        times = alternate({"single": (single,), "octaves": (approx,), "grid": (grid,)}, args.repeats, render_seconds)
        med = {k: float(np.median(v)) for k, v in times.items()}
        print(f"{name}: " + ", ".join(f"{k} {med[k]:.2f} s ({min(v):.2f}-{max(v):.2f}, {med[k] / med['single']:.2f}x)"
                                      for k, v in times.items()), flush=True)
        out[name] = med
    return out


#: the grid's (cells, photons, deposit) below `default`'s (40, 2^23) that ``levels`` measures
GRID_LEVELS = {"24/2^21": (24, 1 << 21, "flights"), "32/2^22": (32, 1 << 22, "flights")}


def levels(args):
    """The grid method at fewer cells and photons (GRID_LEVELS): its error on the report scenes at --size (two
    seeds), then its time at 512 x 512 against single scattering (the scene files), alternating as ``timing``."""
    for label, grid in GRID_LEVELS.items():
        errors = []
        for name, path in REPORT.items():
            e, noise, sec, _ = grid_error(name, path, args.size, args.paths, grid=grid)
            errors.append(e)
            print(f"{label} {name:14s} error {e:.4f} noise {noise:.4f} {sec:.1f} s", flush=True)
        print(label, "worst", max(errors), flush=True)
    for name in ("cumulus.yaml", "cumulus_backlit.yaml"):
        single = cm.load_scene(ROOT / "scenes" / name, width=512, height=512)
        approx = with_settings(replace(single, ambient=None), scattering="approximate", method="grid")
        runs = {"single": (single,), **{label: (with_settings(approx, grid=g),) for label, g in GRID_LEVELS.items()}}
        times = alternate(runs, args.repeats, render_seconds)
        med = {k: float(np.median(v)) for k, v in times.items()}
        print(name, ", ".join(f"{k} {med[k]:.2f} s ({min(v):.2f}-{max(v):.2f}, {med[k] / med['single']:.2f}x)"
                              for k, v in times.items()), flush=True)


#: the report scenes where the grid misses most (``bias``)
BIAS_SCENES = ("cumulus_back", "bank_front", "wispy_puffs")
#: the pixels' alpha bins of ``bias``'s table
ALPHA_BINS = (0.0, 0.3, 0.6, 0.9, 0.99, 0.9999, 1.01)


def bias(args, seeds=3):
    """Where the grid method (`default`, deposits along flights) misses: the mean of ``seeds`` grid images against
    the --paths reference on BIAS_SCENES, printed per bin of the pixels' alpha (mean and RMS of the residual
    over the frame's mean scattered light) and drawn as docs/approximate_grid_bias.png."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(len(BIAS_SCENES), 3, figsize=(11, 2.6 * len(BIAS_SCENES)), dpi=100, squeeze=False,
                             constrained_layout=True)
    for row, name in enumerate(BIAS_SCENES):
        u, se, bt, _ = reference(name, REPORT[name], args.size, args.paths)
        s = with_settings(scene_of(REPORT[name], args.size, "approximate", method="grid"), quality="default")
        images = [cm.render(s, progress=False, seed=k) for k in range(seeds)]
        alpha = images[0][..., 3]
        mean = np.mean([im[..., :3] for im in images], axis=0).astype(np.float64)
        scattered = float(np.mean(u - bt))
        residual = (mean - u).mean(axis=-1) / scattered
        cloud = alpha > 0
        print(f"{name}: the {seeds} seeds' mean against the reference, {rel_error(mean, u, se, bt):.3f} (its noise "
              f"not subtracted); residual over the mean scattered light by the pixels' alpha:", flush=True)
        for lo, hi in zip(ALPHA_BINS[:-1], ALPHA_BINS[1:]):
            k = cloud & (alpha >= lo) & (alpha < hi)
            if k.any():
                print(f"  alpha {lo:.4f}-{min(hi, 1.0):.4f}: {int(k.sum()):4d} pixels, mean {residual[k].mean():+.3f}, "
                      f"RMS {np.sqrt(np.mean(residual[k] ** 2)):.3f}, share of the squared residual "
                      f"{np.sum(residual[k] ** 2) / np.sum(residual[cloud] ** 2):.2f}", flush=True)
        ref = u.mean(axis=-1)
        axes[row, 0].imshow(np.clip(ref / np.percentile(ref, 99.5), 0, 1) ** (1 / 2.2), cmap="gray")
        axes[row, 0].set_title(f"{name}: reference ({args.paths} paths)", fontsize=9)
        im = axes[row, 1].imshow(np.where(cloud, residual, 0.0), cmap="RdBu_r", vmin=-0.5, vmax=0.5)
        axes[row, 1].set_title(f"grid (mean of {seeds} seeds) - reference", fontsize=9)
        axes[row, 2].imshow(alpha, cmap="gray", vmin=0, vmax=1)
        axes[row, 2].set_title("alpha", fontsize=9)
        for ax in axes[row]:
            ax.set_xticks([])
            ax.set_yticks([])
    fig.colorbar(im, ax=axes[:, 1].tolist(), shrink=0.6, label="over the frame's mean scattered light")
    out = ROOT / "docs" / "approximate_grid_bias.png"
    fig.savefig(out)
    print(f"wrote {out}")


def figure(args):
    """docs/approximate_cumulus.png: the shipped cumulus front- and back-lit, single scattering (the scene file
    as it is), the octaves, the grid, 16 denoised paths per pixel and multiple scattering (--paths per pixel),
    --size pixels square, each with its time and its relative RMSE against the multiple-scattering image (its
    noise subtracted)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from cloudmeta.scene.colour import encode_srgb
    from cloudmeta.renderer import render_frame
    fig, axes = plt.subplots(2, 5, figsize=(15, 6.4), dpi=100)
    for row, name in enumerate(("cumulus.yaml", "cumulus_backlit.yaml")):
        path = ROOT / "scenes" / name
        shipped = cm.load_scene(path, width=args.size, height=args.size)
        multi = with_settings(replace(shipped, ambient=None), scattering="multiple")
        approx = with_settings(replace(shipped, ambient=None), scattering="approximate")
        grid = with_settings(approx, method="grid")
        t0 = time.perf_counter()
        det = cm.render(with_settings(multi, scattering="single"), progress=False)
        mean, se = render_multiple(multi, paths=args.paths)
        t_ms = time.perf_counter() - t0
        u = det[..., :3] + mean
        bt = background_times_t(multi, det)
        shots = []
        for label, scene in (("single scattering (as shipped)", shipped), ("approximate: octaves", approx),
                             ("approximate: grid", grid)):
            t0 = time.perf_counter()
            result = render_frame(scene, progress=False, error=scene is not shipped)
            took = time.perf_counter() - t0
            err = rel_error(result.image[..., :3].astype(np.float64), u, se, bt)
            extra = (f"; estimated {result.approximation.rel_rmse:.2f}" if result.approximation is not None else "")
            shots.append((result.image, f"{label}\n{took:.1f} s, error {err:.2f}{extra}"))
        # a preview: 16 paths per pixel (another seed than the reference's), denoised (renderer.denoise)
        t0 = time.perf_counter()
        result = render_frame(with_settings(multi, ms_spp=16), progress=False, seed=1, denoise=True)
        took = time.perf_counter() - t0
        err = rel_error(result.image[..., :3].astype(np.float64), u, se, bt)
        shots.append((result.image, f"multiple, 16 paths, denoised\n{took:.1f} s, error {err:.2f}"))
        noise = np.sqrt(np.mean(se ** 2)) / float(np.mean(u - bt))
        shots.append((np.dstack([u, det[..., 3:]]), f"multiple scattering, {args.paths} paths\n{t_ms:.0f} s, "
                                                     f"its noise {noise:.2f}"))
        for col, (img, title) in enumerate(shots):
            ax = axes[row, col]
            ax.imshow(encode_srgb(np.asarray(img, np.float32)[..., :3], -1.0, shipped.render.colourspace))
            ax.set_title(title, fontsize=8)
            ax.axis("off")
    fig.suptitle(f"The 77-ball cumulus, {args.size} x {args.size}, exposure -1; errors: relative RMSE against the "
                 "scattered light of the multiple-scattering image", fontsize=8)
    fig.tight_layout()
    out = ROOT / "docs" / "approximate_cumulus.png"
    fig.savefig(out)
    print(f"wrote {out}")


def main(argv=None, quick=False):
    ap = parser(__doc__, no_csv=True)
    ap.add_argument("what", choices=("references", "fit", "tune", "report", "deposits", "timing", "levels", "bias",
                                     "figure"))
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--paths", type=int, default=512)
    args, quick = parse(ap, argv, quick)
    return {"references": references, "fit": fit, "tune": tune, "report": report, "deposits": deposits,
            "timing": timing, "levels": levels, "bias": bias, "figure": figure}[args.what](args)


if __name__ == "__main__":
    run_main(main)
