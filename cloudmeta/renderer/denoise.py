"""Denoised previews (``denoise=True``, ``--denoise``): Intel Open Image Denoise on the Monte Carlo part
of a multiple-scattering render only.

The deterministic part of the image (order 1 of every light, the background through the media, surfaces)
is exact up to the quadrature's tolerance and is never filtered. The paths' mean (renderer.multiple) is
denoised by OIDN's ``RT`` filter, HDR, guided by a noise-free albedo image: on each pixel's first camera
ray, the albedo of the medium it enters first (kernels.multiple.aux_pixels), times the pixel's alpha. The
same kernel gives the outward normal of that medium's isosurface there, which OIDN also accepts; as a
guide it made the error larger on 13 of 18 cases measured (validation/accuracy/denoise.py,
docs/multiple_scattering.md): a cloud's light has no edge where the normal of its first surface turns. So
it is left out. The denoised image is biased: its error is no longer the paths' standard error, which
RenderResult.error keeps for the raw image (RenderResult.raw). docs/multiple_scattering.md gives how far
it is from the converged image.

pyoidn is an optional extra (``pip install -e '.[denoise]'``); without it ``denoise=True`` fails at once,
before any work, with one line saying so.
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..kernels.multiple import aux_pixels
from .threads import run_bands


def require_denoiser(scene):
    """The pyoidn module; an InputError (one line) where the scene is not rendered by paths or the extra
    is missing."""
    if scene.render.scattering != "multiple":
        raise InputError(f"denoise: only a multiple-scattering render has Monte Carlo noise to remove "
                         f"({scene.path}: render.scattering is {scene.render.scattering})")
    try:
        import pyoidn
    except ImportError as exc:
        raise InputError("denoise: needs the optional extra pyoidn (pip install -e '.[denoise]'): "
                         f"{exc}") from None
    return pyoidn


def aux_images(scene, packed, window):
    """(albedo, normal), both H x W x 3 float32 over the tile ``window``: see kernels.multiple.aux_pixels."""
    w, h = scene.image.width, scene.image.height
    albedo = np.zeros((h, w, 3))
    normal = np.zeros((h, w, 3))
    camera, records, quad = packed.camera, packed.records, packed.quadrature
    run_bands(lambda row0, p0, p1: aux_pixels(camera, records, quad, row0, p0, p1, albedo, normal), window, w,
              False)
    (r_lo, r_hi), (c_lo, c_hi) = window
    return (albedo[r_lo:r_hi, c_lo:c_hi].astype(np.float32), normal[r_lo:r_hi, c_lo:c_hi].astype(np.float32))


def denoise_paths(pyoidn, mean, albedo, normal, alpha):
    """The paths' mean (H x W x 3, linear RGB) filtered by OIDN (RT, HDR, clean auxiliary images: the albedo
    weighted by the image's ``alpha`` (H x W), and the normal unless None). Weighted by alpha = 1 - T, the
    albedo guide says how much of the pixel the media take, not only what they are: it was better than the
    bare albedo on all 12 cases measured (docs/multiple_scattering.md). Where alpha is 0 no camera ray
    meets a medium and the paths' part is exactly 0: the filter's halo (it spreads ~0.3 % of a cloud's
    light into the sky beside it) is cut there."""
    color = np.ascontiguousarray(np.maximum(mean, 0.0), np.float32)
    guide = np.ascontiguousarray(albedo * np.clip(alpha, 0.0, 1.0)[..., None], np.float32)
    out = np.asarray(pyoidn.denoise(color, guide, normal, hdr=True, clean_aux=True, quality="high"), np.float64)
    out[alpha <= 0.0] = 0.0
    return out
