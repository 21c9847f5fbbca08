"""Animation: keyframed values in a scene file, resolved to one static scene per frame (docs/animation.md).

Any number or list of numbers in the scene (a ball's centre, radius, radii, rotation, weight; the camera; a
light's direction, position, irradiance, intensity, colour; a medium's density scale, albedo, phase; the
background, the ambient light; a field's threshold) may be a keyframe mapping::

    radius: {keys: {0: 1.0, 12: 1.6, 24: 1.2}, interpolate: smooth}   # linear (the default) | smooth

``linear`` joins the keys by straight lines; ``smooth`` by a C1 cubic Hermite spline through the keys, its
slope at an inner key the finite difference of its neighbours, (v[i+1] - v[i-1]) / (k[i+1] - k[i-1])
(Catmull-Rom on uneven spacing), and 0 at the first and last keys, so that the motion eases in and out and
stays C1 where the value holds still beyond the keys. Before the first key and after the last the value is
that key's (clamped). At a key the value is the key's, exactly as written.

``animation: {frames: N, fps: F}`` (top level) declares the sequence, frames 0 .. N - 1; a ``balls_file``
may hold format fields of the frame number (``puffs/cloud_{frame:04d}.csv``). ``resolve_frame`` turns the
YAML document into the static document of one frame, which the scene loader then validates as any other:
its errors name the frame (``scene.yaml: frame 7: media[0].balls[3].radius: ...``).
"""
from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError, SceneError
from .document import Context, describe, read_yaml

INTERPOLATIONS = ("linear", "smooth")
#: sections whose values are settings of the whole sequence: keyframes there are refused
FIXED_SECTIONS = ("image", "render", "output")
DEFAULT_FPS = 24.0


@dataclass(frozen=True)
class Animation:
    frames: int         #: the sequence is frames 0 .. frames - 1
    fps: float


# ------------------------------------------------------------------------------------ interpolation

def _is_number(x):
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        return False
    try:
        return math.isfinite(x)
    except OverflowError:
        return False


def _slopes(frames, values):
    """Slopes of the smooth curve at the keys: finite differences inside, 0 at both ends."""
    slopes = np.zeros_like(values)
    if len(frames) > 2:
        slopes[1:-1] = (values[2:] - values[:-2]) / (frames[2:] - frames[:-2])[:, None]
    return slopes


def interpolate(keys, frame, mode="linear"):
    """The value at ``frame`` (a number, fractional frames allowed) of ``keys``, a {frame: value} mapping of
    numbers or of equal-length lists of numbers, already validated. Returns a float or a list of floats; at a
    key, that key's value as given."""
    if frame in keys:
        value = keys[frame]
        return list(value) if isinstance(value, list) else value
    frames = np.array(sorted(keys), dtype=np.float64)
    vector = isinstance(keys[next(iter(keys))], list)
    values = np.array([np.atleast_1d(np.asarray(keys[k], np.float64)) for k in sorted(keys)])
    if frame <= frames[0] or frame >= frames[-1]:
        out = values[0] if frame <= frames[0] else values[-1]
    else:
        i = int(np.searchsorted(frames, frame, side="right")) - 1
        h = frames[i + 1] - frames[i]
        t = (frame - frames[i]) / h
        v0, v1 = values[i], values[i + 1]
        if mode == "linear":
            out = v0 + t * (v1 - v0)
        else:
            m = _slopes(frames, values)
            t2, t3 = t * t, t * t * t
            out = ((2 * t3 - 3 * t2 + 1) * v0 + (t3 - 2 * t2 + t) * h * m[i] + (3 * t2 - 2 * t3) * v1
                   + (t3 - t2) * h * m[i + 1])
    return [float(x) for x in out] if vector else float(out[0])


# ------------------------------------------------------------------------------------- resolving

def _key(path, key):
    return f"{path}.{key}" if path else str(key)


def is_keyframes(value):
    """Whether a YAML value is a keyframe mapping (a mapping with ``keys``)."""
    return isinstance(value, dict) and "keys" in value


class _Resolver:
    """Walks the raw YAML document of ``file`` and replaces every keyframe mapping by its value at ``frame``."""

    def __init__(self, file, frame, fail):
        self.file, self.frame, self.fail = file, frame, fail
        self.animated = False

    def walk(self, value, path, fixed=None):
        if is_keyframes(value):
            if fixed is not None:
                self.fail(path, f"keyframes animate the scene's values (camera, lights, media, surfaces, "
                                f"background, ambient); the {fixed} settings are fixed for the whole sequence")
            self.animated = True
            return self.keyframes(value, path)
        if isinstance(value, dict):
            return {k: self.field(k, v, path, fixed) for k, v in value.items()}
        if isinstance(value, list):
            return [self.walk(v, f"{path}[{i}]", fixed) for i, v in enumerate(value)]
        return value

    def field(self, key, value, path, fixed):
        if key == "balls_file" and isinstance(value, str) and "{" in value:
            self.animated = True
            try:
                return value.format(frame=self.frame)
            except (KeyError, IndexError, ValueError) as exc:
                self.fail(_key(path, key), f"expected a file name whose only format field is the frame number, "
                                           f"such as cloud_{{frame:04d}}.csv, got {value!r} ({exc})")
        return self.walk(value, _key(path, key), fixed)

    def keyframes(self, spec, path):
        for k in spec:
            if k not in ("keys", "interpolate"):
                self.fail(_key(path, k), "unknown key in a keyframe mapping; expected keys, interpolate")
        mode = spec.get("interpolate", "linear")
        if mode not in INTERPOLATIONS:
            self.fail(_key(path, "interpolate"), f"expected one of {', '.join(INTERPOLATIONS)}, got {describe(mode)}")
        keys, where = spec["keys"], _key(path, "keys")
        if not isinstance(keys, dict) or not keys:
            self.fail(where, f"expected a mapping of frame numbers to values, such as {{0: 1.0, 24: 2.0}}, "
                             f"got {describe(keys)}")
        shape = None
        for frame, value in keys.items():
            if isinstance(frame, bool) or not isinstance(frame, int):
                self.fail(where, f"expected frame numbers (integers) as keys, got {describe(frame)}")
            at = f"{where}.{frame}"
            if isinstance(value, list) and value and all(_is_number(v) for v in value):
                this = len(value)
            elif _is_number(value):
                this = 0
            else:
                self.fail(at, f"expected a finite number or a list of finite numbers, got {describe(value)}")
            if shape is None:
                shape = this
            elif this != shape:
                want = "a number" if shape == 0 else f"a list of {shape} numbers"
                self.fail(at, f"expected {want} like the other keys, got {describe(value)}")
        return interpolate(keys, self.frame, mode)


def _fail_at(file, frame):
    def fail(key_path, message):
        raise with_frame(SceneError(file, key_path, message), frame)
    return fail


def with_frame(exc, frame):
    """A copy of the SceneError ``exc`` whose message names ``frame`` after the file
    (``scene.yaml: frame 7: media[0].radius: ...``); its ``file``, ``key_path`` and ``detail`` are kept."""
    where = f"{exc.file}: frame {frame}" if exc.file else f"frame {frame}"
    out = SceneError(where, exc.key_path, exc.detail)
    out.file, out.frame = exc.file, frame
    return out


@contextlib.contextmanager
def naming_frame(frame):
    """Inside the block, a SceneError gains the frame number in its message (when ``frame`` is not None)."""
    try:
        yield
    except SceneError as exc:
        if frame is None or getattr(exc, "frame", None) is not None:
            raise
        raise with_frame(exc, frame) from None


def _animation(file, raw, fail):
    if not isinstance(raw, dict):
        fail("animation", f"expected a mapping such as {{frames: 48, fps: 24}}, got {describe(raw)}")
    for k in raw:
        if k not in ("frames", "fps"):
            fail(f"animation.{k}", "unknown key; expected one of: frames, fps")
    frames = raw.get("frames")
    if isinstance(frames, bool) or not isinstance(frames, int) or frames < 1:
        fail("animation.frames", f"expected an integer >= 1, got {describe(frames)}"
             if "frames" in raw else "missing required key")
    fps = raw.get("fps", DEFAULT_FPS)
    if not (_is_number(fps) and fps > 0):
        fail("animation.fps", f"expected a finite number > 0, got {describe(fps)}")
    return Animation(int(frames), float(fps))


def resolve_frame(file, data, frame=None):
    """(static document, animated) of the YAML document ``data`` of ``file`` at ``frame`` (default 0).

    Keyframe mappings become their value at the frame, ``{frame}`` fields of ``balls_file`` are filled in
    and ``animation`` is removed (after validation); ``animated`` says whether the document has any of them.
    ``data`` itself is left unchanged. Raises SceneError naming the file, the frame and the key path.
    """
    if frame is None:
        frame = 0
    if isinstance(frame, bool) or not isinstance(frame, (int, np.integer)):
        raise InputError(f"frame: expected an integer, got {frame!r}")
    frame = int(frame)
    fail = _fail_at(file, frame)
    resolver = _Resolver(file, frame, fail)
    out = {}
    for key, value in data.items():
        if key == "animation":
            _animation(file, value, fail)
            resolver.animated = True
            continue
        out[key] = resolver.field(key, value, "", key if key in FIXED_SECTIONS else None)
    return out, resolver.animated


def load_animation(path):
    """The ``animation`` section of the scene file at ``path`` as an Animation, or None when it has none."""
    ctx = Context(path)
    data = read_yaml(ctx)
    if not isinstance(data, dict) or "animation" not in data:
        return None

    def fail(key_path, message):
        raise SceneError(ctx.file, key_path, message)
    return _animation(ctx.file, data["animation"], fail)


def parse_frames(text):
    """The frames of ``A:B[:STEP]`` (B excluded, as Python's range) or of a single frame ``N``."""
    parts = text.split(":")
    try:
        numbers = [int(p) for p in parts]
    except ValueError:
        numbers = None
    if numbers is None or len(numbers) > 3 or (len(numbers) == 3 and numbers[2] < 1) or min(numbers[:2]) < 0:
        raise InputError(f"--frames: expected A:B or A:B:STEP (frames A to B - 1, STEP >= 1) or one frame N, "
                         f"with A, B, N >= 0, got {text!r}")
    frames = range(numbers[0], numbers[0] + 1) if len(numbers) == 1 else range(*numbers)
    if len(frames) == 0:
        raise InputError(f"--frames: {text!r} holds no frame (B must be greater than A)")
    return frames
