"""The optical depth of a shadow ray through one blob, without its pieces: ``sweep.inside_pieces`` and
``sweep.pieces_optical_depth`` fused into one pass over ``sweep.composite``'s intervals.

A shadow ray needs one number, tau = scale * int rho over {F >= T}, not the pieces. The full sweep calls
``clip_roots`` on every composite interval and cuts out every inside piece by two de Casteljau splits
before it integrates them; on the cumulus a shadow ray has 15 intervals, 11 of them wholly inside and
about one that straddles T. Here each of composite's intervals is classed by its control values:

- the hull above T: wholly inside, its integral is the length times the mean of the control values;
- the hull below T: wholly outside;
- otherwise ``clip_roots`` with inside_pieces' rules (a root counts only where the class changes; the
  class at the interval's start is that of F there), the inside parts integrated by the antiderivative
  (a degree-7 Bernstein polynomial).

The integral of rho is affine in that of F (docs/model.md §4), so all three density modes come from the
integral of F and the inside length. The same polynomials and roots as the full sweep, summed in another
order: the depth agrees to rounding (tests/kernels/test_shadow.py).

The pass also counts the ray's entries into {F >= T}. Along a camera ray that count changes exactly where a
shadow line grazes the isosurface: a fold of the light's optical depth, which the quadrature cuts at
(kernels.single ``step_in_scattering``).
"""
from numba import njit

from .config import NJIT, NJIT_INLINE
from .bernstein import NCOEF, bernstein_cumulative
from .clipping import clip_roots
from .density import rho_integral
from .sweep import NOISE, composite, gather_all_chords


@njit(**NJIT_INLINE)
def _antiderivative(g, s, threshold):
    """int_0^s F, where g holds F - T on the interval."""
    return bernstein_cumulative(g, s) + threshold * s


@njit(**NJIT)
def straddling_interval(w, threshold, tol_t, mag, scratch):
    """The inside parts of an interval of length w whose hull straddles T (scratch.g: F - T on it; mag
    the magnitude of its control values): classes and roots as inside_pieces takes them. Returns (int of F
    over the inside parts, their length, the entries into the inside at its roots, the class at its end)."""
    g = scratch.g
    inside = g[0] >= 0.0  # the class at its start (a jump at a chord end counts)
    entries = 0
    n_r = clip_roots(g, tol_t / w, NOISE * (threshold + mag), scratch.st_lo, scratch.st_hi, scratch.st_c,
                     scratch.loc, scratch.rising)
    f_int = 0.0
    s_in = 0.0
    span = 0.0
    for j in range(n_r):
        if scratch.rising[j] == inside:
            continue  # inconsistent with the class we are in: rounding; keep the class we have
        s = scratch.loc[j]
        if inside:
            f_int += _antiderivative(g, s, threshold) - _antiderivative(g, s_in, threshold)
            span += s - s_in
        else:
            s_in = s
            entries += 1
        inside = scratch.rising[j]
    end_inside = inside
    if inside:
        f_int += _antiderivative(g, 1.0, threshold) - _antiderivative(g, s_in, threshold)
        span += 1.0 - s_in
    return w * f_int, w * span, entries, end_inside


@njit(**NJIT)
def intervals_depth(n_iv, threshold, mode, tol_t, scratch):
    """int rho over {F >= T} on the n_iv composite intervals in the scratch (``composite``'s), rho by density
    ``mode``: each classed as ``inside_pieces`` classes it and integrated without cutting out its pieces.
    (The class carried from one interval to the next, which inside_pieces needs for its transitions, does
    not change the measure: each interval starts in the class of F at its start.) Returns (the integral, the
    number of entries into the inside: an interval that starts inside after a gap or an outside part enters)."""
    iv_t0, iv_t1, iv_c, iv_mag, g = scratch.iv_t0, scratch.iv_t1, scratch.iv_c, scratch.iv_mag, scratch.g
    f_int = 0.0
    length = 0.0
    entries = 0
    inside = False  # the class at the end of the last interval (F = 0 < T between chords)
    for k in range(n_iv):
        if k > 0 and iv_t0[k] > iv_t1[k - 1]:
            inside = False
        w = iv_t1[k] - iv_t0[k]
        lo = iv_c[k, 0]
        hi = iv_c[k, 0]
        mean = 0.0
        for q in range(NCOEF):
            lo = min(lo, iv_c[k, q])
            hi = max(hi, iv_c[k, q])
            mean += iv_c[k, q]
        if lo - threshold >= 0.0:
            # the hull lies above T: wholly inside (clip_roots would find no root)
            f_int += w * (mean * (1.0 / NCOEF))
            length += w
            if not inside:
                entries += 1
            inside = True
        elif hi - threshold >= 0.0:
            for q in range(NCOEF):
                g[q] = iv_c[k, q] - threshold
            if g[0] >= 0.0 and not inside:
                entries += 1  # it starts inside (its class there, as straddling_interval takes it)
            f_part, span, n_in, inside = straddling_interval(w, threshold, tol_t, iv_mag[k] * NCOEF, scratch)
            f_int += f_part
            length += span
            entries += n_in
        else:  # the hull lies below T: wholly outside
            inside = False
    return rho_integral(f_int, length, mode, threshold), entries


@njit(**NJIT_INLINE)
def column_density(o, d, tmin, tmax, blob, mode, tol_t, cand, n_cand, scratch):
    """The integral of rho over {F >= T} along the ray within [tmin, tmax] through ``blob`` (its balls
    cand[:n_cand]), rho by density ``mode`` (docs/model.md §4): the optical depth over the medium's scale.
    Grows the scratch when the ray meets more chords than it holds. Returns (scratch, the integral, the
    entries into the medium)."""
    scratch, n_p = gather_all_chords(o, d, tmin, tmax, blob, cand, n_cand, scratch)
    if n_p == 0:
        return scratch, 0.0, 0
    n_iv = composite(n_p, tmin, tmax, scratch)
    rho, entries = intervals_depth(n_iv, blob.threshold, mode, tol_t, scratch)
    return scratch, rho, entries
