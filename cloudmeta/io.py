"""Images out (and back in): linear OpenEXR with the working colourspace's chromaticities, sRGB PNG previews.

The renderer's image is linear RGB(A) in the working colourspace, its RGB already composited over the
background (MODEL.md §7, §8). Nothing here changes the numbers of an EXR; exposure and encoding belong
to the PNG preview alone.
"""
from __future__ import annotations

import contextlib
import os
import tempfile

import numpy as np

from .colour import DEFAULT_COLOURSPACE, chromaticities, encode_srgb
from .errors import InputError

_CHANNELS = "RGBA"


@contextlib.contextmanager
def atomic_output(path):
    """Yield a temporary path in ``path``'s folder; rename it onto ``path`` only when the block succeeds.

    A reader never sees a half-written file, and on any failure (an exception, Ctrl-C) the temporary file
    is removed and ``path`` is left as it was. The temporary name keeps the extension (``.x.exr.tmp-abc.exr``)
    so that tools which look at it still know the format.
    """
    path = os.fspath(path)
    folder, name = os.path.split(os.path.abspath(path))
    ext = os.path.splitext(name)[1]
    fd, tmp = tempfile.mkstemp(prefix=f".{name}.tmp-", suffix=ext, dir=folder)
    os.close(fd)
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def _check_image(image):
    """``image`` as an H x W x 3|4 float64 array of finite values, or InputError."""
    arr = np.asarray(image)
    if arr.dtype.kind not in "fiu":
        raise InputError(f"image: expected an array of real numbers, got dtype {arr.dtype}")
    if arr.ndim != 3 or arr.shape[2] not in (3, 4) or arr.shape[0] < 1 or arr.shape[1] < 1:
        raise InputError(f"image: expected shape (H, W, 3) or (H, W, 4), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InputError("image: expected finite values, found NaN or infinity")
    return arr.astype(np.float64, copy=False)


def write_exr(image, path, colourspace=DEFAULT_COLOURSPACE, half=False):
    """Write an H x W x 3 (RGB) or H x W x 4 (RGBA) linear image as a single-part scanline OpenEXR.

    Channels are FLOAT, or HALF with ``half=True``; the header carries the ``chromaticities`` of
    ``colourspace`` so that readers know the primaries and white of the linear values.
    """
    arr = _check_image(image)
    dtype = np.float16 if half else np.float32
    with np.errstate(over="ignore"):
        stored = arr.astype(dtype)
    if not np.all(np.isfinite(stored)):
        kind = "HALF" if half else "FLOAT"
        raise InputError(f"image: values up to {np.abs(arr).max():g} overflow {kind} channels"
                         + ("; write with half=False" if half else ""))
    header = {"chromaticities": chromaticities(colourspace)}
    channels = {name: np.ascontiguousarray(stored[:, :, i]) for i, name in enumerate(_CHANNELS[:arr.shape[2]])}
    import OpenEXR  # here, not at import: a render that writes no EXR should not pay for it
    header["compression"], header["type"] = OpenEXR.ZIP_COMPRESSION, OpenEXR.scanlineimage
    with atomic_output(path) as tmp:
        OpenEXR.File(header, channels).write(tmp)


def read_exr(path):
    """(image, header) of an OpenEXR file: image is H x W x C float32 with channels in RGBA order.

    Channels other than R, G, B, A follow in name order. ``header`` is the file's header dict.
    """
    import OpenEXR
    with OpenEXR.File(str(path), separate_channels=True) as f:
        header = dict(f.header())  # a copy: File clears its own header dict when it closes
        channels = f.channels()
        order = [c for c in _CHANNELS if c in channels] + sorted(c for c in channels if c not in _CHANNELS)
        # astype copies: the pixels must outlive the File
        image = np.stack([channels[c].pixels.astype(np.float32) for c in order], axis=-1)
    return image, header


def write_png(image, path, exposure=0.0, colourspace=DEFAULT_COLOURSPACE):
    """Write an 8-bit sRGB preview: RGB only (the render's RGB is already over its background; alpha is dropped)."""
    from PIL import Image
    arr = _check_image(image)
    pixels = Image.fromarray(encode_srgb(arr[:, :, :3], exposure, colourspace))
    with atomic_output(path) as tmp:
        pixels.save(tmp, format="PNG")
