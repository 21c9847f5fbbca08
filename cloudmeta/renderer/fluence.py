"""The approximate mode's grid method (``render: {scattering: approximate, method: grid}``, docs/approximate.md):
the radiance grid that kernels.fluence deposits and the single-scattering quadrature gathers.

``radiance_grid`` spreads the photons over the lights and the environment by power, traces them in
BATCHES fixed batches on threads (each deposits into its own array; the sum runs in batch order, so the grid
does not depend on the thread count), and turns the sums into the field's moments at the cells' centres.
Its resolution and photon count come from the quality preset (GRID_PRESETS), or ``render.grid``.
"""
from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np

from ..kernels.fluence import ENVIRONMENT, trace_photons
from ..kernels.kinds import DIRECTIONAL, DOUBLE_HG, HG, RAYLEIGH
from ..kernels.records import PhotonSources, RadianceGrid
from ..scene.atmosphere import sky_mean
from .tracking import RR_ORDER, majorant_grid

#: photons are traced in this many batches, whatever the threads (bit-identical grids)
BATCHES = 8
#: the real spherical harmonics kept: 4 (degree <= 1, the P1 of the issue) or 9 (degree <= 2)
HARMONICS = 9
#: per quality preset: (cells along the longest side of the media's box, photons)
GRID_PRESETS = {"draft": (24, 1 << 17), "default": (32, 1 << 18), "fine": (48, 1 << 20)}


def grid_settings(scene):
    """(cells, photons) of the scene: render.grid's keys, else its quality preset's."""
    cells, photons = GRID_PRESETS[scene.render.quality]
    given_cells, given_photons = scene.render.grid or (None, None)
    return int(given_cells or cells), int(given_photons or photons)


def phase_moments(phase_rows):
    """(M, 3): per medium lambda_0..2 = 2 pi int p(mu) P_l(mu) dmu of its phase function (records.Media.phase
    rows kind, g1, g2, w): 1, g, g^2 for HG, their mix for a double HG, 1, 0, 1/10 for Rayleigh, 1, 0, 0
    isotropic."""
    out = np.zeros((len(phase_rows), 3))
    for m, (kind, g1, g2, w) in enumerate(np.asarray(phase_rows, np.float64)):
        kind = int(kind)
        if kind == HG:
            out[m] = [1.0, g1, g1 * g1]
        elif kind == DOUBLE_HG:
            out[m] = [1.0, w * g1 + (1 - w) * g2, w * g1 * g1 + (1 - w) * g2 * g2]
        elif kind == RAYLEIGH:
            out[m] = [1.0, 0.0, 0.1]
        else:
            out[m] = [1.0, 0.0, 0.0]
    return out


def photon_sources(scene, records, centre, radius, photons) -> PhotonSources:
    """The lights and the environment as photon sources, ``photons`` shared among them by power."""
    kinds, vecs, powers, unit = [], [], [], []
    lights = records.lights
    disk = math.pi * radius * radius
    for li in range(len(lights.kind)):
        rgb = np.asarray(lights.rgb[li], np.float64)
        per = disk if lights.kind[li] == DIRECTIONAL else 4.0 * math.pi  # irradiance x disk, intensity x 4 pi
        kinds.append(int(lights.kind[li]))
        vecs.append(np.asarray(lights.vec[li], np.float64))
        unit.append(rgb * per)
        powers.append(float(np.sum(rgb)) * per)
    sky = np.asarray(sky_mean(records.background), np.float64)
    if np.any(sky > 0):
        kinds.append(ENVIRONMENT)
        vecs.append(np.zeros(3))
        unit.append(np.full(3, 4.0 * math.pi * disk))
        powers.append(float(np.sum(sky)) * 4.0 * math.pi * disk)
    powers = np.asarray(powers)
    keep = powers > 0
    kinds = [k for k, ok in zip(kinds, keep) if ok]
    vecs = [v for v, ok in zip(vecs, keep) if ok]
    unit = [u for u, ok in zip(unit, keep) if ok]
    powers = powers[keep]
    counts = np.maximum(1, np.round(photons * powers / powers.sum())).astype(np.int64) if len(powers) else \
        np.zeros(0, np.int64)
    rgb = np.array([u / n for u, n in zip(unit, counts)], np.float64).reshape(-1, 3)
    return PhotonSources(kind=np.array(kinds, np.int64), vec=np.array(vecs, np.float64).reshape(-1, 3),
                         rgb=np.ascontiguousarray(rgb), first=np.concatenate([[0], np.cumsum(counts)]).astype(np.int64),
                         centre=np.ascontiguousarray(centre, np.float64), radius=float(radius),
                         background=records.background)


def radiance_grid(scene, records, seed) -> RadianceGrid:
    """The records.RadianceGrid of the scene (records: its packed records.SceneRecords): module docstring."""
    cells, photons = grid_settings(scene)
    med = records.media
    mgrid = majorant_grid(scene, med)
    lo = mgrid.origin
    extent = mgrid.dims * mgrid.size
    size = float(extent.max()) / cells
    dims = np.maximum(np.ceil(extent / size - 1e-9), 1).astype(np.int64)
    centre = lo + 0.5 * extent
    radius = 0.5 * float(np.linalg.norm(extent)) * 1.001
    src = photon_sources(scene, records, centre, radius, photons)
    n_cells = int(np.prod(dims))
    shell = RadianceGrid(origin=np.ascontiguousarray(lo, np.float64), size=size, dims=dims,
                         coef=np.zeros((1, 3, HARMONICS)), moments=phase_moments(med.phase))
    total = int(src.first[-1])
    edges = [total * b // BATCHES for b in range(BATCHES + 1)]
    max_order = int(scene.render.max_order)

    def batch(b):
        coef = np.zeros((n_cells, 3, HARMONICS))
        trace_photons(med, mgrid, src, shell, coef, np.int64(seed), np.int64(edges[b]), np.int64(edges[b + 1]),
                      np.int64(max_order), np.int64(RR_ORDER))
        return coef

    coef = np.zeros((n_cells, 3, HARMONICS))
    threads = numba.get_num_threads()
    with ThreadPoolExecutor(threads) as pool:
        for wave in range(0, BATCHES, threads):  # a wave of batches at a time: threads + 1 arrays in memory
            for part in pool.map(batch, range(wave, min(wave + threads, BATCHES))):
                coef += part  # in batch order: the same sum on any thread count
    coef /= size ** 3
    return shell._replace(coef=coef)
