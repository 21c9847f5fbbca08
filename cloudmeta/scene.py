"""Scene files: YAML in, a validated, immutable ``Scene`` out (MODEL.md §9).

Everything is checked here, once, so that the renderer and the kernels never meet a bad value. Every
error is a ``SceneError`` naming the file, the key path (``media[0].balls[12].radius``) and what was
expected; unknown keys are errors, at every level. A half-valid scene is never returned.

Values are read through ``_Node``, a mapping that knows its key path and has typed getters with
defaults (bool is never a number, numbers are finite, ``null`` is allowed only where the default is None).
"""
from __future__ import annotations

import difflib
import math
import os
from dataclasses import dataclass, fields

import numpy as np
import yaml

from .blob import KERNELS, Blob
from .colour import DEFAULT_COLOURSPACE, parse_colour, working_colourspace
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

    def bbox(self):
        """(lo, hi) of the union of every medium's and surface's balls."""
        boxes = [thing.blob.bbox for thing in self.media + self.surfaces]
        return (np.min([lo for lo, _ in boxes], axis=0), np.max([hi for _, hi in boxes], axis=0))


# ------------------------------------------------------------------------------- typed getter layer

_REQUIRED = object()


def _short_repr(value, limit=80):
    text = repr(value)
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
            float(value)
        except ValueError:
            return f"the text {_short_repr(value)}"
        # PyYAML (YAML 1.1) reads 1e3 and 1.0e3 as text: only 1.0e+3 is a number
        return f"the text {value!r} (YAML reads an exponent without a dot and a sign as text: write 1.0e+3)"
    return repr(value)


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
            if k not in allowed:
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

    def vector(self, key, default=_REQUIRED, length=3, check=None, expect=None):
        """A list of ``length`` finite numbers as a read-only float64 array."""
        value, given = self._raw(key, default)
        if not given:
            return None if value is None else _frozen_array(value)
        expect = expect or f"a list of {length} finite numbers"
        if not (isinstance(value, list) and len(value) == length
                and all(_is_finite_number(v) for v in value)):
            self.fail(key, f"expected {expect}, got {_describe(value)}")
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
        try:
            return _frozen_array(parse_colour(value, self.key(key), colourspace))
        except ValueError as exc:
            # parse_colour's message is "<key path>: <what was expected>"
            key_path, _, detail = str(exc).partition(": ")
            self.ctx.fail(key_path, detail)

    def path_to(self, key):
        """An optional file path, resolved against the YAML's folder."""
        value = self.string(key, None)
        return None if value is None else self.ctx.resolve(value)


# ------------------------------------------------------------------------------------------ sections

_POSITIVE = dict(check=lambda v: v > 0, expect="a finite number > 0")
_NON_NEGATIVE = dict(check=lambda v: v >= 0, expect="a finite number >= 0")
_POSITIVE_INT = dict(check=lambda v: v >= 1, expect="an integer >= 1")
_NONZERO_VECTOR = dict(check=lambda v: 0 < np.linalg.norm(v) < np.inf, expect="a list of 3 finite numbers, not all 0")


def _image(top, width, height, spp):
    n = top.node("image", ("width", "height", "spp"))
    # overrides replace the file's values and are validated the same way
    overrides = {k: v for k, v in dict(width=width, height=height, spp=spp).items() if v is not None}
    n = _Node(n.ctx, n.path, dict(n.data, **overrides))
    return ImageSettings(n.integer("width", **_POSITIVE_INT), n.integer("height", **_POSITIVE_INT),
                         n.integer("spp", 1, **_POSITIVE_INT))


def _camera(top):
    n = top.node("camera", ("position", "look_at", "up", "fov"))
    position, look_at = n.vector("position"), n.vector("look_at")
    view = look_at - position
    if not np.linalg.norm(view) > 0:
        n.fail("look_at", f"expected a point other than camera.position, got {look_at.tolist()} for both")
    up = n.vector("up", [0.0, 0.0, 1.0], **_NONZERO_VECTOR)
    sine = np.linalg.norm(np.cross(view / np.linalg.norm(view), up / np.linalg.norm(up)))
    if sine < _PARALLEL_SINE:
        n.fail("up", f"expected a vector not parallel to the view direction look_at - position = {view.tolist()}, "
                     f"got {up.tolist()}")
    fov = n.number("fov", 40.0, check=lambda v: 0 < v < 180, expect="a vertical angle in degrees in (0, 180)")
    return Camera(position, look_at, up, fov)


def _light(ctx, path, raw, colourspace):
    n = _Node(ctx, path, raw, ("type", "color") + sum(LIGHT_KEYS.values(), ()))
    kind = n.choice("type", tuple(LIGHT_KEYS))
    n.only(("type", "color") + LIGHT_KEYS[kind])
    color = n.colour("color", colourspace, [1.0, 1.0, 1.0])
    if kind == "directional":
        direction = n.vector("direction", **_NONZERO_VECTOR)
        return DirectionalLight(_frozen_array(direction / np.linalg.norm(direction)),
                                _frozen_array(n.number("irradiance", 1.0, **_NON_NEGATIVE) * color))
    return PointLight(n.vector("position"), _frozen_array(n.number("intensity", 1.0, **_NON_NEGATIVE) * color))


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


def _balls_inline(n):
    """centers, radii (N, 3), rotations (N, 3) degrees, weights of the ``balls`` list."""
    rows = []
    for path, raw in n.items("balls"):
        b = _Node(n.ctx, path, raw, ("center", "radius", "radii", "rotation", "weight"))
        center = b.vector("center")
        if b.has("radius") and b.has("radii"):
            b.fail("radii", "give either radius (a sphere) or radii (an ellipsoid), not both")
        if b.has("radii"):
            radii = b.vector("radii", check=lambda v: np.all(v > 0), expect="a list of 3 finite numbers > 0")
            rotation = b.vector("rotation", [0.0, 0.0, 0.0])
        else:
            if b.has("rotation"):
                b.fail("rotation", "a rotation applies to an ellipsoid: give radii instead of radius")
            radii = np.full(3, b.number("radius", **_POSITIVE))
            rotation = np.zeros(3)
        rows.append(np.concatenate([center, radii, rotation, [b.number("weight", 1.0)]]))
    return np.array(rows).reshape(-1, 10)


def _balls_csv(n):
    """The same as ``_balls_inline`` from a CSV file; errors name ``balls_file`` and the line number."""
    key = "balls_file"
    csv_path = n.path_to(key)
    try:
        with open(csv_path, encoding="utf-8") as f:
            lines = f.read().splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        n.fail(key, f"cannot read the balls file {csv_path}: {getattr(exc, 'strerror', None) or exc}")
    header, rows = None, []
    for number, line in enumerate(lines, start=1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue  # blank lines and comments
        cells = tuple(c.strip() for c in line.split(","))
        where = f"{csv_path} line {number}"
        if header is None:
            if cells not in CSV_HEADERS:
                n.fail(key, f"{where}: expected the header {' or '.join(','.join(h) for h in CSV_HEADERS)}, "
                            f"got {line.strip()!r}")
            header = cells
            continue
        if len(cells) != len(header):
            n.fail(key, f"{where}: expected {len(header)} comma-separated numbers ({','.join(header)}), "
                        f"got {len(cells)}: {line.strip()!r}")
        try:
            values = [float(c) for c in cells]
        except ValueError:
            values = [np.nan]
        if not np.all(np.isfinite(values)):
            n.fail(key, f"{where}: expected finite numbers, got {line.strip()!r}")
        if CSV_HEADERS[header]:
            row = values  # x, y, z, rx, ry, rz, ax, ay, az, weight: the inline layout already
        else:
            x, y, z, r, w = values
            row = [x, y, z, r, r, r, 0.0, 0.0, 0.0, w]
        if min(row[3:6]) <= 0:
            n.fail(key, f"{where}: expected radii > 0, got {line.strip()!r}")
        rows.append(row)
    if header is None:
        n.fail(key, f"{csv_path}: expected a header line, the file is empty")
    return np.array(rows, dtype=np.float64).reshape(-1, 10)


def _blob(n, what):
    """The Blob of a medium or surface mapping ``n``: kernel, threshold, blobbiness, balls or balls_file."""
    kernel = n.choice("kernel", tuple(KERNELS), "wyvill6")
    threshold = n.number("threshold", 0.5, **_POSITIVE)
    if n.has("blobbiness") and kernel != "blinn":
        n.fail("blobbiness", f"blobbiness applies to the blinn kernel only, the kernel is {kernel}")
    blobbiness = n.number("blobbiness", 4.0, **_POSITIVE)
    if n.has("balls") and n.has("balls_file"):
        n.fail("balls_file", "give either balls (inline) or balls_file (a CSV), not both")
    if not n.has("balls") and not n.has("balls_file"):
        n.fail("balls", "missing required key (or balls_file)")
    key = "balls" if n.has("balls") else "balls_file"
    balls = _balls_inline(n) if key == "balls" else _balls_csv(n)
    if len(balls) == 0:
        n.fail(key, f"a {what} needs at least one ball, got none")
    try:
        return Blob(balls[:, 0:3], balls[:, 3:6], balls[:, 9], kernel, threshold,
                    rotations=balls[:, 6:9], blobbiness=blobbiness)
    except InputError as exc:
        n.fail(key, str(exc))


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


def _render(top):
    n = top.node("render", tuple(f.name for f in fields(RenderSettings)), {})
    colourspace = n.string("colourspace", DEFAULT_COLOURSPACE)
    try:
        colourspace = working_colourspace(colourspace).name  # canonical spelling
    except InputError:
        n.fail("colourspace", f"expected the name of a colour-science RGB colourspace such as "
                              f"{DEFAULT_COLOURSPACE!r} or 'ACEScg', got {colourspace!r}")
    return RenderSettings(
        quality=n.choice("quality", QUALITIES, "default"),
        tolerance=n.number("tolerance", None, check=lambda v: 0 <= v < 1, expect="a number in [0, 1)"),
        max_tau=n.number("max_tau", None, **_POSITIVE),
        max_length=n.number("max_length", None, **_POSITIVE),
        max_angle=n.number("max_angle", None, check=lambda v: 0 < v <= 1.6, expect="an angle in (0, 1.6] radians"),
        cutoff=n.number("cutoff", None, check=lambda v: 0 <= v < 1, expect="a number in [0, 1)"),
        root_tolerance=n.number("root_tolerance", None, **_POSITIVE),
        shadows=n.choice("shadows", SHADOW_MODES, "exact"),
        shadow_map=n.integer("shadow_map", None, check=lambda v: v >= 2, expect="an integer >= 2"),
        colourspace=colourspace,
        scattering=n.choice("scattering", SCATTERING_MODES, "single"),
        max_order=n.integer("max_order", 64, check=lambda v: v >= 1, expect="an integer >= 1"),
        ms_spp=n.integer("ms_spp", 16, check=lambda v: v >= 1, expect="an integer >= 1"))


def _output(top):
    n = top.node("output", ("path", "png", "exposure"), {})
    return OutputSettings(n.path_to("path"), n.path_to("png"), n.number("exposure", 0.0))


# ---------------------------------------------------------------------------------------------- load

# libyaml's parser when PyYAML has it: large inline ball lists parse several times faster
_SafeLoader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


class _UniqueKeyLoader(_SafeLoader):
    """safe_load that refuses a key given twice in one mapping (PyYAML would keep the last silently)."""

    def construct_mapping(self, node, deep=False):
        seen = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            if isinstance(key, str) and key in seen:
                raise yaml.constructor.ConstructorError(
                    None, None, f"duplicate key {key!r}", key_node.start_mark)
            seen.add(key)
        return super().construct_mapping(node, deep)


def _read_yaml(ctx):
    try:
        with open(ctx.file, encoding="utf-8") as f:
            return yaml.load(f, Loader=_UniqueKeyLoader)  # noqa: S506 (a SafeLoader)
    except (OSError, UnicodeDecodeError) as exc:
        ctx.fail(None, f"cannot read the scene file: {getattr(exc, 'strerror', None) or exc}")
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        at = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc)
        ctx.fail(None, f"invalid YAML{at}: {problem}")


def load_scene(path, width=None, height=None, spp=None) -> Scene:
    """Read and validate the YAML scene at ``path``; ``width``, ``height``, ``spp`` override its image settings.

    Raises SceneError (file, key path, what was expected) on the first problem found.
    """
    ctx = _Context(path)
    data = _read_yaml(ctx)
    if not isinstance(data, dict):
        ctx.fail(None, f"expected a mapping of sections (image, camera, media, ...) at the top level, "
                       f"got {_describe(data)}")
    top = _Node(ctx, "", data, ("image", "camera", "background", "ambient", "lights", "media", "surfaces",
                                "render", "output"))
    render = _render(top)  # first: colours depend on its colourspace
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
    return Scene(ctx.file, image, camera, background, ambient, lights, media, surfaces, render, _output(top))
