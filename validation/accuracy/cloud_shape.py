"""The shape of generated cumulus against real ones: the outline's perimeter dimension and the spread of
puff sizes (docs/generate.md, Shape).

Real cumulus outlines are fractal: the area-perimeter relation of cloud and rain areas gives a perimeter
dimension D = 1.35 over three decades of scale (Lovejoy 1982, Science 216, 185-187). This script measures
D on the outlines that ``cloudmeta generate`` makes:

- For each seed, ``generate(kind, balls, seed)``; the cloud is seen from the front (-y, the side the
  written scene's camera looks from) orthographically on a square image of ``--pixels`` pixels, the
  cloud's visible width filling 70 % of it (as the written scene frames it).
- Per pixel, the exact optical depth tau of the suggested medium along y (``cloudmeta.optical_depth``, the
  ray engine: the same density mode and scale a render uses). The outline is that of the alpha a render
  would have, alpha = 1 - exp(-tau) >= 1/2 (tau >= ln 2): a single-scattering render's alpha, without
  rendering the radiance (a render per seed would take minutes on a loaded machine).
- Box counting: N(s), the boxes of s x s pixels that hold an outline pixel (a pixel inside with a
  4-neighbour outside), for s = 2, 4, ..., 32; D is minus the least-squares slope of log N against
  log s. A smooth curve gives 1, a curve that fills the plane 2.
- The area-perimeter relation over the connected pieces of every seed's mask (the cloud and the wisps
  set loose from it): P ~ A^(D/2), fitted on the pieces of at least 4 pixels (perimeter: the number of
  pixel edges between inside and outside).
- Holes (a foam, not a cumulus): the pieces of the background that the mask encloses (4-connected pieces
  of alpha < 1/2 that do not touch the image's border), counted where they have at least 4 pixels, and
  their total area as a part of the cloud's; and the box-counting dimension again with the holes filled
  (the outer outlines alone: how much of D the holes' edges make).
- The spread of puff sizes: the visible radii of the positive balls that are not the body, as the
  cumulative count N(> r) ~ r^-b, fitted between the 5th and 95th percentiles of r, and the ratio of
  those percentiles (the range of sizes).

Run: ``python -m validation.accuracy.cloud_shape`` (seeds 1-20, cumulus, 4,000 balls, 384 pixels;
``--first 11`` for seeds 11-30);
``--module PATH`` measures the ``generate`` of another copy of the generator (a file), e.g. an older one.
"""
from __future__ import annotations

import argparse
import importlib.util
import math
import sys
import time

import numpy as np

import cloudmeta as cm

#: the published perimeter dimension of cloud outlines (Lovejoy 1982) and the target band around it
PUBLISHED = 1.35
TARGET = (1.25, 1.45)
BOXES = (2, 4, 8, 16, 32)


def outline_mask(cloud, pixels, fill=0.7, alpha=0.5):
    """(pixels, pixels) bool, alpha >= ``alpha`` of the cloud seen along +y, orthographic; and the pixel
    size."""
    b = cloud.balls
    blob = cm.Blob(b[:, :3], b[:, 3:6], b[:, 9], kernel=cloud.medium["kernel"],
                   threshold=cloud.medium["threshold"], rotations=b[:, 6:9])
    (x0, y0, z0), (x1, y1, z1) = cloud.extent
    pixel = (x1 - x0) / (fill * pixels)
    cx, cz = 0.5 * (x0 + x1), 0.5 * (z0 + z1)
    offs = (np.arange(pixels) - 0.5 * (pixels - 1)) * pixel
    xx, zz = np.meshgrid(cx + offs, cz - offs)  # row 0 at the top
    origins = np.stack([xx.ravel(), np.full(xx.size, y0 - 0.05 * (y1 - y0) - pixel), zz.ravel()], 1)
    directions = np.tile([0.0, 1.0, 0.0], (len(origins), 1))
    density = cloud.medium["density"]
    tau = cm.optical_depth(blob, origins, directions, density=density["mode"], scale=density["scale"])
    return (tau >= -math.log(1.0 - alpha)).reshape(pixels, pixels), pixel


def edge_pixels(mask):
    """Inside pixels with a 4-neighbour outside (the image's border counts as outside)."""
    m = np.pad(mask, 1)
    inner = m[1:-1, 1:-1]
    outside_nb = ~m[:-2, 1:-1] | ~m[2:, 1:-1] | ~m[1:-1, :-2] | ~m[1:-1, 2:]
    return inner & outside_nb


def box_counts(edge, sizes=BOXES):
    """N(s): boxes of s x s pixels (a grid from the top-left corner) holding an edge pixel."""
    out = []
    for s in sizes:
        h, w = (-(-edge.shape[0] // s)) * s, (-(-edge.shape[1] // s)) * s
        e = np.zeros((h, w), bool)
        e[:edge.shape[0], :edge.shape[1]] = edge
        out.append(int(e.reshape(h // s, s, w // s, s).any(axis=(1, 3)).sum()))
    return np.array(out)


def box_dimension(counts, sizes=BOXES):
    return float(-np.polyfit(np.log(sizes), np.log(np.maximum(counts, 1)), 1)[0])


def pieces(mask):
    """(area, perimeter) of each 4-connected piece of the mask, in pixels and pixel edges."""
    from scipy import ndimage
    labels, n = ndimage.label(mask)
    if n == 0:
        return np.zeros((0, 2))
    area = np.bincount(labels.ravel(), minlength=n + 1)[1:]
    m = np.pad(labels, 1)
    perim = np.zeros(n + 1)
    for a, b in ((m[1:, :], m[:-1, :]), (m[:, 1:], m[:, :-1])):
        diff = a != b
        np.add.at(perim, a[diff], 1)
        np.add.at(perim, b[diff], 1)
    return np.stack([area, perim[1:]], 1)


def holes(mask, least=4):
    """(count, area / the mask's area, the mask with its holes filled): the pieces of the outside the mask
    encloses (not touching the image's border), counted where they have at least ``least`` pixels; the area
    is of them all."""
    from scipy import ndimage
    labels, n = ndimage.label(~mask)
    border = np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]))
    sizes = np.bincount(labels.ravel(), minlength=n + 1)
    inner = np.setdiff1d(np.arange(1, n + 1), border)
    filled = mask | np.isin(labels, inner)
    return (int(np.count_nonzero(sizes[inner] >= least)), float(sizes[inner].sum() / max(int(mask.sum()), 1)),
            filled)


def puff_sizes(cloud):
    """Visible radii (x size) of the positive balls that are not the body."""
    from cloudmeta.generate import iso_u
    b, lv = cloud.balls, cloud.levels
    keep = (lv > 0) & (b[:, 9] > cloud.medium["threshold"])
    return np.sqrt(iso_u(b[keep, 9])) * b[keep, 3:6].max(axis=1) / cloud.size


def size_spread(radii):
    """(b, p95/p5): the exponent of N(> r) ~ r^-b between the 5th and 95th percentiles, and their ratio."""
    r = np.sort(radii)[::-1]
    lo, hi = np.percentile(r, [5, 95])
    n_above = np.arange(1, len(r) + 1)
    sel = (r >= lo) & (r <= hi)
    slope = np.polyfit(np.log(r[sel]), np.log(n_above[sel]), 1)[0]
    return float(-slope), float(hi / lo)


def load_generate(path):
    if path is None:
        return cm.generate
    spec = importlib.util.spec_from_file_location("generator_under_test", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up there
    spec.loader.exec_module(module)
    return module.generate


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--kind", default="cumulus")
    ap.add_argument("--balls", type=int, default=4000)
    ap.add_argument("--seeds", type=int, default=20, help="how many seeds: FIRST .. FIRST + N - 1")
    ap.add_argument("--first", type=int, default=1, help="the first seed (default 1; 11 with --seeds 20 gives "
                                                         "the held-out seeds 11-30)")
    ap.add_argument("--pixels", type=int, default=384)
    ap.add_argument("--alpha", type=float, default=0.5, help="the outline's alpha (default 1/2)")
    ap.add_argument("--module", default=None, help="a file with another copy of the generator's generate")
    ap.add_argument("--png", default=None, help="write the first seed's mask and outline to this PNG")
    ap.add_argument("-p", action="append", default=[], metavar="NAME=VALUE", help="a parameter of the kind")
    args = ap.parse_args(argv)
    generate = load_generate(args.module)
    from cloudmeta.generate import parse_param
    params = dict(parse_param(t) for t in args.p)
    all_counts, outer = [], []
    dims, gen_cpu, all_pieces, exps, spans, gaps = [], [], [], [], [], []
    seeds = range(args.first, args.first + args.seeds)
    for seed in seeds:
        t0 = time.process_time()
        cloud = generate(args.kind, balls=args.balls, seed=seed, **params)
        gen_cpu.append(time.process_time() - t0)
        mask, _ = outline_mask(cloud, args.pixels, alpha=args.alpha)
        edge = edge_pixels(mask)
        counts = box_counts(edge)
        all_counts.append(counts)
        dims.append(box_dimension(counts))
        all_pieces.append(pieces(mask))
        gaps.append(holes(mask))
        outer.append(box_dimension(box_counts(edge_pixels(gaps[-1][2]))))
        b, span = size_spread(puff_sizes(cloud))
        exps.append(b)
        spans.append(span)
        print(f"seed {seed:3d}: D_box {dims[-1]:.3f}  N(s) {' '.join(map(str, counts))}  "
              f"pieces {len(all_pieces[-1])}  holes {gaps[-1][0]} ({gaps[-1][1]:.2%})  puff sizes N(>r)~r^-{b:.2f} over {span:.1f}x  "
              f"generate {gen_cpu[-1]:.2f} s CPU", flush=True)
        if args.png and seed == seeds[0]:
            import matplotlib
            matplotlib.use("Agg")
            import matplotlib.pyplot as plt
            img = np.where(mask, 0.75, 0.15)[..., None].repeat(3, 2)
            img[edge] = (1.0, 0.3, 0.1)
            plt.imsave(args.png, img)
    dims = np.array(dims)
    pcs = np.concatenate(all_pieces)
    pcs = pcs[pcs[:, 0] >= 4]
    if len(pcs) >= 3 and np.ptp(np.log(pcs[:, 0])) > 1.0:
        d_ap = 2.0 * float(np.polyfit(np.log(pcs[:, 0]), np.log(pcs[:, 1]), 1)[0])
        ap_text = (f"{d_ap:.3f} over {len(pcs)} pieces, areas {pcs[:, 0].min():.0f}-{pcs[:, 0].max():.0f} px "
                   f"({math.log10(pcs[:, 0].max() / pcs[:, 0].min()):.1f} decades)")
    else:
        ap_text = f"not fitted ({len(pcs)} pieces of >= 4 px: too few or too alike in area)"
    lo, hi = TARGET
    print(f"\n{args.kind}, {args.balls} balls, seeds {seeds[0]}-{seeds[-1]}, {args.pixels} x {args.pixels} px, "
          f"outline of alpha >= {args.alpha:g} (exact optical depth along y, orthographic)")
    print(f"perimeter dimension, box counting over {BOXES[0]}-{BOXES[-1]} px "
          f"({BOXES[0] / (0.7 * args.pixels):.2%}-{BOXES[-1] / (0.7 * args.pixels):.1%} of the cloud's width): "
          f"mean {dims.mean():.3f}, range {dims.min():.3f}-{dims.max():.3f}; published {PUBLISHED} "
          f"(target {lo}-{hi}: {'met' if lo <= dims.mean() <= hi else 'NOT met'})")
    print(f"perimeter dimension, area-perimeter over the pieces: {ap_text}")
    ratios = np.array([c[:-1] / c[1:] for c in all_counts]).mean(axis=0)
    print(f"box counts N(s) / N(2s), mean over the seeds, s = {', '.join(map(str, BOXES[:-1]))}: "
          f"{', '.join(f'{r:.2f}' for r in ratios)} (a dimension D gives 2^D; 2^{PUBLISHED} = {2 ** PUBLISHED:.2f})")
    print(f"holes through the cloud (enclosed background, >= 4 px): {np.mean([g[0] for g in gaps]):.1f} a seed "
          f"(most {max(g[0] for g in gaps)}), {np.mean([g[1] for g in gaps]):.2%} of the cloud's area; box counting "
          f"with the holes filled: mean {np.mean(outer):.3f}, range {min(outer):.3f}-{max(outer):.3f}")
    print(f"puff sizes (visible radius / size, levels >= 1): N(>r) ~ r^-b, b mean {np.mean(exps):.2f}, "
          f"p95/p5 {np.mean(spans):.1f}x (range {min(spans):.1f}-{max(spans):.1f})")
    print(f"generate: {np.median(gen_cpu):.2f} s CPU median per cloud")
    return 0 if lo <= dims.mean() <= hi else 1


if __name__ == "__main__":
    sys.exit(main())
