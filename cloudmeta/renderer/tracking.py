"""The paths' settings and the majorant grid of their tracked flights (cloudmeta.kernels.tracking,
docs/model.md §10.1), for both estimators that trace paths (renderer.multiple, and renderer.approximate's
error estimate).

``render.track_from`` is the first vertex a tracked flight reaches: vertices before it (and the camera ray's
flight to vertex 1) are reached on the exact optical depth, with exact shadow rays; from it on, flights
are delta-tracked against the grid and transmittances estimated by residual ratio tracking. A value above
``max_order + 1`` keeps every flight exact, and no grid is built.
"""
from __future__ import annotations

import numpy as np

from ..kernels.grid import bin_balls
from ..kernels.records import MajorantGrid, PathSettings
from ..kernels.tracking import cell_bounds
from .pack import build_light_volumes, build_shadow_maps, media_bbox, no_light_volumes

#: Russian roulette from this vertex on (the first vertices carry most of the light: keep them all)
RR_ORDER = 4
#: cells of the majorant grid along the longest side of the media's box
MAJORANT_CELLS = 64
#: at most this many cells in all (a long thin box keeps cubic cells, so fewer along its long side)
MAX_MAJORANT_CELLS = 1 << 21
#: the cells' boxes are widened by this fraction of the box's diagonal (rounding, kernels.tracking)
PAD = 1e-9
#: texels per side of the shadow maps built for the paths alone: the control variate's variance was the same
#: at 96, 192 and 384 texels on the cumulus (docs/multiple_scattering.md), and 384 took 0.34 s to build
PATHS_MAP_RESOLUTION = 128
#: texels per side of the light volumes, at most (128^2 x 130 float32 depths: 8.5 MB per light)
VOLUME_RESOLUTION = 128


def path_settings(scene, paths, max_order) -> PathSettings:
    return PathSettings(max_order=int(max_order), rr_order=RR_ORDER, paths=int(paths),
                        track_from=int(scene.render.track_from))


def tracks(settings) -> bool:
    """Whether any path reads the grid: the flight from vertex track_from - 1 is tracked, and so is the
    environment seen from that vertex, even where max_order stops the path there."""
    return settings.track_from <= settings.max_order + 1


def no_grid(med) -> MajorantGrid:
    """A grid with one empty cell (every flight exact): the same types as majorant_grid's."""
    return MajorantGrid(origin=np.zeros(3), size=1.0, dims=np.ones(3, np.int64), sigma_max=np.zeros(1),
                        sigma_min=np.zeros(1), start=np.zeros(2, np.int64), items=np.zeros(0, np.int64),
                        ball_medium=np.zeros(len(med.weights), np.int64), inv_r2=np.zeros(len(med.weights)))


def majorant_grid(scene, med, cells=MAJORANT_CELLS) -> MajorantGrid:
    """The records.MajorantGrid of the scene's media (med: their records.Media): cubic cells over the box that
    holds every medium's inside (the supports of its balls of positive weight), ``cells`` along its
    longest side."""
    if not scene.media:
        return no_grid(med)
    boxes = [m.blob.inside_bbox() for m in scene.media]
    lo = np.min([b[0] for b in boxes], axis=0)
    hi = np.max([b[1] for b in boxes], axis=0)
    pad = PAD * max(float(np.linalg.norm(hi - lo)), 1e-300)
    lo, hi = lo - pad, hi + pad
    extent = hi - lo
    size = float(extent.max()) / cells
    dims = np.maximum(np.ceil(extent / size), 1).astype(np.int64)
    while int(np.prod(dims)) > MAX_MAJORANT_CELLS:
        size *= 1.25
        dims = np.maximum(np.ceil(extent / size), 1).astype(np.int64)
    bounds = np.ascontiguousarray(np.concatenate([m.blob.bounds for m in scene.media]))
    radii = np.concatenate([m.blob.radii for m in scene.media])
    inv_radii = np.ascontiguousarray(np.stack([1.0 / radii.min(axis=1), 1.0 / radii.max(axis=1)], axis=1))
    ball_medium = np.repeat(np.arange(len(scene.media), dtype=np.int64), [len(m.blob) for m in scene.media])
    start, items = bin_balls(bounds, pad, lo, size, dims)
    n_cells = int(np.prod(dims))
    sigma_max = np.zeros(n_cells)
    sigma_min = np.zeros(n_cells)
    cell_bounds(med, ball_medium, inv_radii, lo, size, dims, pad, start, items, sigma_max, sigma_min)
    sphere = radii.min(axis=1) == radii.max(axis=1)
    inv_r2 = np.ascontiguousarray(np.where(sphere, inv_radii[:, 0] ** 2, 0.0))
    return MajorantGrid(origin=np.ascontiguousarray(lo, dtype=np.float64), size=size, dims=dims, sigma_max=sigma_max,
                        sigma_min=sigma_min, start=start, items=items, ball_medium=ball_medium, inv_r2=inv_r2)


def paths_grid(scene, med, settings) -> MajorantGrid:
    """The grid the paths of ``settings`` read: majorant_grid where they track, else no_grid."""
    return majorant_grid(scene, med) if tracks(settings) else no_grid(med)


def paths_volumes(scene, packed, settings):
    """The light volumes (records.LightVolumes) the tracked vertices read as the control variate of a
    directional light's transmittance (kernels.multiple.light_transmittance), each sampled from a shadow map:
    the render's own (``shadows: map`` or ``hybrid``), else one built here at ``render.shadow_map`` texels
    (PATHS_MAP_RESOLUTION by default); none (every T_l tracked) where no path is tracked or no light is
    directional."""
    lights = packed.records.lights
    if not tracks(settings) or not scene.media:
        return no_light_volumes(len(scene.lights))
    maps = lights.maps
    if maps is None or not np.any(maps.map_of >= 0):
        lo, hi = media_bbox(scene)
        maps = build_shadow_maps(scene.lights, packed.records.media, lo, hi,
                                 scene.render.shadow_map or PATHS_MAP_RESOLUTION, packed.quadrature.tol_t)
    return no_light_volumes(len(scene.lights)) if maps is None else build_light_volumes(maps, VOLUME_RESOLUTION)
