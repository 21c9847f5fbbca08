"""NetCDF voxel clouds (large-eddy simulation output and the like), read through xarray (optional extra:
xarray and netCDF4).

One variable with three spatial dimensions and at most one time dimension (any order). Axes are told by
their coordinate's ``axis`` attribute (X, Y, Z), else by name (x*, y*, z*, height, altitude, level,
west_east, south_north, bottom_top). Coordinates are voxel centres, evenly spaced (ascending or descending),
with one length unit on all three axes (m, km); they give the box, each voxel half a spacing beyond the
first and last centre. A variable without coordinates takes ``box``. Stretched grids are refused.

The variable's ``units`` attribute goes with its values to grid.read_grid, which makes sigma_t of them.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError

_AXIS_NAMES = {"X": ("west_east",), "Y": ("south_north",),
               "Z": ("height", "altitude", "alt", "level", "lev", "bottom_top", "zu_3d")}
_TIME_NAMES = ("time", "t", "times", "time_counter")
#: relative tolerance on the evenness of a coordinate's spacing
_EVEN = 1e-4


def _xarray(path):
    try:
        import xarray
    except ImportError:
        raise InputError(f"{path}: reading NetCDF needs the optional extra fit: pip install xarray netCDF4 "
                         "(or pip install -e '.[fit]')") from None
    return xarray


def read_netcdf(path, *, variable=None, time=None, box=None):
    """The raw grid (grid.read_grid's record) of a NetCDF variable; ``box`` (lower, upper, units) or None."""
    path = Path(path)
    xr = _xarray(path)
    try:
        dataset = xr.open_dataset(path, decode_times=False, mask_and_scale=True)
    except ImportError as exc:
        raise InputError(f"{path}: reading NetCDF needs the optional extra fit: pip install xarray netCDF4 "
                         f"({_one_line(exc)})") from None
    except Exception as exc:  # the backends raise OSError, ValueError, RuntimeError... on a bad file
        raise InputError(f"{path}: not a readable NetCDF file ({_one_line(exc)})") from None
    with dataset:
        name = _variable(dataset, variable, path)
        where = f"{path}: {name}"
        data = dataset[name]
        axes, time_dim = _dimensions(dataset, data, where)
        if time_dim is not None:
            n = data.sizes[time_dim]
            if time is None:
                if n != 1:
                    raise InputError(f"{where}: {n} times along {time_dim!r}: give a time index 0..{n - 1}")
                time = 0
            if isinstance(time, bool) or not isinstance(time, (int, np.integer)) or not -n <= time < n:
                raise InputError(f"{where}: time index must be an integer in 0..{n - 1}, got {time!r}")
            data = data.isel({time_dim: int(time)})
        elif time is not None:
            raise InputError(f"{where}: no time dimension (dimensions {', '.join(map(str, data.dims))}): drop the time index")
        if data.dtype.kind not in "fiu":
            raise InputError(f"{where}: expected real values, got dtype {data.dtype}")
        try:
            values = np.asarray(data.transpose(*axes).values, dtype=np.float64)
        except Exception as exc:  # a truncated file fails here, when the data are read
            raise InputError(f"{path}: cannot read {name!r} ({_one_line(exc)})") from None
        value_units = str(data.attrs.get("units", "")).strip()
        if box is None:
            lower, upper, units, flips = _box(dataset, axes, where)
            for axis in flips:
                values = np.flip(values, axis)
        else:
            if any(a in dataset.coords for a in axes):
                raise InputError(f"{where}: the file's coordinates give the box: drop the box argument")
            lower, upper, units = box
    return {"values": values, "lower": lower, "upper": upper, "units": units, "variable": name,
            "value_units": value_units}


def _variable(dataset, variable, path):
    if variable is not None:
        if variable not in dataset.data_vars:
            raise InputError(f"{path}: no variable {variable!r} (variables: "
                             f"{', '.join(map(str, dataset.data_vars)) or 'none'})")
        return variable
    candidates = [str(v) for v, d in dataset.data_vars.items() if d.ndim in (3, 4)]
    if len(candidates) != 1:
        raise InputError(f"{path}: name the variable to read (3D or 3D + time variables: "
                         f"{', '.join(candidates) or 'none'})")
    return candidates[0]


def _axis_of(dataset, dim):
    coord = dataset.coords[dim] if dim in dataset.coords else None  # .get would make an index up
    if coord is not None:
        axis = str(coord.attrs.get("axis", "")).upper()
        if axis in ("X", "Y", "Z", "T"):
            return axis
        if str(coord.attrs.get("standard_name", "")).lower() == "time":
            return "T"
    low = str(dim).lower()
    if low in _TIME_NAMES:
        return "T"
    for axis, names in _AXIS_NAMES.items():
        if low in names:
            return axis
    if low[:1] in ("x", "y", "z"):
        return low[0].upper()
    return None


def _dimensions(dataset, data, where):
    """(the spatial dimensions in x, y, z order, the time dimension or None)."""
    if data.ndim not in (3, 4):
        raise InputError(f"{where}: expected 3 spatial dimensions and at most one time, got {data.dims}")
    by_axis = {}
    for dim in data.dims:
        axis = _axis_of(dataset, dim)
        if axis is None:
            raise InputError(f"{where}: cannot tell which axis dimension {dim!r} is (give its coordinate an "
                             "axis attribute X, Y, Z or T)")
        if axis in by_axis:
            raise InputError(f"{where}: dimensions {by_axis[axis]!r} and {dim!r} are both axis {axis}")
        by_axis[axis] = str(dim)
    missing = [a for a in "XYZ" if a not in by_axis]
    if missing:
        raise InputError(f"{where}: no {' or '.join(missing)} dimension among {data.dims}")
    return [by_axis[a] for a in "XYZ"], by_axis.get("T")


def _box(dataset, axes, where):
    """(lower, upper, units, the axes whose coordinates descend) from the coordinates of ``axes``."""
    lower, upper, units, flips = np.zeros(3), np.zeros(3), [], []
    for a, dim in enumerate(axes):
        coord = dataset.coords[dim] if dim in dataset.coords else None  # .get would make an index up
        if coord is None:
            raise InputError(f"{where}: dimension {dim!r} has no coordinate: give box=((x0, y0, z0), (x1, y1, z1))")
        c = np.asarray(coord.values, dtype=np.float64)
        if c.ndim != 1 or not np.all(np.isfinite(c)):
            raise InputError(f"{where}: coordinate {dim!r} must be 1D and finite")
        if c.size == 1:
            raise InputError(f"{where}: coordinate {dim!r} has one value: no spacing; give box=...")
        step = np.diff(c)
        d = (c[-1] - c[0]) / (c.size - 1)
        if d == 0 or np.max(np.abs(step - d)) > _EVEN * abs(d):
            raise InputError(f"{where}: coordinate {dim!r} is not evenly spaced (steps {step.min():g} to "
                             f"{step.max():g}): resample the variable onto an even grid first")
        if d < 0:
            flips.append(a)
        lo, hi = min(c[0], c[-1]), max(c[0], c[-1])
        lower[a], upper[a] = lo - abs(d) / 2, hi + abs(d) / 2
        units.append(str(coord.attrs.get("units", "")).strip())
    if len(set(units)) != 1:
        raise InputError(f"{where}: coordinates {', '.join(axes)} have units {units}: expected one length unit")
    return lower, upper, units[0], flips


def _one_line(exc):
    text = " ".join(str(exc).split())
    return text if len(text) <= 200 else text[:197] + "..."

