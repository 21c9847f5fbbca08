"""Far-away geometry: how much a stray ball far from a cloud changes the cloud's pixels.

Renders the shipped cumulus at ``--size`` pixels, with and without one extra ball of radius 1 placed
``distance`` away (out of view, off every shadow ray), at the given presets, and prints the largest pixel
change relative to the image's largest value. Tolerances that follow the scene's diagonal make this grow
with the distance; tolerances that follow the geometry a ray meets (Scene.length_scale) keep it at 0.

    python -m validation.accuracy.far_geometry [--size 48] [--qualities default reference]
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

import cloudmeta as cm
from validation.common import ROOT, parse, parser, run_main

DISTANCES = (1e3, 1e4, 1e5, 1e6)


def with_stray_ball(scene, distance):
    medium = scene.media[0]
    b = medium.blob
    blob = cm.Blob(np.concatenate([b.centers, [[0.0, distance, -distance / 2]]]),
                   np.concatenate([b.radii, [[1.0, 1.0, 1.0]]]), np.concatenate([b.weights, [1.0]]), b.kernel,
                   b.threshold, rotations=np.concatenate([b.rotations, np.eye(3)[None]]))
    return replace(scene, media=(replace(medium, blob=blob),) + scene.media[1:])


def main(argv=None, quick=False):
    ap = parser(__doc__, quick="16 x 16 pixels")
    ap.add_argument("--size", type=int, default=48)
    ap.add_argument("--qualities", nargs="+", default=["default", "reference"])
    args, quick = parse(ap, argv, quick)
    size = 16 if quick else args.size
    rows = []
    for quality in args.qualities:
        base = cm.load_scene(ROOT / "scenes" / "cumulus.yaml", width=size, height=size)
        base = replace(base, render=replace(base.render, quality=quality))
        ref = cm.render(base, progress=False)
        for distance in DISTANCES:
            img = cm.render(with_stray_ball(base, distance), progress=False)
            change = float(np.max(np.abs(img - ref)) / np.max(np.abs(ref)))
            rows.append(dict(quality=quality, distance=distance, max_change=change))
            print(f"{quality:10s} stray ball at {distance:8.0e}: largest pixel change {change:.2e} (relative)")
    worst = max(r["max_change"] for r in rows)
    return dict(rows=rows, worst=worst, passed=worst <= 1e-9)


if __name__ == "__main__":
    run_main(main)
