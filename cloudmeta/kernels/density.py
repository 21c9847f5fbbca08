"""Density modes: rho as a function of the field F inside a medium ({F >= T}), docs/model.md §4.

    field    rho = F
    excess   rho = F - T
    uniform  rho = 1

sigma_t = scale * rho. Every mode is AFFINE in F, and the kernels rely on it in three places: the
control values of rho on a piece are rho of F's control values (``rho_value`` applied to each, in
kernels.media), the mean of rho over a piece is rho of F's mean (``density_mean``), and the integral of
rho over the inside parts of a ray is a function of the integral of F and their length alone
(``rho_integral``, the shadow rays of kernels.shadow). A mode that is not affine in F (F^2, say) needs its
own control values (degree elevation) and its own shadow-ray integral; none of the three above would hold.

The ids live in kernels.kinds; cloudmeta.api.viewer evaluates rho on numpy arrays through ``rho_value.py_func``,
so the formula is written once.
"""
from numba import njit

from .bernstein import bernstein_mean
from .config import NJIT, NJIT_INLINE
from .kinds import DENSITY_EXCESS, DENSITY_UNIFORM


@njit(**NJIT_INLINE)
def rho_value(f, mode, threshold):
    """rho where the field is f, inside (F >= T). Applied to a piece's control values it gives rho's, to
    their mean rho's mean (rho is affine in F)."""
    if mode == DENSITY_UNIFORM:
        return 1.0
    if mode == DENSITY_EXCESS:
        return f - threshold
    return f


@njit(**NJIT)
def density_mean(c, mode, threshold):
    """Mean of rho over a piece whose field has control values c."""
    if mode == DENSITY_UNIFORM:
        return 1.0
    return rho_value(bernstein_mean(c), mode, threshold)


@njit(**NJIT_INLINE)
def rho_integral(f_int, length, mode, threshold):
    """int rho over the inside parts from int F and their length (rho is affine in F)."""
    if mode == DENSITY_UNIFORM:
        return length
    if mode == DENSITY_EXCESS:
        return f_int - threshold * length
    return f_int
