"""The approximate mode's grid method (``render: {scattering: approximate, method: grid}``, docs/approximate.md):
the grid of scattered light towards the camera that kernels.fluence deposits and the single-scattering
quadrature gathers.

``radiance_grid`` spreads the photons over the lights and the environment by power, traces them in
BATCHES fixed batches on threads (each deposits into its own array; the sum runs in batch order, so the grid
does not depend on the thread count), and turns the sums into the field's moments at the cells' centres.
Its resolution, photon count and where the photons deposit are the frame's FrameSettings.grid (its quality
preset's, renderer.quality.PRESETS, or ``render.grid``'s). ``delta_split`` takes each phase function's forward peak
out of the deposits and into the camera ray's extinction (docs/approximate.md).

``fluence_cache`` traces the same photons, in the same batches, for the shared method (renderer.shared): the
spherical harmonics of the scattered radiance, without the camera, which its path tails read beyond an order.
"""
from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np

from ..kernels.fluence import (ENVIRONMENT, FLIGHTS, MOMENTS, SH_DEGREE, SH_TERMS, cell_scattering,
                               trace_photons)
from ..kernels.kinds import DIRECTIONAL
from ..kernels.optics import phase
from ..kernels.records import FluenceCache, PhotonSources, RadianceGrid
from ..scene.atmosphere import sky_mean
from .quality import resolve_settings
from .tracking import RR_ORDER, majorant_grid

#: photons are traced in this many batches, whatever the threads (bit-identical grids)
BATCHES = 8
#: the half-angle (degrees) of the forward cone whose phase peak the camera ray carries, not the grid
PEAK_DEGREES = 10.0
#: the cells' integral of sigma_s (render.grid.deposit: collisions): the mean over SUBCELLS^3 points per cell
SUBCELLS = 4
#: texels per side of a directional light's footprint on its photons' disk (sun_footprint)
FOOTPRINT_TEXELS = 256


def sun_footprint(mgrid, w, centre, radius, texels=FOOTPRINT_TEXELS):
    """(footprint (texels, texels) uint8, axes (2, 3)): which texels of the disk (centre, radius) perpendicular
    to the unit w hold a ray along w that can meet a cell of the majorant grid mgrid with media. Conservative:
    a texel is marked where its centre lies within a cell's bounding-sphere radius plus half the texel's
    diagonal of the cell centre's projection, so no ray that meets a cell starts in an unmarked texel."""
    a = np.cross(w, [0.0, 0.0, 1.0] if abs(w[2]) < 0.9 else [1.0, 0.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.cross(w, a)
    axes = np.stack([a, b])
    footprint = np.zeros((texels, texels), np.uint8)
    cells = np.nonzero(mgrid.sigma_max > 0.0)[0]
    if len(cells) == 0:
        return footprint, axes
    nx, ny = mgrid.dims[0], mgrid.dims[1]
    ijk = np.stack([cells % nx, (cells // nx) % ny, cells // (nx * ny)], axis=1)
    projected = ((mgrid.origin + (ijk + 0.5) * mgrid.size) - centre) @ axes.T + radius  # (n, 2), from the corner
    px = 2.0 * radius / texels
    reach = 0.5 * math.sqrt(3.0) * mgrid.size + px / math.sqrt(2.0)
    span = int(math.ceil(reach / px)) + 1
    base = np.floor(projected / px).astype(np.int64)
    for di in range(-span, span + 1):
        for dj in range(-span, span + 1):
            idx = base + np.array([di, dj])
            near = np.hypot((idx[:, 0] + 0.5) * px - projected[:, 0], (idx[:, 1] + 0.5) * px - projected[:, 1])
            keep = (near <= reach * (1.0 + 1e-9)) & np.all((idx >= 0) & (idx < texels), axis=1)
            footprint[idx[keep, 0], idx[keep, 1]] = 1
    return footprint, axes


def photon_sources(records, centre, radius, photons, mgrid=None) -> PhotonSources:
    """The lights and the environment (records: the packed records.SceneRecords) as photon sources around the
    sphere (centre, radius), ``photons`` shared among those with light by power; each directional light's
    footprint on its disk from the majorant grid mgrid (sun_footprint; everywhere where mgrid is None)."""
    sources = []  # (kind, vec, the power of all its photons per unit of rgb)
    lights = records.lights
    disk = math.pi * radius * radius
    for li in range(len(lights.kind)):
        per = disk if lights.kind[li] == DIRECTIONAL else 4.0 * math.pi  # irradiance x disk, intensity x 4 pi
        sources.append((int(lights.kind[li]), lights.vec[li], lights.rgb[li] * per))
    # the environment's photons carry its radiance along their direction (kernels.fluence.emit): its mean here
    sky = np.asarray(sky_mean(records.background), np.float64)
    sources.append((ENVIRONMENT, np.zeros(3), sky * (4.0 * math.pi * disk)))
    sources = [src for src in sources if np.sum(src[2]) > 0]
    powers = np.array([np.sum(src[2]) for src in sources])
    counts = np.maximum(1, np.round(photons * powers / max(powers.sum(), 1e-300))).astype(np.int64)
    # one photon's rgb: a light's power per photon; the environment's 4 pi x disk per photon, times its radiance
    unit = [(np.full(3, 4.0 * math.pi * disk) if kind == ENVIRONMENT else power) / n
            for (kind, _, power), n in zip(sources, counts)]
    footprint = np.ones((len(sources), FOOTPRINT_TEXELS, FOOTPRINT_TEXELS), np.uint8)
    axes = np.zeros((len(sources), 2, 3))
    for k, (kind, vec, _) in enumerate(sources):
        if kind == DIRECTIONAL and mgrid is not None:
            footprint[k], axes[k] = sun_footprint(mgrid, -np.asarray(vec, np.float64), centre, radius)
    return PhotonSources(footprint=footprint, axes=axes, kind=np.array([src[0] for src in sources], np.int64),
                         vec=np.array([src[1] for src in sources], np.float64).reshape(-1, 3),
                         rgb=np.ascontiguousarray(np.array(unit, np.float64).reshape(-1, 3)),
                         first=np.concatenate([[0], np.cumsum(counts)]).astype(np.int64),
                         centre=np.ascontiguousarray(centre, np.float64), radius=float(radius),
                         background=records.background)


def phase_peak(row, cos_c):
    """(f, p_c) of a medium's phase function (records.Media.phase row): p_c = p(cos_c) and f the part of p above
    p_c inside the cone cos theta > cos_c, f = 1 - the integral over the sphere of p clamped to p_c there."""
    x = (np.arange(20_000) + 0.5) / 20_000  # cos = 1 - (1 - cos_c) x^3 crowds the nodes into the peak
    cos = 1.0 - (1.0 - cos_c) * x ** 3
    dcos = 3.0 * (1.0 - cos_c) * x ** 2 / x.size
    p = phase_table(row, cos)
    p_c = float(phase_table(row, np.array([cos_c]))[0])
    f = 2.0 * math.pi * float(np.sum(np.maximum(p - p_c, 0.0) * dcos))
    return f, p_c


def phase_table(row, cos):
    """The phase function of a records.Media.phase row at each of the cosines ``cos``."""
    return np.array([phase(row[0], row[1], row[2], row[3], float(c)) for c in cos])


def delta_split(media, peak_degrees):
    """(peak (M, 2) for the grid's deposits, the camera ray's records.Media): each medium's forward peak f
    leaves the camera ray's extinction, sigma_t - f sigma_s, and its scattering (docs/approximate.md)."""
    cos_c = math.cos(math.radians(peak_degrees))
    split = [phase_peak(row, cos_c) for row in media.phase]
    f = np.array([s[0] for s in split])
    keep = 1.0 - f * media.albedo
    peak = np.array([[cos_c, s[1]] for s in split], np.float64).reshape(-1, 2)
    return peak, media._replace(scale=media.scale * keep, albedo=media.albedo / keep)


def _box(mgrid, cells):
    """(origin, cell size, dims, sphere centre, sphere radius): cubic cells over the majorant grid's box, as many as
    a cube of ``cells`` per side (a flat deck gets cells as small as a round cloud's), and the sphere around it that
    the parallel photons cross."""
    lo = mgrid.origin
    extent = mgrid.dims * mgrid.size
    size = min(float(np.prod(extent)) ** (1.0 / 3.0) / cells, float(extent.max()) / 2.0)
    dims = np.maximum(np.ceil(extent / size - 1e-9), 1).astype(np.int64)
    return (np.ascontiguousarray(lo, np.float64), size, dims, lo + 0.5 * extent,
            0.5 * float(np.linalg.norm(extent)) * 1.001)


def _trace_batches(med, mgrid, src, shell, shape, seed, max_order, where):
    """The photons' deposits (``shape``: cells x 3 x moments), traced in BATCHES fixed batches on threads and summed
    in batch order: the same sum on any thread count."""
    total = int(src.first[-1])
    edges = [total * b // BATCHES for b in range(BATCHES + 1)]

    def batch(b):
        coef = np.zeros(shape)
        trace_photons(med, mgrid, src, shell, coef, np.int64(seed), np.int64(edges[b]), np.int64(edges[b + 1]),
                      np.int64(max_order), np.int64(RR_ORDER), np.int64(where))
        return coef

    coef = np.zeros(shape)
    threads = numba.get_num_threads()
    with ThreadPoolExecutor(threads) as pool:
        for wave in range(0, BATCHES, threads):  # a wave of batches at a time: threads + 1 arrays in memory
            for part in pool.map(batch, range(wave, min(wave + threads, BATCHES))):
                coef += part
    return coef


def radiance_grid(scene, records, seed, camera_position, peak, grid) -> RadianceGrid:
    """The records.RadianceGrid of the scene (records: its packed records.SceneRecords) seen from
    camera_position, depositing the phase functions clamped by peak (delta_split), with ``grid`` = (cells, photons,
    deposit), FrameSettings.grid: module docstring."""
    cells, photons, where = grid
    med = records.media
    mgrid = majorant_grid(scene, med)
    lo, size, dims, centre, radius = _box(mgrid, cells)
    src = photon_sources(records, centre, radius, photons, mgrid)
    k, j, i = np.meshgrid(*(np.arange(n) for n in dims[::-1]), indexing="ij")
    centres = lo + (np.stack([i, j, k], -1).reshape(-1, 3) + 0.5) * size
    towards = np.asarray(camera_position, np.float64) - centres
    towards /= np.maximum(np.linalg.norm(towards, axis=1, keepdims=True), 1e-300)
    n_cells, n_media = len(centres), len(med.albedo)
    shell = RadianceGrid(origin=lo, size=size, dims=dims, coef=np.zeros((1, 3, n_media)),
                         towards=np.ascontiguousarray(towards), peak=peak, filled=np.ones((1, n_media)))
    coef = _trace_batches(med, mgrid, src, shell, (n_cells, 3, n_media), seed, int(scene.render.max_order), where)
    if where == FLIGHTS:
        return shell._replace(coef=coef / size ** 3, filled=np.ones((n_cells, n_media)))
    # the collisions estimate each cell's integral of sigma_s,m S_m; the gather divides it by that of sigma_s,m
    # (both interpolated): S_m where the medium is, not diluted by the cell's empty part, and a thin cell's few
    # collisions weigh as little as its sigma_s
    sigma_s = np.zeros((n_cells, n_media))
    cell_scattering(mgrid, med, shell, np.int64(SUBCELLS), sigma_s)
    return shell._replace(coef=coef / size ** 3, filled=sigma_s / size ** 3)


def no_cache(n_media) -> FluenceCache:
    """The FluenceCache that no tail reads (order 0): the kernels' one signature with or without a cache."""
    return FluenceCache(origin=np.zeros(3), size=1.0, dims=np.ones(3, np.int64),
                        moments=np.zeros((1, 3, SH_TERMS)), phase_moments=np.zeros((n_media, SH_TERMS)), order=0)


def fluence_cache(scene, records, seed, order, cells, photons) -> FluenceCache:
    """The shared method's records.FluenceCache: the spherical harmonics of the scattered light's radiance (and the
    environment's) in a grid of about ``cells`` cubic cells per side, from ``photons`` photons, for tails that trace
    the orders up to ``order`` and read the cache beyond it (order 0, or not below the scene's max_order: none)."""
    med = records.media
    max_order = int(scene.render.max_order)
    if order <= 0 or order >= max_order:
        return no_cache(len(med.albedo))
    mgrid = majorant_grid(scene, med)
    lo, size, dims, centre, radius = _box(mgrid, cells)
    src = photon_sources(records, centre, radius, photons, mgrid)
    n_cells = int(np.prod(dims))
    shell = RadianceGrid(origin=lo, size=size, dims=dims, coef=np.zeros((1, 3, SH_TERMS)), towards=np.zeros((1, 3)),
                         peak=np.zeros((len(med.albedo), 2)), filled=np.ones((1, SH_TERMS)))
    # the light at a vertex of order ``order`` reaches the camera ``order`` - 1 scatterings later
    moments = _trace_batches(med, mgrid, src, shell, (n_cells, 3, SH_TERMS), seed, max_order - order + 1, MOMENTS)
    degree = np.array(SH_DEGREE)
    phase_moments = np.array([(-1.0) ** degree * legendre_moments(row)[degree] for row in med.phase], np.float64)
    return FluenceCache(origin=lo, size=size, dims=dims, moments=moments / size ** 3,
                        phase_moments=phase_moments.reshape(-1, SH_TERMS), order=int(order))


def legendre_moments(row, degrees=4, nodes=20_000):
    """k_l = 2 pi int p(mu) P_l(mu) d mu, l < degrees, of a records.Media.phase row's phase function (k_0 = 1; g^l
    for Henyey-Greenstein): midpoint rule in x, mu = 1 - 2 x^3 crowding the nodes into the forward peak."""
    x = (np.arange(nodes) + 0.5) / nodes
    mu = 1.0 - 2.0 * x ** 3
    dmu = 6.0 * x ** 2 / nodes
    p = phase_table(row, mu)
    return np.array([2.0 * math.pi * float(np.sum(p * np.polynomial.legendre.Legendre.basis(l)(mu) * dmu))
                     for l in range(degrees)])


def with_radiance_grid(scene, packed, seed, settings=None):
    """``packed`` (a renderer.pack.Packed) with the grid method's records.RadianceGrid in its records, for a scene
    rendered by ``scattering: approximate, method: grid`` with media (its FrameSettings.grid: ``settings``, else the
    scene's own); else ``packed`` as it is."""
    settings = resolve_settings(scene) if settings is None else settings
    if settings.grid is None or not scene.media:
        return packed
    peak, view = delta_split(packed.records.media, PEAK_DEGREES)
    grid = radiance_grid(scene, packed.records, seed, scene.camera.position, peak, settings.grid)
    return packed._replace(records=packed.records._replace(radiance=grid, view_media=view))
