"""Random numbers and the sampling routines of the multiple-scattering path tracer (kernels.multiple).

- ``uniform``: a counter-based stream: the number for (seed, pixel, sample, order, dim) is a hash of
  those integers alone (splitmix64's finaliser, chained), so a render does not depend on the order in
  which threads take pixels, nor on their number.
- ``sample_phase_cos``: cos theta of a new direction drawn exactly from each phase function of docs/model.md §4
  (HG by inversion of its CDF, double HG by its lobe, Rayleigh by the real root of its CDF's cubic,
  isotropic), with cos theta = d' . d, d the incoming propagation direction (so g > 0 keeps going forward).
- ``sobol4``: four numbers of the randomised quasi-Monte Carlo stream for (seed, pixel, path, block): the
  first four dimensions of Sobol's sequence (Joe and Kuo's direction numbers), with the path index
  shuffled and every dimension Owen-scrambled by hashes of (seed, pixel, block, dimension) (Burley 2020,
  "Practical hash-based Owen scrambling"; the "padded" Sobol sampler of pbrt-v4). Within one pixel and one
  block the paths' points are a scrambled (t, m, 4)-net, so the integrand's smooth part averages out
  faster than with independent numbers; across blocks, pixels and seeds they are independent.
- ``free_flight``: the distance at which the exact optical depth of a Bernstein piece reaches a target
  (``invert_depth``: Newton on the exact antiderivative, kept in a bisection bracket).
"""
import math

import numpy as np
from numba import njit

from .config import NJIT, NJIT_INLINE
from .bernstein import bernstein_cumulative, bernstein_eval
from .kinds import DOUBLE_HG, HG, RAYLEIGH

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M32 = np.uint64(0xFFFFFFFF)


def _sobol_matrices(bits=32):
    """The direction numbers v_k (k = 1 .. bits, as 32-bit integers) of Sobol's first four dimensions:
    dimension 0 is van der Corput's; 1-3 follow Joe and Kuo's table (new-joe-kuo-6.21201: s, a, m_i =
    (1, 0, 1), (2, 1, 1 3), (3, 1, 1 3 1)) through the recurrence of Bratley and Fox. Checked against
    scipy.stats.qmc.Sobol in the tests."""
    table = [(0, 0, ()), (1, 0, (1,)), (2, 1, (1, 3)), (3, 1, (1, 3, 1))]
    out = np.zeros((4, bits), dtype=np.uint64)
    for dim, (s, a, m_init) in enumerate(table):
        m = [1] * bits if dim == 0 else list(m_init)
        for k in range(len(m), bits):
            new = m[k - s] ^ (m[k - s] << s)
            for j in range(1, s):
                if (a >> (s - 1 - j)) & 1:
                    new ^= m[k - j] << j
            m.append(new)
        for k in range(bits):
            out[dim, k] = m[k] << (bits - 1 - k)
    return out


def _sobol_bytes(v):
    """table[dim, b, byte]: the XOR of the direction numbers v[dim, 8 b + i] over the set bits i of byte, so
    that Sobol's point for an index is the XOR of four table entries, one per byte of the index (the same
    point as the bit-by-bit loop, without its 32 unpredictable branches)."""
    dims, bits = v.shape
    byte = np.arange(256, dtype=np.uint64)
    table = np.zeros((dims, bits // 8, 256), dtype=np.uint64)
    for b in range(bits // 8):
        for i in range(8):
            has_bit = ((byte >> np.uint64(i)) & np.uint64(1)).astype(bool)
            table[:, b, has_bit] ^= v[:, 8 * b + i][:, None]
    return table


SOBOL_V = _sobol_matrices()
SOBOL_BYTES = _sobol_bytes(SOBOL_V)
#: below this |g| the HG inversion loses digits (it divides by g): sample isotropically, the difference
#: in the phase function is below 3|g|
_G_ISOTROPIC = 1e-6


@njit(**NJIT_INLINE)
def mix64(z):
    """splitmix64's finaliser (a bijection of 64-bit integers with full avalanche)."""
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


@njit(**NJIT)
def uniform(seed, pixel, sample, order, dim):
    """A number in [0, 1) that depends only on (seed, pixel, sample, order, dim): each integer is folded
    into the state through a full mixing round, so neighbouring counters give unrelated numbers."""
    z = mix64(np.uint64(seed) * _GOLDEN + np.uint64(pixel))
    z = mix64(z + np.uint64(sample) * _GOLDEN)
    z = mix64(z + np.uint64(order) * _GOLDEN)
    z = mix64(z + np.uint64(dim) * _GOLDEN + np.uint64(1))
    return float(z >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@njit(**NJIT_INLINE)
def _reverse_bits32(v):
    v = ((v >> np.uint64(1)) & np.uint64(0x55555555)) | ((v & np.uint64(0x55555555)) << np.uint64(1))
    v = ((v >> np.uint64(2)) & np.uint64(0x33333333)) | ((v & np.uint64(0x33333333)) << np.uint64(2))
    v = ((v >> np.uint64(4)) & np.uint64(0x0F0F0F0F)) | ((v & np.uint64(0x0F0F0F0F)) << np.uint64(4))
    v = ((v >> np.uint64(8)) & np.uint64(0x00FF00FF)) | ((v & np.uint64(0x00FF00FF)) << np.uint64(8))
    return ((v >> np.uint64(16)) & np.uint64(0xFFFF)) | ((v & np.uint64(0xFFFF)) << np.uint64(16))


@njit(**NJIT)
def owen_scramble(v, seed):
    """A nested uniform (Owen) scramble of the 32-bit fraction v, keyed by the 32-bit seed: in bit-reversed
    order every step changes a bit only as a function of the bits below it (Laine and Karras's
    permutation with Burley's constants), so each digit of v is permuted as a function of the digits
    above it, which is Owen's scrambling, with a hash for its random permutations."""
    v = _reverse_bits32(v)
    v ^= (v * np.uint64(0x3D20ADEA)) & _M32
    v = (v + seed) & _M32
    v = (v * ((seed >> np.uint64(16)) | np.uint64(1))) & _M32
    v ^= (v * np.uint64(0x05526C56)) & _M32
    v ^= (v * np.uint64(0x53A22864)) & _M32
    return _reverse_bits32(v)


@njit(**NJIT_INLINE)
def _sobol32(index, dim):
    """Sobol's point (a 32-bit fraction) of dimension dim for a 32-bit index: four byte lookups (the
    scrambled indices use all 32 bits, and a loop over them cost ~100 ns)."""
    byte = np.uint64(0xFF)
    t = SOBOL_BYTES[dim]
    return (t[0, index & byte] ^ t[1, (index >> np.uint64(8)) & byte] ^ t[2, (index >> np.uint64(16)) & byte]
            ^ t[3, (index >> np.uint64(24)) & byte])


@njit(**NJIT_INLINE)
def _key32(seed, pixel, block, dim):
    z = mix64(np.uint64(seed) * _GOLDEN + np.uint64(pixel))
    z = mix64(z + np.uint64(block) * _GOLDEN + np.uint64(0x51ED27))
    z = mix64(z + np.uint64(dim) * _GOLDEN + np.uint64(1))
    return z >> np.uint64(32)


@njit(**NJIT)
def sobol4(seed, pixel, path, block):
    """Four numbers in [0, 1) for path ``path`` of a pixel, in block ``block`` (one vertex of the path):
    Sobol's first four dimensions at the path's index shuffled by an Owen scramble of its bits (for the
    first 2^m paths, a permutation of one aligned block of 2^m indices, so they stay a net), each
    dimension Owen-scrambled on its own. Keyed by (seed, pixel, block) alone: threads cannot change it."""
    shuffled = owen_scramble(np.uint64(path) & _M32, _key32(seed, pixel, block, 4))
    scale = 1.0 / 4294967296.0
    u0 = float(owen_scramble(_sobol32(shuffled, 0), _key32(seed, pixel, block, 0))) * scale
    u1 = float(owen_scramble(_sobol32(shuffled, 1), _key32(seed, pixel, block, 1))) * scale
    u2 = float(owen_scramble(_sobol32(shuffled, 2), _key32(seed, pixel, block, 2))) * scale
    u3 = float(owen_scramble(_sobol32(shuffled, 3), _key32(seed, pixel, block, 3))) * scale
    return u0, u1, u2, u3


@njit(**NJIT)
def sample_hg_cos(g, u):
    """cos theta with density HG(g) in cos theta: the inverse of its CDF."""
    if abs(g) < _G_ISOTROPIC:
        return 1.0 - 2.0 * u
    q = (1.0 - g * g) / (1.0 - g + 2.0 * g * u)
    return min(1.0, max(-1.0, (1.0 + g * g - q * q) / (2.0 * g)))


@njit(**NJIT)
def sample_rayleigh_cos(u):
    """cos theta with density 3/8 (1 + mu^2): the real root of mu^3 + 3 mu + 4 - 8u = 0 (Cardano; the
    discriminant is positive, one real root): mu = A - 1/A, A = cbrt(4u - 2 + sqrt((4u - 2)^2 + 1))."""
    a = 4.0 * u - 2.0
    big = (a + math.sqrt(a * a + 1.0)) ** (1.0 / 3.0)
    return min(1.0, max(-1.0, big - 1.0 / big))


@njit(**NJIT)
def sample_phase_cos(kind, g1, g2, w, u_lobe, u):
    """cos theta drawn from the phase function (kind, g1, g2, w) as packed by the renderer; u_lobe picks
    the lobe of a double HG (probability w for g1)."""
    if kind == HG:
        return sample_hg_cos(g1, u)
    if kind == DOUBLE_HG:
        return sample_hg_cos(g1 if u_lobe < w else g2, u)
    if kind == RAYLEIGH:
        return sample_rayleigh_cos(u)
    return 1.0 - 2.0 * u


@njit(**NJIT)
def turn(d, cos_theta, u_phi, out):
    """out = the unit direction at angle theta from the unit vector d, azimuth 2 pi u_phi about it (an
    orthonormal frame after Duff et al. 2017, branch-free but for the sign)."""
    sign = 1.0 if d[2] >= 0.0 else -1.0
    a = -1.0 / (sign + d[2])
    b = d[0] * d[1] * a
    t0, t1, t2 = 1.0 + sign * d[0] * d[0] * a, sign * b, -sign * d[0]
    b0, b1, b2 = b, sign + d[1] * d[1] * a, -d[1]
    sin_theta = math.sqrt(max(0.0, 1.0 - cos_theta * cos_theta))
    phi = 2.0 * math.pi * u_phi
    x = sin_theta * math.cos(phi)
    y = sin_theta * math.sin(phi)
    out[0] = x * t0 + y * b0 + cos_theta * d[0]
    out[1] = x * t1 + y * b1 + cos_theta * d[1]
    out[2] = x * t2 + y * b2 + cos_theta * d[2]
    norm = math.sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2])
    for c in range(3):
        out[c] /= norm


@njit(**NJIT)
def invert_depth(S, w, target, lo, s, tol, max_steps, open_bracket):
    """s in [lo, 1] where w * integral_0^s S (the optical depth across a piece of length w whose sigma_t
    has Bernstein control values S) reaches target; s: the first guess. The depth is monotone (sigma_t >= 0
    inside), so Newton steps on the exact antiderivative are kept inside a shrinking bisection bracket
    [lo, hi]: every step either converges quadratically or halves the bracket. A step outside the bracket
    (or on its ends, where open_bracket) bisects instead; the search stops once a step or the bracket is
    within tol, or after max_steps. The one Newton inversion of the kernels: free flights here, the
    quadrature's nodes in optical depth (kernels.single)."""
    hi = 1.0
    for _ in range(max_steps):
        f = w * bernstein_cumulative(S, s) - target
        if f < 0.0:
            lo = s
        else:
            hi = s
        slope = w * bernstein_eval(S, s)
        sn = s - f / slope if slope > 0.0 else 0.5 * (lo + hi)
        if (not (lo < sn < hi)) if open_bracket else (not (lo <= sn <= hi)):
            sn = 0.5 * (lo + hi)
        if abs(sn - s) <= tol or hi - lo <= tol:
            return sn
        s = sn
    return s


@njit(**NJIT)
def free_flight(S, w, target):
    """s in [0, 1] where w * integral_0^s S (the optical depth across a piece of length w whose sigma_t
    has Bernstein control values S) reaches target, 0 <= target <= w * mean(S) (invert_depth from the root
    for a constant sigma_t)."""
    total = w * bernstein_cumulative(S, 1.0)
    s = target / total if total > 0.0 else 0.5  # the root for a constant sigma_t
    return min(max(invert_depth(S, w, target, 0.0, s, 1e-15, np.int64(100), np.bool_(False)), 0.0), 1.0)
