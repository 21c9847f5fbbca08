"""The clouds' shadow on the sky's ground (docs/atmosphere.md, *The clouds' shadow on the ground*).

The sky's ground is part of the background, a radiance over the view elevation alone. A scene that places it
(``background: {sky: {ground_height: Z}}``, scene.model.Ground) has it on the plane z = Z. Where a camera ray
goes down it meets that plane at g, and the media and surfaces between g and the sun take their share of the
sun's light: the background seen there is L_sky(e) - L_sun(e) (1 - T_sun(g)), with L_sun the part of the
sky's ground that the sun lights directly (atmosphere.ground_sun_table) and T_sun(g) the exact transmittance
from g towards the sun (0 where a surface is in the way). ``ground_shadow`` is that loss per pixel, the mean
over a fixed SUBPIXELS x SUBPIXELS grid of points in the pixel, so that the shadow's edge is antialiased at
any spp. Every pixel's value depends on the pixel alone: a tile gives the frame's pixels, bit for bit.
"""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np

from ..kernels.ground import sun_transmittance_chunk
from .pack import background_along, pixel_directions
from .threads import n_chunks

#: ground points per pixel side
SUBPIXELS = 2


def sun_transmittance(records, direction, points, tol_t):
    """(n,) the exact transmittance from ``points`` (n, 3) along the unit ``direction`` through the media of
    ``records`` (a records.SceneRecords); 0 where one of its surfaces is in the way (kernels.ground)."""
    points = np.ascontiguousarray(points, np.float64)
    direction = np.ascontiguousarray(direction, np.float64)
    out = np.empty(len(points))
    chunks = n_chunks(len(points))
    media, surfaces = records.media, records.surfaces

    def chunk(ch):
        sun_transmittance_chunk(points, direction, media, surfaces, tol_t, np.int64(ch), np.int64(chunks), out)

    with ThreadPoolExecutor(numba.get_num_threads()) as pool:  # nogil chunks, each its own points
        list(pool.map(chunk, range(chunks)))
    return out


def ground_shadow(scene, records, camera, tol_t, window):
    """H x W x 3 over the tile ``window`` = ((r0, r1), (c0, c1)) of a records.Camera: the radiance the shadow
    of the media and surfaces of ``records`` (records.SceneRecords) takes from the background each pixel sees
    (0 where its rays do not reach the ground); None where the scene places no ground. The pixel's background
    seen through the media loses this times the view's transmittance (renderer.frame)."""
    ground = scene.ground
    if ground is None:
        return None
    (r0, r1), (c0, c1) = window
    h, w = r1 - r0, c1 - c0
    offset = (np.arange(SUBPIXELS) + 0.5) / SUBPIXELS - 0.5  # from the pixel's centre
    rows, cols, v, u = np.meshgrid(np.arange(r0, r1), np.arange(c0, c1), offset, offset, indexing="ij")
    d = pixel_directions(camera, (rows + v).ravel(), (cols + u).ravel())
    loss = np.zeros((len(d), 3))
    down = np.flatnonzero(d[:, 2] < 0.0)
    if len(down):
        o = np.asarray(camera.position, np.float64)
        t = (ground.height - o[2]) / d[down, 2]  # > 0: the loader keeps the ground below the camera
        points = o + t[:, None] * d[down]
        shade = 1.0 - sun_transmittance(records, ground.direction, points, tol_t)
        shaded = np.flatnonzero(shade > 0.0)
        loss[down[shaded]] = background_along(ground.sun, d[down[shaded]]) * shade[shaded, None]
    return loss.reshape(h, w, SUBPIXELS * SUBPIXELS, 3).mean(axis=2)
