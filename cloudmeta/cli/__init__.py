"""The cloudmeta command: render a scene to OpenEXR (and PNG), inspect its field in 3D, generate a cloud."""
from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
import time
from pathlib import Path

from ..errors import CloudmetaError, InputError, SceneError
from ..fit import cli as fit_cli
from ..api.runtime import INTERRUPTED, RENDERS, compile_notice, interruptible
from ..scene.vocabulary import DISPLAYS, QUALITIES, SHADOW_MAP_RESOLUTION, SHADOW_MODES


def _render(args):
    from ..errors import OutputError
    from ..scene.animation import load_animation
    for label, path in (("-o", args.output), ("--png", args.png)):
        if path is not None and not path:  # -o '' is no file: refused, not taken for "no -o" (SCENE.exr here)
            raise OutputError(f"{label}: expected a file name, got an empty path")
    # the frames path is taken where the user asks for frames, tiles or a cluster, or the scene is animated;
    # --overwrite means the same in both (replace what exists) and chooses neither
    if any(v is not None for v in (args.frames, args.workers, args.scheduler, args.tiles)) \
            or load_animation(args.scene) is not None:
        if args.error:
            raise InputError("--error: only for a single image, not with --frames, --tiles, --workers, "
                             "--scheduler or an animated scene")
        if args.denoise:
            raise InputError("--denoise: only for a single image, not with --frames, --tiles, --workers, "
                             "--scheduler or an animated scene")
        return _frames(args)  # a sequence, tiles or a cluster (docs/animation.md)
    from ..api.display import check_exposure_setting, check_white_balance
    from ..api.io import atomic_outputs, check_distinct, check_output_path, encode_outputs, png_settings
    from ..scene import load_scene

    if args.exposure is not None:
        check_exposure_setting(args.exposure, "--exposure")  # nan, inf, 2000: 2 ** exposure overflows
    if args.white_balance is not None:
        check_white_balance(args.white_balance, "--white-balance")
    overrides = {"quality": args.quality, "shadows": args.shadows, "shadow_map": args.shadow_map}
    scene = load_scene(args.scene, width=args.width, height=args.height, spp=args.spp, render=overrides)
    if args.denoise:
        from ..renderer.denoise import require_denoiser
        require_denoiser(scene)  # before any work: the mode and the optional extra
    outputs = _outputs(args, scene)
    for label, path, ext in outputs:
        check_output_path(path, ext, label, scene.inputs)  # an existing file is replaced, --overwrite or not
    check_distinct([(label, path) for label, path, _ in outputs])
    exposure = scene.output.exposure if args.exposure is None else args.exposure
    display, white_balance, illuminant = "raw", None, None
    if len(outputs) > 1:  # the PNG's settings, checked before the render (aces needs OpenColorIO)
        display, white_balance, exposure, illuminant = png_settings(
            args.display or scene.output.display, args.white_balance or scene.output.white_balance, exposure, scene)
    verbose = _verbose(args)
    w, h, spp = scene.image.width, scene.image.height, scene.image.spp
    verbose(f"rendering {args.scene}: {w} x {h}, {spp} spp, quality {scene.render.quality}, "
            f"{scene.render.shadows} shadows, "
            f"{sum(len(m.blob) for m in scene.media)} balls in {len(scene.media)} media, "
            f"{sum(len(s.blob) for s in scene.surfaces)} in {len(scene.surfaces)} surfaces, {len(scene.lights)} lights"
            + (f" ({scene.merged_balls} identical balls merged)" if scene.merged_balls else ""))
    # every output is created now as a temporary file and renamed into place only when all are written
    with atomic_outputs([path for _, path, _ in outputs]) as tmps:
        estimate = args.error or scene.render.error is not None  # a target computes the estimate anyway
        result, took = _render_image(scene, progress=not args.quiet and sys.stderr.isatty(), error=estimate,
                                     denoise=args.denoise)
        # the approximate mode's per-pixel error would be the quadrature's alone, far below the approximation's
        # own (RenderResult.approximation, an image-level estimate): its EXR has no error channels
        channels = None if scene.render.scattering == "approximate" else result.error
        stops = encode_outputs(result.image, tmps, scene.render.colourspace, exposure, channels, result.raw,
                               display, white_balance, illuminant)
    _details(verbose, result)
    if stops is not None:
        from ..api.display import describe
        verbose(f"PNG: {describe(display, white_balance, exposure, stops)} (docs/display.md)")
    print(summary(args.scene, scene, result, took, [path for _, path, _ in outputs]), flush=True)
    return 0


def _verbose(args):
    """print(``cloudmeta: `` + a line) with -v, else nothing: the details behind the summary."""
    def say(text):
        if args.verbose:
            print(f"cloudmeta: {text}", flush=True)
    return say


def _scattering_words(render):
    if render.scattering == "approximate":
        return f"approximate multiple scattering ({render.method})"
    return f"{render.scattering} scattering"


def _seconds(took):
    return f"{took:.3g} s" if took < 1000 else f"{took:.0f} s"


def summary(shown, scene, result, took, paths):
    """The one line a render prints (``shown``: the scene as the user named it; ``result``: its
    renderer.RenderResult; ``took``: seconds; ``paths``: the files written): what scene, how big, how long, the
    estimated error against its target where known, what was written."""
    settings = result.settings
    w, h, spp = scene.image.width, scene.image.height, scene.image.spp
    what = [f"{w} x {h}" + (f", {spp} spp" if spp > 1 else ""), _scattering_words(scene.render)]
    if getattr(result, "raw", None) is not None:
        what.append("denoised")
    if settings.shadows != "exact":
        what.append(f"{settings.shadows} shadows")
    what.append(f"quality {settings.quality}")
    target = settings.target
    if settings.shared is not None:  # its estimate holds the tails' noise, which the preset's target is not about
        target = None
    # the image's own estimate where one was made (--error, render.error); else the calibration's measure
    error = result.estimated
    if error is None and result.scattered is not None:
        error = result.scattered.predicted
    told = [_seconds(took)]
    if error is not None:
        told.append(f"estimated error {error:.1e}" + ("" if target is None else f" (target {target:.1e})"))
    elif target is not None and scene.render.scattering != "multiple":  # (the paths' noise is not the preset's)
        told.append(f"target error {target:.1e} (not estimated; --error estimates it)")
    if result.approximation is not None:
        a = result.approximation
        aim = ""
        if settings.shared is not None and settings.shared.tails is None:  # planned tails: the preset's promise
            aim = f" (target {settings.shared.target:g})"
        told.append(f"approximation error {a.rel_rmse:.3f} +- {a.stderr:.3f}{_unresolved(a)} against multiple "
                    f"scattering{aim}")
    return f"cloudmeta: {shown} {', '.join(what)}: {', '.join(told)}; wrote {', '.join(paths)}"


def _details(verbose, result):
    """-v: how the render reached its settings and error (the calibration, the estimate, the denoiser)."""
    settings, scattered = result.settings, result.scattered
    if result.error is not None:
        target = (f"render.error {settings.error:g}" if settings.error is not None else
                  f"quality {settings.quality}: {'none' if settings.target is None else f'{settings.target:g}'}")
        where = "per pixel in the EXR's channels error.R/G/B"
        if result.approximation is not None:
            alone = ("the quadrature's and the shared tails' noise" if settings.shared is not None else
                     "the quadrature's alone")
            where = (f"{alone}; the approximation's is the line's 'approximation error', and the EXR has no "
                     "error channels")
        verbose(f"estimated relative RMSE {result.estimated:.2e} (target of {target}; {where})")
    plan = getattr(result, "plan", None)
    if plan is not None and hasattr(plan, "tails"):
        share = plan.deep_share
        if plan.cache_order:
            cache = f"the orders beyond {plan.cache_order} from the cache of the deep orders" + (
                "" if share is None else f" ({share:.0%} of the light)")
        else:
            cache = "no cache of the deep orders" + ("" if share is None else (
                f" (the orders beyond the preset's cache order carry {share:.0%} of the light, under "
                f"{settings.shared.cache_min_share:.0%})"))
        verbose(f"shared light's tails planned to {plan.target:g}: {plan.tails} per coarsest sample ray, predicted "
                f"noise {plan.predicted:.2e} of the scattered light (the sharing's bias beside it; "
                f"docs/approximate.md); {cache}")
    elif plan is not None:
        h, w = result.image.shape[:2]
        verbose(f"multiple-scattering paths planned to {plan.target:g}: {plan.mean_paths(h, w):.0f} per pixel on "
                f"average, {int(plan.paths.max())} in the busiest 16 x 16 block, predicted {plan.predicted:.2e} "
                f"(docs/multiple_scattering.md)")
    if scattered is not None and scattered.level is not None:
        verbose(f"quadrature calibrated for quality {settings.quality}: {_level_words(scattered.level)}"
                + ("" if scattered.predicted is None else
                   f", measured relative RMSE {scattered.predicted:.1e} on its {scattered.rays} rays")
                + " (render.calibrate; docs/error_estimate.md)")
        from ..renderer.calibrate import MIN_TRUSTED
        if scattered.shorter:
            verbose("most of the calibration reference's steps took the Kronrod nodes: the level above is on "
                    "the shorter ladder (steps half as thick, half a step coarser otherwise)")
        if scattered.trusted is not None and scattered.trusted < MIN_TRUSTED:
            verbose(f"shadows hybrid: the calibration trusted {100 * scattered.trusted:.0f} % of the shadow "
                    f"map's lookups (under {100 * MIN_TRUSTED:.0f} %): exact shadow rays instead")
    if result.raw is not None:
        verbose("denoised the Monte Carlo part (Intel Open Image Denoise); the image before it is in "
                "the EXR's channels raw.R/G/B/A")
    a = result.approximation
    if a is not None:
        verbose(f"the approximation's estimated relative RMSE against unbiased multiple scattering: "
                f"{a.rel_rmse:.3f} +- {a.stderr:.3f}{_unresolved(a)} (from {a.pixels} of {a.cloud_pixels} cloud "
                f"pixels, {a.paths} paths each; docs/approximate.md)")


def _unresolved(a):
    """What the line adds to an approximation error that did not rise above its own noise: the estimate is then
    no measure, and only its bound (the estimate plus two standard errors) says something."""
    if a.resolved:
        return ""
    if a.bound == float("inf"):
        return " (not resolved)"
    return f" (not resolved: at most {a.bound:.3f})"


def _outputs(args, scene):
    """[(where the path came from, path, extension)]: the EXR, then the PNG if one is asked for: --png, or
    the scene's output.png where there is no -o (-o alone writes the EXR alone)."""
    if args.output is not None:
        exr = ("-o", args.output)
    elif scene.output.path:
        exr = (f"{scene.path}: output.path", scene.output.path)
    else:
        exr = ("the default output", str(Path(args.scene).with_suffix(".exr").name))
    out = [(*exr, ".exr")]
    if args.png is not None:
        out.append(("--png", args.png, ".png"))
    elif scene.output.png and args.output is None:
        out.append((f"{scene.path}: output.png", scene.output.png, ".png"))
    return out


def _render_image(scene, progress, error=False, denoise=False):
    """(the renderer.RenderResult, seconds): the render, on a thread of its own (``interruptible``)."""
    import numpy as np

    from ..renderer import render_frame
    compile_notice()
    start = time.perf_counter()
    result = interruptible(render_frame, scene, progress=progress, error=error, denoise=denoise)
    took = time.perf_counter() - start
    if not np.all(np.isfinite(result.image)):
        raise SceneError(scene.path, None, "the rendered image has values beyond the float32 range; lower "
                                           "the lights' irradiance or intensity (README: Limits)")
    return result, took


def _level_words(level):
    """The calibration's level in words: how many steps of renderer.estimate's factors from the ladder's
    settings (renderer.pilot.LADDER)."""
    from ..renderer.calibrate import LADDER
    if level == 0.0:
        return f"quality {LADDER}'s settings"
    return f"{abs(level):.2f} steps {'coarser' if level > 0 else 'finer'} than quality {LADDER}'s settings"


def _frames(args):
    """``cloudmeta render`` for a sequence, tiles or a cluster (cloudmeta.api.cluster.render_frames)."""
    from ..api.cluster import Outputs, parse_tiles, render_frames
    from ..api.display import check_exposure_setting, check_white_balance, describe
    from ..scene.animation import parse_frames
    if args.exposure is not None:
        check_exposure_setting(args.exposure, "--exposure")
    if args.white_balance is not None:
        check_white_balance(args.white_balance, "--white-balance")
    frames = parse_frames(args.frames) if args.frames is not None else None
    tiles = parse_tiles(args.tiles) if args.tiles is not None else 1
    render = {k: v for k, v in (("quality", args.quality), ("shadows", args.shadows),
                                ("shadow_map", args.shadow_map)) if v is not None}
    where = (f"on a local cluster of {args.workers} worker processes" if args.workers is not None
             else f"on the cluster at {args.scheduler}" if args.scheduler is not None else "in this process")
    span = "the scene's frames" if frames is None else f"frames {frames[0]}..{frames[-1]}" + (
        f" step {frames.step}" if frames.step != 1 else "")
    n_tiles = tiles if isinstance(tiles, int) else tiles[0] * tiles[1]
    print(f"cloudmeta: rendering {args.scene}: {span} {where}" + (f", {n_tiles} tiles a frame" if n_tiles > 1 else ""),
          flush=True)
    compile_notice("workers on this machine share the cache")
    start = time.perf_counter()
    outputs = Outputs(exr=args.output, png=args.png, exr_label="-o", png_label="--png")
    report = render_frames(args.scene, frames, outputs, exposure=args.exposure, display=args.display,
                           white_balance=args.white_balance, width=args.width, height=args.height, spp=args.spp,
                           render=render, tiles=tiles, overwrite=args.overwrite, workers=args.workers,
                           scheduler=args.scheduler, progress=not args.quiet)
    took = time.perf_counter() - start
    if report.skipped:
        print(f"cloudmeta: skipped {len(report.skipped)} finished frames (their files exist; --overwrite renders "
              f"them again)")
    print(f"cloudmeta: rendered {len(report.rendered)} frames in {took:.2f} s")
    if report.png is not None and report.stops is not None:
        held = (f" (measured on frame {report.exposure_frame}, held for every frame)"
                if report.exposure_frame is not None else "")
        _verbose(args)(f"PNG: {describe(*report.png, report.stops)}{held} (docs/display.md)")
    for f in sorted(report.rendered):
        print(f"cloudmeta: wrote {' and '.join(p for p in report.outputs[f] if p)}")
    return 0


def _inspect(args):
    from ..errors import OutputError
    from ..api.viewer import inspect_command
    from ..api.io import same_file
    from ..scene import load_scene
    inputs = load_scene(args.scene).inputs
    for label, path in (("--screenshot", args.screenshot), ("--save", args.save)):
        if path and any(same_file(os.path.abspath(path), source) for source in inputs):
            raise OutputError(f"{label} {path}: is an input of the scene; refusing to overwrite it")
    return inspect_command(args)


def _exposure(text):
    if text == "auto":
        return text
    return float(text)


def _texels(text):
    value = int(text)
    if value < 2:
        raise argparse.ArgumentTypeError(f"expected an integer >= 2, got {text}")
    return value


class _Parser(argparse.ArgumentParser):
    """argparse with errors on one line (no usage block): ``cloudmeta: error: ...``, exit 2."""

    def error(self, message):
        print(f"cloudmeta: error: {message} (see {self.prog} --help)", file=sys.stderr)
        sys.exit(2)


def _positive(text):
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {text}")
    return value


def build_parser():
    from .. import __version__
    parser = _Parser(prog="cloudmeta", description="The cloudmeta command: render a scene to OpenEXR (and "
                                                   "PNG), inspect its field in 3D.")
    parser.add_argument("--version", action="version", version=f"cloudmeta {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    r = sub.add_parser("render", help="render a YAML scene to OpenEXR")
    r.add_argument("scene", help="the scene file (YAML, see docs/model.md §9)")
    r.add_argument("-o", "--output", help="EXR path (default: the scene's output.path, else SCENE.exr here); "
                                          "with -o, no PNG unless --png")
    r.add_argument("--png", help="also write an sRGB PNG preview here (default: the scene's output.png, "
                                 "unless -o is given)")
    r.add_argument("--width", type=int)
    r.add_argument("--height", type=int)
    r.add_argument("--spp", type=int, help="samples per pixel")
    r.add_argument("--quality", choices=QUALITIES, help="quadrature preset")
    r.add_argument("--shadows", choices=SHADOW_MODES,
                   help="shadow rays to every light (exact), light-space maps for directional lights (map), or "
                        "maps where their error bound allows and exact rays elsewhere (hybrid)")
    r.add_argument("--shadow-map", type=_texels, help=f"texels per side of a shadow map (default {SHADOW_MAP_RESOLUTION})")
    r.add_argument("--exposure", type=_exposure, help="PNG exposure: auto or stops (default: the scene's "
                                                      "output.exposure, else auto; 0 with --display raw)")
    r.add_argument("--display", choices=DISPLAYS, help="the PNG's display transform: aces (OpenColorIO's ACES "
                                                       "output transform for sRGB) or raw (linear x exposure, sRGB "
                                                       "curve); default: the scene's output.display, else aces")
    r.add_argument("--white-balance", help="the PNG's white balance: scene (its lights and sky), none, or a CIE "
                                           "illuminant such as D65 (default: the scene's, else scene; none for raw)")
    r.add_argument("--denoise", action="store_true",
                   help="multiple scattering: denoise the Monte Carlo part with Intel Open Image Denoise (the "
                        "optional extra pyoidn); the EXR keeps the image before it as channels raw.R/G/B/A")
    r.add_argument("--error", action="store_true",
                   help="estimate each pixel's error (a second, coarser render) and write it into the EXR as "
                        "channels error.R/G/B; prints the estimated relative RMSE (docs/error_estimate.md)")
    r.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    r.add_argument("-v", "--verbose", action="store_true",
                   help="also say how the render reached its settings and error: the scene's size, the "
                        "calibration's level and measure, the error estimate's channels")
    a = r.add_argument_group("sequences and clusters (docs/animation.md)")
    a.add_argument("--frames", help="frames A:B[:STEP] (A to B - 1) or N; -o and --png then take {frame} fields, "
                                    "e.g. out/f_{frame:04d}.exr (default: the scene's animation frames)")
    r.add_argument("--overwrite", action="store_true",
                   help="replace existing outputs: frames whose files exist are rendered again (else skipped); a "
                        "single image replaces its files with or without it")
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
    i.add_argument("--balls", choices=("auto", "all", "points", "none"), default="auto",
                   help="ball centres: all (a dot each), points (small, at most 1,000), none (default auto: all up to "
                        "500 balls, else points)")
    i.add_argument("--grid", help="a voxel grid (.vdb, .nc, .npz, .npy): show a slice of it, the same slice of the "
                                  "scene's sigma_t and their difference side by side (docs/inspect.md)")
    i.add_argument("--var", help="the grid's variable (NetCDF variable, VDB grid, npz array)")
    i.set_defaults(run=_inspect)
    g = sub.add_parser("generate", help="write a procedural cloud, deterministic by seed: a scene (YAML) and its "
                                        "balls file (CSV) beside it (docs/generate.md)")
    g.add_argument("kind", help="cumulus, stratocumulus, tower or cumulonimbus")
    g.add_argument("-o", "--output", required=True, help="the scene file to write (.yaml); the balls go to the same "
                                                        "name with .csv")
    g.add_argument("--balls", type=_positive, default=3000, help="number of metaballs, exactly (default 3000)")
    g.add_argument("--seed", type=_seed, default=1, help="random seed, an integer >= 0 (default 1)")
    g.add_argument("--size", type=float, default=10.0,
                   help="the cloud's horizontal extent along x, in scene units (default 10); its base is at z = 0")
    g.add_argument("-p", "--param", action="append", default=[], metavar="NAME=VALUE",
                   help="a parameter of the kind (repeatable), e.g. -p height_ratio=1.0; see docs/generate.md")
    g.add_argument("--width", type=_positive, help="image width of the written scene (default 512, 640 for a deck)")
    g.add_argument("--height", type=_positive, help="image height of the written scene (default 512, 360 for a deck)")
    g.add_argument("--overwrite", action="store_true",
                   help="replace the scene and balls file if they exist (only files that cloudmeta generate wrote)")
    g.set_defaults(run=_generate)
    fit_cli.add_parser(sub)
    c = sub.add_parser("compile", help="compile the kernels for every kind of scene now (once per machine; "
                                       "for worker images, clusters and test runs)")
    c.add_argument("--jobs", type=_positive, default=2, help="processes side by side (default 2)")
    c.set_defaults(run=_compile)
    return parser


def _seed(text):
    value = int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {text}")
    return value


def _generate(args):
    """``cloudmeta generate``: the paths are checked first, then the cloud is built and both files written."""
    from ..generate import check_scene_paths, generate, parse_param, write_scene
    params = dict(parse_param(text, "-p") for text in args.param)
    check_scene_paths(args.output, None, args.overwrite)
    parts = [f"cloudmeta generate {args.kind} --balls {args.balls} --seed {args.seed}"]
    if args.size != 10.0:
        parts.append(f"--size {args.size:g}")
    parts += [f"-p {text}" for text in args.param]
    if args.width is not None:
        parts.append(f"--width {args.width}")
    if args.height is not None:
        parts.append(f"--height {args.height}")
    parts.append(f"-o {args.output}")
    start = time.perf_counter()
    cloud = generate(args.kind, balls=args.balls, seed=args.seed, size=args.size, **params)
    yaml_path, csv_path = write_scene(cloud, args.output, width=args.width, height=args.height,
                                      overwrite=args.overwrite, command=" ".join(parts))
    took = time.perf_counter() - start
    print(f"cloudmeta: wrote {yaml_path} and {os.path.basename(csv_path)}: a {len(cloud):,}-ball {cloud.kind} "
          f"(seed {cloud.seed}, size {cloud.size:g}, {cloud.params['levels']} levels) in {took:.2f} s")
    return 0


def _compile(args):
    from ..kernels.config import CACHE_FOLDER, cache_problem
    from .compile import precompile
    problem = cache_problem()
    if problem is not None:  # the jobs' kernels would be thrown away with their processes
        print(f"cloudmeta: nothing compiled: {problem}; kernels compile in every process that needs them",
              file=sys.stderr)
        return 1
    start = time.perf_counter()
    results = precompile(args.jobs)
    took = time.perf_counter() - start
    failed = [name for name, _, ok in results if not ok]
    if failed:
        print(f"cloudmeta: {len(failed)} of {len(results)} jobs failed or were not cached ({took:.0f} s): "
              f"{', '.join(failed)}; their kernels compile on first use", file=sys.stderr)
        return 1
    print(f"cloudmeta: compiled in {took:.0f} s; kernels cached in {CACHE_FOLDER}")
    return 0


def _terminate(signum, frame):
    raise KeyboardInterrupt  # SIGTERM ends a run like Ctrl-C: temporary files removed, one line, 130


def _one_line(exc):
    text = " ".join(str(exc).split())
    return text if len(text) <= 600 else text[:597] + "..."


def main(argv=None):
    args = build_parser().parse_args(argv)
    handler = None
    if threading.current_thread() is threading.main_thread():
        handler = signal.signal(signal.SIGTERM, _terminate)
    try:
        return args.run(args)
    except KeyboardInterrupt:
        print("cloudmeta: interrupted", file=sys.stderr, flush=True)
        if RENDERS:  # the kernels cannot be stopped midway: end the process, its temporary files are gone
            sys.stdout.flush()
            os._exit(INTERRUPTED)
        return INTERRUPTED
    except CloudmetaError as exc:
        print(f"cloudmeta: error: {_one_line(exc)}", file=sys.stderr)
        return 2
    except OSError as exc:
        what = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
        print(f"cloudmeta: error: {what}{_one_line(exc.strerror or exc)}", file=sys.stderr)
        return 2
    except MemoryError:
        print("cloudmeta: error: out of memory (README: Limits)", file=sys.stderr)
        return 1
    finally:
        if handler is not None:
            signal.signal(signal.SIGTERM, handler)

