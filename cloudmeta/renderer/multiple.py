"""Multiple scattering (``render: {scattering: multiple}``): the Monte Carlo part of the image.

Order 1 of every light stays the deterministic single-scattering renderer's (exact shadows, the
quadrature of cloudmeta.renderer.single); ``render_multiple`` adds, by path tracing
(cloudmeta.kernels.multiple: exact flights first, tracked ones from ``render.track_from`` on,
renderer.tracking), the orders 2 .. ``max_order`` of the lights and the orders 1 .. ``max_order`` of the
environment, the scene's uniform ``background``. It returns the per-pixel mean and its standard
error, so every multiple-scattering image comes with its own error estimate.

Both estimators read one packing of the scene (cloudmeta.renderer.pack.pack_scene); with ``shadows: map`` the
paths' next-event shadow rays read the same maps as the single-scattering renderer (at exact vertices as
they are, at tracked ones as a control variate).

``ambient`` is refused in multiple mode: the background already lights the medium at every order, and
an ambient term on top would count the sky twice.
"""
from __future__ import annotations

import numpy as np

from ..errors import SceneError
from ..kernels.multiple import render_paths
from .threads import run_bands, tile_window
from .pack import pack_scene
from .tracking import path_settings, paths_grid, paths_volumes


def check_multiple(scene):
    """Refuse what multiple scattering cannot take (one line naming the file and the key)."""
    if scene.ambient is not None:
        raise SceneError(scene.path, "ambient", "not allowed with render.scattering: multiple (the background "
                                                "lights the medium at every order; ambient would count it twice)")


def render_multiple(scene, paths=None, max_order=None, seed=0, progress=False, rows=None, columns=None,
                    packed=None):
    """The Monte Carlo part of a multiple-scattering render: (radiance, stderr), both H x W x 3 float64,
    linear RGB. radiance is the mean of ``paths`` paths per pixel (default ``render.ms_spp``) of the light
    the deterministic renderer leaves out (orders >= 2 of the lights, >= 1 of the environment), up to
    ``max_order`` (default ``render.max_order``); stderr its standard error per pixel and channel (inf
    with one path). Bit-identical for any number of threads. ``rows`` and ``columns`` as in
    cloudmeta.renderer.render (a tile: the same numbers as those pixels of the whole frame); ``packed``:
    the render's pack.Packed of the same scene and seed, so the scene is packed once."""
    check_multiple(scene)
    paths = scene.render.ms_spp if paths is None else int(paths)
    max_order = scene.render.max_order if max_order is None else int(max_order)
    window = tile_window(rows, scene.image.height, "rows"), tile_window(columns, scene.image.width, "columns")
    packed = pack_scene(scene, seed) if packed is None else packed
    camera, records, quad = packed.camera, packed.records, packed.quadrature
    settings = path_settings(scene, paths, max_order)
    grid = paths_grid(scene, records.media, settings)
    volumes = paths_volumes(scene, packed, settings)
    w, h = scene.image.width, scene.image.height
    mean = np.zeros((h, w, 3))
    stderr = np.zeros((h, w, 3))
    # bands write their own rows with their own work arrays, and every random number is keyed by the
    # pixel: the result depends neither on the threads nor on the tile
    run_bands(lambda row0, p0, p1: render_paths(camera, records, quad, settings, grid, volumes, row0, p0, p1, mean,
                                                stderr), window, w, progress)
    (r_lo, r_hi), (c_lo, c_hi) = window
    return mean[r_lo:r_hi, c_lo:c_hi], stderr[r_lo:r_hi, c_lo:c_hi]
