"""Writes merging_clouds.yaml: two small cumulus puffs that drift together and merge (an animated scene).

Each puff is a flat base of squashed ellipsoids and a heap of spheres (deterministic); every ball's centre is
keyframed from frame 0 to the last frame (smooth: the puffs ease in and out), and the sun sinks a little.
Where the puffs meet, their fields add: metaballs merge their volumes exactly, with no seam.
Run from the repository root: python scenes/make_merging_clouds.py [OUTDIR]
"""
import sys
from pathlib import Path

import numpy as np

FRAMES = 24


def puff(rng, n_base=5, n_top=8):
    """(centre, radii, rotation z) of the balls of one puff around the origin."""
    balls = []
    for _ in range(n_base):
        r = rng.uniform(1.6, 1.9)
        balls.append(((rng.uniform(-1.8, 1.8), rng.uniform(-0.8, 0.8), rng.uniform(0.3, 0.6)),
                      (r, r * rng.uniform(0.8, 1.0), r * 0.55), rng.uniform(0, 180)))
    for _ in range(n_top):
        h = rng.uniform(0.0, 1.0) ** 0.8
        r = 1.75 - 0.8 * h + rng.uniform(-0.1, 0.1)
        balls.append(((rng.normal(0, 0.8 * (1 - 0.5 * h)), rng.normal(0, 0.5), 1.0 + 2.4 * h), (r, r, r), 0.0))
    return balls


def vec(v):
    return "[" + ", ".join(f"{x:.3f}" for x in v) + "]"


def scene_text():
    rng = np.random.default_rng(11)
    last = FRAMES - 1
    lines = []
    for shift in ((-5.2, 1.5), (5.2, 1.3)):  # (start x, end x offset towards the middle)
        start, end = shift[0], np.sign(shift[0]) * shift[1]
        for (x, y, z), radii, az in puff(rng):
            c0, c1 = (x + start, y, z), (x + end, y, z)
            lines.append(f"      - {{center: {{keys: {{0: {vec(c0)}, {last}: {vec(c1)}}}, interpolate: smooth}}, "
                         f"radii: {vec(radii)}, rotation: [0, 0, {az:.1f}]}}")
    balls = "\n".join(lines)
    return f"""# Two cumulus puffs drift together and merge: {2 * 13} keyframed metaballs, {FRAMES} frames.
# Written by scenes/make_merging_clouds.py. Render every frame (docs/animation.md):
#   cloudmeta render scenes/merging_clouds.yaml -o out/merge_{{frame:04d}}.exr --png out/merge_{{frame:04d}}.png
# or on a local Dask cluster of 2 worker processes: add --workers 2
animation: {{frames: {FRAMES}, fps: 12}}
image: {{width: 480, height: 270, spp: 1}}
camera: {{position: [0, -15, 2.2], look_at: [0, 0, 1.9], up: [0, 0, 1], fov: 40}}
background: [0.22, 0.38, 0.72]
ambient: [0.10, 0.14, 0.22]
lights:
  - type: directional
    direction: {{keys: {{0: [0.45, -0.6, 0.65], {last}: [0.85, -0.35, 0.35]}}, interpolate: smooth}}
    irradiance: 20.0
    color: {{temperature: 5400}}
media:
  - name: puffs
    kernel: wyvill6
    threshold: 0.5
    density: {{mode: field, scale: 2.5}}
    albedo: 0.95
    phase: {{type: hg, g: 0.6}}
    balls:
{balls}
render: {{quality: default}}
output: {{path: "merging_clouds_{{frame:04d}}.exr", png: "merging_clouds_{{frame:04d}}.png"}}
"""


if __name__ == "__main__":
    here = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parent
    (here / "merging_clouds.yaml").write_text(scene_text())
    print(f"wrote {here / 'merging_clouds.yaml'}")
