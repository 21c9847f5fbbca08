"""Write a fitted cloud: a scene (YAML) and its balls file (CSV) beside it, both or neither (atomic), with
the fit's errors in the scene's comments (docs/fit.md)."""
from __future__ import annotations

import math
import os

import numpy as np

from ..errors import InputError, OutputError

MARK = "# Written by cloudmeta fit"
COLUMNS = ("x", "y", "z", "radius", "weight")
#: the threshold of weights whose largest is 1: just above 10^-6, the least the loader accepts (|q| <= 10^6 T,
#: docs/model.md §13), so that the density is the sum of the ball fields wherever it exceeds 10^-6 of a ball's
THRESHOLD = 1.000001e-6


def _fmt(v):
    text = f"{float(v):.6g}"
    return text if any(ch in text for ch in ".en") else text + ".0"


def _vec(v):
    return "[" + ", ".join(_fmt(x) for x in v) + "]"


def normalised(result):
    """(centres, radii, weights / largest, scale = largest weight, threshold): the balls as written, each
    value rounded to the 7 significant digits of the balls file, so that errors computed from them are the
    errors of the file."""
    q = np.asarray(result.weights, dtype=float)
    scale = float(q.max())
    rows = np.column_stack([result.centers, result.radii, q / scale])
    rows = np.char.mod("%.7g", rows).astype(float)
    scale = float(f"{scale:.7g}")
    threshold = THRESHOLD  # the largest weight is 1
    return rows[:, :3], rows[:, 3], rows[:, 4], scale, threshold


def csv_text(rows, head):
    body = "\n".join(",".join("%.7g" % x for x in r) for r in rows.tolist())
    return f"{head}\n{','.join(COLUMNS)}\n{body}\n"


def scene_text(result, csv_name, scale, threshold, errors, command=None, yaml_label=None, name="fitted"):
    """The YAML of a scene for the fitted medium: the balls in ``csv_name``, density mode `field` (sigma_t =
    scale x F, the sum of the ball fields), a camera in front (-y) framing the grid's box, the sun."""
    lo, hi = np.asarray(result.lower, float), np.asarray(result.upper, float)
    c = 0.5 * (lo + hi)
    size = hi - lo
    fov = 30.0
    dist = 0.5 * max(size[0], size[2]) / (0.7 * math.tan(math.radians(fov) / 2)) + 0.5 * size[1]
    position = [c[0], c[1] - dist, c[2]]
    src = f" to {result.source}" + (f" ({result.variable})" if result.variable else "") if result.source else ""
    lines = [f"{MARK}: {len(result):,} balls fitted{src}; box {_vec(lo)} to {_vec(hi)} (docs/fit.md).",
             f"# Command: {command}" if command else "# Command: cloudmeta.fit_volume",
             f"# Fit error: density relative L2 error on the grid {errors['density']:.4g}; optical-depth relative "
             f"RMSE {errors['depth']:.4g} along {errors['rays']:,} random rays (reference: the grid's trilinear "
             f"interpolant, {errors['samples']} samples per voxel width); fit {result.seconds:.1f} s wall, "
             f"{result.cpu_seconds:.1f} s CPU.",
             "# Density: mode field, sigma_t = scale x (sum of the ball fields); the threshold is the least the "
             "loader accepts (docs/model.md §13).",
             f"# Render: cloudmeta render {yaml_label or 'SCENE.yaml'}",
             "image: {width: 512, height: 512, spp: 1}",
             f"camera: {{position: {_vec(position)}, look_at: {_vec(c)}, up: [0, 0, 1], fov: {_fmt(fov)}}}",
             "background: sky",
             "lights:",
             "  - {type: sun, elevation: 35.0, azimuth: 125.0}",
             "media:",
             f"  - name: {name}",
             "    kernel: wyvill6",
             f"    threshold: {threshold:.7g}",
             f"    density: {{mode: field, scale: {scale:.7g}}}",
             "    albedo: 1.0",
             "    phase: {type: hg, g: 0.8}",
             f"    balls_file: {csv_name}",
             "render: {quality: default, scattering: approximate}",
             f"output: {{path: {os.path.splitext(csv_name)[0]}.exr, png: {os.path.splitext(csv_name)[0]}.png}}", ""]
    return "\n".join(lines)


def _check_target(path, label, ext, overwrite):
    from ..api.io import check_replaceable
    return check_replaceable(path, ext, label, overwrite, MARK, "cloudmeta fit", how="--overwrite")


def check_paths(yaml_path, overwrite=False, inputs=()):
    """(scene, balls file) absolute paths where ``write_fit`` would write, checked before any work: the scene
    ends in .yaml or .yml, the balls file is the same name with .csv; an existing file only with
    ``overwrite`` and only one that cloudmeta fit wrote; neither may be one of ``inputs`` (the grid)."""
    from ..api.io import same_file
    yaml_path = os.fspath(yaml_path)
    ext = os.path.splitext(yaml_path)[1]
    if ext.lower() not in (".yaml", ".yml"):
        raise OutputError(f"-o {yaml_path or repr(yaml_path)}: expected a name ending in .yaml or .yml")
    csv_path = os.path.splitext(yaml_path)[0] + ".csv"
    y_full = _check_target(yaml_path, "-o", ext.lower(), overwrite)
    c_full = _check_target(csv_path, "balls file", ".csv", overwrite)
    for src in inputs:
        for label, full in (("-o", y_full), ("balls file", c_full)):
            if same_file(full, src):
                raise OutputError(f"{label} {full}: is the grid being fitted; refusing to overwrite it")
    return y_full, c_full


def write_fit(result, yaml_path, errors, overwrite=False, command=None, inputs=()):
    """Write the scene ``yaml_path`` and its balls file (same name, .csv) for a FitResult; ``errors`` is
    {'density', 'depth', 'rays', 'samples'}. Both files go to temporary names and are renamed into place
    together (cloudmeta.api.io.write_texts). Returns (yaml path, csv path), absolute."""
    from ..api.io import write_texts
    if len(result) == 0:
        raise InputError("fit: no balls to write")
    y_full, c_full = check_paths(yaml_path, overwrite, inputs)
    centers, radii, weights, scale, threshold = normalised(result)
    head = f"{MARK}: {len(result):,} balls" + (f"; {command}" if command else "")
    csv_body = csv_text(np.column_stack([centers, radii, weights]), head)
    yaml_body = scene_text(result, os.path.basename(c_full), scale, threshold, errors, command,
                           os.fspath(yaml_path))
    write_texts([(y_full, yaml_body), (c_full, csv_body)])
    return y_full, c_full
