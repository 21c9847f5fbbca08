"""A prototype of sharing the multiply scattered light along the camera's optical depth, measured.

Per sample camera ray (every ``stride``-th pixel in each direction, and the last row and column), at fixed
optical depths tau_a of the ray (TAUS), K path tails estimate Q(tau_a) = (sigma_s / sigma_t) J(x), J the
light of orders >= 2 (and >= 1 of the environment) that x scatters towards the camera: exactly what a path
of the unbiased estimator adds after its first vertex (renderer.multiple), started at x instead of at a
random depth. Each pixel then takes the integral over its own ray of e^-tau Q(tau) d tau up to its own
optical depth U, Q bilinear between the four neighbouring sample rays at equal tau (those whose U passes
tau), linear in tau. With stride 1 every pixel has its own ray and only the depths are fixed. The tails are
the renderer's own (kernels.shared, whose first depth is at most half the ray's); the approximate mode's
``method: shared`` (renderer.shared) builds this with refinement.

Error as validation.accuracy.approximate.rel_error against its references (64 x 48, 2,048 paths, their
noise subtracted), with single scattering at ``fine`` added. A prototype: its times are not tuned, the
number of paths is the measure.

With ``--sizes`` (no reference needed) it measures instead how the sharing's bias depends on the image size:
at each size, the tails of every pixel's own ray (two seeds, ``--paths`` per point) against the same tails at
every s-th pixel, interpolated; bias^2 = mean (I_s,seed 1 - I_1,seed 2)^2 - the variances of both (each
from its two seeds), relative to the frame's mean scattered light.

    python -m validation.accuracy.ms_tau_sharing [--scenes cumulus_front bank_front] [--strides 4 2 1] [--paths 16 64]
    python -m validation.accuracy.ms_tau_sharing --scenes cumulus_front --sizes 64 128 256 --paths 256 128 32 --strides 2 4 8
"""
from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import cloudmeta as cm
from cloudmeta.kernels.media import n_media
from cloudmeta.kernels.shared import depth_tails
from cloudmeta.kernels.tracking import alloc_track_work
from cloudmeta.renderer.fluence import no_cache
from cloudmeta.renderer.multiple import _tracked_records
from cloudmeta.renderer.pack import pack_scene
from cloudmeta.renderer.quality import resolve_settings
from cloudmeta.renderer.tracking import path_settings
from validation.accuracy.approximate import REPORT, background_times_t, reference, rel_error, scene_of
from validation.common import parse, parser, run_main, with_settings

TAUS = np.array([0.02, 0.1, 0.25, 0.5, 0.8, 1.2, 1.8, 2.7, 4.0, 6.0, 9.0])


def run_tails(packed, settings, grid, volumes, rows, cols, taus, K, seed, threads=2):
    """(out (n, len(taus), 3): each sample ray's mean tail at each depth, NaN where it does not reach; u (n,): its
    optical depth), by the renderer's own kernel (kernels.shared.depth_tails, K tails at every depth)."""
    n = len(rows)
    out = np.full((n, len(taus), 3), np.nan)
    u = np.zeros(n)
    parts = np.array_split(np.arange(n), threads * 4)
    cam, rec, quad = packed.camera._replace(spp=1), packed.records, packed.quadrature
    tails = np.full(len(taus), K, np.int64)
    width = np.int64(packed.camera.width)

    def go(idx):
        if len(idx) == 0:
            return
        o = np.empty((len(idx), len(taus), 3))
        uu = np.zeros(len(idx))
        r, c = rows[idx].astype(np.int64), cols[idx].astype(np.int64)
        depth_tails(cam, rec, quad, settings, grid, volumes, no_cache(n_media(rec.media)), r, c, r * width + c, taus, tails, np.int64(seed),
                    alloc_track_work(np.int64(n_media(rec.media))), o, np.empty_like(o), uu)
        out[idx] = o
        u[idx] = uu
    with ThreadPoolExecutor(threads) as pool:
        list(pool.map(go, parts))
    return out, u


def sample_axis(n, s):
    ax = np.arange(0, n, s)
    if ax[-1] != n - 1:
        ax = np.append(ax, n - 1)
    return ax


def gather(Q, U_s, rows_ax, cols_ax, U_pix, taus, n_grid=600):
    """Per pixel int_0^U e^-tau Q(tau) dtau, Q bilinear between sample rays at each tau node (valid ones only),
    piecewise linear in tau, held constant outside the nodes."""
    H, W = U_pix.shape
    nr, nc = len(rows_ax), len(cols_ax)
    Qg = Q.reshape(nr, nc, len(taus), 3)
    img = np.zeros((H, W, 3))
    for i in range(H):
        r1 = np.searchsorted(rows_ax, i)
        r0 = max(r1 - 1, 0) if rows_ax[min(r1, nr - 1)] != i else min(r1, nr - 1)
        r1 = min(r1, nr - 1)
        fr = 0.0 if r1 == r0 else (i - rows_ax[r0]) / (rows_ax[r1] - rows_ax[r0])
        for j in range(W):
            U = U_pix[i, j]
            if U <= 0:
                continue
            c1 = np.searchsorted(cols_ax, j)
            c0 = max(c1 - 1, 0) if cols_ax[min(c1, nc - 1)] != j else min(c1, nc - 1)
            c1 = min(c1, nc - 1)
            fc = 0.0 if c1 == c0 else (j - cols_ax[c0]) / (cols_ax[c1] - cols_ax[c0])
            nb = [(r0, c0, (1 - fr) * (1 - fc)), (r0, c1, (1 - fr) * fc), (r1, c0, fr * (1 - fc)), (r1, c1, fr * fc)]
            prof = np.full((len(taus), 3), np.nan)
            for a in range(len(taus)):
                if taus[a] >= U and a > 0 and taus[a - 1] >= U:
                    break
                acc = np.zeros(3)
                wsum = 0.0
                for (rr, cc, w) in nb:
                    if w > 0 and not np.isnan(Qg[rr, cc, a, 0]):
                        acc += w * Qg[rr, cc, a]
                        wsum += w
                if wsum > 0:
                    prof[a] = acc / wsum
            ok = ~np.isnan(prof[:, 0])
            if not ok.any():
                # no neighbour reaches this pixel's first node: nearest sample ray with any value
                cand = [Qg[rr, cc][~np.isnan(Qg[rr, cc, :, 0])] for (rr, cc, w) in nb]
                cand = [c_[0] for c_ in cand if len(c_)]
                if not cand:
                    continue
                prof[0] = np.mean(cand, axis=0)
                ok = ~np.isnan(prof[:, 0])
            tk, qk = taus[ok], prof[ok]
            t = np.linspace(0, min(U, 40.0), n_grid)
            wts = np.exp(-t)
            vals = np.stack([np.interp(t, tk, qk[:, c]) for c in range(3)], -1)
            img[i, j] = np.trapezoid(wts[:, None] * vals, t, axis=0)
    return img


def main(argv=None):
    ap = parser(__doc__)
    ap.add_argument("--scenes", nargs="+", default=["cumulus_front", "bank_front"], choices=list(REPORT))
    ap.add_argument("--strides", type=int, nargs="+", default=[4, 2, 1])
    ap.add_argument("--paths", type=int, nargs="+", default=[16, 64], help="tails per sample point (K)")
    ap.add_argument("--reference-paths", type=int, default=2048)
    ap.add_argument("--sizes", type=int, nargs="+", help="image widths of the bias-by-size measurement (with "
                    "--paths: one count per size)")
    args, _ = parse(ap, argv)
    if args.sizes:
        return dict(rows=[row for name in args.scenes
                          for size, k in zip(args.sizes, args.paths) for row in bias_by_size(name, size, k, args.strides)])
    rows = []
    for name in args.scenes:
        path = REPORT[name]
        u, se, bt, _ = reference(name, path, 64, args.reference_paths)
        s = with_settings(scene_of(path, 64, "multiple"), quality="fine")
        single = cm.render(with_settings(s, scattering="single"), progress=False)[..., :3].astype(np.float64)
        packed = pack_scene(s, 0, resolve_settings(s))
        max_order = s.render.max_order
        grid, volumes = _tracked_records(s, packed, max_order)
        h, w = s.image.height, s.image.width
        rr, cc = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
        _, u_all = run_tails(packed, path_settings(s, 1, max_order), grid, volumes, rr.ravel(), cc.ravel(), TAUS, 0, 1)
        ms_ref = u - single
        print(f"{name}: multiply scattered share of the reference {ms_ref.mean() / (u - bt).mean():.2f}", flush=True)
        for stride in args.strides:
            ra, ca = sample_axis(h, stride), sample_axis(w, stride)
            R, C = np.meshgrid(ra, ca, indexing="ij")
            for k in args.paths:
                t0 = time.perf_counter()
                q, u_s = run_tails(packed, path_settings(s, k, max_order), grid, volumes, R.ravel(), C.ravel(), TAUS,
                                   k, 7)
                seconds = time.perf_counter() - t0
                image = gather(q, u_s, ra, ca, u_all.reshape(h, w), TAUS)
                err = rel_error(single + image, u, se, bt)
                n_paths = int(np.sum(~np.isnan(q[..., 0]))) * k
                print(f"  stride {stride} K {k:5d}: {n_paths:8d} paths ({n_paths / (h * w):6.1f} a pixel), error {err:.4f},"
                      f" mean / reference {image.mean() / ms_ref.mean():.3f}  ({seconds:.1f} s)", flush=True)
                rows.append(dict(scene=name, stride=stride, paths=k, paths_per_pixel=n_paths / (h * w), error=err))
    return dict(rows=rows)


def bias_by_size(name, size, k, strides):
    """The sharing's bias floor per stride at this image width, against every pixel's own tails (module
    docstring); prints and returns rows."""
    s = with_settings(scene_of(REPORT[name], size, "multiple"), quality="default")
    single = cm.render(with_settings(s, scattering="single"), progress=False)
    bt = background_times_t(s, single)
    single = single[..., :3].astype(np.float64)
    packed = pack_scene(s, 0, resolve_settings(s))
    max_order = s.render.max_order
    grid, volumes = _tracked_records(s, packed, max_order)
    h, w = s.image.height, s.image.width
    rr, cc = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
    runs = [run_tails(packed, path_settings(s, k, max_order), grid, volumes, rr.ravel(), cc.ravel(), TAUS, k, seed)
            for seed in (7, 8)]
    u_pix = runs[0][1].reshape(h, w)
    own = [gather(q, u, np.arange(h), np.arange(w), u_pix, TAUS) for q, u in runs]
    scattered = float((single + 0.5 * (own[0] + own[1]) - bt).mean())
    v_own = np.mean((own[0] - own[1]) ** 2) / 2
    print(f"{name} {w} x {h}, {k} tails a point: every pixel's own tails' noise {np.sqrt(v_own) / scattered:.4f}",
          flush=True)
    rows = []
    for stride in strides:
        ra, ca = sample_axis(h, stride), sample_axis(w, stride)
        shared = []
        for q, _ in runs:
            q_s = q.reshape(h, w, len(TAUS), 3)[np.ix_(ra, ca)].reshape(-1, len(TAUS), 3)
            shared.append(gather(q_s, u_pix[np.ix_(ra, ca)].ravel(), ra, ca, u_pix, TAUS))
        v_s = np.mean((shared[0] - shared[1]) ** 2) / 2
        bias = np.sqrt(max(np.mean((shared[0] - own[1]) ** 2) - v_s - v_own, 0.0)) / scattered
        print(f"  stride {stride}: bias {bias:.4f} of the scattered light (the shared image's noise "
              f"{np.sqrt(v_s) / scattered:.4f})", flush=True)
        rows.append(dict(scene=name, size=size, stride=stride, paths=k, bias=bias))
    return rows


if __name__ == "__main__":
    run_main(main)
