"""The pilot: how bright a frame's scattered light is, measured before the frame is rendered
(docs/model.md §11, docs/error_estimate.md).

The presets are targets for the image's RMSE against the converged image divided by the mean scattered
radiance. The scattered radiance is the image less what is computed exactly: the background seen through
the media, and the shading of surfaces. A tolerance relative to each ray's own brightest light cannot keep
such a target. A thin wisp, or a small cloud in a large frame, makes the image's scattered light small
while the ray's own light stays bright.

So the in-scattering quadrature's tolerance is absolute, relative to one scale per frame. A pilot
measures that scale: it renders the scattered light alone (black background, black surfaces) at
``draft`` on a coarse grid over the frame. The scale is the RMS over the pilot's pixels of r + g + b, the
unit of the kernels' J sums. If every cloud pixel has the same absolute error, the image's RMSE is that
error times the square root of the cloud's coverage, and sqrt(mean S^2) = mean S / sqrt(coverage).

The pilot depends on the whole frame alone, never on a tile, a thread count or a worker, so every tile of a
frame gets the same tolerance and renders stay bit-identical. A pilot that sees no scattered light gives
scale 0. The quadrature then falls back to a tolerance relative to each ray's brightest J.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .pack import Packed, pack_camera, quadrature
from .quality import resolve_quality
from .single import render_single

#: the pilot samples every STRIDE-th pixel of the frame in each direction, or fewer so that its shorter side
#: keeps MIN_SIDE pixels (all of them where the frame's is shorter still); its aspect is the frame's
STRIDE = 8
MIN_SIDE = 16


@dataclass(frozen=True)
class LightScale:
    """What the pilot measured: ``mean``, the mean over its pixels and RGB of the scattered radiance (the
    denominator of the presets' relative RMSE); ``scale``, the RMS over its pixels of r + g + b (the
    quadrature's absolute unit); ``width`` x ``height``, the pilot's grid."""
    mean: float
    scale: float
    width: int
    height: int


def pilot_size(width, height):
    """The pilot grid of a width x height frame: each side divided by one stride, at most STRIDE, so that
    the shorter side keeps at least MIN_SIDE pixels."""
    stride = max(1, min(STRIDE, min(width, height) // MIN_SIDE))
    return -(-width // stride), -(-height // stride)


def pilot_image(scene, packed, quality):
    """The pilot's H x W x 4 image at ``quality`` (a renderer.quality.Quality): the scattered light alone
    on the pilot grid, rendered by the single-scattering driver with ``packed``'s scene records (BVHs,
    shadow maps), the background and the surfaces' colours blackened, so that it compiles nothing new."""
    width, height = pilot_size(scene.image.width, scene.image.height)
    small = replace(scene, image=replace(scene.image, width=width, height=height, spp=1))
    rec = packed.records
    surfaces = rec.surfaces
    if surfaces is not None:
        surfaces = surfaces._replace(colour=np.zeros_like(surfaces.colour))
    records = rec._replace(background=np.zeros((1, 3)), surfaces=surfaces)
    pilot = Packed(camera=pack_camera(small, 0), records=records, quadrature=quadrature(quality))
    image, _, _ = render_single(small, pilot, ((0, height), (0, width)), False)
    return image


def light_scale(scene, packed) -> LightScale:
    """The frame's scattered-light scale, measured by the pilot at ``draft`` (this module's docstring)."""
    draft = replace(scene.render, quality="draft", tolerance=None, max_tau=None, max_length=None,
                    max_angle=None, cutoff=None, root_tolerance=None)
    quality = replace(resolve_quality(draft, scene.length_scale()), tol_t=packed.quadrature.tol_t)
    image = pilot_image(scene, packed, quality)
    rgb = image[..., :3]
    total = rgb.sum(axis=-1)
    return LightScale(mean=float(rgb.mean()), scale=float(np.sqrt(np.mean(total * total))),
                      width=image.shape[1], height=image.shape[0])


def pilot_quality(scene, packed, quality):
    """(the frame's Quality, its LightScale): ``quality`` (the scene's resolved settings) with the pilot's
    scattered-light scale."""
    scale = light_scale(scene, packed)
    return replace(quality, light_scale=scale.scale), scale
