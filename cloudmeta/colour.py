"""Colour: every conversion goes through colour-science (MODEL.md §7).

Colours in cloudmeta are linear RGB in a *working colourspace* (default ITU-R BT.709 primaries, D65 white).
A scene colour is written as ``[r, g, b]``, ``{temperature: K}`` (a blackbody) or ``{illuminant: D65}``;
spectral colours are normalised to luminance Y = 1 and converted to RGB without chromatic adaptation, so
that the illuminant matching the colourspace's white (D65 for BT.709) comes out as (1, 1, 1).

Encoding (exposure, sRGB transfer function, clipping) happens only here, when a display image is made.
"""
from __future__ import annotations

import functools

import colour
import numpy as np
from colour.colorimetry import reshape_msds, reshape_sd

from .errors import InputError

#: the working colourspace when a scene names none: linear BT.709 primaries with a D65 white
DEFAULT_COLOURSPACE = "ITU-R BT.709"
#: blackbody temperatures accepted by ``{temperature: K}``, in kelvin
TEMPERATURE_RANGE = (1000.0, 40000.0)
#: what a display preview is encoded for (the PNG)
_DISPLAY_COLOURSPACE = "sRGB"
_COLOUR_FORMS = "[r, g, b] (finite numbers >= 0), {temperature: K} or {illuminant: NAME}"


def working_colourspace(name=DEFAULT_COLOURSPACE):
    """The ``colour.RGB_Colourspace`` called ``name`` (an RGB_Colourspace is returned as is)."""
    if isinstance(name, colour.RGB_Colourspace):
        return name
    if not isinstance(name, str) or name not in colour.RGB_COLOURSPACES:
        raise InputError(f"colourspace: expected the name of a colour-science RGB colourspace such as "
                         f"{DEFAULT_COLOURSPACE!r} or 'ACEScg', got {name!r}")
    return colour.RGB_COLOURSPACES[name]


_CMFS = "CIE 1931 2 Degree Standard Observer"


def _xyz_unit_luminance(sd):
    """XYZ of an emission spectrum, scaled to Y = 1.

    Spectrum, CMFs and the equal-energy illuminant of an emission are put on colour-science's default
    wavelengths first: the same numbers as its defaults give, without its shape-alignment warnings.
    """
    shape = colour.SPECTRAL_SHAPE_DEFAULT
    cmfs = reshape_msds(colour.MSDS_CMFS[_CMFS], shape)
    xyz = colour.sd_to_XYZ(reshape_sd(sd, shape), cmfs, colour.sd_ones(shape))
    return tuple(xyz / xyz[1])


@functools.lru_cache(maxsize=256)
def _xyz_blackbody(kelvin: float) -> tuple:
    """XYZ of a blackbody with Y = 1 (colour-science integration is slow, hence the cache)."""
    return _xyz_unit_luminance(colour.sd_blackbody(kelvin))


@functools.lru_cache(maxsize=64)
def _xyz_illuminant(name: str) -> tuple:
    """XYZ of a CIE illuminant's spectrum with Y = 1."""
    return _xyz_unit_luminance(colour.SDS_ILLUMINANTS[name])


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
    cs = working_colourspace(colourspace)
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
        if not isinstance(arg, str) or arg not in colour.SDS_ILLUMINANTS:
            _fail(f"{where}.illuminant", f"expected an illuminant of colour.SDS_ILLUMINANTS such as D65, A, "
                                         f"D50 or FL2, got {arg!r}")
        xyz = _xyz_illuminant(arg)
    rgb = cs.matrix_XYZ_to_RGB @ np.array(xyz)
    return np.maximum(rgb, 0.0)


def chromaticities(colourspace=DEFAULT_COLOURSPACE):
    """The 8 floats red x, y, green x, y, blue x, y, white x, y of ``colourspace`` (the EXR attribute)."""
    cs = working_colourspace(colourspace)
    return tuple(float(v) for v in np.concatenate([np.ravel(cs.primaries), np.ravel(cs.whitepoint)]))


def encode_srgb(linear_rgb, exposure=0.0, colourspace=DEFAULT_COLOURSPACE):
    """8-bit sRGB of a linear image (..., 3) in ``colourspace``: scale by 2**exposure, encode, clip, round.

    A working colourspace with other primaries than sRGB's is first converted to them (with colour-science's
    default chromatic adaptation where the whites differ); for BT.709 this step is skipped, it is the identity.
    """
    rgb = np.asarray(linear_rgb, dtype=np.float64)
    if rgb.ndim < 1 or rgb.shape[-1] != 3:
        raise InputError(f"linear_rgb: expected an array of shape (..., 3), got {rgb.shape}")
    if not np.all(np.isfinite(rgb)):
        raise InputError("linear_rgb: expected finite values, found NaN or infinity")
    if not (_is_number(exposure) and np.isfinite(exposure)):
        raise InputError(f"exposure: expected a finite number (stops), got {exposure!r}")
    cs = working_colourspace(colourspace)
    display = colour.RGB_COLOURSPACES[_DISPLAY_COLOURSPACE]
    if not (np.allclose(cs.primaries, display.primaries, atol=1e-9)
            and np.allclose(cs.whitepoint, display.whitepoint, atol=1e-9)):
        rgb = colour.RGB_to_RGB(rgb, cs, display)
    encoded = colour.cctf_encoding(rgb * 2.0 ** exposure, function="sRGB")
    return np.rint(np.clip(encoded, 0.0, 1.0) * 255.0).astype(np.uint8)
