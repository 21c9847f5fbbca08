"""Colour: every conversion goes through colour-science (docs/model.md §7).

Colours in cloudmeta are linear RGB in a *working colourspace* (default ITU-R BT.709 primaries, D65 white).
A scene colour is written as ``[r, g, b]``, ``{temperature: K}`` (a blackbody) or ``{illuminant: D65}``;
spectral colours are normalised to luminance Y = 1 and converted to RGB without chromatic adaptation, so
that the illuminant matching the colourspace's white (D65 for BT.709) comes out as (1, 1, 1).

Encoding (exposure, sRGB transfer function, clipping) happens only here, when a display image is made.

Start-up: importing colour-science takes longer than the rest of a small render (it imports scipy, and
matplotlib for its plotting module), so it is imported on first use only, with ``colour.plotting``
deferred until something reads from it. The few numbers a render asks of it (a colourspace's primaries,
white point and XYZ -> RGB matrix; the XYZ of a blackbody or illuminant) are kept, as colour-science
computed them, in a small JSON file beside the kernel cache (``$CLOUDMETA_CACHE_DIR`` or
``~/.cache/cloudmeta``; ``CLOUDMETA_NO_CACHE=1`` turns it off), one file per colour-science installation:
a later process reads them back bit for bit without importing colour-science. The 8-bit sRGB encoding
of a PNG preview is a look-up in the thresholds of colour-science's encoding, stored the same way.
"""
from __future__ import annotations

import functools
import hashlib
import importlib
import importlib.util
import json
import os
import sys
import tempfile
import types
from pathlib import Path

import numpy as np

from ..errors import InputError

#: the working colourspace when a scene names none: linear BT.709 primaries with a D65 white
DEFAULT_COLOURSPACE = "ITU-R BT.709"
#: blackbody temperatures accepted by ``{temperature: K}``, in kelvin
TEMPERATURE_RANGE = (1000.0, 40000.0)
#: what a display preview is encoded for (the PNG)
_DISPLAY_COLOURSPACE = "sRGB"
_COLOUR_FORMS = "[r, g, b] (finite numbers >= 0), {temperature: K} or {illuminant: NAME}"
_CMFS = "CIE 1931 2 Degree Standard Observer"


class _Deferred(types.ModuleType):
    """Stands in for a module in ``sys.modules`` until one of its attributes is read, then imports it."""

    def __getattr__(self, attr):
        real = sys.modules.get(self.__name__)
        if real is self or real is None:
            del sys.modules[self.__name__]
            real = importlib.import_module(self.__name__)
        return getattr(real, attr)


def _colour():
    """The colour-science package, imported here on first use. Its ``__init__`` imports ``colour.plotting``
    and with it matplotlib, which nothing in a render uses: a stand-in takes its place in ``sys.modules``
    and imports the real module when an attribute of it is first read."""
    module = sys.modules.get("colour")
    if module is None:
        if "colour.plotting" not in sys.modules:
            stand_in = _Deferred("colour.plotting")
            stand_in.__spec__ = None  # the import system reads it: a module that is not being initialised
            sys.modules["colour.plotting"] = stand_in
        try:
            import colour as module
        except BaseException:
            if isinstance(sys.modules.get("colour.plotting"), _Deferred):
                del sys.modules["colour.plotting"]
            raise
    return module


def _store_path():
    """The JSON file of colour-science's numbers for this installation of it, or None (no cache)."""
    if os.environ.get("CLOUDMETA_NO_CACHE", "") != "":
        return None
    spec = importlib.util.find_spec("colour")
    if spec is None or spec.origin is None:
        return None
    stat = os.stat(spec.origin)
    key = hashlib.sha1(f"{spec.origin}:{stat.st_size}:{stat.st_mtime_ns}".encode()).hexdigest()[:16]
    base = Path(os.environ.get("CLOUDMETA_CACHE_DIR", Path.home() / ".cache" / "cloudmeta"))
    return base / f"colour-{key}.json"


_STORE = None


def _values():
    """The store's values, read from its file on first use."""
    global _STORE
    if _STORE is None:
        path = _store_path()
        _STORE = {"path": path, "values": {}}
        if path is not None:
            try:
                _STORE["values"] = json.loads(path.read_text())
            except (OSError, ValueError):
                pass  # none yet, or unreadable: computed again and rewritten
    return _STORE["values"]


def _write_store(path, values):
    """The whole store, written to a temporary file in its folder and renamed into place."""
    tmp = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=path.name, suffix=".tmp", dir=path.parent)
        with os.fdopen(fd, "w") as f:
            json.dump(values, f)
        os.replace(tmp, path)
    except OSError:
        if tmp is not None and os.path.exists(tmp):
            os.unlink(tmp)
        # nowhere to write: the next process asks colour-science again


def _stored(key, compute):
    """``compute()`` (a JSON value: lists of floats round-trip exactly), kept in the store under ``key``.
    What other processes stored since this one read the file is merged in before the write (the numbers
    are colour-science's, the same in every process), so that processes side by side (a parallel test
    run, Dask workers) do not drop each other's entries."""
    values = _values()
    if key not in values:
        values[key] = compute()
        path = _STORE["path"]
        if path is not None:
            try:
                on_disk = json.loads(path.read_text())
            except (OSError, ValueError):
                on_disk = {}
            if isinstance(on_disk, dict):
                for k, v in on_disk.items():
                    values.setdefault(k, v)
            _write_store(path, values)
    return values[key]


def working_colourspace(name=DEFAULT_COLOURSPACE):
    """The ``colour.RGB_Colourspace`` called ``name`` (an RGB_Colourspace is returned as is)."""
    colour = _colour()
    if isinstance(name, colour.RGB_Colourspace):
        return name
    if not isinstance(name, str) or name not in colour.RGB_COLOURSPACES:
        raise InputError(f"colourspace: expected the name of a colour-science RGB colourspace such as "
                         f"{DEFAULT_COLOURSPACE!r} or 'ACEScg', got {name!r}")
    return colour.RGB_COLOURSPACES[name]


def _space(name):
    """A colourspace's canonical name, primaries, white point and XYZ -> RGB matrix as colour-science
    gives them (through the store); an RGB_Colourspace object is read directly."""
    def compute(cs=None):
        cs = cs or working_colourspace(name)
        return dict(name=cs.name, primaries=np.ravel(cs.primaries).tolist(),
                    whitepoint=np.ravel(cs.whitepoint).tolist(), XYZ_to_RGB=np.ravel(cs.matrix_XYZ_to_RGB).tolist())

    if not isinstance(name, str):
        return compute(working_colourspace(name))
    return _stored(f"colourspace:{name}", compute)


def colourspace_name(name=DEFAULT_COLOURSPACE):
    """The canonical spelling of a colourspace's name; InputError where colour-science has none such."""
    return _space(name)["name"]


def _xyz_unit_luminance(sd):
    """XYZ of an emission spectrum, scaled to Y = 1.

    Spectrum, CMFs and the equal-energy illuminant of an emission are put on colour-science's default
    wavelengths first: the same numbers as its defaults give, without its shape-alignment warnings.
    """
    colour = _colour()
    from colour.colorimetry import reshape_msds, reshape_sd

    shape = colour.SPECTRAL_SHAPE_DEFAULT
    cmfs = reshape_msds(colour.MSDS_CMFS[_CMFS], shape)
    xyz = colour.sd_to_XYZ(reshape_sd(sd, shape), cmfs, colour.sd_ones(shape))
    return tuple(xyz / xyz[1])


@functools.lru_cache(maxsize=256)
def _xyz_blackbody(kelvin: float) -> tuple:
    """XYZ of a blackbody with Y = 1 (colour-science integration is slow, hence the caches)."""
    return tuple(_stored(f"blackbody:{kelvin!r}",
                         lambda: [float(v) for v in _xyz_unit_luminance(_colour().sd_blackbody(kelvin))]))


@functools.lru_cache(maxsize=64)
def _xyz_illuminant(name: str) -> tuple:
    """XYZ of a CIE illuminant's spectrum with Y = 1."""
    return tuple(_stored(f"illuminant:{name}",
                         lambda: [float(v) for v in _xyz_unit_luminance(_colour().SDS_ILLUMINANTS[name])]))


def _is_illuminant(name):
    return f"illuminant:{name}" in _values() or name in _colour().SDS_ILLUMINANTS


def _is_number(x):
    # bool is an int to Python, never a number in a scene
    return isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, (bool, np.bool_))


def _fail(where, detail):
    # The message starts with the key path and ': ' so that the scene loader can put it in a SceneError.
    raise ValueError(f"{where}: {detail}")


def parse_colour(value, where="colour", colourspace=DEFAULT_COLOURSPACE):
    """Linear RGB, shape (3,) float64, in the working ``colourspace`` of a scene colour ``value``.

    ``value`` is ``[r, g, b]``, ``{temperature: K}`` or ``{illuminant: NAME}`` (a name in
    ``colour.SDS_ILLUMINANTS``). ``where`` is the key path named in errors. Spectral colours that fall
    outside the colourspace's gamut (very low temperatures) have their negative components clipped to 0:
    a negative radiance has no meaning in the renderer.

    Raises ``ValueError("<where>: expected ...")`` on bad input.
    """
    cs = _space(colourspace)  # validates the name whatever the value
    if isinstance(value, (list, tuple, np.ndarray)):
        if len(value) != 3:
            _fail(where, f"expected {_COLOUR_FORMS}, got a list of {len(value)} items")
        for i, c in enumerate(value):
            if not _is_number(c) or not np.isfinite(c) or c < 0:
                _fail(f"{where}[{i}]", f"expected a finite number >= 0, got {c!r}")
        return np.array(value, dtype=np.float64)
    if not isinstance(value, dict) or len(value) != 1 or next(iter(value)) not in ("temperature", "illuminant"):
        _fail(where, f"expected {_COLOUR_FORMS}, got {value!r}")
    (key, arg), = value.items()
    if key == "temperature":
        lo, hi = TEMPERATURE_RANGE
        if not _is_number(arg) or not lo <= arg <= hi:
            _fail(f"{where}.temperature", f"expected a temperature in kelvin in [{lo:g}, {hi:g}], got {arg!r}")
        xyz = _xyz_blackbody(float(arg))
    else:
        if not isinstance(arg, str) or not _is_illuminant(arg):
            _fail(f"{where}.illuminant", f"expected an illuminant of colour.SDS_ILLUMINANTS such as D65, A, "
                                         f"D50 or FL2, got {arg!r}")
        xyz = _xyz_illuminant(arg)
    rgb = np.array(cs["XYZ_to_RGB"]).reshape(3, 3) @ np.array(xyz)
    return np.maximum(rgb, 0.0)


def chromaticities(colourspace=DEFAULT_COLOURSPACE):
    """The 8 floats red x, y, green x, y, blue x, y, white x, y of ``colourspace`` (the EXR attribute)."""
    cs = _space(colourspace)
    return tuple(float(v) for v in cs["primaries"] + cs["whitepoint"])


def _srgb_code(values):
    """colour-science's 8-bit sRGB code of linear values: encode, clip to [0, 1], scale, round."""
    encoded = _colour().cctf_encoding(values, function="sRGB")
    return np.rint(np.clip(encoded, 0.0, 1.0) * 255.0)


def _srgb_thresholds():
    """(255,) float64: entry k - 1 is the least linear value whose 8-bit sRGB code is k or more, found by
    bisection over the float64 numbers in [0, 1] (positive floats are ordered like their bit patterns)
    on colour-science's encoding, so that a table look-up reproduces it exactly for every double."""
    def compute():
        want = np.arange(1, 256, dtype=np.float64)
        lo = np.zeros(255, np.int64)                                  # code(lo) < k
        hi = np.full(255, np.array(1.0).view(np.int64), np.int64)    # code(hi) >= k
        while np.any(hi - lo > 1):
            mid = lo + (hi - lo) // 2
            up = _srgb_code(mid.view(np.float64)) >= want
            hi = np.where(up, mid, hi)
            lo = np.where(up, lo, mid)
        return hi.view(np.float64).tolist()

    return np.array(_stored("srgb8:thresholds", compute))


def encode_srgb(linear_rgb, exposure=0.0, colourspace=DEFAULT_COLOURSPACE):
    """8-bit sRGB of a linear image (..., 3) in ``colourspace``: scale by 2**exposure, encode, clip, round.

    A working colourspace with other primaries than sRGB's is first converted to them (with colour-science's
    default chromatic adaptation where the whites differ); for BT.709 this step is skipped, it is the identity.
    The encoding itself is a look-up in the 255 code thresholds of colour-science's sRGB encoding
    (``_srgb_thresholds``, kept in the store): the same bytes, without importing colour-science.
    """
    rgb = np.asarray(linear_rgb, dtype=np.float64)
    if rgb.ndim < 1 or rgb.shape[-1] != 3:
        raise InputError(f"linear_rgb: expected an array of shape (..., 3), got {rgb.shape}")
    if not np.all(np.isfinite(rgb)):
        raise InputError("linear_rgb: expected finite values, found NaN or infinity")
    if not (_is_number(exposure) and np.isfinite(exposure)):
        raise InputError(f"exposure: expected a finite number (stops), got {exposure!r}")
    cs, display = _space(colourspace), _space(_DISPLAY_COLOURSPACE)
    if not (np.allclose(cs["primaries"], display["primaries"], atol=1e-9)
            and np.allclose(cs["whitepoint"], display["whitepoint"], atol=1e-9)):
        colour = _colour()
        rgb = colour.RGB_to_RGB(rgb, working_colourspace(colourspace), colour.RGB_COLOURSPACES[_DISPLAY_COLOURSPACE])
    return np.searchsorted(_srgb_thresholds(), rgb * 2.0 ** exposure, side="right").astype(np.uint8)
