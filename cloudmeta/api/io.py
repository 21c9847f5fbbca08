"""Images out (and back in): linear OpenEXR with the working colourspace's chromaticities, sRGB PNG previews.

The renderer's image is linear RGB(A) in the working colourspace, its RGB already composited over the
background (docs/model.md §7, §8). Nothing here changes the numbers of an EXR; exposure and encoding belong
to the PNG preview alone.
"""
from __future__ import annotations

import contextlib
import hashlib
import os
import re
import socket
import stat
import tempfile
import time

try:
    import fcntl
except ImportError:  # not POSIX: temporary files go unlocked (the writer's PID alone marks them as in use)
    fcntl = None

import numpy as np

from ..errors import InputError, OutputError
from ..scene.colour import DEFAULT_COLOURSPACE, chromaticities
from ..scene.limits import MAX_EXPOSURE

_CHANNELS = "RGBA"
#: the EXR channels of the per-pixel error estimate (render(..., error=True))
ERROR_CHANNELS = ("error.R", "error.G", "error.B")
#: the image before denoising (render(..., denoise=True); renderer.denoise), beside the denoised one
RAW_CHANNELS = ("raw.R", "raw.G", "raw.B", "raw.A")
#: the process's umask, read once at import (reading it means setting it): outputs get the permissions an
#: ordinary open() would give them, not mkstemp's 0600
_UMASK = os.umask(0o022)
os.umask(_UMASK)


#: this machine, as the temporary names carry it: a folder may be shared between machines, and only the
#: temporary files written here can be told to be stale (their writer's PID means nothing elsewhere)
_HOST = hashlib.blake2s(socket.gethostname().encode(errors="replace"), digest_size=3).hexdigest()
#: cloudmeta's temporary names: .NAME.tmp-PID-HOST-RANDOM.EXT (the extension of NAME), and .old beside a
#: commit's backup (``_commit``)
_TEMP_NAME = re.compile(r"\.(?P<name>.+)\.tmp-(?P<pid>[1-9][0-9]{0,9})-(?P<host>[0-9a-f]{6})-[a-z0-9_]{6,16}"
                        r"(?P<ext>\.[^.]*)?(?:\.old)?\Z", re.DOTALL)
#: the longest PID in a temporary name (Linux's pid_max is at most 2 ** 22): for the length checks
_PID_WIDTH = 7
#: folder -> when it was last swept of stale temporary files (``sweep_stale``), by this process
_SWEPT = {}
#: seconds before a folder is swept again by the same process
_SWEEP_AGAIN = 600.0


def _temporary(folder, name):
    """(path, fd) of a new empty file beside ``name`` in ``folder`` (same extension), with ordinary
    permissions, locked (flock) through ``fd`` for as long as the writer keeps it open. Its name carries
    this process's PID and this machine's tag, so that a later writer can tell, should this process die
    before it removes the file (kill -9), that the file is stale (``sweep_stale``)."""
    fd, tmp = tempfile.mkstemp(prefix=f".{name}.tmp-{os.getpid()}-{_HOST}-", suffix=os.path.splitext(name)[1],
                               dir=folder)
    try:
        os.fchmod(fd, 0o666 & ~_UMASK)
        if fcntl is not None:
            with contextlib.suppress(OSError):  # a file system without locks: the PID still marks it in use
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BaseException:
        os.close(fd)
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    return tmp, fd


def _longest_temporary(name, ext):
    """The longest name that atomic_outputs may create beside ``name``: for the length checks."""
    return f".{name}.tmp-{'9' * _PID_WIDTH}-{_HOST}-xxxxxxxx{ext}.old"


def sweep_stale(folder):
    """Remove from ``folder`` the temporary files of cloudmeta writers that died before they could remove
    them (kill -9, a crash, a power cut), and return their names. Only cloudmeta's own kind
    (``.NAME.tmp-PID-HOST-RANDOM.EXT``, and the ``.old`` backup of a commit), only those written on this
    machine, and only where the writer is gone: no live process has that PID (a zombie counts as gone) and
    the file's lock (flock, held by a writer for the file's life) can be taken. Anything else is left
    alone; a file that cannot be read or removed is skipped (a best effort: never an error)."""
    removed = []
    try:
        with os.scandir(folder) as it:
            entries = [e for e in it if e.name.startswith(".") and ".tmp-" in e.name]
    except OSError:
        return removed
    for entry in entries:
        m = _TEMP_NAME.match(entry.name)
        if m is None or m["host"] != _HOST or (m["ext"] or "") != os.path.splitext(m["name"])[1]:
            continue
        try:
            if not entry.is_file(follow_symlinks=False) or _alive(int(m["pid"])) or not _lock_free(entry.path):
                continue
            os.unlink(entry.path)
        except OSError:
            continue
        removed.append(entry.name)
    return removed


def _sweep_once(folder):
    """``sweep_stale(folder)`` unless this process did so lately (a sequence writes many frames to a folder)."""
    now = time.monotonic()
    if now - _SWEPT.get(folder, -_SWEEP_AGAIN) >= _SWEEP_AGAIN:
        _SWEPT[folder] = now
        sweep_stale(folder)


def _alive(pid):
    """Whether a process ``pid`` runs on this machine (True where that cannot be told: keep the file)."""
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (OSError, OverflowError):  # PermissionError: it runs, as another user
        return True
    try:  # a zombie (killed, not yet reaped by its parent) is no writer
        with open(f"/proc/{pid}/stat", "rb") as f:
            return f.read().rpartition(b")")[2].split()[0] != b"Z"
    except (OSError, IndexError):
        return True


def _lock_free(path):
    """Whether the flock of the file at ``path`` can be taken (then no writer holds it)."""
    if fcntl is None:
        return True
    fd = None
    for flags in (os.O_RDWR, os.O_RDONLY):  # a lock over NFS needs a file open for writing
        try:
            fd = os.open(path, flags | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC)
            break
        except PermissionError:
            continue
        except OSError:
            return False
    if fd is None:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        return True
    except OSError:  # held by a writer (EWOULDBLOCK), or no locks here: cannot tell, keep the file
        return False
    finally:
        os.close(fd)


@contextlib.contextmanager
def atomic_output(path):
    """Yield a temporary path in ``path``'s folder; rename it onto ``path`` only when the block succeeds.

    A reader never sees a half-written file, and on any failure (an exception, Ctrl-C) the temporary file
    is removed and ``path`` is left as it was. The temporary name keeps the extension
    (``.x.exr.tmp-PID-HOST-abc.exr``) so that tools which look at it still know the format; one left by a
    killed process is removed by the next write into the folder (``sweep_stale``).
    """
    with atomic_outputs([path]) as tmps:
        yield tmps[0]


@contextlib.contextmanager
def atomic_outputs(paths):
    """Like ``atomic_output`` for several files at once: yields one temporary path per path (all created
    now, so that a folder that cannot take them fails before any work), and renames them into place only
    when the whole block succeeded. Should a rename fail, the files already renamed are put back as they
    were (the previous file restored from a hard link, or removed where there was none): nothing new is left.
    Before it creates them, the temporary files that killed writers left in those folders are removed
    (``sweep_stale``, at most every few minutes per folder and process).
    """
    for p in paths:
        if not os.fspath(p):
            raise OutputError("path: expected a file name, got an empty path")
    paths = [os.path.abspath(os.fspath(p)) for p in paths]
    for folder in dict.fromkeys(os.path.dirname(p) for p in paths):
        _sweep_once(folder)
    tmps, fds = [], []
    try:
        for path in paths:
            folder, name = os.path.split(path)
            try:
                tmp, fd = _temporary(folder, name)
            except OSError as exc:
                raise OutputError(f"{path}: cannot create a file in {folder}: {exc.strerror or exc}") from None
            tmps.append(tmp)
            fds.append(fd)
        yield list(tmps)
        _commit(paths, tmps)
    except BaseException:
        for tmp in tmps:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
        raise
    finally:
        for fd in fds:  # the locks go with them, once the files are in place or gone
            os.close(fd)


def _commit(paths, tmps):
    """Rename every temporary file onto its path, or none of them."""
    done, backups = [], {}
    try:
        for path, tmp in zip(paths, tmps):
            if len(paths) > 1 and os.path.exists(path):
                backup = f"{tmp}.old"
                os.link(path, backup)
                backups[path] = backup
            os.replace(tmp, path)
            done.append(path)
    except BaseException:
        for path in done:
            with contextlib.suppress(OSError):
                if path in backups:
                    os.replace(backups.pop(path), path)
                else:
                    os.unlink(path)
        raise
    finally:
        for backup in backups.values():
            with contextlib.suppress(OSError):
                os.unlink(backup)


def check_image(image):
    """``image`` as an H x W x 3|4 float64 array of finite values, or InputError."""
    try:
        arr = np.asarray(image)
    except (TypeError, ValueError):
        raise InputError("image: expected an array of numbers, got a ragged or mixed sequence") from None
    if arr.dtype.kind not in "fiu":
        raise InputError(f"image: expected an array of real numbers, got dtype {arr.dtype}")
    if arr.ndim != 3 or arr.shape[2] not in (3, 4) or arr.shape[0] < 1 or arr.shape[1] < 1:
        raise InputError(f"image: expected shape (H, W, 3) or (H, W, 4), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InputError("image: expected finite values, found NaN or infinity")
    return arr.astype(np.float64, copy=False)


def write_exr(image, path, colourspace=DEFAULT_COLOURSPACE, half=False, error=None, raw=None):
    """Write an H x W x 3 (RGB) or H x W x 4 (RGBA) linear image as a single-part scanline OpenEXR.

    Channels are FLOAT, or HALF with ``half=True``; the header carries the ``chromaticities`` of
    ``colourspace`` so that readers know the primaries and white of the linear values. ``error``: an
    H x W x 3 estimate of each pixel's absolute error (cloudmeta.render(..., error=True)), written as the
    extra channels error.R, error.G, error.B (FLOAT). ``raw``: the image before denoising, of the image's
    shape (cloudmeta.render_frame(..., denoise=True).raw), written as raw.R, raw.G, raw.B (raw.A) (FLOAT).
    """
    with _api_output(path) as tmp:
        encode_exr(image, tmp, colourspace, half, error, raw)


def encode_exr(image, path, colourspace=DEFAULT_COLOURSPACE, half=False, error=None, raw=None):
    """``write_exr`` straight to ``path``, without a temporary file (for callers that hold one already)."""
    arr = check_image(image)
    if not isinstance(half, (bool, np.bool_)):
        raise InputError(f"half: expected True or False, got {half!r}")
    dtype = np.float16 if half else np.float32
    with np.errstate(over="ignore"):
        stored = arr.astype(dtype)
    if not np.all(np.isfinite(stored)):
        kind = "HALF" if half else "FLOAT"
        raise InputError(f"image: values up to {np.abs(arr).max():g} overflow {kind} channels"
                         + ("; write with half=False" if half else ""))
    header = {"chromaticities": chromaticities(colourspace)}
    channels = {name: np.ascontiguousarray(stored[:, :, i]) for i, name in enumerate(_CHANNELS[:arr.shape[2]])}
    if error is not None:
        err = np.asarray(error, np.float64)  # inf is allowed: no estimate (multiple scattering, one path)
        if err.shape != arr.shape[:2] + (3,):
            raise InputError(f"error: expected an H x W x 3 array of the image's size, got shape {err.shape}")
        for i, name in enumerate(ERROR_CHANNELS):
            channels[name] = np.ascontiguousarray(err[:, :, i].astype(np.float32))
    if raw is not None:
        before = np.asarray(raw, np.float64)
        if before.shape != arr.shape:
            raise InputError(f"raw: expected an array of the image's shape {arr.shape}, got shape {before.shape}")
        for i, name in enumerate(RAW_CHANNELS[:arr.shape[2]]):
            channels[name] = np.ascontiguousarray(before[:, :, i].astype(np.float32))
    import OpenEXR  # here, not at import: a render that writes no EXR should not pay for it
    header["compression"], header["type"] = OpenEXR.ZIP_COMPRESSION, OpenEXR.scanlineimage
    try:
        OpenEXR.File(header, channels).write(os.fspath(path))
    except RuntimeError as exc:  # OpenEXR reports a failed write (a full disk, a lost folder) so
        raise OSError(f"cannot write {os.fspath(path)}: {exc}") from None


def read_exr(path):
    """(image, header) of an OpenEXR file: image is H x W x C float32 with channels in RGBA order.

    Channels other than R, G, B, A follow in name order. ``header`` is the file's header dict.
    """
    import OpenEXR
    try:
        exr = OpenEXR.File(str(path), separate_channels=True)
    except RuntimeError as exc:  # OpenEXR's one error class (a missing, unreadable or damaged file)
        raise InputError(f"path {path}: cannot read it as OpenEXR: {' '.join(str(exc).split())}") from None
    with exr as f:
        header = dict(f.header())  # a copy: File clears its own header dict when it closes
        channels = f.channels()
        order = [c for c in _CHANNELS if c in channels] + sorted(c for c in channels if c not in _CHANNELS)
        # astype copies: the pixels must outlive the File
        image = np.stack([channels[c].pixels.astype(np.float32) for c in order], axis=-1)
    return image, header


def write_png(image, path, exposure=None, colourspace=DEFAULT_COLOURSPACE, display="aces", white_balance=None,
              scene=None):
    """Write an 8-bit sRGB picture of a linear image: RGB only (the render's RGB is already over its background;
    alpha only picks the pixels that ``exposure="auto"`` measures). Through cloudmeta.api.display
    (docs/display.md): ``display`` aces (OpenColorIO's ACES output transform) or raw (linear times
    2 ** exposure under the sRGB curve: the preview as it was); ``white_balance`` scene (the light of
    ``scene``), none, a CIE illuminant's name (D65) or an illuminant's RGB; ``exposure`` stops or auto.
    None takes the display's default: for aces, white balance to ``scene`` where one is given (else none)
    and auto exposure; for raw, none and 0 stops."""
    display, white_balance, exposure, illuminant = png_settings(display, white_balance, exposure, scene)
    with _api_output(path) as tmp:
        encode_png(image, tmp, exposure, colourspace, display, white_balance, illuminant)


def png_settings(display="aces", white_balance=None, exposure=None, scene=None):
    """(display, white_balance, exposure, illuminant) checked, the display's defaults in place of None:
    white balance to ``scene``'s light where a scene is given and the display is aces (none without one).
    InputError (one line, naming the setting) before any work, also where aces needs OpenColorIO."""
    from .display import check_display, require_ocio, resolve, scene_illuminant
    check_display(display)
    if white_balance is None and scene is None:
        white_balance = "none"
    display, white_balance, exposure = resolve(display, white_balance, exposure)
    if display == "aces":
        require_ocio()
    illuminant = scene_illuminant(scene) if scene is not None and white_balance == "scene" else None
    if white_balance == "scene" and illuminant is None:
        raise InputError("white_balance: scene needs the scene: write_png(image, path, scene=scene); or give an "
                         "illuminant such as D65, or none")
    return display, white_balance, exposure, illuminant


@contextlib.contextmanager
def _api_output(path, label="path"):
    """``atomic_output`` for write_exr and write_png: an empty path or a folder refused before any work,
    and errors that name ``path``, not the hidden temporary file beside it."""
    if not isinstance(path, (str, bytes, os.PathLike)):
        raise InputError(f"{label}: expected a file path, got {type(path).__name__}")
    path = os.fsdecode(path)
    if not path:
        raise OutputError(f"{label}: expected a file name, got an empty path")
    if os.path.isdir(path):
        raise OutputError(f"{path}: is a folder; expected a file name")
    with atomic_output(path) as tmp:
        try:
            yield tmp
        except OSError as exc:
            text = str(exc.strerror or exc).replace(tmp, path)
            raise (OSError(exc.errno, text, path) if exc.errno else OSError(text)) from None


def encode_png(image, path, exposure=0.0, colourspace=DEFAULT_COLOURSPACE, display="raw", white_balance=None,
               illuminant=None):
    """``write_png`` straight to ``path``, without a temporary file (for callers that hold one already); the
    white balance ``scene`` takes the scene's ``illuminant`` (cloudmeta.api.display.scene_illuminant). Returns
    the exposure applied, in stops. The display defaults to raw here: callers name the managed one."""
    from PIL import Image

    from .display import display_image
    arr = check_image(image)
    if exposure is None or isinstance(exposure, str):  # the display's default, or auto
        from .display import check_exposure_setting
        check_exposure_setting("auto" if exposure is None else exposure)
    else:
        check_exposure(exposure)
    codes, stops = display_image(arr, colourspace, display, white_balance, exposure, illuminant)
    Image.fromarray(codes).save(os.fspath(path), format="PNG")
    return stops


def encode_outputs(image, tmps, colourspace=DEFAULT_COLOURSPACE, exposure=0.0, error=None, raw=None, display="raw",
                   white_balance=None, illuminant=None):
    """The one writer of a render's files: the EXR to ``tmps[0]`` (with the ``error`` channels if given) and,
    where ``tmps`` has a second path, the PNG to it (``encode_png``: ``display``, ``white_balance``,
    ``illuminant``, ``exposure``; the EXR never depends on them). ``tmps`` are atomic_outputs' temporary files,
    so both are renamed into place together or neither is. ``raw``: the image before denoising (raw.* channels).
    Returns the PNG's exposure in stops (None without a PNG)."""
    encode_exr(image, tmps[0], colourspace=colourspace, error=error, raw=raw)
    if len(tmps) > 1:
        return encode_png(image, tmps[1], exposure, colourspace, display, white_balance, illuminant)
    return None


def check_exposure(exposure, label="exposure"):
    """Refuse a PNG exposure (stops) that is not a finite number within +-MAX_EXPOSURE (``2 ** 2000``
    overflows): InputError naming ``label`` (``--exposure``). Returns it as a float."""
    if not (isinstance(exposure, (int, float, np.integer, np.floating)) and not isinstance(exposure, (bool, np.bool_))
            and abs(exposure) <= MAX_EXPOSURE):  # nan and inf fail the comparison
        got = f"{exposure:g}" if isinstance(exposure, (float, np.floating)) else repr(exposure)
        raise InputError(f"{label}: expected a finite number of stops within +-{MAX_EXPOSURE:g}, got {got}")
    return float(exposure)


def write_texts(texts):
    """Write [(full path, text)] together (UTF-8, LF), atomically: all of them or none (a scene and its balls
    file)."""
    paths = [path for path, _ in texts]
    with atomic_outputs(paths) as tmps:
        for tmp, (_, text) in zip(tmps, texts):
            with open(tmp, "w", encoding="utf-8", newline="\n") as f:
                f.write(text)


def check_replaceable(path, ext, label, overwrite, mark, producer, how="--overwrite"):
    """The full path of a file that a scene producer (``producer``, e.g. "cloudmeta generate") is about to
    write: a new one, or, with ``overwrite``, one it wrote itself (its first line starts with ``mark``).
    Anything else, a hand-made scene above all, is refused with an OutputError naming the path."""
    full = check_output_path(path, ext, label)
    if os.path.lexists(full):
        if not overwrite:
            raise OutputError(f"{label} {path}: exists; refusing to overwrite it ({how} replaces a file that "
                              f"{producer} wrote)")
        try:
            with open(full, "r", encoding="utf-8", errors="replace") as f:
                first = f.readline()
        except OSError as exc:
            raise OutputError(f"{label} {path}: {exc.strerror or exc}") from None
        if not first.startswith(mark):
            raise OutputError(f"{label} {path}: exists and was not written by {producer} (it may be a "
                              f"hand-made scene or another scene's input); refusing to overwrite it")
    return full


def check_output_path(path, ext, label, inputs=()):
    """Refuse, before any work, an output ``path`` that cannot be written or must not be: one of ``inputs``
    (the scene's own files), an existing target that is a folder, a device or a FIFO, a wrong extension
    (``ext``, e.g. ``.exr``), a folder that does not exist or cannot be written, or a name too long for the
    file system (the temporary name included). ``label`` names where the path came from (``-o``).
    Raises OutputError; returns the absolute path."""
    path = os.fspath(path)
    if not path:  # else the current folder, or argparse's "-o ''" taken for no -o at all
        raise OutputError(f"{label}: expected a file name, got an empty path")
    where = f"{label} {_shorten(path)}"
    if path.endswith(os.sep) or os.path.basename(path) in (".", ".."):
        raise OutputError(f"{where}: expected a file name, got a folder")
    full = os.path.abspath(path)
    folder, name = os.path.split(full)
    name_max, path_max = _fs_limit(folder, "PC_NAME_MAX", 255), _fs_limit(folder, "PC_PATH_MAX", 4096)
    tmp_name = _longest_temporary(name, ext)  # the longest name atomic_outputs creates next to it
    extra = len(os.fsencode(tmp_name)) - len(os.fsencode(name))
    if len(os.fsencode(tmp_name)) > name_max:
        raise OutputError(f"{where}: the name is too long for this file system (at most {name_max - extra} bytes)")
    if len(os.fsencode(os.path.join(folder, tmp_name))) >= path_max:
        raise OutputError(f"{where}: the path is too long for this file system "
                          f"(at most {path_max - extra - 1} bytes)")
    if os.path.isdir(full):
        raise OutputError(f"{where}: is a folder")
    for source in inputs:
        if same_file(full, source):
            raise OutputError(f"{where}: is an input of the scene ({_shorten(source)}); refusing to overwrite it")
    if os.path.lexists(full):
        try:
            info = os.stat(full)
        except OSError as exc:
            raise OutputError(f"{where}: {exc.strerror or exc}") from None
        if not stat.S_ISREG(info.st_mode):
            raise OutputError(f"{where}: is not a regular file (a device, FIFO or socket); refusing to replace it")
    if os.path.splitext(name)[1].lower() != ext:
        raise OutputError(f"{where}: expected a name ending in {ext} (this output is written as {ext[1:].upper()})")
    if not os.path.isdir(folder):
        missing = "does not exist" if not os.path.exists(folder) else "is not a folder"
        raise OutputError(f"{where}: the folder {_shorten(folder)} {missing}")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise OutputError(f"{where}: the folder {_shorten(folder)} is not writable")
    return full


def _shorten(text, limit=100):
    return text if len(text) <= limit else f"{text[:45]}...{text[-45:]}"


def check_distinct(outputs):
    """Refuse two outputs that name one file: [(label, path)]."""
    for i, (label_a, a) in enumerate(outputs):
        for label_b, b in outputs[i + 1:]:
            if same_file(a, b):
                raise OutputError(f"{label_a} {a} and {label_b} {b} name the same file; give each its own")


def same_file(a, b):
    """True where the paths name one file: the same real path, or hard links to one file."""
    if os.path.realpath(a) == os.path.realpath(b):
        return True
    try:
        return os.path.samefile(a, b)  # hard links
    except OSError:
        return False


def _fs_limit(folder, name, default):
    try:
        return os.pathconf(folder if os.path.isdir(folder) else "/", name)
    except (OSError, ValueError):
        return default
