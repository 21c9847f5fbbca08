"""Phase functions (docs/model.md §4), normalised so that their integral over the sphere is 1.

cos_theta = l . d with d the camera ray direction and l towards the light: g > 0 scatters forward, so a
cloud seen against the sun brightens.
"""
import math

from numba import njit

from .config import NJIT
from .kinds import DOUBLE_HG, HG, RAYLEIGH


INV_4PI = 1.0 / (4.0 * math.pi)


@njit(**NJIT)
def phase_hg(cos_theta, g):
    """Henyey-Greenstein: (1 - g^2) / (4 pi (1 + g^2 - 2 g cos)^(3/2))."""
    denom = 1.0 + g * g - 2.0 * g * cos_theta
    return INV_4PI * (1.0 - g * g) / (denom * math.sqrt(denom))


@njit(**NJIT)
def phase_rayleigh(cos_theta):
    return 3.0 / (16.0 * math.pi) * (1.0 + cos_theta * cos_theta)


@njit(**NJIT)
def phase(kind, g1, g2, w, cos_theta):
    """The phase function of a medium: kind with parameters (g1, g2, w) as packed by the renderer."""
    if kind == HG:
        return phase_hg(cos_theta, g1)
    if kind == DOUBLE_HG:
        return w * phase_hg(cos_theta, g1) + (1.0 - w) * phase_hg(cos_theta, g2)
    if kind == RAYLEIGH:
        return phase_rayleigh(cos_theta)
    return INV_4PI
