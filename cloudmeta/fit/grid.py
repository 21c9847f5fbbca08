"""Voxel clouds in: one record (``VoxelGrid``) for every reader, and ``read_grid``, which picks the reader
by the file's suffix.

A grid's values are the extinction coefficient sigma_t per unit length of its box (docs/model.md), unless
a conversion says otherwise:

    conversion                  sigma_t
    None                        the stored value
    a number f > 0              f * value
    LiquidWater(r_e, units)     3 LWC / (2 rho_w r_e), liquid water content LWC (kg m-3 or g m-3, or a
                                mixing ratio kg kg-1 times the air density), droplet effective radius r_e
                                (m), rho_w = 1000 kg m-3; the result per metre is scaled to the box's unit

Values whose stated units are an extinction (NetCDF ``units`` m-1, km-1, 1/m) are scaled to the box's length
unit; values stated as a water content need a LiquidWater conversion.

Readers: ``.npy`` / ``.npz`` (numpy_grid), ``.nc`` / ``.nc4`` / ``.cdf`` / ``.netcdf`` (netcdf, optional
extra xarray + netCDF4), ``.vdb`` (vdb; Blosc-compressed files need the optional extra blosc). Every reader
ends a bad file in one InputError line that names the file.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError

#: metres per unit of length, by the names files give them (CF / UDUNITS spellings included)
LENGTH_UNITS = {"m": 1.0, "meter": 1.0, "meters": 1.0, "metre": 1.0, "metres": 1.0,
                "km": 1000.0, "kilometer": 1000.0, "kilometers": 1000.0, "kilometre": 1000.0,
                "kilometres": 1000.0, "cm": 0.01, "mm": 0.001}
#: density of liquid water, kg m-3
RHO_WATER = 1000.0
#: kilograms per unit of mass in a liquid water content's units
_MASS = {"kg": 1.0, "g": 1e-3}
_SUFFIXES = {".npy": "numpy", ".npz": "numpy", ".nc": "netcdf", ".nc4": "netcdf", ".cdf": "netcdf",
             ".netcdf": "netcdf", ".vdb": "vdb"}


@dataclass(frozen=True)
class VoxelGrid:
    """A dense voxel cloud: ``density[i, j, k]`` is sigma_t (per unit length of the box) of the voxel centred
    at ``lower + (i + 0.5, j + 0.5, k + 0.5) * voxel``; outside the box the density is zero.

    Built by the readers; constructing one directly validates it the same way (density float64, 3D, finite,
    >= 0; a box with upper > lower on every axis). The arrays are stored read-only."""
    density: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    source: str
    variable: str
    units: str

    def __post_init__(self):
        where = f"{self.source}: {self.variable}" if self.variable else str(self.source)
        density = np.asarray(self.density)
        if density.ndim != 3:
            raise InputError(f"{where}: expected a 3D density array, got shape {density.shape}")
        if 0 in density.shape:
            raise InputError(f"{where}: the density array is empty (shape {density.shape})")
        if density.dtype.kind not in "fiub":
            raise InputError(f"{where}: expected real density values, got dtype {density.dtype}")
        density = np.ascontiguousarray(density, dtype=np.float64)
        bad = ~np.isfinite(density)
        if bad.any():
            raise InputError(f"{where}: {int(bad.sum())} density values are not finite, the first at index "
                             f"{tuple(int(v) for v in np.argwhere(bad)[0])}")
        if density.min() < 0:
            raise InputError(f"{where}: density must be >= 0, got {density.min():g} at index "
                             f"{tuple(int(v) for v in np.unravel_index(np.argmin(density), density.shape))}")
        lower, upper = (_corner(self.upper if n == "upper" else self.lower, n, where) for n in ("lower", "upper"))
        if not np.all(upper > lower):
            raise InputError(f"{where}: the box is empty: lower {lower.tolist()}, upper {upper.tolist()}")
        for name, array in (("density", density), ("lower", lower), ("upper", upper)):
            if array is getattr(self, name) and array.flags.writeable:
                array = array.copy()  # never freeze the caller's own array
            array.flags.writeable = False
            object.__setattr__(self, name, array)
        object.__setattr__(self, "source", str(self.source))
        object.__setattr__(self, "variable", str(self.variable))
        object.__setattr__(self, "units", str(self.units))

    @property
    def shape(self):
        return self.density.shape

    @property
    def voxel(self):
        """(3,) voxel size along x, y, z."""
        return (self.upper - self.lower) / np.array(self.density.shape, dtype=np.float64)

    def centres(self, axis):
        """The voxel centres along ``axis`` (0, 1, 2)."""
        n = self.density.shape[axis]
        return self.lower[axis] + (np.arange(n) + 0.5) * self.voxel[axis]


def _corner(value, name, where):
    try:
        corner = np.array(value, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise InputError(f"{where}: {name} must be 3 numbers, got {value!r}") from None
    if corner.shape != (3,) or not np.all(np.isfinite(corner)):
        raise InputError(f"{where}: {name} must be 3 finite numbers, got {np.asarray(value).tolist()!r}")
    return corner


@dataclass(frozen=True)
class LiquidWater:
    """Values are a liquid water content: sigma_t = 3 LWC / (2 rho_w r_e) (geometric optics, extinction
    efficiency 2). ``effective_radius`` r_e in metres (10e-6 for a typical cumulus); ``units`` of the values
    ("kg m-3", "g m-3", or "kg kg-1" with ``air_density`` in kg m-3), None to take them from the file's
    variable (NetCDF ``units`` attribute)."""
    effective_radius: float
    units: str | None = None
    air_density: float | None = None

    def per_metre(self, units, where):
        """The factor from a value in ``units`` (or self.units) to sigma_t in m-1."""
        r_e = self.effective_radius
        if not (isinstance(r_e, (int, float)) and math.isfinite(r_e) and 0 < r_e < 1e-2):
            raise InputError(f"{where}: effective radius must be in metres, 0 < r_e < 0.01, got {r_e!r}")
        units = self.units if self.units is not None else units
        if not units:
            raise InputError(f"{where}: the liquid water content's units are not stated: give "
                             f"LiquidWater(..., units='g m-3' or 'kg m-3' or 'kg kg-1')")
        kind = _lwc_units(units)
        if kind is None:
            raise InputError(f"{where}: unknown liquid water content units {units!r} "
                             f"(expected kg m-3, g m-3, kg kg-1 or g kg-1)")
        mass, per_volume = kind
        factor = mass
        if not per_volume:
            rho = self.air_density
            if not (isinstance(rho, (int, float)) and math.isfinite(rho) and rho > 0):
                raise InputError(f"{where}: a mixing ratio ({units}) needs LiquidWater(..., air_density=kg m-3)")
            factor *= rho
        return 3.0 * factor / (2.0 * RHO_WATER * r_e)


def _lwc_units(units):
    """(kg per unit of mass, True for per m3 / False for per kg of air), or None: for "g m-3", "g/m3",
    "g m**-3", "kg kg-1", "kg/kg", "g/kg" and the like."""
    text = units.strip().lower().replace("**", "").replace("^", "")
    m = re.fullmatch(r"(kg|g)\s*(?:/\s*(m3|kg)|\s+(m-3|kg-1))", text)
    if not m:
        return None
    denominator = m.group(2) or m.group(3)
    return _MASS[m.group(1)], denominator.startswith("m")


def parse_conversion(text):
    """A conversion from its command-line form: "" or "none" -> None; a number -> that factor;
    "lwc:R" or "lwc:R:UNITS" with R the effective radius and its unit (10um, 1e-5m) -> LiquidWater."""
    text = text.strip()
    if text.lower() in ("", "none"):
        return None
    try:
        return float(text)
    except ValueError:
        pass
    parts = text.split(":")
    if parts[0].lower() == "lwc" and len(parts) in (2, 3):
        m = re.fullmatch(r"([0-9.eE+-]+)\s*(um|µm|mm|m)", parts[1].strip())
        if m:
            try:
                # a division by an exact power of ten rounds once: 10um is exactly the double 1e-5
                radius = float(m.group(1)) / {"um": 1e6, "µm": 1e6, "mm": 1e3, "m": 1.0}[m.group(2)]
            except ValueError:
                radius = None
            if radius is not None:
                return LiquidWater(radius, parts[2] if len(parts) == 3 else None)
    raise InputError(f"conversion: expected a number or lwc:RADIUS[:UNITS] (e.g. lwc:10um:g m-3), got {text!r}")


def length_scale(units):
    """Metres per unit of ``units`` ("m", "km", ...), or None where unknown."""
    return LENGTH_UNITS.get(units.strip().lower()) if units else None


def extinction(values, conversion, *, value_units, length_units, where):
    """sigma_t per ``length_units`` from stored values (see the module's table). Without a conversion, values
    whose stated units are an extinction (m-1, 1/km, ...) are scaled to the box's unit, and values stated as a
    water content are refused; a conversion that the units leave undefined is refused."""
    if conversion is None:
        if not value_units:
            return values
        if _lwc_units(value_units) is not None:
            raise InputError(f"{where}: values are {value_units!r}, a water content, not an extinction: give "
                             f"conversion=LiquidWater(effective_radius=...) (sigma_t = 3 LWC / (2 rho_w r_e))")
        m = re.fullmatch(r"(?:1\s*/\s*(\w+)|(\w+)\s*(?:\*\*|\^)?\s*-1)", value_units.strip())
        per = length_scale(m.group(1) or m.group(2)) if m else None
        if per is None:
            return values
        box = length_scale(length_units)
        if box is None:
            raise InputError(f"{where}: values are per {m.group(1) or m.group(2)} but the box's length unit is "
                             f"{'unknown' if not length_units else repr(length_units)}: state it (m, km)")
        return values * (box / per)
    if isinstance(conversion, LiquidWater):
        per_metre = conversion.per_metre(value_units, where)
        scale = length_scale(length_units)
        if scale is None:
            raise InputError(f"{where}: a liquid water conversion gives sigma_t per metre, but the box's length "
                             f"unit is {'unknown' if not length_units else repr(length_units)}: state it (m, km)")
        return values * (per_metre * scale)
    if isinstance(conversion, (int, float)) and not isinstance(conversion, bool):
        if not (math.isfinite(conversion) and conversion > 0):
            raise InputError(f"{where}: conversion factor must be finite and > 0, got {conversion!r}")
        return values * float(conversion)
    raise InputError(f"{where}: conversion must be None, a factor or LiquidWater(...), got {conversion!r}")


def parse_box(box, where):
    """(lower, upper, units) from a box argument: ((x0, y0, z0), (x1, y1, z1)) or a mapping with keys
    lower, upper and optionally units."""
    units = ""
    if isinstance(box, dict):
        unknown = set(box) - {"lower", "upper", "units"}
        if unknown or not {"lower", "upper"} <= set(box):
            raise InputError(f"{where}: box: expected keys lower, upper (units optional), got {sorted(box)}")
        lower, upper, units = box["lower"], box["upper"], box.get("units", "") or ""
        if not isinstance(units, str):
            raise InputError(f"{where}: box.units must be a string, got {units!r}")
    else:
        try:
            pair = np.array(box, dtype=np.float64)
        except (TypeError, ValueError):
            raise InputError(f"{where}: box must be ((x0, y0, z0), (x1, y1, z1)), got {box!r}") from None
        if pair.shape != (2, 3):
            raise InputError(f"{where}: box must be ((x0, y0, z0), (x1, y1, z1)), got shape {pair.shape}")
        lower, upper = pair
    return _corner(lower, "box lower", where), _corner(upper, "box upper", where), units


def read_grid(path, *, variable=None, time=None, box=None, conversion=None):
    """The VoxelGrid in ``path``, read by its suffix (.npy, .npz, .nc/.nc4/.cdf/.netcdf, .vdb).

    variable   the array / NetCDF variable / VDB grid name (None: the file's only candidate, or "density")
    time       NetCDF only: the index along the time dimension (None: a time dimension of length 1)
    box        the grid's box where the file has none: ((x0, y0, z0), (x1, y1, z1)) or
               {"lower": ..., "upper": ..., "units": "m"} (.npy, .npz, a NetCDF variable without
               coordinates; a .vdb's transform gives its own)
    conversion None (values are sigma_t), a factor, or LiquidWater(...) (module docstring)

    Each reader returns the raw values and box ({"values", "lower", "upper", "units", "variable",
    "value_units"}); the conversion and the checks are made here, once for every format.
    """
    path = Path(path)
    kind = _SUFFIXES.get(path.suffix.lower())
    if kind is None:
        raise InputError(f"{path}: unknown voxel file type {path.suffix!r} (expected one of "
                         f"{', '.join(sorted(_SUFFIXES))})")
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    given = parse_box(box, str(path)) if box is not None else None
    if kind == "numpy":
        from .numpy_grid import read_numpy as read
    elif kind == "netcdf":
        from .netcdf import read_netcdf as read
    else:
        from .vdb import read_vdb as read
    raw = read(path, variable=variable, time=time, box=given)
    where = f"{path}: {raw['variable']}"
    values = extinction(raw["values"], conversion, value_units=raw["value_units"], length_units=raw["units"],
                        where=where)
    return VoxelGrid(values, raw["lower"], raw["upper"], str(path), raw["variable"], raw["units"])
