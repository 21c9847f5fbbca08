"""SHA-256 of small renders of every scene: a before / after check that a refactor changes no pixel.

Renders each scene of scenes/*.yaml and docs/*.yaml at WIDTH pixels wide (the height keeps the scene's
aspect; spp as the scene says), plus a few variants (shadow maps, 2 spp, the depth output, the reference
preset, a scene with its ambient removed), and prints one line per render: its name and the SHA-256 of the
float32 image bytes (and of the float64 depth bytes where asked).

    python -m validation.hash_renders [--width 72] > hashes.txt
"""
from __future__ import annotations

import argparse
import hashlib
import sys
from dataclasses import replace
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numpy as np

import cloudmeta as cm

ROOT = Path(__file__).resolve().parent.parent


def sha(a):
    return hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest()


def small(path, width, **render_settings):
    s = cm.load_scene(path)
    h = max(1, round(width * s.image.height / s.image.width))
    s = cm.load_scene(path, width=width, height=h)
    if render_settings:
        s = replace(s, render=replace(s.render, **render_settings))
    return s


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
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--width", type=int, default=72)
    args = ap.parse_args(argv)
    for name, scene, depth in cases(args.width):
        if depth:
            img, dep = cm.render(scene, progress=False, depth=True)
            print(f"{name:45s} {sha(img)} depth {sha(dep)}", flush=True)
        else:
            img = cm.render(scene, progress=False)
            print(f"{name:45s} {sha(img)}", flush=True)


if __name__ == "__main__":
    main()
