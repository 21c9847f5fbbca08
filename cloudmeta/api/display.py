"""The PNG's picture: white balance, exposure and a display transform (docs/display.md).

The renderer's image is scene-linear RGB of the working colourspace; the EXR keeps it so. A picture for a
screen is made here, in three steps, each of which can be turned off:

1. **white balance**: von Kries adaptation in XYZ with colour-science's CAT02 matrix, from an illuminant to
   the display's white (D65): the scene's own (``scene_illuminant``: its lights and its sky or ambient, as a
   camera balanced to the light that falls on the scene), a named CIE illuminant, or none (the working
   colourspace's white, which is the display's for BT.709);
2. **exposure**: stops, or ``auto``: the ``AUTO_PERCENTILE``-th percentile of the luminance of the pixels
   whose alpha exceeds ``AUTO_ALPHA`` (the cloud), or of the whole frame where that is brighter, is brought
   to ``AUTO_LEVEL[display]``;
3. **display**: ``aces``, the ACES output transform for an sRGB display through OpenColorIO's built-in
   config (ACES 2.0 SDR 100 nits where the installed OpenColorIO has it): a filmic tone curve that rolls
   highlights off to white instead of clipping them; or ``raw``: linear times 2^exposure, the sRGB curve,
   clipped (``cloudmeta.scene.colour.encode_srgb``; with white balance ``none`` the very bytes it gives).
"""
from __future__ import annotations

import functools

import numpy as np

from ..errors import InputError
from ..scene.colour import DEFAULT_COLOURSPACE, _colour, _space, _stored, _xyz_illuminant, encode_srgb
from ..scene.limits import MAX_EXPOSURE
from ..scene.vocabulary import AUTO_EXPOSURE, DISPLAYS, WHITE_BALANCE_WORDS

#: the exposure ``auto`` measures this percentile of the cloud's luminance ...
AUTO_PERCENTILE = 97.0
#: ... over the pixels whose alpha exceeds this (the cloud seen through little background) ...
AUTO_ALPHA = 0.5
#: ... and brings it to this scene-linear luminance: under ACES 2.0 SDR 2.0 shows as 0.82 of display white
#: (sRGB code 209), 4.0 as 0.90 and 16 as 0.97: the brightest 3 % roll off towards white, and the cloud's
#: shaded side stays on the curve's steeper part instead of its shoulder; raw clips at 1.0
AUTO_LEVEL = {"aces": 2.0, "raw": 0.8}
#: OpenColorIO's built-in configs, the first one the installed version knows is used
OCIO_CONFIGS = ("ocio://cg-config-v5.0.0_aces-v2.1_ocio-v2.6", "ocio://cg-config-v4.0.0_aces-v2.0_ocio-v2.5",
                "ocio://default")
OCIO_DISPLAY = "sRGB - Display"
#: the display transform: the first view of OCIO_DISPLAY the config has
OCIO_VIEWS = ("ACES 2.0 - SDR 100 nits (Rec.709)", "ACES 1.0 - SDR Video")
#: the colourspace of the config the linear image is handed over in (BT.709 primaries, D65 white)
OCIO_INPUT = "Linear Rec.709 (sRGB)"
#: the colour-science colourspace the display's primaries and white are read from: sRGB's, with the matrix
#: derived from them (colour-science's "sRGB" keeps the standard's rounded one, which maps D65 1e-4 off grey)
_DISPLAY_COLOURSPACE = "ITU-R BT.709"
_MISSING_OCIO = ("display aces needs OpenColorIO: pip install opencolorio (or choose the display raw: "
                 "--display raw, output.display: raw, write_png(..., display='raw'))")


def check_display(display, label="display"):
    """``display`` if one of DISPLAYS, else InputError naming ``label``."""
    if not (isinstance(display, str) and display in DISPLAYS):
        raise InputError(f"{label}: expected one of {', '.join(DISPLAYS)}, got {display!r}")
    return display


def check_white_balance(value, label="white_balance"):
    """``value`` as a white balance: ``scene``, ``none``, a CIE illuminant's name (colour.SDS_ILLUMINANTS,
    e.g. D65), or an illuminant's linear RGB in the working colourspace (3 finite numbers >= 0, not all 0).
    InputError naming ``label`` otherwise. A name is returned as it is, an RGB as a tuple of floats."""
    from ..scene.colour import _is_illuminant
    if isinstance(value, str):
        if value in WHITE_BALANCE_WORDS or _is_illuminant(value):
            return value
    elif isinstance(value, (list, tuple, np.ndarray)) and not isinstance(value, (bool, np.bool_)):
        arr = np.asarray(value, dtype=object).ravel() if np.ndim(value) <= 1 else None
        if arr is not None and len(arr) == 3 and all(
                isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_))
                for v in arr):
            rgb = np.array(arr, np.float64)
            if np.all(np.isfinite(rgb)) and np.all(rgb >= 0) and np.any(rgb > 0):
                return tuple(float(v) for v in rgb)
    raise InputError(f"{label}: expected scene, none, a CIE illuminant such as D65, D50 or A, or an illuminant's "
                     f"linear RGB [r, g, b], got {value!r}")


def check_exposure_setting(value, label="exposure"):
    """``auto`` or a finite number of stops within +-MAX_EXPOSURE (returned as a float); InputError naming
    ``label`` otherwise."""
    if isinstance(value, str) and value == AUTO_EXPOSURE:
        return value
    if (isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))
            and abs(value) <= MAX_EXPOSURE):
        return float(value)
    got = f"{value:g}" if isinstance(value, (float, np.floating)) else repr(value)
    raise InputError(f"{label}: expected auto or a finite number of stops within +-{MAX_EXPOSURE:g}, got {got}")


def parse_exposure(text, label="--exposure"):
    """The command line's ``--exposure auto|STOPS`` as check_exposure_setting returns it."""
    if text == AUTO_EXPOSURE:
        return text
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"{label}: expected auto or a number of stops, got {text!r}") from None
    return check_exposure_setting(value, label)


def resolve(display="aces", white_balance=None, exposure=None):
    """(display, white_balance, exposure) with the display's defaults in place of None: ``aces`` balances to
    the scene and exposes automatically, ``raw`` does neither (exposure 0 stops): today's preview."""
    check_display(display)
    if white_balance is None:
        white_balance = "scene" if display == "aces" else "none"
    if exposure is None:
        exposure = AUTO_EXPOSURE if display == "aces" else 0.0
    return display, check_white_balance(white_balance), check_exposure_setting(exposure)


def require_ocio():
    """Raise InputError (one line: the package to install) where OpenColorIO cannot be imported."""
    try:
        import PyOpenColorIO  # noqa: F401
    except ImportError:
        raise InputError(_MISSING_OCIO) from None


# --- white balance -----------------------------------------------------------------------------------------

def scene_illuminant(scene):
    """(3,) linear RGB of the working colourspace: the light that falls on the scene's media, as a camera
    balanced to it would measure it on a white card facing each light: every directional light's irradiance,
    every point light's at the centre of the media's (or surfaces') box, and pi times the ambient radiance,
    or where there is none, the background's mean radiance (a sky's mean over the sphere, ground included)."""
    total = np.zeros(3)
    lo, hi = scene.bbox()
    centre = 0.5 * (np.asarray(lo) + np.asarray(hi))
    for light in scene.lights:
        place = light.place()
        if place is None:
            total += np.asarray(light.record()[1], np.float64)
        else:
            d2 = float(np.sum((np.asarray(place, np.float64) - centre) ** 2))
            if d2 > 0:
                total += np.asarray(light.record()[1], np.float64) / d2
    surround = scene.ambient if scene.ambient is not None else scene.background
    if surround is not None:
        total += np.pi * np.asarray(surround, np.float64)
    return total


def _cat02():
    """colour-science's CAT02 matrix (XYZ -> sharpened LMS), kept in its store like every number it gives."""
    return np.array(_stored("cat:CAT02", lambda: np.asarray(_colour().adaptation.CAT_CAT02, np.float64).tolist()))


def _rgb_to_xyz(colourspace):
    return np.linalg.inv(np.array(_space(colourspace)["XYZ_to_RGB"]).reshape(3, 3))


def _white_xyz(colourspace):
    """XYZ (Y = 1) of a colourspace's white point."""
    x, y = _space(colourspace)["whitepoint"]
    return np.array([x / y, 1.0, (1.0 - x - y) / y])


def illuminant_xyz(white_balance, colourspace=DEFAULT_COLOURSPACE, illuminant=None):
    """XYZ (Y = 1) of what the white balance adapts from: the working colourspace's white for ``none``; the
    CIE illuminant's spectrum for a name; ``illuminant`` (the scene's, linear RGB) for ``scene``; the given
    RGB for an RGB. None where the light is black (nothing to balance to: no adaptation)."""
    if white_balance == "none":
        return _white_xyz(colourspace)
    if white_balance == "scene":
        if illuminant is None:
            raise InputError("white_balance: scene needs the scene's illuminant: pass scene= (write_png(image, "
                             "path, scene=scene)), or give an illuminant such as D65, or none")
        rgb = illuminant
    elif isinstance(white_balance, str):
        return np.array(_xyz_illuminant(white_balance), np.float64)
    else:
        rgb = white_balance
    xyz = _rgb_to_xyz(colourspace) @ np.asarray(rgb, np.float64)
    return xyz / xyz[1] if xyz[1] > 0 else None


def balance_matrix(white_balance, colourspace=DEFAULT_COLOURSPACE, illuminant=None):
    """(3, 3): linear RGB of ``colourspace`` -> linear RGB of the display's primaries (BT.709, D65), the
    illuminant of ``white_balance`` (illuminant_xyz) adapted to D65 by von Kries scaling of CAT02's cone
    responses (colour.adaptation.matrix_chromatic_adaptation_VonKries with transform CAT02)."""
    source = illuminant_xyz(white_balance, colourspace, illuminant)
    target = _white_xyz(_DISPLAY_COLOURSPACE)
    cat = _cat02()
    if source is None:
        source = _white_xyz(colourspace)
    adapt = np.linalg.inv(cat) @ np.diag((cat @ target) / (cat @ source)) @ cat
    to_display = np.array(_space(_DISPLAY_COLOURSPACE)["XYZ_to_RGB"]).reshape(3, 3)
    return to_display @ adapt @ _rgb_to_xyz(colourspace)


# --- exposure ----------------------------------------------------------------------------------------------

def luminance(rgb709):
    """Y of linear BT.709 RGB (..., 3)."""
    return np.asarray(rgb709, np.float64) @ _rgb_to_xyz(_DISPLAY_COLOURSPACE)[1]


def auto_exposure(rgb709, alpha=None, display="aces"):
    """Stops that bring the AUTO_PERCENTILE-th percentile of the luminance of the pixels with alpha above
    AUTO_ALPHA (the cloud) to AUTO_LEVEL[display], or that of the whole frame where it is brighter (a cloud
    darker than its sky: the sky is not blown out); the whole frame's where ``alpha`` is None or no pixel
    passes. 0 for a black image. Within +-MAX_EXPOSURE."""
    y = luminance(rgb709).ravel()
    level = float(np.percentile(y, AUTO_PERCENTILE))
    if alpha is not None:
        cloud = np.asarray(alpha, np.float64).ravel() > AUTO_ALPHA
        if np.any(cloud):
            level = max(level, float(np.percentile(y[cloud], AUTO_PERCENTILE)))
    if not level > 0:
        return 0.0
    return float(np.clip(np.log2(AUTO_LEVEL[display] / level), -MAX_EXPOSURE, MAX_EXPOSURE))


def exposure_of(image, colourspace=DEFAULT_COLOURSPACE, display="aces", white_balance=None, illuminant=None):
    """The stops ``auto`` gives ``image`` (H x W x 3|4 linear, of ``colourspace``) after its white balance:
    what display_image applies with exposure auto. A sequence measures its first frame so and holds the
    stops for every frame (cloudmeta.api.cluster.render_frames): an exposure per frame would flicker."""
    display, white_balance, _ = resolve(display, white_balance, AUTO_EXPOSURE)
    arr = np.asarray(image, np.float64)
    rgb709 = arr[..., :3] @ balance_matrix(white_balance, colourspace, illuminant).T
    return auto_exposure(rgb709, arr[..., 3] if arr.shape[-1] == 4 else None, display)


# --- the display transform ---------------------------------------------------------------------------------

@functools.lru_cache(maxsize=1)
def ocio_processor():
    """(CPU processor, config name, view) of the display transform: OCIO_INPUT to OCIO_DISPLAY through the
    first of OCIO_VIEWS in the first of OCIO_CONFIGS that the installed OpenColorIO has."""
    require_ocio()
    import PyOpenColorIO as ocio
    config = None
    for name in OCIO_CONFIGS:
        try:
            config = ocio.Config.CreateFromFile(name)
            break
        except ocio.Exception:
            continue
    if config is None:
        raise InputError(f"display aces: this OpenColorIO ({ocio.__version__}) has none of the built-in configs "
                         f"{', '.join(OCIO_CONFIGS)}; pip install -U opencolorio")
    views = list(config.getViews(OCIO_DISPLAY))
    view = next((v for v in OCIO_VIEWS if v in views), None)
    if view is None:
        raise InputError(f"display aces: OpenColorIO's config {config.getName()} has no ACES view for "
                         f"{OCIO_DISPLAY}; pip install -U opencolorio")
    processor = config.getProcessor(OCIO_INPUT, OCIO_DISPLAY, view, ocio.TRANSFORM_DIR_FORWARD)
    return processor.getDefaultCPUProcessor(), config.getName(), view


def ocio_display(rgb709):
    """Display-encoded RGB in [0, 1] (float64) of linear BT.709 RGB (..., 3) through the ACES view."""
    processor = ocio_processor()[0]
    pixels = np.ascontiguousarray(np.asarray(rgb709, np.float32).reshape(-1, 3))
    processor.applyRGB(pixels)
    return np.clip(pixels.astype(np.float64), 0.0, 1.0).reshape(np.shape(rgb709))


# --- the picture -------------------------------------------------------------------------------------------

def display_image(image, colourspace=DEFAULT_COLOURSPACE, display="aces", white_balance=None, exposure=None,
                  illuminant=None):
    """(H x W x 3 uint8 sRGB display codes, exposure in stops as applied) of an H x W x 3|4 linear image of
    ``colourspace`` (alpha, where there is one, only chooses the pixels ``auto`` measures).

    ``display``: aces | raw. ``white_balance``: scene (needs ``illuminant``, scene_illuminant(scene)), none,
    a CIE illuminant's name or an RGB; None: the display's default (scene for aces, none for raw).
    ``exposure``: stops or auto; None: the display's default (auto for aces, 0 for raw).
    ``raw`` with white balance none and stops is encode_srgb's output byte for byte."""
    display, white_balance, exposure = resolve(display, white_balance, exposure)
    if display == "aces":
        require_ocio()  # before any work
    arr = np.asarray(image, np.float64)
    rgb = arr[..., :3]
    alpha = arr[..., 3] if arr.shape[-1] == 4 else None
    if display == "raw" and white_balance == "none" and exposure != AUTO_EXPOSURE:
        return encode_srgb(rgb, exposure, colourspace), exposure
    rgb709 = rgb @ balance_matrix(white_balance, colourspace, illuminant).T
    stops = auto_exposure(rgb709, alpha, display) if exposure == AUTO_EXPOSURE else exposure
    if display == "raw":
        return encode_srgb(rgb709, stops, _DISPLAY_COLOURSPACE), stops
    shown = ocio_display(np.maximum(rgb709, 0.0) * 2.0 ** stops)  # out of gamut: negative light has no display
    return np.rint(shown * 255.0).astype(np.uint8), stops


def describe(display, white_balance, exposure, stops):
    """One line for the command line: what the PNG went through."""
    display, white_balance, exposure = resolve(display, white_balance, exposure)
    how = f"{ocio_processor()[2]} (OpenColorIO)" if display == "aces" else "raw sRGB"
    wb = white_balance if isinstance(white_balance, str) else "rgb"
    ev = f"auto {stops:+.2f}" if exposure == AUTO_EXPOSURE else f"{stops:+g}"
    return f"{how}, white balance {wb}, exposure {ev} stops"
