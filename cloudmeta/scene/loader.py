"""Scene files: YAML in, a validated, immutable ``Scene`` out (MODEL.md §9).

Everything is checked here, once, so that the renderer and the kernels never meet a bad value. Every
error is a ``SceneError`` naming the file, the key path (``media[0].balls[12].radius``) and what was
expected; unknown keys are errors, at every level. A half-valid scene is never returned.

Values are read through ``_Node``, a mapping that knows its key path and has typed getters with
defaults (bool is never a number, numbers are finite, ``null`` is allowed only where the default is None).
"""
from __future__ import annotations

import array
import difflib
import math
import os
import re
import reprlib
import stat
from dataclasses import dataclass, fields

import numpy as np
import yaml

from . import limits as lim
from .blob import KERNELS, Blob
from .colour import DEFAULT_COLOURSPACE, colourspace_name, parse_colour
from .errors import InputError, SceneError

QUALITIES = ("draft", "default", "fine", "reference")
SHADOW_MODES = ("exact", "map")
SCATTERING_MODES = ("single", "multiple")
DENSITY_MODES = ("field", "excess", "uniform")
#: phase type -> its parameters (all required when the type is named)
PHASE_PARAMS = {"isotropic": (), "hg": ("g",), "double_hg": ("g1", "g2", "w"), "rayleigh": ()}
#: light type -> its keys besides ``type`` and ``color``
LIGHT_KEYS = {"directional": ("direction", "irradiance"), "point": ("position", "intensity")}
#: CSV headers of a balls file -> does it describe ellipsoids
CSV_HEADERS = {("x", "y", "z", "radius", "weight"): False,
               ("x", "y", "z", "rx", "ry", "rz", "ax", "ay", "az", "weight"): True}
#: an up vector closer than this (sine of the angle) to the view direction is refused
_PARALLEL_SINE = 1e-6


# ---------------------------------------------------------------------------------------------- data

def _frozen_array(value):
    arr = np.array(value, dtype=np.float64)
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True)
class ImageSettings:
    width: int
    height: int
    spp: int


@dataclass(frozen=True, eq=False)
class Camera:
    position: np.ndarray
    look_at: np.ndarray
    up: np.ndarray
    fov: float  #: vertical field of view, degrees


@dataclass(frozen=True, eq=False)
class DirectionalLight:
    direction: np.ndarray   #: unit vector towards the light
    irradiance: np.ndarray  #: (3,) irradiance x color


@dataclass(frozen=True, eq=False)
class PointLight:
    position: np.ndarray
    intensity: np.ndarray   #: (3,) intensity x color


@dataclass(frozen=True)
class Density:
    mode: str = "field"     #: field | excess | uniform (MODEL.md §4)
    scale: float = 1.0      #: sigma_t = scale * rho


@dataclass(frozen=True)
class Phase:
    type: str = "isotropic"  #: isotropic | hg | double_hg | rayleigh
    g: float = 0.0           #: hg
    g1: float = 0.0          #: double_hg: w HG(g1) + (1 - w) HG(g2)
    g2: float = 0.0
    w: float = 1.0


@dataclass(frozen=True, eq=False)
class Medium:
    name: str
    blob: Blob
    density: Density
    albedo: float
    phase: Phase


@dataclass(frozen=True, eq=False)
class Surface:
    name: str
    blob: Blob
    color: np.ndarray


@dataclass(frozen=True)
class RenderSettings:
    quality: str = "default"
    tolerance: float | None = None  #: quadrature: J's estimated error per step, relative to its largest value
    max_tau: float | None = None
    max_length: float | None = None
    max_angle: float | None = None  #: radians, seen from a point light
    cutoff: float | None = None
    root_tolerance: float | None = None  #: relative to the scene's bounding-box diagonal
    shadows: str = "exact"
    shadow_map: int | None = None
    colourspace: str = DEFAULT_COLOURSPACE
    scattering: str = "single"  #: single | multiple (README: multiple scattering)
    max_order: int = 64         #: multiple: the highest scattering order
    ms_spp: int = 16            #: multiple: Monte Carlo paths per pixel
    error: float | None = None  #: a target relative RMSE: the quadrature is refined until the estimate meets it


@dataclass(frozen=True)
class OutputSettings:
    path: str | None = None  #: EXR, absolute (resolved against the YAML's folder)
    png: str | None = None
    exposure: float = 0.0


@dataclass(frozen=True, eq=False)
class Scene:
    path: str
    image: ImageSettings
    camera: Camera
    background: np.ndarray
    ambient: np.ndarray | None
    lights: tuple
    media: tuple
    surfaces: tuple
    render: RenderSettings
    output: OutputSettings
    inputs: tuple = ()  #: absolute paths of the files the scene was read from (the YAML, every balls_file)

    def bbox(self):
        """(lo, hi) of the union of every medium's and surface's balls."""
        boxes = [thing.blob.bbox for thing in self.media + self.surfaces]
        return (np.min([lo for lo, _ in boxes], axis=0), np.max([hi for _, hi in boxes], axis=0))


# ------------------------------------------------------------------------------- typed getter layer

_REQUIRED = object()
#: what an unknown key may look like to be quoted in an error (scene keys are names)
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_ -]{0,39}")


_REPR = reprlib.Repr()
_REPR.maxlevel, _REPR.maxlist, _REPR.maxdict, _REPR.maxstring, _REPR.maxother = 2, 4, 3, 40, 40
_REPR.maxlong = 24


def _short_repr(value, limit=80):
    """A bounded repr: a few items of a few levels, so that a huge or deeply shared value costs nothing."""
    if _is_integer(value) and abs(value) >= 10 ** 20:
        return f"an integer of {len(str(abs(int(value))))} digits"
    text = _REPR.repr(value)
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _describe(value):
    """A value as an error message shows it: its (shortened) repr and, where it helps, its YAML type."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return f"{value} (a boolean)"
    if isinstance(value, dict):
        return f"a mapping {_short_repr(value)}"
    if isinstance(value, list):
        return f"a list {_short_repr(value)}"
    if isinstance(value, str):
        try:
            float(value[:64])
        except ValueError:
            return f"the text {_short_repr(value)}"
        # PyYAML (YAML 1.1) reads 1e3 and 1.0e3 as text: only 1.0e+3 is a number
        return f"the text {value!r} (YAML reads an exponent without a dot and a sign as text: write 1.0e+3)"
    return _short_repr(value)


def _is_integer(x):
    """True for an int (numpy's too, for overrides); bool is not a number in a scene file."""
    return isinstance(x, (int, np.integer)) and not isinstance(x, (bool, np.bool_))


def _is_finite_number(x):
    """True for a finite int or float (numpy's too); bool is not a number in a scene file."""
    if not (_is_integer(x) or isinstance(x, (float, np.floating))):
        return False
    try:
        return math.isfinite(x)
    except OverflowError:  # an int beyond the float range
        return False


class _Context:
    """The file being read: where errors point and where relative paths start."""

    def __init__(self, path):
        self.file = str(path)
        self.folder = os.path.dirname(os.path.abspath(path))
        self.inputs = [os.path.abspath(path)]  #: every file read, for the CLI's output checks
        self.ball_sources = {}  #: id(blob) -> locate(i, field) -> (key path, message prefix) of ball i

    def fail(self, key_path, message):
        raise SceneError(self.file, key_path, message)

    def resolve(self, relative):
        return os.path.normpath(os.path.join(self.folder, relative))


class _Node:
    """A mapping of the scene file at ``path``, read with typed getters that raise SceneError."""

    def __init__(self, ctx, path, data, allowed=None):
        self.ctx, self.path = ctx, path
        if not isinstance(data, dict):
            ctx.fail(path, f"expected a mapping, got {_describe(data)}")
        self.data = data
        if allowed is not None:
            self.only(allowed)

    def key(self, key):
        return f"{self.path}.{key}" if self.path else str(key)

    def fail(self, key, message):
        self.ctx.fail(self.key(key), message)

    def only(self, allowed):
        """Refuse any key outside ``allowed``, suggesting the closest allowed one."""
        for k in self.data:
            if not isinstance(k, str):
                self.fail(_short_repr(k), f"expected a key that is text, got {_describe(k)}; "
                                          f"expected one of: {', '.join(allowed) or 'no keys'}")
            if k not in allowed:
                if not _NAME.fullmatch(k):  # not a name: perhaps a line of a file that is no scene, never quoted
                    self.fail(f"<a key of {len(k)} characters>", f"unknown key, not a name; expected one of: "
                                                                f"{', '.join(allowed) or 'no keys'}")
                close = difflib.get_close_matches(str(k), list(allowed), n=1)
                hint = f" (did you mean {close[0]!r}?)" if close else ""
                self.fail(k, f"unknown key{hint}; expected one of: {', '.join(allowed) or 'no keys'}")
        return self

    def has(self, key):
        return key in self.data

    def _raw(self, key, default):
        """(value, given): the value, or the default when absent (or null where the default is None)."""
        value = self.data.get(key)
        if key not in self.data or (value is None and default is None):
            if default is _REQUIRED:
                self.fail(key, "missing required key")
            return default, False
        return value, True

    def number(self, key, default=_REQUIRED, check=None, expect="a finite number"):
        value, given = self._raw(key, default)
        if given and not (_is_finite_number(value) and (check is None or check(value))):
            self.fail(key, f"expected {expect}, got {_describe(value)}")
        return float(value) if value is not None else None

    def integer(self, key, default=_REQUIRED, check=None, expect="an integer"):
        value, given = self._raw(key, default)
        if given and not (_is_integer(value) and (check is None or check(value))):
            self.fail(key, f"expected {expect}, got {_describe(value)}")
        return None if value is None else int(value)

    def choice(self, key, options, default=_REQUIRED):
        value, given = self._raw(key, default)
        if given and not (isinstance(value, str) and value in options):
            self.fail(key, f"expected one of {', '.join(options)}, got {_describe(value)}")
        return value

    def string(self, key, default=_REQUIRED):
        value, given = self._raw(key, default)
        if given and not (isinstance(value, str) and value.strip()):
            self.fail(key, f"expected a non-empty string, got {_describe(value)}")
        return value

    def vector(self, key, default=_REQUIRED, length=3, check=None, expect=None, bounded=True):
        """A list of ``length`` finite numbers (each within +-1e100, limits.LENGTH_RANGE) as a read-only
        float64 array."""
        value, given = self._raw(key, default)
        if not given:
            return None if value is None else _frozen_array(value)
        expect = expect or f"a list of {length} finite numbers"
        if not (isinstance(value, list) and len(value) == length
                and all(_is_finite_number(v) for v in value)):
            self.fail(key, f"expected {expect}, got {_describe(value)}")
        if bounded and any(abs(float(v)) > lim.LENGTH_RANGE[1] for v in value):
            self.fail(key, f"expected {expect}, each within +-{lim.LENGTH_RANGE[1]:g} (README: Limits), "
                           f"got {_describe(value)}")
        arr = _frozen_array(value)
        if check is not None and not check(arr):
            self.fail(key, f"expected {expect}, got {_describe(value)}")
        return arr

    def node(self, key, allowed, default=_REQUIRED):
        """The mapping under ``key`` (an empty one when absent and optional), its keys limited to ``allowed``."""
        value, _ = self._raw(key, default)
        return _Node(self.ctx, self.key(key), {} if value is None else value, allowed)

    def items(self, key):
        """[(key path, item)] of the list under ``key`` (empty when absent)."""
        value, _ = self._raw(key, None)
        if value is None:
            return []
        if not isinstance(value, list):
            self.fail(key, f"expected a list, got {_describe(value)}")
        return [(f"{self.key(key)}[{i}]", item) for i, item in enumerate(value)]

    def colour(self, key, colourspace, default=_REQUIRED):
        """A colour (MODEL.md §7) as linear RGB of ``colourspace``, read-only; errors keep colour's key path."""
        value, given = self._raw(key, default)
        if not given:
            return None if value is None else _frozen_array(value)
        if isinstance(value, list):
            for i, c in enumerate(value):
                if _is_integer(c) and not _is_finite_number(c):  # an int beyond the float range
                    self.ctx.fail(f"{self.key(key)}[{i}]", f"expected a finite number >= 0, got {_describe(c)}")
        try:
            rgb = parse_colour(value, self.key(key), colourspace)
        except ValueError as exc:
            # parse_colour's message is "<key path>: <what was expected>"
            key_path, _, detail = str(exc).partition(": ")
            self.ctx.fail(key_path, detail)
        if not np.max(rgb) <= lim.MAX_RADIANCE:
            self.fail(key, f"expected a colour with components <= {lim.MAX_RADIANCE:g} (README: Limits), "
                           f"got {_describe(value)}")
        return _frozen_array(rgb)

    def path_to(self, key):
        """An optional file path, resolved against the YAML's folder."""
        value = self.string(key, None)
        return None if value is None else self.ctx.resolve(value)


# ------------------------------------------------------------------------------------------ sections

_POSITIVE = dict(check=lambda v: v > 0, expect="a finite number > 0")
_NON_NEGATIVE = dict(check=lambda v: v >= 0, expect="a finite number >= 0")
_NONZERO_VECTOR = dict(check=lambda v: np.any(v != 0), expect="a list of 3 finite numbers, not all 0")


def _int_range(lo, hi):
    return dict(check=lambda v: lo <= v <= hi, expect=f"an integer >= {lo} and <= {hi} (README: Limits)")


def unit(v):
    """v / |v| without overflow or underflow: scaled by its largest component first."""
    v = np.asarray(v, dtype=np.float64)
    v = v / np.max(np.abs(v))
    return v / np.linalg.norm(v)


def _image(top, width, height, spp):
    n = top.node("image", ("width", "height", "spp"))
    # overrides replace the file's values and are validated the same way
    overrides = {k: v for k, v in dict(width=width, height=height, spp=spp).items() if v is not None}
    n = _Node(n.ctx, n.path, dict(n.data, **overrides))
    w = n.integer("width", **_int_range(1, lim.MAX_SIDE))
    h = n.integer("height", **_int_range(1, lim.MAX_SIDE))
    spp = n.integer("spp", 1, **_int_range(1, lim.MAX_SPP))
    if w * h > lim.MAX_PIXELS:
        n.fail("height", f"expected at most {lim.MAX_PIXELS} pixels (README: Limits), got {w} x {h} = {w * h}")
    if w * h * spp > lim.MAX_SAMPLES:
        n.fail("spp", f"expected at most {lim.MAX_SAMPLES} samples in all (README: Limits), "
                      f"got {w} x {h} x {spp} = {w * h * spp}")
    return ImageSettings(w, h, spp)


def _camera(top):
    n = top.node("camera", ("position", "look_at", "up", "fov"))
    position, look_at = n.vector("position"), n.vector("look_at")
    view = look_at - position  # finite: both within +-1e100
    if not np.any(view != 0):
        n.fail("look_at", f"expected a point other than camera.position, got {look_at.tolist()} for both")
    if np.abs(view).max() < lim.LENGTH_RANGE[0]:
        n.fail("look_at", f"expected a point at least {lim.LENGTH_RANGE[0]:g} from camera.position, got "
                          f"{_g(look_at)} (the camera is at {_g(position)})")
    up = n.vector("up", [0.0, 0.0, 1.0], bounded=False, **_NONZERO_VECTOR)
    sine = np.linalg.norm(np.cross(unit(view), unit(up)))
    if sine < _PARALLEL_SINE:
        n.fail("up", f"expected a vector not parallel to the view direction look_at - position = {view.tolist()}, "
                     f"got {up.tolist()}")
    fov = n.number("fov", 40.0, check=lambda v: lim.MIN_FOV <= v <= lim.MAX_FOV,
                   expect=f"a vertical angle in degrees in (0, 180), from {lim.MIN_FOV:g} to {lim.MAX_FOV:g}")
    return Camera(position, look_at, _frozen_array(unit(up)), fov)  # unit: the renderer's cross products stay finite


def _light(ctx, path, raw, colourspace):
    n = _Node(ctx, path, raw, ("type", "color") + sum(LIGHT_KEYS.values(), ()))
    kind = n.choice("type", tuple(LIGHT_KEYS))
    n.only(("type", "color") + LIGHT_KEYS[kind])
    color = n.colour("color", colourspace, [1.0, 1.0, 1.0])
    key = "irradiance" if kind == "directional" else "intensity"
    with np.errstate(over="ignore"):
        value = n.number(key, 1.0, **_NON_NEGATIVE) * color
    if kind == "directional":
        if not np.max(value) <= lim.MAX_RADIANCE:
            n.fail(key, f"expected irradiance x color <= {lim.MAX_RADIANCE:g} (README: Limits), got {_g(value)}")
        return DirectionalLight(_frozen_array(unit(n.vector("direction", bounded=False, **_NONZERO_VECTOR))), _frozen_array(value))
    if not np.all(np.isfinite(value)):
        n.fail(key, f"expected intensity x color to be finite, got {_g(value)}")
    return PointLight(n.vector("position"), _frozen_array(value))


def _g(values):
    return "[" + ", ".join(f"{v:.3g}" for v in np.ravel(values)) + "]"


def _phase(n):
    p = n.node("phase", ("type",) + sum(PHASE_PARAMS.values(), ()), {})
    kind = p.choice("type", tuple(PHASE_PARAMS), "isotropic")
    p.only(("type",) + PHASE_PARAMS[kind])
    g = dict(check=lambda v: -1 < v < 1, expect="an asymmetry in (-1, 1)")
    if kind == "hg":
        return Phase(kind, g=p.number("g", **g))
    if kind == "double_hg":
        return Phase(kind, g1=p.number("g1", **g), g2=p.number("g2", **g),
                     w=p.number("w", check=lambda v: 0 <= v <= 1, expect="a weight in [0, 1]"))
    return Phase(kind)


_RADIUS = dict(check=lambda v: lim.LENGTH_RANGE[0] <= v <= lim.LENGTH_RANGE[1],
               expect=f"a finite number > 0, from {lim.LENGTH_RANGE[0]:g} to {lim.LENGTH_RANGE[1]:g}")
_RADII = dict(check=lambda v: np.all((v >= lim.LENGTH_RANGE[0]) & (v <= lim.LENGTH_RANGE[1])),
              expect=f"a list of 3 finite numbers > 0, from {lim.LENGTH_RANGE[0]:g} to {lim.LENGTH_RANGE[1]:g}")
_ROTATION = dict(check=lambda v: np.all(np.abs(v) <= 1e6), expect="a list of 3 angles in degrees within +-1e6")
#: a decimal number as a balls_file writes it; Python's float also reads "1_0", "infinity" and other digits
_DECIMAL = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")


def _balls_inline(n):
    """centers, radii (N, 3), rotations (N, 3) degrees, weights of the ``balls`` list; records where each
    ball was given (``ctx.ball_sources``, read by _check_domain)."""
    items = n.items("balls")
    if len(items) > lim.MAX_BALLS:
        n.fail("balls", f"expected at most {lim.MAX_BALLS} balls (README: Limits), got {len(items)}")
    rows, radius_key = [], []
    for path, raw in items:
        b = _Node(n.ctx, path, raw, ("center", "radius", "radii", "rotation", "weight"))
        center = b.vector("center")
        if b.has("radius") and b.has("radii"):
            b.fail("radii", "give either radius (a sphere) or radii (an ellipsoid), not both")
        if b.has("radii"):
            radii = b.vector("radii", **_RADII)
            rotation = b.vector("rotation", [0.0, 0.0, 0.0], **_ROTATION)
        else:
            if b.has("rotation"):
                b.fail("rotation", "a rotation applies to an ellipsoid: give radii instead of radius")
            radii = np.full(3, b.number("radius", **_RADIUS))
            rotation = np.zeros(3)
        radius_key.append("radii" if b.has("radii") else "radius")
        rows.append(np.concatenate([center, radii, rotation, [b.number("weight", 1.0)]]))
    prefix = n.key("balls")

    def locate(i, field):
        field = radius_key[i] if field == "radius" else field
        return f"{prefix}[{i}].{field}", ""
    return np.array(rows).reshape(-1, 10), locate


def _open_regular(ctx, key_path, path, what, limit):
    """A binary file object of the regular file ``path`` (stat before opening: a FIFO or a device is never
    opened for reading, and O_NONBLOCK keeps a FIFO swapped in meanwhile from blocking), at most ``limit`` bytes."""
    try:
        info = os.stat(path)
        if not stat.S_ISREG(info.st_mode):
            kind = "a folder" if stat.S_ISDIR(info.st_mode) else "not a regular file (a device, FIFO or socket)"
            ctx.fail(key_path, f"cannot read the {what} {path}: it is {kind}")
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except OSError as exc:
        ctx.fail(key_path, f"cannot read the {what} {path}: {exc.strerror or exc}")
    f = os.fdopen(fd, "rb")
    info = os.fstat(fd)
    if not stat.S_ISREG(info.st_mode):
        f.close()
        ctx.fail(key_path, f"cannot read the {what} {path}: it is not a regular file")
    if info.st_size > limit:
        f.close()
        ctx.fail(key_path, f"the {what} {path} has {info.st_size} bytes, more than the limit of {limit} "
                           f"(README: Limits)")
    return f


def _csv_lines(n, key, csv_path):
    """(line number, text) of the balls file, read in bounded lines; decoding and size errors name the line."""
    import io
    raw = _open_regular(n.ctx, n.key(key), csv_path, "balls file", lim.MAX_BALLS_FILE_BYTES)
    text = io.TextIOWrapper(raw, encoding="utf-8", errors="strict", newline=None)
    number, total = 0, 0
    with text:
        while True:
            number += 1
            try:
                line = text.readline(lim.MAX_CSV_LINE + 1)
            except UnicodeDecodeError:
                n.fail(key, f"{csv_path} line {number}: expected UTF-8 text")
            except OSError as exc:
                n.fail(key, f"cannot read the balls file {csv_path}: {exc.strerror or exc}")
            if not line:
                return
            total += len(line)
            if len(line) > lim.MAX_CSV_LINE:
                n.fail(key, f"{csv_path} line {number}: longer than {lim.MAX_CSV_LINE} characters")
            if total > lim.MAX_BALLS_FILE_BYTES:
                n.fail(key, f"the balls file {csv_path} is larger than {lim.MAX_BALLS_FILE_BYTES} bytes")
            yield number, line.rstrip("\r\n")


def _balls_csv(n):
    """The same as ``_balls_inline`` from a CSV file; errors name ``balls_file`` and the line number, and
    quote only cells of a file whose header is a balls file's (never a line of any other file)."""
    key = "balls_file"
    csv_path = n.path_to(key)
    n.ctx.inputs.append(csv_path)
    header, values, lines = None, array.array("d"), array.array("q")
    lo, hi = lim.LENGTH_RANGE
    for number, line in _csv_lines(n, key, csv_path):
        if not line.strip() or line.lstrip().startswith("#"):
            continue  # blank lines and comments
        cells = tuple(c.strip() for c in line.split(","))
        where = f"{csv_path} line {number}"
        if header is None:
            if cells not in CSV_HEADERS:
                n.fail(key, f"{where}: expected the header {' or '.join(','.join(h) for h in CSV_HEADERS)}; "
                            f"the first line is not a valid header ({len(cells)} fields)")
            header = cells
            continue
        if len(cells) != len(header):
            n.fail(key, f"{where}: expected {len(header)} comma-separated numbers ({','.join(header)}), "
                        f"got {len(cells)}")
        row = []
        for name, cell in zip(header, cells):
            value = float(cell) if _DECIMAL.fullmatch(cell) else math.nan
            if not math.isfinite(value):
                n.fail(key, f"{where}: expected finite numbers, {name} is {_short_repr(cell[:40])}")
            if name in ("x", "y", "z") and abs(value) > hi:
                n.fail(key, f"{where}: expected coordinates within +-{hi:g}, {name} is {cell[:40]}")
            row.append(value)
        if not CSV_HEADERS[header]:
            x, y, z, r, w = row
            row = [x, y, z, r, r, r, 0.0, 0.0, 0.0, w]
        if min(row[3:6]) <= 0:
            n.fail(key, f"{where}: expected radii > 0, got {_g(row[3:6])}")
        if not (lo <= min(row[3:6]) and max(row[3:6]) <= hi):
            n.fail(key, f"{where}: expected radii from {lo:g} to {hi:g}, got {_g(row[3:6])}")
        if max(abs(a) for a in row[6:9]) > 1e6:
            n.fail(key, f"{where}: expected angles in degrees within +-1e6, got {_g(row[6:9])}")
        values.extend(row)
        lines.append(number)
        if len(lines) > lim.MAX_BALLS:
            n.fail(key, f"{csv_path}: expected at most {lim.MAX_BALLS} balls (README: Limits)")
    if header is None:
        n.fail(key, f"{csv_path}: expected a header line, the file is empty")
    prefix = n.key(key)

    def locate(i, field):
        return prefix, f"{csv_path} line {lines[i]}: "
    return np.frombuffer(values, dtype=np.float64).reshape(-1, 10).copy(), locate


def _blob(n, what):
    """The Blob of a medium or surface mapping ``n``: kernel, threshold, blobbiness, balls or balls_file."""
    kernel = n.choice("kernel", tuple(KERNELS), "wyvill6")
    threshold = n.number("threshold", 0.5, check=lambda v: lim.THRESHOLD_RANGE[0] <= v <= lim.THRESHOLD_RANGE[1],
                         expect=f"a finite number > 0, from {lim.THRESHOLD_RANGE[0]:g} to {lim.THRESHOLD_RANGE[1]:g}")
    if n.has("blobbiness") and kernel != "blinn":
        n.fail("blobbiness", f"blobbiness applies to the blinn kernel only, the kernel is {kernel}")
    blobbiness = n.number("blobbiness", 4.0, check=lambda v: 0 < v <= lim.MAX_BLOBBINESS,
                          expect=f"a finite number > 0 and <= {lim.MAX_BLOBBINESS:g}")
    if n.has("balls") and n.has("balls_file"):
        n.fail("balls_file", "give either balls (inline) or balls_file (a CSV), not both")
    if not n.has("balls") and not n.has("balls_file"):
        n.fail("balls", "missing required key (or balls_file)")
    key = "balls" if n.has("balls") else "balls_file"
    balls, locate = _balls_inline(n) if key == "balls" else _balls_csv(n)
    if len(balls) == 0:
        n.fail(key, f"a {what} needs at least one ball, got none")
    heavy = np.flatnonzero(np.abs(balls[:, 9]) > lim.MAX_WEIGHT * threshold)
    if len(heavy):
        i = int(heavy[0])
        key_path, prefix = locate(i, "weight")
        n.ctx.fail(key_path, f"{prefix}expected a weight with |weight| <= {lim.MAX_WEIGHT:g} x threshold "
                             f"({lim.MAX_WEIGHT * threshold:g}; README: Limits), got {balls[i, 9]:g}")
    try:
        blob = Blob(balls[:, 0:3], balls[:, 3:6], balls[:, 9], kernel, threshold,
                    rotations=balls[:, 6:9], blobbiness=blobbiness)
    except InputError as exc:  # "radii[3]: expected ...": point at ball 3 where it was given
        found = re.match(r"(centers|radii|weights|rotations)\[(\d+)[^\]]*\]: (.*)", str(exc))
        if not found:
            n.fail(key, str(exc))
        field = {"centers": "center", "radii": "radius", "weights": "weight", "rotations": "rotation"}
        key_path, prefix = locate(int(found.group(2)), field[found.group(1)])
        n.ctx.fail(key_path, prefix + found.group(3))
    n.ctx.ball_sources[id(blob)] = locate
    return blob


def _named(ctx, items, prefix, build):
    """Build each item of a media / surfaces list; names default to ``{prefix}{i}`` and must be unique."""
    out, seen = [], {}
    for i, (path, raw) in enumerate(items):
        thing = build(path, raw, f"{prefix}{i}")
        if thing.name in seen:
            ctx.fail(f"{path}.name", f"expected a unique name, {thing.name!r} is also {seen[thing.name]}")
        seen[thing.name] = path
        out.append(thing)
    return tuple(out)


_BLOB_KEYS = ("name", "kernel", "threshold", "blobbiness", "balls", "balls_file")


def _medium(ctx, path, raw, default_name):
    n = _Node(ctx, path, raw, _BLOB_KEYS + ("density", "albedo", "phase"))
    name = n.string("name", default_name)
    d = n.node("density", ("mode", "scale"), {})
    density = Density(d.choice("mode", DENSITY_MODES, "field"), d.number("scale", 1.0, **_NON_NEGATIVE))
    albedo = n.number("albedo", 1.0, check=lambda v: 0 <= v <= 1, expect="an albedo in [0, 1]")
    return Medium(name, _blob(n, "medium"), density, albedo, _phase(n))


def _surface(ctx, path, raw, default_name, colourspace):
    n = _Node(ctx, path, raw, _BLOB_KEYS + ("color",))
    name = n.string("name", default_name)
    return Surface(name, _blob(n, "surface"), n.colour("color", colourspace, [1.0, 1.0, 1.0]))


def _render(top, overrides=None):
    n = top.node("render", tuple(f.name for f in fields(RenderSettings)), {})
    if overrides:  # the command line's --quality, --shadows, --shadow-map: validated like the file's values
        n = _Node(n.ctx, n.path, dict(n.data, **{k: v for k, v in overrides.items() if v is not None}))
    colourspace = n.string("colourspace", DEFAULT_COLOURSPACE)
    try:
        colourspace = colourspace_name(colourspace)  # canonical spelling
    except InputError:
        n.fail("colourspace", f"expected the name of a colour-science RGB colourspace such as "
                              f"{DEFAULT_COLOURSPACE!r} or 'ACEScg', got {colourspace!r}")
    return RenderSettings(
        quality=n.choice("quality", QUALITIES, "default"),
        tolerance=n.number("tolerance", None, check=lambda v: 0 <= v < 1, expect="a number in [0, 1)"),
        max_tau=n.number("max_tau", None, check=lambda v: v >= lim.MIN_MAX_TAU,
                         expect=f"a finite number > 0, at least {lim.MIN_MAX_TAU:g} (README: Limits)"),
        max_length=n.number("max_length", None, **_POSITIVE),  # against the scene's size in _check_domain
        max_angle=n.number("max_angle", None, check=lambda v: lim.MIN_MAX_ANGLE <= v <= 1.6,
                           expect=f"an angle in (0, 1.6] radians, at least {lim.MIN_MAX_ANGLE:g}"),
        cutoff=n.number("cutoff", None, check=lambda v: 0 <= v < 1, expect="a number in [0, 1)"),
        root_tolerance=n.number("root_tolerance", None,
                                check=lambda v: lim.ROOT_TOLERANCE_RANGE[0] <= v <= lim.ROOT_TOLERANCE_RANGE[1],
                                expect="a finite number > 0, from {:g} to {:g} of the scene's diagonal".format(
                                    *lim.ROOT_TOLERANCE_RANGE)),
        shadows=n.choice("shadows", SHADOW_MODES, "exact"),
        shadow_map=n.integer("shadow_map", None, **_int_range(2, lim.MAX_SHADOW_MAP)),
        colourspace=colourspace,
        scattering=n.choice("scattering", SCATTERING_MODES, "single"),
        max_order=n.integer("max_order", 64, **_int_range(1, lim.MAX_ORDER)),
        ms_spp=n.integer("ms_spp", 16, **_int_range(1, lim.MAX_SPP)),
        error=n.number("error", None, check=lambda v: lim.MIN_ERROR_TARGET <= v <= 0.5,
                       expect=f"a relative RMSE from {lim.MIN_ERROR_TARGET:g} to 0.5 (docs/error_estimate.md)"))


EXPOSURE = dict(check=lambda v: abs(v) <= lim.MAX_EXPOSURE,
                expect=f"a finite number of stops within +-{lim.MAX_EXPOSURE:g}")


def _output(top):
    n = top.node("output", ("path", "png", "exposure"), {})
    return OutputSettings(n.path_to("path"), n.path_to("png"), n.number("exposure", 0.0, **EXPOSURE))


# ---------------------------------------------------------------------------------------------- load

# libyaml's parser when PyYAML has it: large inline ball lists parse several times faster
_SafeLoader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def _children(node):
    """(child, key path suffix) of a YAML node: a mapping's keys and values, a sequence's items."""
    if isinstance(node, yaml.MappingNode):
        out = []
        for k, v in node.value:
            name = k.value if isinstance(k, yaml.ScalarNode) else "?"
            out += [(k, f".{name}"), (v, f".{name}")]
        return out
    if isinstance(node, yaml.SequenceNode):
        return [(v, f"[{i}]") for i, v in enumerate(node.value)]
    return []


def _check_tree(root):
    """Refuse a document whose nodes, every alias expanded, exceed limits.MAX_YAML_NODES, or nest deeper
    than MAX_YAML_DEPTH, or that is recursive: before anything is built, in time linear in the distinct
    nodes (a billion-laughs tree of aliases is refused at once). Raises ConstructorError at the node."""
    size, depth, active = {}, {}, set()
    stack = [(root, False, "")]
    while stack:
        node, done, path = stack.pop()
        key = id(node)
        kids = _children(node)
        if done:
            size[key] = 1 + sum(size[id(k)] for k, _ in kids)
            depth[key] = 1 + max((depth[id(k)] for k, _ in kids), default=0)
            active.discard(key)
            where = path.lstrip(".") or "the document"
            where = where if len(where) <= 60 else where[:57] + "..."
            if size[key] > lim.MAX_YAML_NODES:
                raise yaml.constructor.ConstructorError(
                    None, None, f"{where}: more than {lim.MAX_YAML_NODES} YAML nodes with every alias expanded "
                                f"(README: Limits)", node.start_mark)
            if depth[key] > lim.MAX_YAML_DEPTH:
                raise yaml.constructor.ConstructorError(
                    None, None, f"{where}: lists and mappings nested more than {lim.MAX_YAML_DEPTH} deep",
                    node.start_mark)
            continue
        if key in size:
            continue
        active.add(key)
        stack.append((node, True, path))
        for k, suffix in kids:
            if id(k) in active:
                raise yaml.constructor.ConstructorError(
                    None, None, f"{(path + suffix).lstrip('.')}: a recursive alias (a node that contains itself)",
                    k.start_mark)
            if id(k) not in size:
                stack.append((k, False, path + suffix))


def _check_nesting(text):
    """Refuse lists and mappings nested deeper than MAX_YAML_DEPTH from the parser's events, before the
    composer builds nodes (libyaml's composer recurses in C: a deep enough nesting crashes it)."""
    depth = 0
    for event in yaml.parse(text, Loader=_SafeLoader):
        if isinstance(event, yaml.CollectionStartEvent):
            depth += 1
            if depth > lim.MAX_YAML_DEPTH:
                raise yaml.constructor.ConstructorError(
                    None, None, f"lists and mappings nested more than {lim.MAX_YAML_DEPTH} deep", event.start_mark)
        elif isinstance(event, yaml.CollectionEndEvent):
            depth -= 1


class _UniqueKeyLoader(_SafeLoader):
    """safe_load that refuses a key given twice in one mapping (PyYAML would keep the last silently), keys
    that are lists or mappings (YAML complex keys), and documents beyond the limits of _check_tree."""

    def construct_document(self, node):
        _check_tree(node)
        return super().construct_document(node)

    def construct_mapping(self, node, deep=False):
        seen = set()
        for key_node, _ in node.value:
            if not isinstance(key_node, yaml.ScalarNode):
                raise yaml.constructor.ConstructorError(
                    None, None, "expected a key that is text, got a list or mapping (a YAML complex key)",
                    key_node.start_mark)
            key = self.construct_object(key_node, deep=deep)
            if isinstance(key, str) and key in seen:
                raise yaml.constructor.ConstructorError(
                    None, None, f"duplicate key {_short_repr(key)}", key_node.start_mark)
            seen.add(key)
        return super().construct_mapping(node, deep)


def _read_yaml(ctx):
    f = _open_regular(ctx, None, ctx.file, "scene file", lim.MAX_SCENE_BYTES)
    try:
        with f:
            text = f.read(lim.MAX_SCENE_BYTES + 1).decode("utf-8")
        if len(text) > lim.MAX_SCENE_BYTES:
            ctx.fail(None, f"the scene file is larger than {lim.MAX_SCENE_BYTES} bytes (README: Limits)")
        _check_nesting(text)
        return yaml.load(text, Loader=_UniqueKeyLoader)  # noqa: S506 (a SafeLoader)
    except SceneError:
        raise
    except (OSError, UnicodeDecodeError) as exc:
        ctx.fail(None, f"cannot read the scene file: {getattr(exc, 'strerror', None) or exc}")
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        at = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc)
        if "maximum nesting depth" in problem:  # PyYAML >= 6.0.4's own limit (1000) can come before ours
            problem = f"lists and mappings nested more than {lim.MAX_YAML_DEPTH} deep"
        ctx.fail(None, f"invalid YAML{at}: {problem}")
    except (ValueError, OverflowError, RecursionError, MemoryError) as exc:
        if "digits" in str(exc):  # Python refuses to convert an integer of more than 4300 digits
            ctx.fail(None, "invalid YAML: an integer of more than 4300 digits")
        ctx.fail(None, f"invalid YAML: {type(exc).__name__} {_short_repr(str(exc))}")


def load_scene(path, width=None, height=None, spp=None, render=None, frame=None) -> Scene:
    """Read and validate the YAML scene at ``path``; ``width``, ``height``, ``spp`` override its image settings,
    ``render`` (a dict) its ``render:`` keys, validated like the file's own.

    An animated scene (keyframes, ``animation:``, docs/animation.md) is read at ``frame`` (default 0).
    Raises SceneError (file, key path, what was expected) on the first problem found; a scene outside the
    limits or the numeric domain (cloudmeta.limits, README "Limits") is refused too.
    """
    ctx = _Context(path)
    data = _read_yaml(ctx)
    if not isinstance(data, dict):
        # the type only: a file that is not a scene (``cloudmeta render /etc/shadow``) must not be quoted
        got = "null" if data is None else {list: "a list", str: "a text"}.get(type(data), type(data).__name__)
        ctx.fail(None, f"expected a mapping of sections (image, camera, media, ...) at the top level, got {got}")
    from .animation import naming_frame, resolve_frame  # here: animation.py reads this module's helpers
    data, animated = resolve_frame(ctx.file, data, frame)
    with naming_frame((frame or 0) if animated else None):
        return _scene(ctx, data, width, height, spp, render)


def _scene(ctx, data, width, height, spp, render):
    """The Scene of the static YAML document ``data`` (a mapping) of ``ctx``'s file."""
    top = _Node(ctx, "", data, ("image", "camera", "background", "ambient", "lights", "media", "surfaces",
                                "render", "output"))
    render = _render(top, render)  # first: colours depend on its colourspace
    cs = render.colourspace
    image = _image(top, width, height, spp)
    camera = _camera(top)
    background = top.colour("background", cs, [0.0, 0.0, 0.0])
    ambient = top.colour("ambient", cs, None)
    lights = tuple(_light(ctx, p, raw, cs) for p, raw in top.items("lights"))
    media = _named(ctx, top.items("media"), "medium", lambda p, raw, name: _medium(ctx, p, raw, name))
    surfaces = _named(ctx, top.items("surfaces"), "surface", lambda p, raw, name: _surface(ctx, p, raw, name, cs))
    if not media and not surfaces:
        ctx.fail("media", "a scene needs at least one medium or surface, found none")
    scene = Scene(ctx.file, image, camera, background, ambient, lights, media, surfaces, render, _output(top),
                  tuple(ctx.inputs))
    _check_domain(ctx, scene)
    return scene


# ------------------------------------------------------------------------------------ numeric domain

def _phase_peak(phase):
    """The largest value of the phase function (at cos theta = +-1)."""
    hg = lambda g: (1 + abs(g)) / (4 * math.pi * (1 - abs(g)) ** 2)  # noqa: E731
    if phase.type == "hg":
        return hg(phase.g)
    if phase.type == "double_hg":
        return phase.w * hg(phase.g1) + (1 - phase.w) * hg(phase.g2)
    return 3 / (8 * math.pi) if phase.type == "rayleigh" else 1 / (4 * math.pi)


def _check_domain(ctx, scene):
    """Refuse values outside the domain where the kernels' tolerances hold (docs/model_notes.md "Numeric
    domain"): lengths relative to the scene's diagonal L, optical depths and radiances far from overflow,
    and work and memory within the machine's means (README "Limits")."""
    lo, hi = scene.bbox()
    diag = float(np.linalg.norm(hi - lo))
    things = [(f"media[{i}]", m) for i, m in enumerate(scene.media)] + \
             [(f"surfaces[{i}]", s) for i, s in enumerate(scene.surfaces)]
    if not lim.LENGTH_RANGE[0] <= diag <= 2 * lim.LENGTH_RANGE[1]:
        ctx.fail(f"{things[0][0]}.balls", f"the scene's bounding-box diagonal is {diag:g}, outside "
                                         f"[{lim.LENGTH_RANGE[0]:g}, {lim.LENGTH_RANGE[1]:g}] (README: Limits)")
    far = lim.MAX_OFFSET * diag
    # a ball spans at least 1000 root tolerances (1e-6 of the diagonal at the default 1e-9)
    min_radius = lim.MIN_RADIUS_TOLERANCES * (scene.render.root_tolerance or 1e-9)
    for path, thing in things:
        blob, locate = thing.blob, ctx.ball_sources[id(thing.blob)]
        bad = np.flatnonzero(np.abs(blob.centers).max(axis=1) > far)
        if len(bad):
            key_path, prefix = locate(int(bad[0]), "center")
            ctx.fail(key_path, f"{prefix}expected a centre within +-{far:.3g} ({lim.MAX_OFFSET:g} x the scene's "
                               f"diagonal {diag:.3g}), got {_g(blob.centers[bad[0]])}")
        small = np.flatnonzero(blob.radii.min(axis=1) < min_radius * diag)
        if len(small):
            key_path, prefix = locate(int(small[0]), "radius")
            ctx.fail(key_path, f"{prefix}expected radii of at least {min_radius * diag:.3g} ({min_radius:g} x the "
                               f"scene's diagonal {diag:.3g}: 1000 root tolerances; a ball far from the rest makes the "
                               f"diagonal large), got {_g(blob.radii[small[0]])}")
    for key, point in (("camera.position", scene.camera.position), ("camera.look_at", scene.camera.look_at)) + \
            tuple((f"lights[{i}].position", l.position) for i, l in enumerate(scene.lights)
                  if isinstance(l, PointLight)):
        if np.abs(point).max() > far:
            ctx.fail(key, f"expected a point within +-{far:.3g} ({lim.MAX_OFFSET:g} x the scene's diagonal "
                          f"{diag:.3g}), got {_g(point)}")
    for i, m in enumerate(scene.media):
        rho = 1.0 if m.density.mode == "uniform" else float(np.abs(m.blob.weights).sum())
        if m.density.scale * rho * diag > lim.MAX_TAU_BOUND:
            ctx.fail(f"media[{i}].density.scale", f"expected scale x sum |weight| x diagonal <= "
                                                  f"{lim.MAX_TAU_BOUND:g} (a bound on optical depth), got "
                                                  f"{m.density.scale * rho * diag:.3g}")
    for i, light in enumerate(scene.lights):
        if isinstance(light, PointLight) and np.max(light.intensity) / diag ** 2 > lim.MAX_RADIANCE:
            ctx.fail(f"lights[{i}].intensity", f"expected intensity x color / diagonal^2 <= {lim.MAX_RADIANCE:g}, "
                                               f"got {np.max(light.intensity) / diag ** 2:.3g}")
    # the brightest radiance single scattering and surfaces can make: background + ambient x (1 + colour)
    # + each light's irradiance (a point light's at one diagonal) x the largest phase peak or colour / pi
    peak = max([m.albedo * _phase_peak(m.phase) for m in scene.media] + [s.color.max() / math.pi
                                                                        for s in scene.surfaces])
    colour = max([1.0] + [s.color.max() for s in scene.surfaces])
    irradiance = sum(float(np.max(l.irradiance)) if isinstance(l, DirectionalLight)
                     else float(np.max(l.intensity)) / diag ** 2 for l in scene.lights)
    ambient = 0.0 if scene.ambient is None else float(np.max(scene.ambient))
    terms = {"background": float(np.max(scene.background)), "ambient": ambient * (1 + colour),
             "lights": irradiance * peak}
    bound = sum(terms.values())
    if not bound <= lim.MAX_RADIANCE:
        ctx.fail(max(terms, key=terms.get),
                 f"the brightest radiance this scene can make is about {bound:.3g}, above the limit "
                 f"{lim.MAX_RADIANCE:g} (README: Limits)")
    r = scene.render
    if r.max_length is not None and diag / r.max_length > lim.MAX_STEPS_PER_RAY:
        ctx.fail("render.max_length", f"expected at least {diag / lim.MAX_STEPS_PER_RAY:.3g} (the scene's "
                                      f"diagonal {diag:.3g} / {lim.MAX_STEPS_PER_RAY:g} steps), got {r.max_length:g}")
    _check_memory(ctx, scene)


def _check_memory(ctx, scene):
    w, h = scene.image.width, scene.image.height
    balls = sum(len(t.blob) for t in scene.media + scene.surfaces)
    directional = sum(isinstance(l, DirectionalLight) for l in scene.lights)
    res = scene.render.shadow_map or 384  # render.SHADOW_MAP_RESOLUTION
    texels = directional * res * res if scene.render.shadows == "map" and scene.media else 0
    need, have = lim.render_memory(w, h, balls, texels), lim.physical_memory()
    if have is not None and need > lim.MEMORY_FRACTION * have:
        key = "render.shadow_map" if texels * lim.BYTES_PER_TEXEL > w * h * lim.BYTES_PER_PIXEL else "image"
        ctx.fail(key, f"a render of {w} x {h} pixels, {balls} balls and {texels} shadow-map texels needs about "
                      f"{lim.gib(need)}, more than {lim.MEMORY_FRACTION:g} of this machine's {lim.gib(have)}")
