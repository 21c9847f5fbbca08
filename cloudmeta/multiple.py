"""Multiple scattering (``render: {scattering: multiple}``): the Monte Carlo part of the image.

Order 1 of every light stays the deterministic single-scattering renderer's (exact shadows, the
quadrature of cloudmeta.render); ``render_multiple`` adds, by path tracing on the exact optical depth
(cloudmeta.kernels.multiple), the orders 2 .. ``max_order`` of the lights and the orders 1 .. ``max_order``
of the environment, the scene's uniform ``background``. It returns the per-pixel mean and its standard
error, so every multiple-scattering image comes with its own error estimate.

``ambient`` is refused in multiple mode: the background already lights the medium at every order, and
an ambient term on top would count the sky twice.
"""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np

from .errors import SceneError
from .kernels.multiple import render_paths
from .render import (BANDS_PER_THREAD, MAX_BAND_ROWS, _progress, camera_basis, pack_lights, pack_media,
                     pack_surfaces, resolve_quality)

#: Russian roulette from this vertex on (the first vertices carry most of the light: keep them all)
RR_ORDER = 4


def check_multiple(scene):
    """Refuse what multiple scattering cannot take (one line naming the file and the key)."""
    if scene.ambient is not None:
        raise SceneError(scene.path, "ambient", "not allowed with render.scattering: multiple (the background "
                                                "lights the medium at every order; ambient would count it twice)")


def _pack(scene):
    """(med, surf, lights, tol_t): the kernel tuples of cloudmeta.render, exact shadow rays to every light."""
    lo, hi = scene.bbox()
    q = resolve_quality(scene.render, float(np.linalg.norm(hi - lo)))
    return (pack_media(scene.media).args(), pack_surfaces(scene.surfaces).args(), pack_lights(scene.lights),
            q.tol_t)


def render_multiple(scene, paths=None, max_order=None, seed=0, progress=False):
    """The Monte Carlo part of a multiple-scattering render: (radiance, stderr), both H x W x 3 float64,
    linear RGB. radiance is the mean of ``paths`` paths per pixel (default ``render.ms_spp``) of the light
    the deterministic renderer leaves out (orders >= 2 of the lights, >= 1 of the environment), up to
    ``max_order`` (default ``render.max_order``); stderr its standard error per pixel and channel (inf
    with one path). Bit-identical for any number of threads."""
    check_multiple(scene)
    paths = scene.render.ms_spp if paths is None else int(paths)
    max_order = scene.render.max_order if max_order is None else int(max_order)
    med, surf, lights, tol_t = _pack(scene)
    w, h = scene.image.width, scene.image.height
    fwd, right, up = camera_basis(scene.camera, w, h)
    camera = (np.array(scene.camera.position, np.float64), fwd, right, up)
    background = np.array(scene.background, np.float64)
    params = (int(max_order), RR_ORDER, float(tol_t))
    mean = np.zeros((h, w, 3))
    stderr = np.zeros((h, w, 3))
    threads = numba.get_num_threads()
    rows = max(1, min(MAX_BAND_ROWS, -(-h // (BANDS_PER_THREAD * threads))))
    bands = [(r0, min(h, r0 + rows)) for r0 in range(0, h, rows)]
    bar = _progress(h, progress)

    def band(rows):
        r0, r1 = rows
        render_paths(r0, w, h, scene.image.spp, paths, seed, camera, 0, (r1 - r0) * w, med, surf, lights, params, background,
                     mean, stderr)
        return r1 - r0

    # bands write their own rows with their own work arrays, and every random number is keyed by the
    # pixel: the result does not depend on the threads
    with ThreadPoolExecutor(threads) as pool:
        for done in pool.map(band, bands):
            bar.update(done)
    bar.close()
    return mean, stderr


def add_multiple(scene, image, seed=0, progress=False):
    """The render hook: image (H x W x 4, the deterministic part) with the Monte Carlo part added to its
    RGB. Returns (image, stderr)."""
    mean, stderr = render_multiple(scene, seed=seed, progress=progress)
    image[..., :3] += mean
    return image, stderr
