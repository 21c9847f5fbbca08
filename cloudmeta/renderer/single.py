"""The single-scattering driver: the deterministic image of a tile, the radiance kernel
(cloudmeta.kernels.single.render_pixels) run over bands of rows. Every estimator starts from it: order 1
of every light, exact optical depth and shadows, surfaces and the background (docs/model.md §5-6)."""
from __future__ import annotations

import numpy as np

from ..kernels.lighting import N_COUNTS
from ..kernels.single import render_pixels
from .threads import run_bands


def render_single(scene, packed, window, progress):
    """(image, nearest, counts) of the tile ``window``: the H x W x 4 float64 radiance and alpha, per pixel the
    distance to the nearest surface hit (inf where none), and per pixel what its light cost (H x W x N_COUNTS:
    quadrature nodes, exact shadow rays, shadow-map lookups, lookups trusted, steps, steps with Kronrod nodes,
    splits, splits at folds; kernels.lighting.COUNT_*).
    ``packed``: a pack.Packed of the scene."""
    w, h = scene.image.width, scene.image.height
    image = np.zeros((h, w, 4), np.float64)
    nearest = np.full((h, w), np.inf)
    counts = np.zeros((h, w, N_COUNTS), np.float64)
    camera, records, quad = packed.camera, packed.records, packed.quadrature
    run_bands(lambda row0, p0, p1: render_pixels(camera, records, quad, row0, p0, p1, image, nearest, counts),
              window, w, progress)
    (r_lo, r_hi), (c_lo, c_hi) = window
    return image[r_lo:r_hi, c_lo:c_hi], nearest[r_lo:r_hi, c_lo:c_hi], counts[r_lo:r_hi, c_lo:c_hi]
