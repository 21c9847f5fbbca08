"""Multiple scattering (``render: {scattering: multiple}``) against exact answers and adding-doubling.

1. White furnace: an albedo-1 medium with heterogeneous (`field`) density under a uniform environment
   (the background), no lights: every pixel must show exactly the environment's radiance. Measured: the
   mean over the pixels that meet the medium (relative error per channel), and per pixel the z-score
   (image - environment) / (the renderer's own standard error, with the float32 image's rounding added in
   quadrature: with tracked flights every path of a camera ray gives the same estimate here).
2. Slab: a wide flat uniform slab (one `uniform` ellipsoid of radii 10^4, 10^4, 1: locally flat to 1e-8
   where the camera looks), lit at normal incidence by a directional light of irradiance 1, against
   adding-doubling (iadpython, index 1 everywhere, 32 quadrature angles; its fluxes UR1, UT1 at 16
   against 32 angles show how far it has converged). The radiance reflected (camera above) and transmitted (camera below) at the quadrature
   angle nu nearest 0.6 is compared with R[nu, 1] / pi and T[nu, 1] / pi of iadpython's matrices (their
   columns at nu = 1 are normal incidence; sum_i 2 nu_i w_i R[i, 1] is its UR1). Optical thickness 0.5, 2
   and 8, albedo 0.8 and 0.99, g = 0 and 0.85. Requirement: within 1 % or within 3 standard errors.
3. Cumulus: the 77-ball cumulus front-lit and back-lit (ambient removed: the environment lights it),
   multiple scattering at a reduced size: the time and the estimated relative RMSE of the Monte Carlo
   part (from the per-pixel standard errors), extrapolated to 512^2 at 1 % relative RMSE (time scales
   with pixels x paths; error with 1 / sqrt(paths)). Labelled as extrapolated.

    python -m validation.accuracy.multiple_scattering [--quick] [--skip-cumulus]
    python -m validation.accuracy.multiple_scattering --figures docs/multiple_cumulus.png [--size 256] [--paths 64]

Writes validation/results/multiple_scattering.csv (full runs only).
"""
from __future__ import annotations

import math
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numba
import numpy as np

import cloudmeta as cm
from cloudmeta.renderer.multiple import render_multiple
from validation.common import ROOT, parse, parser, run_main, with_settings, write_csv

FURNACE = """
image: {{width: {n}, height: {n}, spp: 1}}
camera: {{position: [0, -8, 0], look_at: [0, 0, 0], up: [0, 0, 1], fov: 30}}
background: [0.5, 0.7, 1.0]
media:
  - name: puff
    kernel: wyvill6
    threshold: 0.3
    density: {{mode: field, scale: 4.0}}
    albedo: 1.0
    phase: {{type: hg, g: 0.6}}
    balls:
      - {{center: [0, 0, 0], radius: 1.5, weight: 1.0}}
      - {{center: [0.8, 0.3, 0.4], radius: 1.0, weight: 0.8}}
      - {{center: [-0.9, -0.2, -0.5], radius: 0.9, weight: 1.2}}
render: {{scattering: multiple, max_order: 1000000, ms_spp: {paths}}}
"""

SLAB = """
image: {{width: 2, height: 2, spp: 1}}
camera: {{position: {cam}, look_at: {target}, up: [0, 1, 0], fov: 0.05}}
lights:
  - {{type: directional, direction: [0, 0, 1], irradiance: 1.0}}
media:
  - name: slab
    kernel: wyvill6
    threshold: {threshold}
    density: {{mode: uniform, scale: {scale}}}
    albedo: {albedo}
    phase: {{type: hg, g: {g}}}
    balls:
      - {{center: [0, 0, 0], radii: [10000.0, 10000.0, 1.0], rotation: [0, 0, 0], weight: 1.0}}
render: {{quality: reference, scattering: multiple, max_order: 1000000, ms_spp: {paths}}}
"""
SLAB_THRESHOLD = 0.5
#: camera distance from the slab's face (in units of the ellipsoid's short radius)
SLAB_DISTANCE = 20.0


def _write(tmp, name, text):
    path = Path(tmp) / name
    path.write_text(text)
    return path


# ------------------------------------------------------------------------------------------ furnace

def furnace(tmp, n, paths):
    scene = cm.load_scene(_write(tmp, "furnace.yaml", FURNACE.format(n=n, paths=paths)))
    t0 = time.perf_counter()
    image = cm.render(scene, progress=False).astype(np.float64)[..., :3]
    seconds = time.perf_counter() - t0
    ms, err = render_multiple(scene)  # the same paths again: its standard error (deterministic stream)
    bg = np.array(scene.background)
    inside = ms[..., 0] > 0.0  # the camera ray meets the medium
    mean_rel = image[inside].mean(axis=0) / bg - 1.0
    # tracked flights with albedo 1 give every path of a camera ray the same estimate (its escape sees the
    # environment; roulette never plays): err is then 0, and the image's float32 rounding is the scale
    z = ((image[inside] - bg) / np.sqrt(err[inside] ** 2 + (4 * 2.0 ** -24 * bg) ** 2)).ravel()
    outside_exact = bool(np.all(image[~inside] == bg.astype(np.float32)))
    passed = bool(np.all(np.abs(mean_rel) < 0.01) and np.mean(np.abs(z) < 3) >= 0.97 and outside_exact)
    return dict(pixels=int(inside.sum()), paths=paths, mean_rel=mean_rel, z_rms=float(np.sqrt(np.mean(z * z))),
                z_max=float(np.abs(z).max()), within_3=float(np.mean(np.abs(z) < 3)),
                rel_err_px=float(np.median(err[inside] / bg)), seconds=seconds, outside_exact=outside_exact,
                passed=passed)


# ---------------------------------------------------------------------------------------------- slab

def _half_thickness():
    """u* where wyvill6's k(u) = T (the isosurface of one ball of weight 1): the slab's half thickness is
    sqrt(u*) times the short radius."""
    lo, hi = 0.0, 1.0
    for _ in range(200):
        u = 0.5 * (lo + hi)
        k = (1 - u) ** 2 * (1 - 4 * u / 9)
        lo, hi = (u, hi) if k > SLAB_THRESHOLD else (lo, u)
    return math.sqrt(0.5 * (lo + hi))


def adding_doubling(tau, albedo, g, quad_pts):
    """(nu, R[:, nu=1] / pi, T[:, nu=1] / pi): radiance per unit normal irradiance from iadpython."""
    import iadpython as iad
    s = iad.Sample(a=albedo, b=tau, g=g, n=1.0, n_above=1.0, n_below=1.0, quad_pts=quad_pts)
    R, _, T, _ = s.rt_matrices()
    return np.array(s.nu), R[:, -1] / math.pi, T[:, -1] / math.pi


def iad_fluxes(tau, albedo, g, quad_pts):
    """(UR1, UT1): iadpython's total reflectance and transmittance for normal incidence."""
    import iadpython as iad
    s = iad.Sample(a=albedo, b=tau, g=g, n=1.0, n_above=1.0, n_below=1.0, quad_pts=quad_pts)
    ur1, ut1, _, _ = s.rt()
    return float(ur1), float(ut1)


def slab_radiance(tmp, tau, albedo, g, nu, reflected, paths, target_rel, max_seconds):
    """The slab's radiance in direction nu (cosine from the normal) above (reflected) or below it:
    deterministic order 1 plus batches of Monte Carlo paths until the standard error is below target_rel
    of the value or max_seconds pass. Returns (radiance, stderr, paths used, seconds)."""
    h = _half_thickness()
    sin = math.sqrt(1 - nu * nu)
    z = (h + SLAB_DISTANCE * nu) if reflected else -(h + SLAB_DISTANCE * nu)
    cam = [SLAB_DISTANCE * sin, 0.0, z]
    target = [0.0, 0.0, h if reflected else -h]
    text = SLAB.format(cam=cam, target=target, threshold=SLAB_THRESHOLD, scale=tau / (2 * h), albedo=albedo, g=g,
                       paths=paths)
    scene = cm.load_scene(_write(tmp, "slab.yaml", text))
    t0 = time.perf_counter()
    single = cm.render(with_settings(scene, scattering="single"), progress=False)
    single = float(single[..., 0].astype(np.float64).mean())
    means, variances = [], []
    while True:
        mean, err = render_multiple(scene, paths=paths, seed=len(means))
        # 4 pixels of the same radiance, each the mean of `paths` paths: one batch's mean and its variance
        means.append(float(mean[..., 0].mean()))
        variances.append(float((err[..., 0] ** 2).sum()) / 16.0)
        value = single + float(np.mean(means))
        se = math.sqrt(sum(variances)) / len(means)
        if se <= target_rel * value or time.perf_counter() - t0 > max_seconds:
            return value, se, 4 * paths * len(means), time.perf_counter() - t0


def slab_cases(quick):
    if quick:
        return [(2.0, 0.8, 0.0)]
    return [(tau, a, g) for tau in (0.5, 2.0, 8.0) for a in (0.8, 0.99) for g in (0.0, 0.85)]


def slab(tmp, quick):
    rows = []
    for tau, a, g in slab_cases(quick):
        nu32, r32, t32 = adding_doubling(tau, a, g, 32)
        i = int(np.argmin(np.abs(nu32 - 0.6)))
        nu = float(nu32[i])
        ref_conv = None
        if not quick:
            # the reference's own convergence: its total reflectance and transmittance, 16 against 32 angles
            # (iadpython 0.5.3 returns nonsense at 64)
            flux = [iad_fluxes(tau, a, g, n) for n in (32, 16)]
            ref_conv = (flux[1][0] / flux[0][0] - 1, flux[1][1] / flux[0][1] - 1)
        for reflected, ref in ((True, r32[i]), (False, t32[i])):
            value, se, n, sec = slab_radiance(tmp, tau, a, g, nu, reflected, paths=64 if quick else 256,
                                              target_rel=0.01 if quick else 0.002,
                                              max_seconds=20 if quick else 60)
            rel = value / ref - 1
            ok = abs(rel) < 0.01 or abs(value - ref) < 3 * se
            rows.append(dict(tau=tau, albedo=a, g=g, side="R" if reflected else "T", nu=nu, cloudmeta=value,
                             stderr=se, iad=float(ref), rel=rel, z=(value - ref) / se if se > 0 else np.inf,
                             paths=n, seconds=sec, iad_16_vs_32=None if ref_conv is None else
                             ref_conv[0 if reflected else 1], passed=bool(ok)))
            r = rows[-1]
            print(f"  tau {tau:4.1f} a {a:4.2f} g {g:4.2f} {r['side']} nu {nu:.4f}: cloudmeta {value:.6f} "
                  f"+- {se:.1e}  iad {ref:.6f}  rel {rel:+.2%}  z {r['z']:+.1f}  {n} paths {sec:.0f} s "
                  f"{'ok' if ok else 'FAIL'}", flush=True)
    return rows


# ------------------------------------------------------------------------------------------- cumulus

def cumulus(size, paths):
    rows = []
    for name in ("cumulus", "cumulus_backlit"):
        scene = cm.load_scene(ROOT / "scenes" / f"{name}.yaml", width=size, height=size)
        scene = replace(scene, ambient=None, render=replace(scene.render, scattering="multiple", ms_spp=paths))
        single_scene = with_settings(scene, scattering="single")
        # untimed, on 8^2: what this scene's features compile must not be charged to its 512^2 time
        cm.render(replace(single_scene, image=replace(single_scene.image, width=8, height=8)), progress=False)
        render_multiple(replace(scene, image=replace(scene.image, width=8, height=8)))
        t0 = time.perf_counter()
        single = cm.render(single_scene, progress=False)[..., :3].astype(np.float64)
        t_single = time.perf_counter() - t0
        t0 = time.perf_counter()
        mean, err = render_multiple(scene)
        t_mc = time.perf_counter() - t0
        total = single + mean
        rel_rmse = float(np.sqrt(np.mean(err ** 2)) / np.sqrt(np.mean(total ** 2)))
        # time to 1 % at 512^2: pixels x (paths needed) at the measured cost per path
        paths_1pc = paths * (rel_rmse / 0.01) ** 2
        t_512 = t_single * (512 / size) ** 2 + t_mc * (512 / size) ** 2 * paths_1pc / paths
        rows.append(dict(scene=name, size=size, paths=paths, t_single=t_single, t_mc=t_mc, rel_rmse=rel_rmse,
                         ms_share=float(mean.sum() / total.sum()), paths_for_1pc=paths_1pc, t_512_1pc=t_512))
        r = rows[-1]
        print(f"  {name:16s} {size}^2 {paths} paths: single {t_single:.1f} s, MC {t_mc:.1f} s, "
              f"MC share of the light {r['ms_share']:.1%}, est. rel RMSE {rel_rmse:.2%}; "
              f"1 % needs ~{paths_1pc:.0f} paths/px: ~{t_512:.0f} s at 512^2 (extrapolated)", flush=True)
    return rows


#: exposure of the side-by-side pictures (stops, the same for all): multiply scattered light makes the
#: cumulus several times brighter than its single-scattering scene files were set up for
EXPOSURE = -2.0


def figures(size, paths, out):
    """Single and multiple scattering side by side, front-lit and back-lit, with time and estimated error
    under each picture (docs/multiple_cumulus.png), all at exposure EXPOSURE."""
    from PIL import Image, ImageDraw

    from cloudmeta.scene.colour import encode_srgb
    tiles = []
    for name in ("cumulus", "cumulus_backlit"):
        scene = cm.load_scene(ROOT / "scenes" / f"{name}.yaml", width=size, height=size)
        t0 = time.perf_counter()
        single = cm.render(scene, progress=False)  # as the scene file says: single scattering with ambient
        t_single = time.perf_counter() - t0
        multi_scene = replace(scene, ambient=None, render=replace(scene.render, scattering="multiple", ms_spp=paths))
        t0 = time.perf_counter()
        base = cm.render(with_settings(multi_scene, scattering="single"), progress=False)[..., :3].astype(np.float64)
        mean, err = render_multiple(multi_scene)
        t_multi = time.perf_counter() - t0
        multi = base + mean
        rel = float(np.sqrt(np.mean(err ** 2)) / np.sqrt(np.mean(multi ** 2)))
        tiles.append((single[..., :3], f"{name}\nsingle + ambient, {t_single:.1f} s"))
        tiles.append((multi, f"multiple, {paths} paths: {t_multi:.0f} s\nest. rel. RMSE {rel:.1%}"))
        print(f"  {name}: single {t_single:.1f} s; multiple {t_multi:.1f} s ({paths} paths), rel RMSE {rel:.2%}")
    pad = 30
    sheet = Image.new("RGB", (2 * size, 2 * (size + pad)), "white")
    draw = ImageDraw.Draw(sheet)
    for k, (img, caption) in enumerate(tiles):
        x, y = (k % 2) * size, (k // 2) * (size + pad)
        sheet.paste(Image.fromarray(encode_srgb(np.asarray(img, np.float64), EXPOSURE, "ITU-R BT.709")), (x, y))
        draw.multiline_text((x + 3, y + size + 3), caption, fill="black")
    sheet.save(out)
    print(f"  wrote {out}")


def main(argv=None, quick=False):
    ap = parser(__doc__, quick="small furnace, one slab case, small cumulus")
    ap.add_argument("--skip-cumulus", action="store_true")
    ap.add_argument("--skip-slab", action="store_true")
    ap.add_argument("--figures", metavar="PNG", help="only the side-by-side cumulus pictures, written to PNG")
    ap.add_argument("--size", type=int, default=256, help="--figures: pixels per side")
    ap.add_argument("--paths", type=int, default=64, help="--figures: Monte Carlo paths per pixel")
    args, quick = parse(ap, argv, quick)
    if args.figures:
        figures(args.size, args.paths, args.figures)
        return dict(passed=True)
    print(f"Multiple scattering ({numba.get_num_threads()} threads)")
    with tempfile.TemporaryDirectory() as tmp:
        print("1. white furnace (albedo 1, field density, uniform environment, no lights)")
        f = furnace(tmp, 8 if quick else 24, 256 if quick else 1024)
        print(f"  {f['pixels']} pixels x {f['paths']} paths: mean rel. error per channel "
              f"{', '.join(f'{v:+.3%}' for v in f['mean_rel'])}; z-scores: rms {f['z_rms']:.2f}, max {f['z_max']:.2f}, "
              f"{f['within_3']:.1%} within 3; median per-pixel std. error {f['rel_err_px']:.2%}; "
              f"outside exact: {f['outside_exact']}; {f['seconds']:.1f} s  {'PASS' if f['passed'] else 'FAIL'}")
        slab_rows = []
        if not args.skip_slab:
            print("2. slab at normal incidence against adding-doubling (iadpython), radiance at nu ~ 0.6")
            slab_rows = slab(tmp, quick)
    cum_rows = []
    if not args.skip_cumulus:
        print("3. cumulus, multiple scattering (ambient removed; the background is the environment)")
        cum_rows = cumulus(32 if quick else 128, 4 if quick else 16)
    passed = f["passed"] and all(r["passed"] for r in slab_rows)
    if not quick and slab_rows:
        write_csv("multiple_scattering.csv", slab_rows)
    print("PASS" if passed else "FAIL")
    return dict(furnace=f, slab=slab_rows, cumulus=cum_rows, passed=passed)


if __name__ == "__main__":
    run_main(main)
