"""Camera rays (docs/model.md §8): the direction of a pixel's sample, its jitter, and the sample of a ray that
meets nothing. Shared by both estimators' pixel loops, so that a multiple-scattering path starts on the
very camera ray of the single-scattering renderer."""
import math

import numpy as np
from numba import njit

from .config import NJIT, NJIT_INLINE
from .sampling import mix64


@njit(**NJIT)
def jitter(seed, pixel, sample, dim):
    key = (np.uint64(seed) * np.uint64(0x9E3779B97F4A7C15) + np.uint64(pixel) * np.uint64(0x632BE59BD9B4E019)
           + np.uint64(sample) * np.uint64(0x85EBCA77C2B2AE63) + np.uint64(dim))
    # a counter-based hash, so jitter depends only on (pixel, sample)
    return float(mix64(key) >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@njit(**NJIT_INLINE)
def camera_ray(camera, i, j, s, strata, d):
    """d = the unit direction of sample s of pixel (i, j) (docs/model.md §8): the pixel centre with spp = 1,
    else a jittered point of its stratum on a strata x strata grid."""
    width, height, spp = camera.width, camera.height, camera.spp
    if spp == 1:
        jx = 0.5
        jy = 0.5
    else:
        pix = i * width + j
        jx = ((s % strata) + jitter(camera.seed, pix, s, np.int64(0))) / strata
        jy = (((s // strata) % strata) + jitter(camera.seed, pix, s, np.int64(1))) / strata
    x = 2.0 * (j + jx) / width - 1.0
    y = 1.0 - 2.0 * (i + jy) / height
    for c in range(3):
        d[c] = camera.forward[c] + x * camera.right[c] + y * camera.up[c]
    norm = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
    for c in range(3):
        d[c] /= norm


@njit(**NJIT_INLINE)
def background_gives_light(background):
    """Whether the background (a records' (K, 3) table) gives light in any direction: paths must then look for it
    at every order, not only up to the lights' last."""
    for q in range(background.shape[0]):
        for c in range(3):
            if background[q, c] > 0.0:
                return True
    return False


@njit(**NJIT_INLINE)
def background_radiance(background, d):
    """(r, g, b): the radiance of the background seen along the unit direction d. ``background`` is a
    (K, 3) table over the elevation of d (z up), rows from -90 to 90 degrees in equal steps, interpolated
    linearly; one row (K = 1) is a uniform background, returned as it is (no arithmetic: bit for bit)."""
    k = background.shape[0]
    if k == 1:
        return background[0, 0], background[0, 1], background[0, 2]
    x = (math.asin(min(1.0, max(-1.0, d[2]))) / math.pi + 0.5) * (k - 1)
    i = min(int(x), k - 2)
    f = x - i
    return ((1.0 - f) * background[i, 0] + f * background[i + 1, 0],
            (1.0 - f) * background[i, 1] + f * background[i + 1, 1],
            (1.0 - f) * background[i, 2] + f * background[i + 1, 2])


@njit(**NJIT_INLINE)
def background_sample(background, d, out):
    out[0], out[1], out[2] = background_radiance(background, d)
    out[3] = 1.0
    out[4] = np.inf
