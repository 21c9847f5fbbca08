"""A GIF preview of an animated scene: its frames rendered (cloudmeta.render_frames) to PNGs, then joined by
Pillow at the scene's fps.

    python scenes/preview_gif.py scenes/merging_clouds.yaml docs/merging_clouds.gif [--width 160 --height 90]
        [--quality draft] [--workers N] [--frames A:B[:STEP]]

The PNGs go to a temporary folder (kept with --keep DIR); the GIF has an adaptive palette per frame.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # the repository's cloudmeta

from cloudmeta import render_frames  # noqa: E402
from cloudmeta.scene.animation import DEFAULT_FPS, load_animation, parse_frames  # noqa: E402


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("scene")
    p.add_argument("gif")
    p.add_argument("--width", type=int, default=160)
    p.add_argument("--height", type=int, default=90)
    p.add_argument("--quality", default="draft")
    p.add_argument("--frames", help="A:B[:STEP] (default: the scene's animation)")
    p.add_argument("--workers", type=int, help="render on a local Dask cluster of N processes")
    p.add_argument("--keep", help="write the PNGs (and EXRs) here instead of a temporary folder")
    args = p.parse_args(argv)
    from PIL import Image

    animation = load_animation(args.scene)
    fps = animation.fps if animation else DEFAULT_FPS
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(args.keep or tmp)
        folder.mkdir(parents=True, exist_ok=True)
        report = render_frames(args.scene, parse_frames(args.frames) if args.frames else None,
                               folder / "f_{frame:04d}.exr", folder / "f_{frame:04d}.png", width=args.width,
                               height=args.height, render={"quality": args.quality}, workers=args.workers)
        frames = [Image.open(report.outputs[f][1]).convert("RGB") for f in sorted(report.outputs)]
        frames = [im.quantize(colors=255, method=Image.Quantize.MEDIANCUT) for im in frames]
        frames[0].save(args.gif, save_all=True, append_images=frames[1:], duration=round(1000 / fps), loop=0,
                       optimize=True)
    print(f"wrote {args.gif}: {len(frames)} frames at {fps:g} fps, {Path(args.gif).stat().st_size / 1024:.0f} KiB")


if __name__ == "__main__":
    main()
