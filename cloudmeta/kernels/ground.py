"""The sky's ground in the clouds' shadow (cloudmeta.renderer.ground): the exact transmittance from points on
the ground towards the sun, through every medium, 0 where a surface is in the way. The same shadow ray as
single scattering's (kernels.media.shadow_transmittance, kernels.optional.surfaces_blocking), in chunks that
run side by side on threads; every point is independent, so results do not depend on the number of threads."""
import numpy as np
from numba import njit

from .config import NJIT
from .borrow import borrow
from .bvh import STACK
from .media import shadow_transmittance
from .optional import surface_balls, surfaces_blocking
from .records import ShadowWork
from .sweep import alloc_scratch


@njit(**NJIT)
def sun_transmittance_chunk(points, l_dir, med, surf, tol_t, chunk, n_chunks, transmittance):
    """transmittance[k] = T from points[k] along the unit l_dir to infinity through ``med`` (a records.Media),
    0 where a surface of ``surf`` (records.Surfaces, or None) meets the ray, for the points of chunk ``chunk``
    of n_chunks. nogil, with its own work arrays."""
    med = borrow(med)  # the caller holds the records for the whole call (kernels.borrow)
    surf = borrow(surf)
    scratch = alloc_scratch(np.int64(64))
    work = ShadowWork(np.empty(max(med.centers.shape[0], surface_balls(surf), 1), np.int64),
                      np.empty(2 * STACK, np.int64))
    n = points.shape[0]
    for k in range(chunk * n // n_chunks, (chunk + 1) * n // n_chunks):
        x = points[k]
        scratch, blocked = surfaces_blocking(x, l_dir, np.inf, surf, tol_t, scratch, work)
        if blocked:
            transmittance[k] = 0.0
            continue
        scratch, t, _ = shadow_transmittance(x, l_dir, np.inf, med, tol_t, np.inf, scratch, work.cand, work.stack)
        transmittance[k] = t
