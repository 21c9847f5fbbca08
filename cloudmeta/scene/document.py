"""The YAML document layer: safe reading of a scene file (size, nesting, aliases, duplicate keys, only
safe_load's types) and the typed getters every section reader uses (``Node``), so that every error is one
SceneError naming the file, the key path and what was expected.

Values are read through ``Node``, a mapping that knows its key path and has typed getters with defaults
(bool is never a number, numbers are finite, ``null`` is allowed only where the default is None).
"""
from __future__ import annotations

import difflib
import math
import os
import re
import reprlib
import stat

import numpy as np
import yaml

from ..errors import SceneError
from . import limits as lim
from .colour import parse_colour


def frozen_array(value):
    arr = np.array(value, dtype=np.float64)
    arr.setflags(write=False)
    return arr


def fmt_numbers(values):
    """A short text of numbers for error messages: [1, 2.5, 3e+10]."""
    return "[" + ", ".join(f"{v:.3g}" for v in np.ravel(values)) + "]"


REQUIRED = object()
#: what an unknown key may look like to be quoted in an error (scene keys are names)
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_ -]{0,39}")


_REPR = reprlib.Repr()
_REPR.maxlevel, _REPR.maxlist, _REPR.maxdict, _REPR.maxstring, _REPR.maxother = 2, 4, 3, 40, 40
_REPR.maxlong = 24


def short_repr(value, limit=80):
    """A bounded repr: a few items of a few levels, so that a huge or deeply shared value costs nothing."""
    if is_integer(value) and abs(value) >= 10 ** 20:
        return f"an integer of {len(str(abs(int(value))))} digits"
    text = _REPR.repr(value)
    return text if len(text) <= limit else text[:limit - 3] + "..."


def describe(value):
    """A value as an error message shows it: its (shortened) repr and, where it helps, its YAML type."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return f"{value} (a boolean)"
    if isinstance(value, dict):
        return f"a mapping {short_repr(value)}"
    if isinstance(value, list):
        return f"a list {short_repr(value)}"
    if isinstance(value, str):
        try:
            float(value[:64])
        except ValueError:
            return f"the text {short_repr(value)}"
        # PyYAML (YAML 1.1) reads 1e3 and 1.0e3 as text: only 1.0e+3 is a number
        return f"the text {value!r} (YAML reads an exponent without a dot and a sign as text: write 1.0e+3)"
    return short_repr(value)


def is_integer(x):
    """True for an int (numpy's too, for overrides); bool is not a number in a scene file."""
    return isinstance(x, (int, np.integer)) and not isinstance(x, (bool, np.bool_))


def is_finite_number(x):
    """True for a finite int or float (numpy's too); bool is not a number in a scene file."""
    if not (is_integer(x) or isinstance(x, (float, np.floating))):
        return False
    try:
        return math.isfinite(x)
    except OverflowError:  # an int beyond the float range
        return False


class Context:
    """The file being read: where errors point and where relative paths start."""

    def __init__(self, path):
        self.file = str(path)
        self.folder = os.path.dirname(os.path.abspath(path))
        self.inputs = [os.path.abspath(path)]  #: every file read, for the CLI's output checks
        self.ball_sources = {}  #: id(blob) -> locate(i, field) -> (key path, message prefix) of ball i
        self.merged_balls = 0  #: identical balls merged into one (cloudmeta.scene.balls.merge_identical)

    def fail(self, key_path, message):
        raise SceneError(self.file, key_path, message)

    def resolve(self, relative):
        return os.path.normpath(os.path.join(self.folder, relative))


class Node:
    """A mapping of the scene file at ``path``, read with typed getters that raise SceneError."""

    def __init__(self, ctx, path, data, allowed=None):
        self.ctx, self.path = ctx, path
        if not isinstance(data, dict):
            ctx.fail(path, f"expected a mapping, got {describe(data)}")
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
                self.fail(short_repr(k), f"expected a key that is text, got {describe(k)}; "
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
            if default is REQUIRED:
                self.fail(key, "missing required key")
            return default, False
        return value, True

    def number(self, key, default=REQUIRED, check=None, expect="a finite number"):
        value, given = self._raw(key, default)
        if given and not (is_finite_number(value) and (check is None or check(value))):
            self.fail(key, f"expected {expect}, got {describe(value)}")
        return float(value) if value is not None else None

    def integer(self, key, default=REQUIRED, check=None, expect="an integer"):
        value, given = self._raw(key, default)
        if given and not (is_integer(value) and (check is None or check(value))):
            self.fail(key, f"expected {expect}, got {describe(value)}")
        return None if value is None else int(value)

    def flag(self, key, default=REQUIRED):
        value, given = self._raw(key, default)
        if given and not isinstance(value, bool):
            self.fail(key, f"expected true or false, got {describe(value)}")
        return value

    def choice(self, key, options, default=REQUIRED):
        value, given = self._raw(key, default)
        if given and not (isinstance(value, str) and value in options):
            self.fail(key, f"expected one of {', '.join(options)}, got {describe(value)}")
        return value

    def string(self, key, default=REQUIRED):
        value, given = self._raw(key, default)
        if given and not (isinstance(value, str) and value.strip()):
            self.fail(key, f"expected a non-empty string, got {describe(value)}")
        return value

    def vector(self, key, default=REQUIRED, length=3, check=None, expect=None, bounded=True):
        """A list of ``length`` finite numbers (each within +-1e100, limits.LENGTH_RANGE) as a read-only
        float64 array."""
        value, given = self._raw(key, default)
        if not given:
            return None if value is None else frozen_array(value)
        expect = expect or f"a list of {length} finite numbers"
        if not (isinstance(value, list) and len(value) == length
                and all(is_finite_number(v) for v in value)):
            self.fail(key, f"expected {expect}, got {describe(value)}")
        if bounded and any(abs(float(v)) > lim.LENGTH_RANGE[1] for v in value):
            self.fail(key, f"expected {expect}, each within +-{lim.LENGTH_RANGE[1]:g} (README: Limits), "
                           f"got {describe(value)}")
        arr = frozen_array(value)
        if check is not None and not check(arr):
            self.fail(key, f"expected {expect}, got {describe(value)}")
        return arr

    def node(self, key, allowed, default=REQUIRED):
        """The mapping under ``key`` (an empty one when absent and optional), its keys limited to ``allowed``."""
        value, _ = self._raw(key, default)
        return Node(self.ctx, self.key(key), {} if value is None else value, allowed)

    def items(self, key):
        """[(key path, item)] of the list under ``key`` (empty when absent)."""
        value, _ = self._raw(key, None)
        if value is None:
            return []
        if not isinstance(value, list):
            self.fail(key, f"expected a list, got {describe(value)}")
        return [(f"{self.key(key)}[{i}]", item) for i, item in enumerate(value)]

    def colour(self, key, colourspace, default=REQUIRED):
        """A colour (docs/model.md §7) as linear RGB of ``colourspace``, read-only; errors keep colour's key path."""
        value, given = self._raw(key, default)
        if not given:
            return None if value is None else frozen_array(value)
        if isinstance(value, list):
            for i, c in enumerate(value):
                if is_integer(c) and not is_finite_number(c):  # an int beyond the float range
                    self.ctx.fail(f"{self.key(key)}[{i}]", f"expected a finite number >= 0, got {describe(c)}")
        try:
            rgb = parse_colour(value, self.key(key), colourspace)
        except ValueError as exc:
            # parse_colour's message is "<key path>: <what was expected>"
            key_path, _, detail = str(exc).partition(": ")
            self.ctx.fail(key_path, detail)
        if not np.max(rgb) <= lim.MAX_RADIANCE:
            self.fail(key, f"expected a colour with components <= {lim.MAX_RADIANCE:g} (README: Limits), "
                           f"got {describe(value)}")
        return frozen_array(rgb)

    def path_to(self, key):
        """An optional file path, resolved against the YAML's folder."""
        value = self.string(key, None)
        return None if value is None else self.ctx.resolve(value)



def open_regular(ctx, key_path, path, what, limit):
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


class UniqueKeyLoader(_SafeLoader):
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
                    None, None, f"duplicate key {short_repr(key)}", key_node.start_mark)
            seen.add(key)
        return super().construct_mapping(node, deep)


def read_yaml(ctx):
    f = open_regular(ctx, None, ctx.file, "scene file", lim.MAX_SCENE_BYTES)
    try:
        with f:
            text = f.read(lim.MAX_SCENE_BYTES + 1).decode("utf-8")
        if len(text) > lim.MAX_SCENE_BYTES:
            ctx.fail(None, f"the scene file is larger than {lim.MAX_SCENE_BYTES} bytes (README: Limits)")
        _check_nesting(text)
        return yaml.load(text, Loader=UniqueKeyLoader)  # noqa: S506 (a SafeLoader)
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
        ctx.fail(None, f"invalid YAML: {type(exc).__name__} {short_repr(str(exc))}")
