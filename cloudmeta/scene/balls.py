"""Balls of a medium or surface: inline lists and CSV balls files, read into one Blob (docs/model.md §1, §9);
errors name the ball's key path or the file's line."""
from __future__ import annotations

import array
import io
import math
import re

import numpy as np

from ..errors import InputError
from . import limits as lim
from .blob import Blob
from .document import Node, fmt_numbers, open_regular, short_repr
from .vocabulary import CSV_HEADERS, FALLOFFS

_RADIUS = dict(check=lambda v: lim.LENGTH_RANGE[0] <= v <= lim.LENGTH_RANGE[1],
               expect=f"a finite number > 0, from {lim.LENGTH_RANGE[0]:g} to {lim.LENGTH_RANGE[1]:g}")
_RADII = dict(check=lambda v: np.all((v >= lim.LENGTH_RANGE[0]) & (v <= lim.LENGTH_RANGE[1])),
              expect=f"a list of 3 finite numbers > 0, from {lim.LENGTH_RANGE[0]:g} to {lim.LENGTH_RANGE[1]:g}")
_ROTATION = dict(check=lambda v: np.all(np.abs(v) <= 1e6), expect="a list of 3 angles in degrees within +-1e6")
#: a decimal number as a balls_file writes it; Python's float also reads "1_0", "infinity" and other digits
_DECIMAL = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")



def balls_inline(n):
    """centers, radii (N, 3), rotations (N, 3) degrees, weights of the ``balls`` list; records where each
    ball was given (``ctx.ball_sources``, read by _check_domain)."""
    items = n.items("balls")
    if len(items) > lim.MAX_BALLS:
        n.fail("balls", f"expected at most {lim.MAX_BALLS} balls (README: Limits), got {len(items)}")
    rows, radius_key = [], []
    for path, raw in items:
        b = Node(n.ctx, path, raw, ("center", "radius", "radii", "rotation", "weight"))
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



def _csv_lines(n, key, csv_path):
    """(line number, text) of the balls file, read in bounded lines; decoding and size errors name the line."""
    raw = open_regular(n.ctx, n.key(key), csv_path, "balls file", lim.MAX_BALLS_FILE_BYTES)
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


def balls_csv(n):
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
                n.fail(key, f"{where}: expected finite numbers, {name} is {short_repr(cell[:40])}")
            if name in ("x", "y", "z") and abs(value) > hi:
                n.fail(key, f"{where}: expected coordinates within +-{hi:g}, {name} is {cell[:40]}")
            row.append(value)
        ellipsoid = CSV_HEADERS[header]
        if not ellipsoid:
            x, y, z, r, w = row
            row = [x, y, z, r, r, r, 0.0, 0.0, 0.0, w]
        if min(row[3:6]) <= 0 or not (lo <= min(row[3:6]) and max(row[3:6]) <= hi):
            # the text as written: 1e-400 is a number > 0 that double precision rounds to 0
            names = ("rx", "ry", "rz") if ellipsoid else ("radius",)
            written = ", ".join(f"{k} {cells[header.index(k)][:40]}" for k in names)
            expect = "radii > 0" if min(row[3:6]) <= 0 else f"radii from {lo:g} to {hi:g}"
            n.fail(key, f"{where}: expected {expect}, got {written}")
        if max(abs(a) for a in row[6:9]) > 1e6:
            n.fail(key, f"{where}: expected angles in degrees within +-1e6, got {fmt_numbers(row[6:9])}")
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


def read_blob(n, what):
    """The Blob of a medium or surface mapping ``n``: kernel, threshold, blobbiness, balls or balls_file."""
    kernel = n.choice("kernel", tuple(FALLOFFS), "wyvill6")
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
    balls, locate = balls_inline(n) if key == "balls" else balls_csv(n)
    if len(balls) == 0:
        n.fail(key, f"a {what} needs at least one ball, got none")
    heavy = np.flatnonzero(np.abs(balls[:, 9]) > lim.MAX_WEIGHT * threshold)
    if len(heavy):
        i = int(heavy[0])
        key_path, prefix = locate(i, "weight")
        n.ctx.fail(key_path, f"{prefix}expected a weight with |weight| <= {lim.MAX_WEIGHT:g} x threshold "
                             f"({lim.MAX_WEIGHT * threshold:g}; README: Limits), got {balls[i, 9]:g}")
    n_given = len(balls)
    balls, first = merge_identical(balls)
    n.ctx.merged_balls += n_given - len(balls)
    given_locate = locate

    def locate(i, field):  # a merged ball is reported where it was first given
        return given_locate(int(first[i]), field)
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


def merge_identical(balls):
    """(balls, first): the (N, 10) rows [centre, radii, rotation, weight] with every set of balls that share
    centre, radii and rotation exactly made one ball whose weight is their sum (the field is sum q_i k(u_i),
    and identical balls have identical u_i: the same field, to rounding of the sum), in the order of first
    appearance; first[j] is the row of the input where merged ball j first appears. Without duplicates the
    input comes back as it is."""
    keys = np.ascontiguousarray(balls[:, :9])
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    if len(first) == len(balls):
        return balls, np.arange(len(balls))
    inverse = inverse.reshape(-1)
    order = np.argsort(first, kind="stable")  # unique rows in order of first appearance
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    merged = balls[first[order]].copy()
    weights = np.zeros(len(order))
    np.add.at(weights, rank[inverse], balls[:, 9])  # summed in input order: deterministic
    merged[:, 9] = weights
    return merged, first[order]
