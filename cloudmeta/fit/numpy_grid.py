"""numpy voxel clouds: a 3D array in ``.npy`` (its box given, or in a sidecar NAME.box.json beside it) or in
``.npz`` (keys ``density``, ``lower``, ``upper`` and optionally ``units``; another array by ``variable``).

    sidecar NAME.box.json   {"lower": [x0, y0, z0], "upper": [x1, y1, z1], "units": "m"}

Arrays are loaded without pickle; index [i, j, k] is x, y, z (grid.VoxelGrid).
"""
from __future__ import annotations

import json
import zipfile
from pathlib import Path

import numpy as np

from ..errors import InputError


def sidecar(path):
    """The box sidecar of a .npy file: NAME.box.json beside NAME.npy."""
    path = Path(path)
    return path.with_name(path.stem + ".box.json")


def read_numpy(path, *, variable=None, time=None, box=None):
    """The raw grid (grid.read_grid's record) of a .npy or .npz file; ``box`` (lower, upper, units) or None."""
    path = Path(path)
    if time is not None:
        raise InputError(f"{path}: a time index applies to NetCDF files only")
    if path.suffix.lower() == ".npy":
        if variable is not None:
            raise InputError(f"{path}: a .npy file holds one array: no variable to choose ({variable!r})")
        values = _load(path, lambda: np.load(path, allow_pickle=False))
        name = "density"
        side = sidecar(path)
        if box is None:
            if not side.is_file():
                raise InputError(f"{path}: no box: give box=((x0, y0, z0), (x1, y1, z1)) or write {side.name} "
                                 f'beside it ({{"lower": [...], "upper": [...], "units": "m"}})')
            lower, upper, units = _sidecar_box(side)
    else:
        name = variable or "density"
        arrays = _load(path, lambda: _npz(path))
        if name not in arrays:
            raise InputError(f"{path}: no array {name!r} (arrays: {', '.join(sorted(arrays)) or 'none'})")
        values = arrays[name]
        if box is None:
            missing = [k for k in ("lower", "upper") if k not in arrays]
            if missing:
                raise InputError(f"{path}: no {' and '.join(missing)} array: store the box beside {name!r} or "
                                 f"give box=((x0, y0, z0), (x1, y1, z1))")
            units = arrays.get("units", np.array(""))
            if units.ndim != 0 or units.dtype.kind not in "US":
                raise InputError(f"{path}: units must be a string, got an array of {units.dtype}, shape "
                                 f"{units.shape}")
            units = str(units.item() if units.dtype.kind == "U" else units.item().decode(errors="replace"))
            lower, upper = arrays["lower"], arrays["upper"]
    if box is not None:
        lower, upper, units = box
    if values.dtype.kind not in "fiu":
        raise InputError(f"{path}: {name}: expected real density values, got dtype {values.dtype}")
    return {"values": np.asarray(values, dtype=np.float64), "lower": lower, "upper": upper, "units": units,
            "variable": name, "value_units": ""}


def _sidecar_box(side):
    """(lower, upper, units) of a NAME.box.json (checked as numbers in grid.VoxelGrid)."""
    try:
        stored = json.loads(side.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"{side}: not a readable JSON box ({_one_line(exc)})") from None
    if not isinstance(stored, dict) or not {"lower", "upper"} <= set(stored) or set(stored) - {"lower", "upper",
                                                                                              "units"}:
        raise InputError(f"{side}: expected {{\"lower\": [x0, y0, z0], \"upper\": [x1, y1, z1], \"units\": \"m\"}}")
    units = stored.get("units", "")
    if not isinstance(units, str):
        raise InputError(f"{side}: units must be a string, got {units!r}")
    return stored["lower"], stored["upper"], units


def _npz(path):
    with np.load(path, allow_pickle=False) as npz:
        return {key: npz[key] for key in npz.files}


def _load(path, load):
    """load(), its failures on a bad or truncated file as one InputError line."""
    try:
        return load()
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, KeyError) as exc:
        raise InputError(f"{path}: not a readable numpy file ({_one_line(exc)})") from None


def _one_line(exc):
    text = " ".join(str(exc).split())
    return text if len(text) <= 200 else text[:197] + "..."
