"""Sequences and tiles: render frames of a scene, each frame whole or in tiles, here or on a Dask cluster.

``render_frames`` writes one EXR (and optionally one PNG) per frame, through ``cloudmeta.io``'s atomic
outputs: a file that exists is complete, so a frame whose files all exist is finished and skipped on a
re-run (unless ``overwrite``), and a killed run resumes where it stopped.

Without a cluster the frames render one after another in this process (each on all its threads). With one
(``client``, ``workers=N`` for a local cluster of N processes, or ``scheduler=ADDRESS``) every tile of every
frame is a task. A task is small: the scene's path, the frame and the settings; the worker loads that frame
itself (the path must be readable there, at the same place) and sends back its pixels; this process
assembles each frame and writes its files, so the workers need no write access and a frame is written once.
A worker that dies takes no frame with it: the scheduler gives its tasks to the other workers (a task may
meet up to ``distributed.scheduler.allowed-failures`` dying workers, 3 by default), a task that raises is
retried ``retries`` times, and nothing is written before every tile of a frame is back. A bad scene is not
retried: its error comes back as it is, naming the file, the frame and the key path.

Every pixel's rays and samples depend on its place in the frame alone, and a render does not depend on the
number of threads, so a frame is bit-identical however it is cut into tiles and wherever they ran.
"""
from __future__ import annotations

import contextlib
import os
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import CloudmetaError, InputError, OutputError, SceneError

#: a task that raises (not a dying worker: that is the scheduler's allowed-failures) is tried this many more times
RETRIES = 2


@dataclass(frozen=True)
class FrameJob:
    """What a task needs to render its part of a frame: small and picklable."""
    scene: str                   #: absolute path of the scene file
    frame: int
    width: int | None = None     #: overrides of the scene's image settings
    height: int | None = None
    spp: int | None = None
    render: tuple = ()           #: (key, value) overrides of the scene's render settings
    threads: int | None = None   #: numba threads of the task (None: the worker's default)


@dataclass
class FramesReport:
    """What ``render_frames`` did: frames rendered (in the order they were written) and frames skipped
    because their files already existed; ``outputs`` maps each frame to its (exr, png or None) paths."""
    rendered: list = field(default_factory=list)
    skipped: list = field(default_factory=list)
    outputs: dict = field(default_factory=dict)


@dataclass(frozen=True)
class _Failure:
    """An error of cloudmeta's met by a task, sent back as a value (so that it is not retried) and raised here."""
    message: str
    file: str | None = None      #: a SceneError's fields, kept
    key_path: str | None = None
    detail: str | None = None
    frame: int | None = None

    @classmethod
    def of(cls, exc):
        if isinstance(exc, SceneError):
            return cls(str(exc), exc.file, exc.key_path, exc.detail, getattr(exc, "frame", None))
        return cls(str(exc))

    def error(self):
        if self.detail is None:
            return CloudmetaError(self.message)
        err = SceneError(self.file, self.key_path, self.detail)
        err.args, err.frame = (self.message,), self.frame
        return err


def load_frame(job: FrameJob):
    """The validated Scene of ``job``'s frame, with its overrides."""
    from .scene import load_scene
    # the render overrides validated like the file's own (limits included)
    return load_scene(job.scene, width=job.width, height=job.height, spp=job.spp, render=dict(job.render),
                      frame=job.frame)


def render_tile(job: FrameJob, rows=None, columns=None):
    """The pixels of rows x columns of ``job``'s frame (all of it by default): the task of a cluster."""
    import numba

    from .render import render
    if job.threads is not None:
        numba.set_num_threads(max(1, min(job.threads, numba.config.NUMBA_NUM_THREADS)))
    try:
        return render(load_frame(job), progress=False, rows=rows, columns=columns)
    except CloudmetaError as exc:
        return _Failure.of(exc)


def tile_windows(height, width, tiles=1):
    """[(rows, columns)] of the tiles of a height x width frame: ``tiles`` K gives K bands of rows, (R, C)
    an R x C grid; tiles differ in size by one row or column at most."""
    grid = (tiles, 1) if isinstance(tiles, int) and not isinstance(tiles, bool) else tuple(tiles)
    if (len(grid) != 2 or not all(isinstance(n, int) and not isinstance(n, bool) for n in grid)
            or not (1 <= grid[0] <= height and 1 <= grid[1] <= width)):
        raise InputError(f"tiles: expected a number of bands K or a grid (R, C) with 1 <= K, R <= {height} "
                         f"(the height) and 1 <= C <= {width} (the width), got {tiles!r}")
    cuts = lambda n, size: [(k * size // n, (k + 1) * size // n) for k in range(n)]  # noqa: E731
    return [(r, c) for r in cuts(grid[0], height) for c in cuts(grid[1], width)]


def parse_tiles(text):
    """``K`` or ``RxC`` (the CLI's --tiles) as K or (R, C)."""
    try:
        parts = [int(p) for p in text.lower().split("x")]
    except ValueError:
        parts = []
    if len(parts) == 1:
        return parts[0]
    if len(parts) == 2:
        return tuple(parts)
    raise InputError(f"--tiles: expected K (bands of rows) or RxC (a grid, e.g. 2x2), got {text!r}")


def frame_paths(pattern, frames, what):
    """{frame: path} of an output path with ``{frame}`` format fields (``out/f_{frame:04d}.exr``);
    several frames must give several files."""
    paths = {}
    for f in frames:
        try:
            paths[f] = os.path.abspath(str(pattern).format(frame=f))
        except (KeyError, IndexError, ValueError) as exc:
            raise InputError(f"{what} {pattern}: expected a path whose only format field is the frame number, "
                             f"such as out/f_{{frame:04d}}.exr ({exc})") from None
    if len(set(paths.values())) < len(paths):
        raise InputError(f"{what} {pattern}: {len(paths)} frames would write the same file; put the frame "
                         f"number in the path, such as {_with_frame_field(pattern)}")
    return paths


def _check_outputs(frames, exrs, pngs, labels, inputs_of):
    """Every frame's outputs checked before any work (cloudmeta.io.check_output_path, check_distinct): the
    folder, the extension, the name, not an input of the scene at that frame (``inputs_of(frame)``), and no
    two outputs of the sequence naming one file (symbolic links resolved)."""
    from .io import check_distinct, check_output_path
    seen = {}
    for f in frames:
        outputs = [(labels[0], exrs[f], ".exr")] + ([(labels[1], pngs[f], ".png")] if f in pngs else [])
        inputs = inputs_of(f)
        for label, path, ext in outputs:
            check_output_path(path, ext, label, inputs)
        check_distinct([(label, path) for label, path, _ in outputs])
        for label, path, _ in outputs:
            other = seen.setdefault(os.path.realpath(path), (f, path))
            if other[0] != f:
                raise OutputError(f"{label} {path}: frames {other[0]} and {f} would write the same file "
                                  f"({other[1]})")


def _with_frame_field(path):
    p = Path(str(path))
    return str(p.with_name(f"{p.stem}_{{frame:04d}}{p.suffix}"))


class _NoBar:
    def update(self, n):
        pass

    def close(self):
        pass


def _frames_bar(total, enabled):
    if not (enabled and total and sys.stderr.isatty()):
        return _NoBar()
    from tqdm import tqdm
    return tqdm(total=total, unit="frame", desc="frames", leave=False)


def render_frames(scene, frames=None, output=None, png=None, *, exposure=None, width=None, height=None, spp=None,
                  render=None, tiles=1, overwrite=False, client=None, workers=None, scheduler=None,
                  retries=RETRIES, progress=True, labels=("output", "png")) -> FramesReport:
    """Render ``frames`` of the scene file ``scene`` to one EXR each (and one PNG each with ``png``).

    ``frames``: an iterable of frame numbers; by default the scene's ``animation`` frames, or frame 0.
    ``output`` / ``png``: paths with ``{frame}`` format fields (``out/f_{frame:04d}.exr``), relative to the
    current folder; ``output`` defaults to the scene's output.path, else SCENE.exr here (with _{frame:04d}
    before the extension for several frames). ``width``, ``height``, ``spp`` and ``render`` (a dict of render
    settings such as {"quality": "draft"}) override the scene's; ``exposure`` the PNG's. ``tiles``: K bands
    of rows or an (R, C) grid per frame. A frame whose files exist is skipped unless ``overwrite``.
    ``client``: a dask.distributed Client; or ``workers=N`` (a local cluster, started and closed here) or
    ``scheduler`` (the address of a running one). ``labels``: how errors name ``output`` and ``png`` (the
    CLI's -o and --png). Every frame's outputs are checked before any work (cloudmeta.io.check_output_path;
    the frames to render are loaded for that, so a bad frame fails before the first is rendered); each
    frame's EXR and PNG are written together (cloudmeta.io.atomic_outputs: both or neither). Locally each
    frame renders on a thread of its own (cloudmeta.cli.interruptible), so Ctrl-C stops at once and leaves
    the finished frames; on a cluster the futures are cancelled and a cluster started here is closed (a
    best effort: the tasks running on workers end when their frame does). Returns a FramesReport.
    """
    from .animation import load_animation
    from .cli import interruptible
    from .io import atomic_outputs, check_exposure, encode_exr, encode_png

    path = os.path.abspath(os.fspath(scene))
    if frames is None:
        animation = load_animation(path)
        frames = range(animation.frames) if animation is not None else [0]
    frames = list(frames)
    if not frames or not all(isinstance(f, (int, np.integer)) and not isinstance(f, bool) and f >= 0
                             for f in frames):
        raise InputError(f"frames: expected frame numbers (integers >= 0), got {frames!r}")
    frames = [int(f) for f in frames]
    render_overrides = tuple(sorted((render or {}).items()))
    if exposure is not None:
        check_exposure(exposure)
    first = load_frame(FrameJob(path, frames[0], width, height, spp, render_overrides))  # fail before any work
    labels = list(labels)
    if output is None:
        labels[0] = f"{path}: output.path" if first.output.path else "the default output"
        output = first.output.path or str(Path(path).with_suffix(".exr").name)
        if len(frames) > 1 and first.output.path is None:
            output = _with_frame_field(output)
    if png is None and first.output.png:
        labels[1] = f"{path}: output.png"
    png = png if png is not None else first.output.png
    exrs = frame_paths(output, frames, labels[0])
    pngs = frame_paths(png, frames, labels[1]) if png else {}
    # first against the inputs every frame shares (an output that is the scene file must not count as a
    # finished frame), then each frame to render against its own (a balls_file per frame)
    _check_outputs(dict.fromkeys(frames), exrs, pngs, labels, lambda f: first.inputs)
    report = FramesReport(outputs={f: (exrs[f], pngs.get(f)) for f in frames})
    todo = []
    for f in dict.fromkeys(frames):
        finished = all(os.path.exists(p) for p in report.outputs[f] if p is not None)
        (report.skipped if finished and not overwrite else todo).append(f)
    _check_outputs(todo, exrs, pngs, labels, lambda f: first.inputs if f == frames[0] else load_frame(
        FrameJob(path, f, width, height, spp, render_overrides)).inputs)
    windows = tile_windows(first.image.height, first.image.width, tiles)
    colourspace = first.render.colourspace
    exposure = first.output.exposure if exposure is None else exposure

    def write(f, image):
        if not np.all(np.isfinite(image)):  # as for a single render (cloudmeta.cli)
            raise SceneError(path, None, f"frame {f}: the rendered image has values beyond the float32 range; "
                                         f"lower the lights' irradiance or intensity (README: Limits)")
        # both files or neither: a frame is finished when all its files exist
        with atomic_outputs([exrs[f]] + ([pngs[f]] if f in pngs else [])) as tmps:
            encode_exr(image, tmps[0], colourspace=colourspace)
            if f in pngs:
                encode_png(image, tmps[1], exposure=exposure, colourspace=colourspace)
        report.rendered.append(f)

    if not todo:
        return report
    bar = _frames_bar(len(todo), progress)
    try:
        if client is None and workers is None and scheduler is None:
            for f in todo:
                job = FrameJob(path, f, width, height, spp, render_overrides)
                pixels = interruptible(lambda: [(w, render_tile(job, *w)) for w in windows])
                write(f, _assemble(first, pixels))
                bar.update(1)
        else:
            with _dask_client(client, workers, scheduler) as (dask_client, threads):
                jobs = [FrameJob(path, f, width, height, spp, render_overrides, threads) for f in todo]
                _run_on_cluster(dask_client, jobs, windows, first, retries, write, bar)
    finally:
        bar.close()
    return report


def _assemble(first, tiles):
    """One frame from its [(window, pixels)] (raises a task's scene error)."""
    image = np.empty((first.image.height, first.image.width, 4), np.float32)
    for ((r0, r1), (c0, c1)), pixels in tiles:
        if isinstance(pixels, _Failure):
            raise pixels.error()
        image[r0:r1, c0:c1] = pixels
    return image


def _run_on_cluster(client, jobs, windows, first, retries, write, bar):
    """Every tile of every job as a task; each frame written as soon as all its tiles are back."""
    import uuid

    from distributed import as_completed

    token = uuid.uuid4().hex[:8]
    futures, where = [], {}
    for job in jobs:
        for k, window in enumerate(windows):
            fut = client.submit(render_tile, job, *window, key=f"cloudmeta-{token}-frame-{job.frame}-tile-{k}",
                                retries=retries, pure=False)
            futures.append(fut)
            where[fut.key] = (job.frame, window)
    pending = {job.frame: [] for job in jobs}
    try:
        for fut in as_completed(futures):
            frame, window = where[fut.key]
            try:
                pixels = fut.result()
            except Exception as exc:  # a task that failed every try, or a worker that died too often
                raise CloudmetaError(f"frame {frame}: the cluster could not render it: "
                                     f"{type(exc).__name__}: {exc}") from exc
            fut.release()
            pending[frame].append((window, pixels))
            if len(pending[frame]) == len(windows):
                write(frame, _assemble(first, pending.pop(frame)))
                bar.update(1)
    except BaseException:
        client.cancel(futures)
        raise


@contextlib.contextmanager
def _dask_client(client, workers, scheduler):
    """(client, numba threads per task): the given client, a running scheduler's, or a local cluster's."""
    import logging
    import warnings
    if client is not None:
        yield client, None
        return
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise InputError("a cluster needs dask.distributed: pip install 'dask[distributed]' "
                         "(or cloudmeta's extra: pip install 'cloudmeta[cluster]')") from None
    if scheduler is not None:
        with Client(scheduler) as c:
            yield c, None
        return
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise InputError(f"workers: expected an integer >= 1, got {workers!r}")
    # one task per worker process, each on its share of this machine's cores (a render uses threads)
    threads = max(1, (os.cpu_count() or 1) // workers)
    with warnings.catch_warnings():
        # the scheduler's HTTP server (loopback) moves to a free port when 8787 is taken: no news to the user
        warnings.filterwarnings("ignore", message="Port .* is already in use", category=UserWarning)
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                               dashboard_address=None, silence_logs=logging.ERROR)
    with cluster, Client(cluster) as c:
        yield c, threads


def frames_command(args):
    """``cloudmeta render`` for a sequence, tiles or a cluster (cloudmeta.cli's arguments)."""
    import time

    from .animation import parse_frames
    from .cli import compile_notice
    from .io import check_exposure
    if args.exposure is not None:
        check_exposure(args.exposure, "--exposure")
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
    report = render_frames(args.scene, frames, args.output, args.png, exposure=args.exposure, width=args.width,
                           height=args.height, spp=args.spp, render=render, tiles=tiles, overwrite=args.overwrite,
                           workers=args.workers, scheduler=args.scheduler, progress=not args.quiet,
                           labels=("-o", "--png"))
    took = time.perf_counter() - start
    if report.skipped:
        print(f"cloudmeta: skipped {len(report.skipped)} finished frames (their files exist; --overwrite renders "
              f"them again)")
    print(f"cloudmeta: rendered {len(report.rendered)} frames in {took:.2f} s")
    for f in sorted(report.rendered):
        print(f"cloudmeta: wrote {' and '.join(p for p in report.outputs[f] if p)}")
    return 0
