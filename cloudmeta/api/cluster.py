"""Sequences and tiles: render frames of a scene, each frame whole or in tiles, here or on a Dask cluster.

``render_frames`` writes one EXR (and optionally one PNG) per frame, through ``cloudmeta.api.io``'s atomic
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

from ..errors import CloudmetaError, InputError, OutputError, SceneError
from .display import check_display, check_exposure_setting, check_white_balance, exposure_of
from .io import atomic_outputs, check_distinct, check_output_path, encode_outputs, png_settings, read_exr
from ..renderer import render
from ..renderer.threads import progress_bar
from .runtime import interruptible
from ..scene import load_scene
from ..scene.animation import load_animation
from ..scene.vocabulary import AUTO_EXPOSURE

#: a task that raises (not a dying worker: that is the scheduler's allowed-failures) is tried this many more times
RETRIES = 2
#: frames rendered here keep the scene validated by the output checks, up to this many balls in all (about
#: 0.7 KB each); frames beyond it are loaded again when their turn comes
KEEP_BALLS = 1_000_000


@dataclass(frozen=True)
class Outputs:
    """Where a sequence's frames go: ``exr`` and ``png`` are paths with ``{frame}`` format fields
    (``out/f_{frame:04d}.exr``), relative to the current folder. ``exr`` None: the scene's output.path, else
    SCENE.exr here, and then the scene's output.png too if it has one; an ``exr`` given with no ``png``
    writes no PNG (whatever the scene's output.png). An empty path is refused. ``exr_label`` and
    ``png_label`` are how an error names them (the CLI passes "-o" and "--png")."""
    exr: str | None = None
    png: str | None = None
    exr_label: str = "output"
    png_label: str = "png"


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
    because their files already existed; ``outputs`` maps each frame to its (exr, png or None) paths.
    ``png``: the PNGs' settings, (display, white balance, exposure as asked: stops or "auto") where there
    are PNGs, else None; ``stops``: the exposure every PNG of the sequence got (for auto, measured on
    ``exposure_frame``), None where no PNG was written or measured."""
    rendered: list = field(default_factory=list)
    skipped: list = field(default_factory=list)
    outputs: dict = field(default_factory=dict)
    png: tuple | None = None
    stops: float | None = None
    exposure_frame: int | None = None


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
    # the render overrides validated like the file's own (limits included)
    return load_scene(job.scene, width=job.width, height=job.height, spp=job.spp, render=dict(job.render),
                      frame=job.frame)


def render_tile(job: FrameJob, rows=None, columns=None, scene=None):
    """The pixels of rows x columns of ``job``'s frame (all of it by default): the task of a cluster."""
    import numba
    if job.threads is not None:
        numba.set_num_threads(max(1, min(job.threads, numba.config.NUMBA_NUM_THREADS)))
    try:
        frame_scene = load_frame(job) if scene is None else scene  # ``scene``: job's frame, validated already
        return render(frame_scene, progress=False, rows=rows, columns=columns)
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
    """Every frame's outputs checked before any work (cloudmeta.api.io.check_output_path, check_distinct): the
    folder, the extension, the name, not an input of the scene at that frame (``inputs_of(frame)``), and no
    two outputs of the sequence naming one file (symbolic links resolved)."""
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


def _frames_bar(total, enabled):
    return progress_bar(total, bool(enabled and total and sys.stderr.isatty()), unit="frame", desc="frames",
                        mininterval=0.1)


def render_frames(scene, frames=None, output=None, png=None, *, exposure=None, display=None, white_balance=None,
                  width=None, height=None, spp=None, render=None, tiles=1, overwrite=False, client=None,
                  workers=None, scheduler=None, retries=RETRIES, progress=True) -> FramesReport:
    """Render ``frames`` of the scene file ``scene`` to one EXR each (and one PNG each with ``png``).

    ``frames``: an iterable of frame numbers; by default the scene's ``animation`` frames, or frame 0.
    ``output`` / ``png``: paths with ``{frame}`` format fields (``out/f_{frame:04d}.exr``), relative to the
    current folder; ``output`` defaults to the scene's output.path, else SCENE.exr here (with _{frame:04d}
    before the extension for several frames), and ``png`` then to the scene's output.png; an ``output``
    given with no ``png`` writes no PNG. ``output`` may instead be an Outputs (both paths and how
    errors name them; ``png`` must then be None). ``width``, ``height``, ``spp`` and ``render`` (a dict of render
    settings such as {"quality": "draft"}) override the scene's. The PNGs are pictures as cm.write_png makes
    them (docs/display.md): ``display`` (aces, raw), ``white_balance`` (scene, none, a CIE illuminant, an RGB)
    and ``exposure`` (stops or auto) override the scene's output.display, output.white_balance and
    output.exposure, and None takes the display's default. The whole sequence gets one picture: the white
    balance ``scene`` is the light of its first frame (the first of ``frames``), and ``auto`` is measured on
    that frame's image (rendered now, or read back from its EXR where a re-run skips it) and held for every
    frame, so that the sequence does not flicker; a tiled frame is displayed once assembled. ``tiles``: K
    bands of rows or an (R, C) grid per frame. A frame whose files exist is skipped unless ``overwrite``.
    ``client``: a dask.distributed Client; or ``workers=N`` (a local cluster, started and closed here) or
    ``scheduler`` (the address of a running one). Every frame's outputs are checked before any work (cloudmeta.api.io.check_output_path;
    the frames to render are loaded for that, so a bad frame fails before the first is rendered); each
    frame's EXR and PNG are written together (cloudmeta.api.io.atomic_outputs: both or neither). Locally each
    frame renders on a thread of its own (cloudmeta.api.runtime.interruptible), from the scene validated by the
    output checks (not read again, up to KEEP_BALLS balls in all), so Ctrl-C stops at once and leaves
    the finished frames; on a cluster the futures are cancelled and a cluster started here is closed (a
    best effort: the tasks running on workers end when their frame does). Returns a FramesReport.
    """
    if isinstance(output, Outputs):
        if png is not None:
            raise InputError("png: give it in the Outputs (output=Outputs(exr=..., png=...)), not both")
        spec = output
    else:
        spec = Outputs(exr=output, png=png)
    output, png = spec.exr, spec.png
    for label, value in ((spec.exr_label, output), (spec.png_label, png)):
        if isinstance(value, (str, bytes)) and not value:  # else the current folder, or the default output
            raise OutputError(f"{label}: expected a file name, got an empty path")
    explicit = output is not None  # then no PNG unless asked for: the scene's output.png is for its own output
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
        check_exposure_setting(exposure)
    if display is not None:
        check_display(display)
    if white_balance is not None:
        check_white_balance(white_balance)
    first = load_frame(FrameJob(path, frames[0], width, height, spp, render_overrides))  # fail before any work
    labels = [spec.exr_label, spec.png_label]
    if output is None:
        labels[0] = f"{path}: output.path" if first.output.path else "the default output"
        output = first.output.path or str(Path(path).with_suffix(".exr").name)
        if len(frames) > 1 and first.output.path is None:
            output = _with_frame_field(output)
    if png is None and first.output.png and not explicit:
        labels[1] = f"{path}: output.png"
        png = first.output.png
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
    kept = {frames[0]: first}  # the validated scenes of the frames to render, each loaded once

    def inputs_of(f):
        if f not in kept:
            kept[f] = load_frame(FrameJob(path, f, width, height, spp, render_overrides))
        return kept[f].inputs
    _check_outputs(todo, exrs, pngs, labels, inputs_of)
    balls = 0
    for f in todo:  # keep the scenes of the first frames up to KEEP_BALLS balls; load the others again
        balls += sum(len(t.blob) for t in kept[f].media + kept[f].surfaces)
        if balls > KEEP_BALLS and f != frames[0]:
            del kept[f]
    windows = tile_windows(first.image.height, first.image.width, tiles)
    colourspace = first.render.colourspace
    look = None  # the PNGs' (display, white balance, exposure, illuminant), checked before any work
    if pngs:
        look = png_settings(first.output.display if display is None else display,
                            first.output.white_balance if white_balance is None else white_balance,
                            first.output.exposure if exposure is None else exposure, first)
        report.png = look[:3]
        if look[2] != AUTO_EXPOSURE:
            report.stops = float(look[2])
    anchor = frames[0]  # the frame whose image sets an auto exposure for the whole sequence
    held = {}  # frames back before the anchor, waiting for its exposure (a cluster returns them out of order)

    def write_now(f, image):
        # both files or neither: a frame is finished when all its files exist
        with atomic_outputs([exrs[f]] + ([pngs[f]] if f in pngs else [])) as tmps:
            if look is None:  # the EXR alone
                encode_outputs(image, tmps, colourspace)
            else:
                encode_outputs(image, tmps, colourspace, report.stops, display=look[0], white_balance=look[1],
                               illuminant=look[3])
        report.rendered.append(f)

    def write(f, image):
        if not np.all(np.isfinite(image)):  # as for a single render (cloudmeta.cli)
            raise SceneError(path, None, f"frame {f}: the rendered image has values beyond the float32 range; "
                                         f"lower the lights' irradiance or intensity (README: Limits)")
        if look is not None and report.stops is None:
            if f != anchor:
                held[f] = image
                return
            _measure(image)
        write_now(f, image)
        for g in list(held):
            write_now(g, held.pop(g))

    def _measure(image):
        report.stops = exposure_of(image, colourspace, look[0], look[1], look[3])
        report.exposure_frame = anchor

    if not todo:
        return report
    if report.stops is None and look is not None and anchor not in todo:
        # a re-run that skips the anchor: its EXR holds the image that set the exposure
        try:
            image = read_exr(exrs[anchor])[0][..., :4]
        except (OSError, ValueError, RuntimeError) as exc:
            raise OutputError(f"{labels[0]} {exrs[anchor]}: cannot read frame {anchor}, whose image sets the "
                              f"sequence's auto exposure ({exc}); --overwrite renders it again") from None
        _measure(image)
    bar = _frames_bar(len(todo), progress)
    try:
        if client is None and workers is None and scheduler is None:
            for f in todo:
                job = FrameJob(path, f, width, height, spp, render_overrides)
                frame_scene = kept.pop(f, None)
                pixels = interruptible(lambda: [(w, render_tile(job, *w, scene=frame_scene)) for w in windows])
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
        try:
            c = Client(scheduler)
        except Exception as exc:  # dask's own errors (an address it cannot parse or reach): one of cloudmeta's
            raise InputError(f"scheduler {scheduler}: cannot connect: {type(exc).__name__}: {exc}") from exc
        with c:
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
