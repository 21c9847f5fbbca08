"""The README's picture of the paper's 77-ball cumulus, front-lit and back-lit (docs/cumulus_pair.png), in multiple
scattering: the approximate mode's shared method (docs/approximate.md) at ``--quality`` (default ``default``).

scenes/cumulus.yaml and scenes/cumulus_backlit.yaml are single-scattering scenes with an ambient term (the paper's
look); here each renders without the ambient (multiple scattering lights the cloud with the sky itself) at
``--width`` x 3/4 of it, seed 0, with ``error=True`` for the approximation's own estimate, and goes through the
default display (docs/display.md: white balance to the scene's light, auto exposure, the ACES output transform).
The two pictures are put side by side. Prints each one's time, planned tails and estimated error.

    python -m validation.tools.readme_pictures [--quality default] [--width 512] [--tails N] [--cache K] [--out PATH]
"""
from __future__ import annotations

import time
from dataclasses import replace

import numpy as np
from PIL import Image

import cloudmeta as cm
from cloudmeta.api.display import display_image, scene_illuminant
from validation.common import ROOT, parse, parser, run_main

SCENES = ("cumulus.yaml", "cumulus_backlit.yaml")


def picture(name, quality, width, tails=None, cache=None):
    """(display codes H x W x 3 uint8, a dict of what the render measured) of one scene; ``tails`` per coarsest
    sample ray, else planned to the preset's target; ``cache``: render.shared.cache (None: the preset's)."""
    scene = cm.load_scene(ROOT / "scenes" / name)
    height = width * 3 // 4
    scene = replace(scene, ambient=None, image=replace(scene.image, width=width, height=height),
                    render=replace(scene.render, scattering="approximate", method="shared", quality=quality,
                                   shared=(None, tails, cache)))
    t0 = time.perf_counter()
    result = cm.render_frame(scene, progress=False, seed=0, error=True)
    seconds = time.perf_counter() - t0
    codes, stops = display_image(result.image, white_balance="scene", illuminant=scene_illuminant(scene))
    a = result.approximation
    return codes, dict(scene=name, seconds=seconds, tails=getattr(result.plan, "tails", None),
                       estimated=a.rel_rmse, stderr=a.stderr, stops=stops)


def main(argv=None):
    ap = parser(__doc__)
    ap.add_argument("--quality", default="default")
    ap.add_argument("--width", type=int, default=512)
    ap.add_argument("--tails", type=int, default=None, help="a fixed count per coarsest sample ray (default: planned)")
    ap.add_argument("--cache", type=int, default=None, help="render.shared.cache: the order the tails read the cache "
                    "after (0: none; default: the preset's)")
    ap.add_argument("--out", default=str(ROOT / "docs" / "cumulus_pair.png"))
    args, _ = parse(ap, argv)
    pictures, rows = [], []
    for name in SCENES:
        codes, row = picture(name, args.quality, args.width, args.tails, args.cache)
        pictures.append(codes)
        rows.append(row)
        print(f"{name:22s} {row['seconds']:7.1f} s  tails {row['tails']}  estimated {row['estimated']:.3f} +- "
              f"{row['stderr']:.3f}  exposure {row['stops']:+.2f} stops", flush=True)
    Image.fromarray(np.concatenate(pictures, axis=1)).save(args.out)
    print(f"wrote {args.out}")
    return dict(rows=rows)


if __name__ == "__main__":
    run_main(main)
