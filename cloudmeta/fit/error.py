"""The fit's error against the grid it came from (docs/fit.md, *What the errors mean*).

- Density: the relative L2 error on the grid, |F_fit(x_v) scale - rho_v| / |rho_v| over every voxel centre
  x_v, with F_fit the fitted blob's field (summed ball by ball over the voxels each covers, in double
  precision, 0 where F < T) and rho the grid.
- Optical depth: the relative RMSE along random rays through the box, sqrt(mean (tau_fit - tau_ref)^2) /
  sqrt(mean tau_ref^2). Each ray is the line through two points drawn uniformly in the box, cut to the box.
  tau_fit is exact (cloudmeta.optical_depth of the fitted medium, mode `field`); tau_ref integrates the
  grid's trilinear interpolant (0 outside the grid: voxel values padded with zeros) by the midpoint rule
  with ``samples`` points per smallest voxel width, far finer than the interpolant's variation.
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError

RAYS = 10_000          #: rays of the reported optical-depth error
SAMPLES = 8            #: midpoint samples per voxel width of the reference
SEED = 12345           #: the rays' seed (fixed: the reported error is reproducible)


def voxel_centers(shape, lower, upper):
    """(nx ny nz, 3) voxel centres, x slowest (the order of density.ravel())."""
    shape = tuple(int(s) for s in shape)
    h = (np.asarray(upper, float) - np.asarray(lower, float)) / np.array(shape)
    axes = [lower[a] + (np.arange(shape[a]) + 0.5) * h[a] for a in range(3)]
    g = np.meshgrid(*axes, indexing="ij")
    return np.stack([x.ravel() for x in g], axis=1)


def grid_field(blob, shape, lower, upper, budget=1 << 22):
    """F of a blob of spheres at every voxel centre, (nx, ny, nz), float64: each ball adds q k(u) to the
    voxels in its support (a stencil per ball: O(balls x voxels a ball covers), where cloudmeta.field
    sums every ball at every point). The wyvill6 kernel, as the fit writes; F < T set to 0 (mode field)."""
    shape = np.array([int(s) for s in shape])
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    h = (upper - lower) / shape
    centers, weights = np.asarray(blob.centers, float), np.asarray(blob.weights, float)
    radii = np.asarray(blob.radii, float)
    if radii.ndim == 2:
        if not np.allclose(radii, radii[:, :1]):
            raise InputError("grid_field: spheres only")
        radii = radii[:, 0]
    out = np.zeros(int(np.prod(shape)))
    for radius in np.unique(radii):
        sel = radii == radius
        c, q = centers[sel], weights[sel]
        reach = np.ceil(radius / h).astype(np.int64)
        offs = np.stack([g.ravel() for g in np.meshgrid(*[np.arange(-r, r + 2) for r in reach], indexing="ij")],
                        axis=1)
        idx = (c - lower) / h - 0.5
        base = np.floor(idx).astype(np.int64)
        chunk = max(1, budget // len(offs))
        for s in range(0, len(c), chunk):
            b = base[s:s + chunk, None, :] + offs[None, :, :]
            d = (b - idx[s:s + chunk, None, :]) * h
            u = np.einsum("mkc,mkc->mk", d, d) / radius ** 2
            ok = (u < 1.0) & (b >= 0).all(axis=2) & (b < shape).all(axis=2)
            m_i, k_i = np.nonzero(ok)
            bb = b[m_i, k_i]
            uu = u[m_i, k_i]
            flat = (bb[:, 0] * shape[1] + bb[:, 1]) * shape[2] + bb[:, 2]
            out += np.bincount(flat, weights=q[s:s + chunk][m_i] * (1.0 - uu) ** 2 * (1.0 - 4.0 * uu / 9.0),
                               minlength=len(out))
    out[out < blob.threshold] = 0.0
    return out.reshape(tuple(shape))


def density_error(blob, scale, density, lower, upper):
    """Relative L2 error of scale x F(voxel centres) against the grid's density (F < T counted as 0)."""
    y = np.asarray(density, dtype=float)
    f = scale * grid_field(blob, y.shape, lower, upper)
    den = float(np.sum(y * y))
    return float(np.sqrt(np.sum((f - y) ** 2) / den)) if den > 0 else float("nan")


def random_rays(lower, upper, n=RAYS, seed=SEED):
    """(origins, directions, lengths): ``n`` lines through two uniform points in the box, each from where
    it enters the box to where it leaves (origin on the box, unit direction, length inside)."""
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    rng = np.random.default_rng(seed)
    a = lower + rng.random((n, 3)) * (upper - lower)
    b = lower + rng.random((n, 3)) * (upper - lower)
    d = b - a
    norm = np.linalg.norm(d, axis=1)
    bad = norm < 1e-12 * np.linalg.norm(upper - lower)
    d[bad] = [1.0, 0.0, 0.0]
    norm[bad] = 1.0
    d /= norm[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        t0 = (lower - a) / d
        t1 = (upper - a) / d
    t_in = np.nanmax(np.where(np.isfinite(t0), np.minimum(t0, t1), -np.inf), axis=1)
    t_out = np.nanmin(np.where(np.isfinite(t0), np.maximum(t0, t1), np.inf), axis=1)
    origins = a + t_in[:, None] * d
    return origins, d, np.maximum(t_out - t_in, 0.0)


def reference_depth(density, lower, upper, origins, directions, lengths, samples=SAMPLES,
                    budget=1 << 22):
    """Optical depth of the grid's trilinear interpolant (zero outside the grid) along each ray over
    [0, length], by the midpoint rule with ``samples`` points per smallest voxel width."""
    rho = np.asarray(density, dtype=float)
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    shape = np.array(rho.shape)
    h = (upper - lower) / shape
    pad = np.pad(rho, 1)
    step_target = float(h.min()) / samples
    counts = np.maximum(1, np.ceil(lengths / step_target).astype(np.int64))
    out = np.zeros(len(lengths))
    i = 0
    while i < len(lengths):
        j, total = i, 0
        while j < len(lengths) and (j == i or total + counts[j] <= budget):
            total += counts[j]
            j += 1
        c = counts[i:j]
        ray = np.repeat(np.arange(i, j), c)
        first = np.repeat(np.cumsum(c) - c, c)
        k = np.arange(total) - first
        dt = lengths[ray] / counts[ray]
        t = (k + 0.5) * dt
        p = origins[ray] + t[:, None] * directions[ray]
        g = (p - lower) / h + 0.5            # index in the padded array (voxel 0's centre at 1)
        g = np.clip(g, 0.0, shape + 1 - 1e-9)
        g0 = np.floor(g).astype(np.int64)
        f = g - g0
        g0 = np.minimum(g0, shape)            # a point on the last centre interpolates with weight 0
        x0, y0, z0 = g0[:, 0], g0[:, 1], g0[:, 2]
        fx, fy, fz = f[:, 0], f[:, 1], f[:, 2]
        v = 0.0
        for ddx, wx in ((0, 1 - fx), (1, fx)):
            for ddy, wy in ((0, 1 - fy), (1, fy)):
                for ddz, wz in ((0, 1 - fz), (1, fz)):
                    v = v + wx * wy * wz * pad[x0 + ddx, y0 + ddy, z0 + ddz]
        out[i:j] = np.bincount(ray - i, weights=v * dt, minlength=j - i)
        i = j
    return out


def depth_error(blob, scale, density, lower, upper, rays=RAYS, seed=SEED, samples=SAMPLES,
                reference=None):
    """(relative RMSE, tau_fit, tau_ref) along ``rays`` random rays; ``reference`` reuses
    (origins, directions, lengths, tau_ref) of an earlier call with the same rays."""
    import cloudmeta as cm
    if reference is None:
        reference = depth_reference(density, lower, upper, rays, seed, samples)
    o, d, length, tau_ref = reference
    tau_fit = cm.optical_depth(blob, o, d, t_max=length, density="field", scale=scale)
    den = float(np.sqrt(np.mean(tau_ref ** 2)))
    if den == 0:
        raise InputError("grid: no ray through the box meets any density")
    return float(np.sqrt(np.mean((tau_fit - tau_ref) ** 2)) / den), tau_fit, tau_ref


def depth_reference(density, lower, upper, rays=RAYS, seed=SEED, samples=SAMPLES):
    """(origins, directions, lengths, tau_ref) of the random rays."""
    o, d, length = random_rays(lower, upper, rays, seed)
    return o, d, length, reference_depth(density, lower, upper, o, d, length, samples)
