"""The error estimate of a render and error-controlled rendering (docs/error_estimate.md).

A render's error is estimated as its difference to a second render of the same scene with every quadrature
setting coarser (``COARSER``): where the quadrature converges, that difference is of the size of the
coarser render's error, an estimate that errs on the large side. ``render.error: TARGET`` (a relative RMSE)
refines the settings by the same factors until the estimate is at most the target.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from .pack import background_along, pixel_directions

#: how much coarser each quadrature setting of the estimate's second render is (finer: divided by these)
COARSER = dict(tolerance=3.0, max_tau=2.0, max_length=2.0, max_angle=2.0, cutoff=3.0)
#: error-controlled renders refine at most this often (each step costs about twice the one before)
MAX_REFINEMENTS = 5


#: the widest angle a step may subtend at a point light, in any coarser setting: beyond about pi / 2 a step's nodes
#: no longer resolve the light's 1 / r^2 (the estimate's second render at 3.2 radians erred 75x the image's)
MAX_ANGLE = 1.6


def coarser_quality(q):
    """The settings of the error estimate's second render: every quadrature setting coarser (the cutoff at most
    0.5, the widest angle at most MAX_ANGLE)."""
    return replace(q, tolerance=q.tolerance * COARSER["tolerance"], max_tau=q.max_tau * COARSER["max_tau"],
                   max_length=q.max_length * COARSER["max_length"],
                   max_angle=min(q.max_angle * COARSER["max_angle"], MAX_ANGLE),
                   cutoff=min(q.cutoff * COARSER["cutoff"], 0.5))


def scaled_quality(q, level):
    """Every quadrature setting coarser by COARSER's factors raised to ``level`` (a real number; negative is
    finer; 0 returns q itself): the calibration's scale of settings (renderer.pilot), continuous between the
    estimate's steps. The cutoff stays at most 0.5, and the widest angle at most MAX_ANGLE / 2: the error estimate's
    second render (coarser_quality) doubles it, and every setting must be coarser there for its difference to
    see the error (cumulus_point_inside at `draft`, its angle at MAX_ANGLE: the estimate 0.6x the true error)."""
    if level == 0.0:
        return q
    f = {key: factor ** level for key, factor in COARSER.items()}
    return replace(q, tolerance=q.tolerance * f["tolerance"], max_tau=q.max_tau * f["max_tau"],
                   max_length=q.max_length * f["max_length"],
                   max_angle=min(q.max_angle * f["max_angle"], MAX_ANGLE / COARSER["max_angle"]),
                   cutoff=min(q.cutoff * f["cutoff"], 0.5))


def finer_quality(q):
    """One refinement of an error-controlled render: every quadrature setting finer by COARSER's factors."""
    return replace(q, tolerance=q.tolerance / COARSER["tolerance"], max_tau=q.max_tau / COARSER["max_tau"],
                   max_length=q.max_length / COARSER["max_length"], max_angle=q.max_angle / COARSER["max_angle"],
                   cutoff=q.cutoff / COARSER["cutoff"])


def estimated_rel_rmse(image, error, scattered_mean=0.0):
    """The image's estimated relative RMSE, the measure of the presets' targets: sqrt(mean over pixels and
    RGB of error^2) / the mean scattered radiance (``scattered_mean``, renderer.pilot); where that is 0 (a
    pilot that saw no scattered light), over sqrt(mean of image^2) instead."""
    e = np.asarray(error, np.float64)
    norm = float(scattered_mean)
    if not norm > 0.0:
        rgb = np.asarray(image, np.float64)[..., :3]
        norm = float(np.sqrt(np.mean(rgb * rgb)))
    return float(np.sqrt(np.mean(e * e))) / norm if norm > 0 else 0.0


def background_seen(camera, background, window, shadow=None):
    """Per pixel of the tile ``window`` = ((r0, r1), (c0, c1)), the background's radiance along the ray through the
    pixel's centre (renderer.pack: pixel_directions, background_along), H x W x 3; a uniform background as its one
    row. ``shadow`` (H x W x 3, renderer.ground), where the scene places a ground, is taken from it."""
    if background.shape[0] == 1:
        seen = background[0]
    else:
        (r0, r1), (c0, c1) = window
        rows, cols = np.mgrid[r0:r1, c0:c1]
        directions = pixel_directions(camera, rows.ravel(), cols.ravel())
        seen = background_along(background, directions).reshape(r1 - r0, c1 - c0, 3)
    return seen if shadow is None else seen - shadow


def frame_scattered_mean(image, nearest, camera, background, window, sampled, shadow=None):
    """The mean scattered radiance of the estimate's denominator: the image less the background seen through the
    media (alpha = 1 - transmittance; less the clouds' ``shadow`` on a ground, renderer.ground), where no surface is
    hit, from the image itself; where some pixel hits a
    surface (whose shading is exact too, and not told apart) at least ``sampled``, the calibration's or the pilot's
    mean. A sample of rays misses a bright spot that the frame does not: deck_point_inside's lamp at 256 x 192, whose
    calibration grid measured 2.6x too little scattered light."""
    rgb = np.asarray(image, np.float64)[..., :3]
    transmittance = 1.0 - np.asarray(image, np.float64)[..., 3:4]
    scattered = rgb - background_seen(camera, background, window, shadow) * transmittance
    surface = np.isfinite(nearest)
    if not surface.any():
        return float(scattered.mean())
    return max(float(sampled), float(np.where(surface[..., None], 0.0, scattered).mean()))


def with_estimate(render_at, quality, target=None, scattered_mean=0.0):
    """(image, error, quality used, refinements): render_at(quality) -> H x W x 4 (float64) at the given
    settings and at coarser ones; with a ``target`` relative RMSE (relative to ``scattered_mean``, a number or a
    function of the image, see estimated_rel_rmse), refined until the estimate is at most the target (or
    MAX_REFINEMENTS were made). Each refinement's estimate is its difference to the render before it, which is
    exactly its coarser render."""
    norm = scattered_mean if callable(scattered_mean) else (lambda image: scattered_mean)
    image = render_at(quality)
    previous = render_at(coarser_quality(quality))
    error = np.abs(image[..., :3] - previous[..., :3])
    steps = 0
    while (target is not None and steps < MAX_REFINEMENTS
           and estimated_rel_rmse(image, error, norm(image)) > target):
        quality = finer_quality(quality)
        previous, image = image, render_at(quality)
        error = np.abs(image[..., :3] - previous[..., :3])
        steps += 1
    return image, error, quality, steps
