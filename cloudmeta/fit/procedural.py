"""Procedural voxel clouds for the fit's tests and validation: thresholded fractal value noise in a soft
ellipsoid envelope. They are *not* made of metaballs, so a fit to them measures how well balls represent
a density they did not produce. Deterministic by seed."""
from __future__ import annotations

import numpy as np

from ..errors import InputError


def _value_noise(rng, shape, cells):
    """Value noise on ``shape``: random values on a lattice of about ``cells`` cells along the longest
    axis, interpolated with a smoothstep (C^1) between lattice points."""
    n = max(shape)
    out_axes = []
    lat_shape = []
    for size in shape:
        c = max(1, int(round(cells * size / n)))
        lat_shape.append(c + 1)
        x = (np.arange(size) + 0.5) / size * c
        i0 = np.minimum(np.floor(x).astype(np.int64), c - 1)
        f = x - i0
        f = f * f * (3.0 - 2.0 * f)
        out_axes.append((i0, f))
    lattice = rng.random(lat_shape)
    (ix, fx), (iy, fy), (iz, fz) = out_axes
    # separable interpolation, one axis at a time
    a = lattice[ix] * (1 - fx)[:, None, None] + lattice[ix + 1] * fx[:, None, None]
    a = a[:, iy] * (1 - fy)[None, :, None] + a[:, iy + 1] * fy[None, :, None]
    a = a[:, :, iz] * (1 - fz)[None, None, :] + a[:, :, iz + 1] * fz[None, None, :]
    return a


def noise_cloud(shape=(64, 64, 64), seed=1, octaves=5, base_cells=4, coverage=0.5, peak=1.0,
                size=1.0):
    """A voxel cloud: (density, lower, upper). ``density`` is float64 of ``shape``, >= 0, its largest
    value ``peak`` (sigma_t per unit length); the box is centred on the origin, ``size`` along its longest
    axis, cubic voxels. Fractal value noise (``octaves`` octaves from ``base_cells`` cells, gain 1/2)
    times a soft ellipsoid envelope, less a threshold chosen so that about ``coverage`` of the envelope's
    inside is occupied: a cloud with sharp, noisy edges and holes, like a thresholded simulation field."""
    shape = tuple(int(s) for s in shape)
    if len(shape) != 3 or min(shape) < 2:
        raise InputError(f"shape: expected three sizes >= 2, got {shape}")
    if not 0.0 < coverage <= 1.0:
        raise InputError(f"coverage: expected a number in (0, 1], got {coverage}")
    rng = np.random.default_rng(seed)
    fbm = np.zeros(shape)
    amp, total = 1.0, 0.0
    for o in range(int(octaves)):
        fbm += amp * _value_noise(rng, shape, base_cells * 2 ** o)
        total += amp
        amp *= 0.5
    fbm /= total
    n = max(shape)
    axes = [((np.arange(s) + 0.5) - 0.5 * s) / (0.5 * n) for s in shape]  # -1..1 along the longest axis
    x, y, z = np.meshgrid(*axes, indexing="ij")
    r2 = (x / 0.85) ** 2 + (y / 0.7) ** 2 + (z / 0.55) ** 2
    envelope = np.clip(1.0 - r2, 0.0, None) ** 0.5
    field = fbm * envelope
    inside = envelope > 0
    cut = np.quantile(field[inside], 1.0 - coverage) if inside.any() else 0.0
    density = np.clip(field - cut, 0.0, None)
    top = density.max()
    if top > 0:
        density *= peak / top
    h = size / n
    upper = 0.5 * h * np.array(shape, dtype=float)
    return density, -upper, upper
