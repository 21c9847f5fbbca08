"""SHA-256 of small renders of every scene: a before / after check that a refactor changes no pixel.

Renders each scene of scenes/*.yaml and docs/*.yaml at WIDTH pixels wide (the height keeps the scene's
aspect; spp as the scene says), plus a few variants (shadow maps, 2 spp, the depth output, the reference
preset, a scene with its ambient removed), and prints one line per render: its name and the SHA-256 of the
float32 image bytes (and of the float64 depth bytes where asked).

    python -m validation.tools.hash_renders [--width 72] > hashes.txt
"""
from __future__ import annotations

import hashlib
from dataclasses import replace

import numpy as np

import cloudmeta as cm
from validation.common import ROOT, parse, parser, run_main, with_settings


def sha(a):
    return hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest()


def small(path, width, **render_settings):
    s = cm.load_scene(path)
    h = max(1, round(width * s.image.height / s.image.width))
    s = cm.load_scene(path, width=width, height=h)
    return with_settings(s, **render_settings) if render_settings else s


def cases(width):
    paths = sorted((ROOT / "scenes").glob("*.yaml")) + sorted((ROOT / "docs").glob("*.yaml"))
    for p in paths:
        yield p.relative_to(ROOT).as_posix(), small(p, width), False
    cumulus = ROOT / "scenes" / "cumulus.yaml"
    yield "scenes/cumulus.yaml shadows=map", small(cumulus, width, shadows="map", shadow_map=96), False
    yield "scenes/two_media.yaml shadows=map", small(ROOT / "scenes" / "two_media.yaml", width, shadows="map",
                                                     shadow_map=64), False
    yield "scenes/cumulus.yaml spp=2", replace(small(cumulus, width), image=replace(small(cumulus, width).image,
                                                                                     spp=2)), False
    yield "scenes/cumulus.yaml quality=reference", small(cumulus, 32, quality="reference"), False
    yield "scenes/cumulus.yaml quality=draft", small(cumulus, width, quality="draft"), False
    yield "scenes/cumulus.yaml no ambient", replace(small(cumulus, width), ambient=None), False
    yield "scenes/hand.yaml depth", small(ROOT / "scenes" / "hand.yaml", width), True
    yield "scenes/creature.yaml depth", small(ROOT / "scenes" / "creature.yaml", width), True
    yield "docs/surfaces.yaml depth shadows=map", small(ROOT / "docs" / "surfaces.yaml", width, shadows="map",
                                                        shadow_map=64), True


def main(argv=None):
    ap = parser(__doc__)
    ap.add_argument("--width", type=int, default=72)
    args, _ = parse(ap, argv)
    hashes = {}
    for name, scene, depth in cases(args.width):
        if depth:
            img, dep = cm.render(scene, progress=False, depth=True)
            hashes[name] = f"{sha(img)} depth {sha(dep)}"
        else:
            hashes[name] = sha(cm.render(scene, progress=False))
        print(f"{name:45s} {hashes[name]}", flush=True)
    return dict(hashes=hashes)


if __name__ == "__main__":
    run_main(main)
