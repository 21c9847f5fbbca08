"""The ``cloudmeta`` command: ``render`` a scene to OpenEXR (and PNG), ``inspect`` its field in 3D."""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from .errors import CloudmetaError


def _render(args):
    from .animation import load_animation
    if any(v is not None for v in (args.frames, args.workers, args.scheduler, args.tiles)) or args.overwrite \
            or load_animation(args.scene) is not None:
        from .cluster import frames_command  # a sequence, tiles or a cluster (docs/animation.md)
        return frames_command(args)
    from .io import write_exr, write_png
    from .render import render
    from .scene import load_scene

    scene = load_scene(args.scene, width=args.width, height=args.height, spp=args.spp)
    overrides = {k: v for k, v in (("quality", args.quality), ("shadows", args.shadows),
                                   ("shadow_map", args.shadow_map)) if v is not None}
    if overrides:
        from dataclasses import replace
        scene = replace(scene, render=replace(scene.render, **overrides))
    exr = args.output or scene.output.path or str(Path(args.scene).with_suffix(".exr").name)
    png = args.png or scene.output.png
    w, h, spp = scene.image.width, scene.image.height, scene.image.spp
    print(f"cloudmeta: rendering {args.scene}: {w} x {h}, {spp} spp, quality {scene.render.quality}, "
          f"{scene.render.shadows} shadows, "
          f"{sum(len(m.blob) for m in scene.media)} balls in {len(scene.media)} media, "
          f"{sum(len(s.blob) for s in scene.surfaces)} in {len(scene.surfaces)} surfaces, {len(scene.lights)} lights")
    from .config import is_compiled
    from .kernels.radiance import render_pixels
    if not is_compiled(render_pixels):
        print("cloudmeta: compiling the kernels for this machine (once: about 2 minutes on 2 cores, then cached)",
              flush=True)
    start = time.perf_counter()
    image = render(scene, progress=not args.quiet)
    took = time.perf_counter() - start
    write_exr(image, exr, colourspace=scene.render.colourspace)
    print(f"cloudmeta: rendered in {took:.2f} s; wrote {exr}")
    if png:
        write_png(image, png, exposure=scene.output.exposure if args.exposure is None else args.exposure,
                  colourspace=scene.render.colourspace)
        print(f"cloudmeta: wrote {png}")
    return 0


def _inspect(args):
    from .inspect import inspect_command
    return inspect_command(args)


def _texels(text):
    value = int(text)
    if value < 2:
        raise argparse.ArgumentTypeError(f"expected an integer >= 2, got {text}")
    return value


def _positive(text):
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {text}")
    return value


def build_parser():
    parser = argparse.ArgumentParser(prog="cloudmeta", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)

    r = sub.add_parser("render", help="render a YAML scene to OpenEXR")
    r.add_argument("scene", help="the scene file (YAML, see MODEL.md §9)")
    r.add_argument("-o", "--output", help="EXR path (default: the scene's output.path, else SCENE.exr here)")
    r.add_argument("--png", help="also write an sRGB PNG preview here")
    r.add_argument("--width", type=int)
    r.add_argument("--height", type=int)
    r.add_argument("--spp", type=int, help="samples per pixel")
    r.add_argument("--quality", choices=["draft", "default", "fine", "reference"], help="quadrature preset")
    r.add_argument("--shadows", choices=["exact", "map"],
                   help="shadow rays to every light (exact), or light-space maps for directional lights (map)")
    r.add_argument("--shadow-map", type=_texels, help="texels per side of a shadow map (default 384)")
    r.add_argument("--exposure", type=float, help="PNG exposure in stops (default: the scene's)")
    r.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    a = r.add_argument_group("sequences and clusters (docs/animation.md)")
    a.add_argument("--frames", help="frames A:B[:STEP] (A to B - 1) or N; -o and --png then take {frame} fields, "
                                    "e.g. out/f_{frame:04d}.exr (default: the scene's animation frames)")
    a.add_argument("--overwrite", action="store_true", help="render frames whose files exist again (else skipped)")
    a.add_argument("--tiles", help="cut each frame into K bands of rows or an RxC grid of tiles (tasks)")
    on = a.add_mutually_exclusive_group()
    on.add_argument("--workers", type=_positive, help="render on a local Dask cluster of N worker processes")
    on.add_argument("--scheduler", help="render on the running Dask cluster at this address (tcp://host:8786)")
    r.set_defaults(run=_render)

    i = sub.add_parser("inspect", help="look at a scene's field and density in 3D (pyvista)")
    i.add_argument("scene")
    i.add_argument("--screenshot", help="render off screen to this PNG instead of opening a window")
    i.add_argument("--save", help="write the sampled grid to this .vti file (ParaView)")
    i.add_argument("--resolution", type=int, default=96, help="grid samples along the longest side (default 96)")
    i.add_argument("--slice", help="one plane only, e.g. z=2.0, coloured by sigma_t with the contour F = T")
    i.set_defaults(run=_inspect)
    return parser


def main(argv=None):
    args = build_parser().parse_args(argv)
    try:
        return args.run(args)
    except CloudmetaError as exc:
        print(f"cloudmeta: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"cloudmeta: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
