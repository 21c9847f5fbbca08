"""How much darker the base of the generated cumulus is than its sunlit top: the ratio of the base's luminance
to the sunlit top's, in unbiased multiple scattering and in the octaves approximation (docs/display.md, "What
the picture cannot fix").

scenes/generated_cumulus.yaml is rendered at 128 x 128 (quality draft) twice: ``scattering: multiple``
(unbiased paths, ``--ms-spp`` paths per pixel, orders up to ``max_order`` 64) and ``scattering:
approximate`` with the octaves method (the scene's own setting; docs/approximate.md). On the linear image
(luminance Y of BT.709 RGB), the same pixels for both renders, chosen on the approximate render (smooth: the
noise of the paths would pick their brightest outliers as the top):

- the cloud: the pixels whose alpha exceeds 1/2;
- the sunlit top: the cloud's pixels at or above the 97th percentile of its luminance (the brightest 3 %:
  what the display's auto exposure measures, docs/display.md);
- the base: the cloud's pixels in the lowest 15 % of the rows the cloud spans (rows from its highest to
  its lowest cloud pixel); the camera stands a little below the base, so these rows are the flat underside
  and the foot of the flanks.

It prints, for each render, the mean luminance of the base, of the top, their ratio, and the process CPU
time of the render (numba's threads included; a loaded machine's wall time says little).

    python -m validation.accuracy.base_top [--size 128] [--ms-spp 1024] [--scene PATH] [--png-dir DIR]

``--png-dir`` writes both pictures there (base_top_approximate.png, base_top_multiple.png: the default display,
at the approximate render's auto exposure for both, so that their brightness compares).

A real cumulus's base is grey against its white sunlit top, a ratio of roughly 0.2-0.5 in photographs
(the base is lit only by light that has crossed the cloud and by the ground and the sky below).
"""
from __future__ import annotations

import time

import numpy as np

import cloudmeta as cm
from cloudmeta.api.display import _rgb_to_xyz
from validation.common import ROOT, parse, parser, run_main

#: the sunlit top: the cloud's pixels at or above this percentile of its luminance
TOP_PERCENTILE = 97.0
#: the base: the cloud's pixels in this lowest part of the rows the cloud spans
BASE_ROWS = 0.15
#: a pixel is the cloud's where its alpha exceeds this
CLOUD_ALPHA = 0.5
_Y = _rgb_to_xyz("ITU-R BT.709")[1]


def luminance(image):
    return np.asarray(image[..., :3], np.float64) @ _Y


def regions(image):
    """(cloud, top, base, rows of the base) of an H x W x 4 linear image: boolean masks (docs above)."""
    cloud = image[..., 3] > CLOUD_ALPHA
    y = luminance(image)
    top = cloud & (y >= np.percentile(y[cloud], TOP_PERCENTILE))
    rows = np.flatnonzero(cloud.any(axis=1))
    top_row, bottom_row = int(rows[0]), int(rows[-1])
    first = bottom_row + 1 - max(1, int(round(BASE_ROWS * (bottom_row + 1 - top_row))))
    base = cloud.copy()
    base[:first] = False
    return cloud, top, base, (first, bottom_row)


def ratio(image, top, base):
    """(base luminance, top luminance, base / top) of a linear image over these masks."""
    y = luminance(image)
    b, t = float(y[base].mean()), float(y[top].mean())
    return b, t, b / t


def main(argv=None):
    ap = parser(__doc__)
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--ms-spp", type=int, default=1024, help="paths per pixel of the multiple-scattering render")
    ap.add_argument("--png-dir", default=None, help="write both pictures to this folder")
    ap.add_argument("--scene", default=str(ROOT / "scenes" / "generated_cumulus.yaml"))
    args, _ = parse(ap, argv)
    renders = (("approximate (octaves)", {"quality": "draft", "scattering": "approximate", "method": "octaves"}),
               (f"multiple, {args.ms_spp} paths a pixel", {"quality": "draft", "scattering": "multiple",
                                                           "ms_spp": args.ms_spp}))
    images, cpu, scene = {}, {}, None
    for name, settings in renders:
        scene = cm.load_scene(args.scene, width=args.size, height=args.size, render=settings)
        t0 = time.process_time()
        images[name] = np.asarray(cm.render(scene, progress=False), np.float64)
        cpu[name] = time.process_time() - t0
    cloud, top, base, (first, last) = regions(images[renders[0][0]])
    print(f"{args.scene}: {args.size} x {args.size}, quality draft; cloud: {int(cloud.sum())} pixels (alpha > "
          f"{CLOUD_ALPHA:g}); base: {int(base.sum())} pixels in rows {first}-{last} (the lowest {BASE_ROWS:.0%} of "
          f"the cloud's rows); sunlit top: {int(top.sum())} pixels (at or above the {TOP_PERCENTILE:g}th percentile of the "
          f"cloud's luminance in the approximate render)")
    print(f"{'render':<30} {'base Y':>9} {'top Y':>9} {'base / top':>11} {'CPU s':>8}")
    result = {}
    for name, _ in renders:
        b, t, r = ratio(images[name], top, base)
        result[name] = r
        print(f"{name:<30} {b:>9.4f} {t:>9.4f} {r:>11.3f} {cpu[name]:>8.1f}")
    if args.png_dir:
        from cloudmeta.api.display import exposure_of, scene_illuminant
        illuminant = scene_illuminant(scene)
        stops = exposure_of(images[renders[0][0]], scene.render.colourspace, illuminant=illuminant)
        for (name, _), label in zip(renders, ("approximate", "multiple")):
            cm.write_png(images[name], f"{args.png_dir}/base_top_{label}.png", exposure=stops, scene=scene)
    return result


if __name__ == "__main__":
    run_main(main)
