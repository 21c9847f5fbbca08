"""Pack a validated scene into the named records the kernels read (cloudmeta.kernels.records).

One job per function: the media, the surfaces and the lights into their records (with every blob's BVH
merged into one); the shadow maps of directional lights (traced once, traced again where the single
pass overflows); the camera's basis; and the G7-K15 quadrature rule with its Lagrange bases. Every array
is fresh, writable and C-contiguous with a fixed dtype, also when a scene has no media, surfaces or
lights: numba then sees the same types and compiles once. A scene with neither surfaces nor shadow maps
gets None for both (kernels.features): the kernels then compile a second, smaller version without them.
"""
from __future__ import annotations

import math
from collections import namedtuple
from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np

from ..kernels.kinds import DENSITY_MODES, LIGHTS, PHASES
from ..kernels.records import (SHADOWS_EXACT, BVH, Camera, LightVolumes, Lights, MapPieces, Media, Quadrature,
                               SceneRecords, ShadowMaps, Surfaces)
from ..kernels.shadowmap import fill_volume_chunk, trace_texel_chunk
from ..scene.atmosphere import sky_mean
from ..scene.vocabulary import HYBRID_SHARE, ShadowMode
from .threads import n_chunks
from .quality import FrameSettings, resolve_settings

#: map pieces reserved per texel for the single tracing pass (a map that needs more is traced again)
MAP_PIECES_PER_TEXEL = 4


# --- media, surfaces, lights -------------------------------------------------------------------------------

def merge_bvhs(blobs, starts):
    """One records.BVH for several blobs: node and item indices shifted, one root per blob."""
    parts, roots, n_nodes = [], [], 0
    for blob, first in zip(blobs, starts):
        box, a, b, n, items = blob.bvh
        leaf = n > 0
        parts.append((box, np.where(leaf, a + first, a + n_nodes), np.where(leaf, b, b + n_nodes), n,
                      items + first))
        roots.append(n_nodes)
        n_nodes += len(box)
    if not parts:
        return BVH(np.zeros((1, 6)), np.zeros(1, np.int64), np.zeros(1, np.int64), np.zeros(1, np.int64),
                   np.zeros(0, np.int64), np.zeros(0, np.int64))
    cat = [np.ascontiguousarray(np.concatenate([p[k] for p in parts])) for k in range(5)]
    return BVH(*cat, np.array(roots, np.int64))


def _pack_blobs(blobs):
    """The fields every packing shares: balls concatenated, ball offsets, per-blob kernel, threshold,
    blobbiness, and the merged BVH."""
    counts = [len(b) for b in blobs]
    start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    cat = lambda attr, empty: (np.ascontiguousarray(np.concatenate([getattr(b, attr) for b in blobs]))  # noqa: E731
                               if blobs else empty)
    return dict(centers=cat("centers", np.zeros((0, 3))), frames=cat("frames", np.zeros((0, 3, 3))),
                weights=cat("weights", np.zeros(0)), start=start,
                kernel=np.array([b.kernel_id for b in blobs], np.int64),
                threshold=np.array([b.threshold for b in blobs], np.float64),
                blobbiness=np.array([b.blobbiness for b in blobs], np.float64),
                bvh=merge_bvhs(blobs, start[:-1]))


def pack_media(media) -> Media:
    """Every medium of the scene in one records.Media."""
    phase = np.zeros((len(media), 4))
    for i, m in enumerate(media):
        p = m.phase
        g1 = p.g if p.type == "hg" else p.g1
        phase[i] = (PHASES[p.type], g1, p.g2, p.w)
    return Media(**_pack_blobs([m.blob for m in media]),
                 mode=np.array([DENSITY_MODES[m.density.mode] for m in media], np.int64),
                 scale=np.array([m.density.scale for m in media], np.float64),
                 albedo=np.array([m.albedo for m in media], np.float64), phase=phase)


def pack_surfaces(surfaces) -> Surfaces:
    """Every opaque surface of the scene in one records.Surfaces."""
    return Surfaces(**_pack_blobs([s.blob for s in surfaces]),
                    colour=np.array([s.color for s in surfaces], np.float64).reshape(-1, 3))


def no_shadow_maps(n_lights) -> ShadowMaps:
    """Exact shadow rays towards every light: no map (empty arrays of the maps' dtypes)."""
    return ShadowMaps(map_of=np.full(n_lights, -1, np.int64), geo=np.zeros((0, 13)), res=np.zeros(0, np.int64),
                      base=np.zeros(0, np.int64), start=np.zeros(1, np.int64), t0=np.zeros(0), t1=np.zeros(0),
                      c=np.zeros((0, 7)), cum=np.zeros(0), reach=np.zeros(0))


def pack_lights(lights, maps=None) -> Lights:
    """The lights in one records.Lights; ``maps`` from build_shadow_maps, or None for exact shadow rays
    towards every light."""
    # each light says what records.Lights holds for it (scene.lights): its kind's id, its vector (the
    # direction towards it, or its position) and its rgb (irradiance or intensity)
    kind = np.array([LIGHTS[l.KIND] for l in lights], np.int64).reshape(-1)
    vec = np.array([l.record()[0] for l in lights], np.float64).reshape(-1, 3)
    rgb = np.array([l.record()[1] for l in lights], np.float64).reshape(-1, 3)
    return Lights(kind=kind, vec=vec, rgb=rgb, maps=no_shadow_maps(len(lights)) if maps is None else maps)


def media_bbox(scene):
    """The box [lo, hi] that holds every medium."""
    boxes = [m.blob.bbox for m in scene.media]
    return np.min([b[0] for b in boxes], axis=0), np.max([b[1] for b in boxes], axis=0)


def scene_records(scene, quad, shadow_map_resolution) -> SceneRecords:
    """The scene as the radiance kernels read it; where ``quad`` (a records.Quadrature) takes shadows from maps
    (SHADOWS_MAP or SHADOWS_HYBRID) and the scene has media, a shadow map of ``shadow_map_resolution`` texels per
    side for each directional light."""
    med = pack_media(scene.media)
    maps = None
    if quad.shadow_mode != SHADOWS_EXACT and scene.media:
        lo, hi = media_bbox(scene)
        maps = build_shadow_maps(scene.lights, med, lo, hi, shadow_map_resolution, quad.tol_t)
    # fresh writable copies: numba types read-only arrays apart, and a second type means a second compile
    ambient = np.zeros(3) if scene.ambient is None else np.array(scene.ambient, np.float64)
    if not scene.surfaces and maps is None:
        # neither surfaces nor shadow maps: None in their places, so that the kernels compile without
        # their code (kernels.features); a scene with either gets both records, so that every kernel has
        # at most two compiled versions
        surfaces, lights = None, pack_lights(scene.lights)._replace(maps=None)
    else:
        surfaces, lights = pack_surfaces(scene.surfaces), pack_lights(scene.lights, maps)
    background = background_table(scene)
    octaves = single_octave()
    if scene.render.scattering == "approximate" and scene.render.method == "octaves":
        # renderer.approximate: the octaves, the environment as ambient (method grid: renderer.fluence adds its grid)
        octaves = octave_table(*scene.render.octaves)
        ambient = sky_mean(background)  # a one-row table is its own mean
    return SceneRecords(media=med, surfaces=surfaces, lights=lights, background=background, ambient=ambient,
                        octaves=octaves, radiance=None, view_media=med)


def without_maps(scene, records) -> SceneRecords:
    """``records`` as a scene with exact shadow rays has them (``scene_records``): no shadow maps, and no surface
    record where the scene has no surfaces, so that a frame whose shadow rays are all exact runs the kernel compiled
    for exact shadows, without the map code (renderer.frame)."""
    if records.lights.maps is None:
        return records
    if not scene.surfaces:
        return records._replace(surfaces=None, lights=records.lights._replace(maps=None))
    return records._replace(lights=records.lights._replace(maps=no_shadow_maps(len(scene.lights))))


def single_octave():
    """The octaves of single scattering (kernels.single.octave_phase): one, (a^0, b^0, c^0) = (1, 1, 1)."""
    return np.ones((1, 3))


def octave_table(count, a, b, c):
    """The approximate mode's octaves as kernels.single.octave_phase reads them: rows (a^i, b^i, c^i)."""
    i = np.arange(count, dtype=np.float64)
    return np.ascontiguousarray(np.stack([a ** i, b ** i, c ** i], axis=1))


def background_along(table, directions):
    """(n, 3): the background's radiance along unit directions (n, 3), as kernels.camera.background_radiance."""
    if table.shape[0] == 1:
        return np.repeat(table, len(directions), axis=0)
    x = (np.arcsin(np.clip(directions[:, 2], -1.0, 1.0)) / np.pi + 0.5) * (table.shape[0] - 1)
    i = np.minimum(x.astype(np.int64), table.shape[0] - 2)
    f = (x - i)[:, None]
    return (1.0 - f) * table[i] + f * table[i + 1]


def background_table(scene):
    """The background as kernels.camera.background_radiance reads it: the sky's (181, 3) table over elevation
    (-90 .. 90 degrees, z up) where the scene has one, else its uniform colour as one row."""
    sky = getattr(scene, "sky", None)
    table = np.array(scene.background, np.float64).reshape(1, 3) if sky is None else np.array(sky, np.float64)
    return np.ascontiguousarray(table)


# --- shadow maps ------------------------------------------------------------------------------------------

def build_shadow_maps(lights, med, lo, hi, resolution, tol_t):
    """A shadow map per directional light over the bounding sphere of the box [lo, hi]
    (cloudmeta.kernels.shadowmap), as one records.ShadowMaps; None without directional lights."""
    centre = 0.5 * (lo + hi)
    radius = 0.5 * float(np.linalg.norm(hi - lo)) * 1.01
    map_of = np.full(len(lights), -1, np.int64)
    geos, parts, bases, offset = [], [], [], 0
    for i, light in enumerate(lights):
        if not light.casts_map:
            continue
        geo = _map_geometry(np.asarray(light.direction, np.float64), centre, radius, resolution)
        start, arrays = _trace_map(geo, resolution, med, tol_t)
        map_of[i] = len(geos)
        geos.append(geo)
        bases.append(offset)
        parts.append((start, arrays))
        offset += resolution * resolution
    if not geos:
        return None
    piece_offsets = np.cumsum([0] + [int(st[-1]) for st, _ in parts])
    start = np.concatenate([st[:-1] + po for (st, _), po in zip(parts, piece_offsets)] + [[piece_offsets[-1]]])
    cat = {name: np.ascontiguousarray(np.concatenate([getattr(a, name) for _, a in parts])) for name in MapPieces._fields}
    return ShadowMaps(map_of=map_of, geo=np.array(geos), res=np.full(len(geos), resolution, np.int64),
                      base=np.array(bases, np.int64), start=start.astype(np.int64), **cat)


def no_light_volumes(n_lights) -> LightVolumes:
    """No light volume (empty arrays of the volumes' dtypes)."""
    return LightVolumes(map_of=np.full(n_lights, -1, np.int64), geo=np.zeros((0, 13)), res=np.zeros(0, np.int64),
                        depth_n=np.zeros(0, np.int64), base=np.zeros(0, np.int64),
                        tau=np.zeros(0, np.float32))


def build_light_volumes(maps, max_resolution) -> LightVolumes:
    """A light volume (records.LightVolumes) over each shadow map of ``maps``: the optical depth at the
    texels' centres (at most max_resolution per side) every texel size along the light, read from the map
    (kernels.shadowmap.fill_volume_chunk)."""
    geos, bases, ress, depths, parts, offset = [], [], [], [], [], 0
    for mi in range(len(maps.geo)):
        res = min(int(maps.res[mi]), int(max_resolution))
        geo = maps.geo[mi].copy()
        geo[12] *= maps.res[mi] / res  # the same square, coarser texels
        depth_n = res + 2  # depths 0 .. 2 radius (the map's square is the bounding sphere's), and one more
        tau = np.empty(res * res * depth_n, np.float32)
        chunks = n_chunks(res * res)

        def chunk(ch, mi=mi, geo=geo, res=res, depth_n=depth_n, tau=tau, chunks=chunks):
            fill_volume_chunk(maps, np.int64(mi), geo, np.int64(res), np.int64(depth_n), np.int64(ch),
                              np.int64(chunks), tau)

        with ThreadPoolExecutor(numba.get_num_threads()) as pool:  # nogil chunks, each its own texels
            list(pool.map(chunk, range(chunks)))
        geos.append(geo)
        ress.append(res)
        depths.append(depth_n)
        bases.append(offset)
        parts.append(tau)
        offset += tau.size
    if not geos:
        return no_light_volumes(len(maps.map_of))
    return LightVolumes(map_of=maps.map_of.copy(), geo=np.array(geos), res=np.array(ress, np.int64),
                        depth_n=np.array(depths, np.int64), base=np.array(bases, np.int64),
                        tau=np.ascontiguousarray(np.concatenate(parts)))


def _map_geometry(l, centre, radius, resolution):
    """geo (13,) of a map towards l: origin, e1, e2, the texel rays' direction -l, texel size."""
    helper = np.array([1.0, 0, 0]) if abs(l[0]) < 0.9 else np.array([0, 1.0, 0])
    e1 = np.cross(l, helper)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(l, e1)
    origin = centre + l * radius - (e1 + e2) * radius
    return np.concatenate([origin, e1, e2, -l, [2 * radius / resolution]])


def _trace_map(geo, resolution, med, tol_t):
    """Every texel's pieces, traced once into per-chunk rows and packed texel after texel.
    Returns (start (res^2 + 1,), (t0, t1, c, cum, reach))."""
    n = resolution * resolution
    chunks = n_chunks(n)
    cap = MAP_PIECES_PER_TEXEL * (n // chunks + 1)
    counts = np.zeros(n, np.int64)
    used = np.zeros(chunks, np.int64)
    while True:
        rows = chunks * cap
        arrays = MapPieces(np.empty(rows), np.empty(rows), np.empty((rows, 7)), np.empty(rows), np.empty(rows))

        def chunk(ch, cap=cap, arrays=arrays):
            trace_texel_chunk(geo, resolution, med, tol_t, ch, chunks, cap, counts, used, arrays)

        with ThreadPoolExecutor(numba.get_num_threads()) as pool:  # nogil chunks, each with its own rows
            list(pool.map(chunk, range(chunks)))
        if used.max() <= cap:
            break
        cap = int(used.max())  # a dense map: the second pass fits
    keep = np.concatenate([np.arange(ch * cap, ch * cap + used[ch]) for ch in range(chunks)])
    start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    return start, MapPieces(*(np.ascontiguousarray(a[keep]) for a in arrays))


# --- camera -----------------------------------------------------------------------------------------------

def camera_frame(camera):
    """Unit forward, right and up vectors of the camera (docs/model.md §8: up is re-orthogonalised)."""
    fwd = camera.look_at - camera.position
    fwd = fwd / np.linalg.norm(fwd)
    right = np.cross(fwd, camera.up)
    right /= np.linalg.norm(right)
    return fwd, right, np.cross(right, fwd)


def camera_basis(camera, width, height):
    """Forward, and right / up scaled to the image plane's half-extent at distance 1 (docs/model.md §8)."""
    fwd, right, up = camera_frame(camera)
    half_h = math.tan(math.radians(camera.fov) / 2)
    return fwd, right * half_h * width / height, up * half_h


def pixel_directions(camera, rows, cols):
    """(n, 3): the unit directions through the centres of pixels (rows, cols) of a records.Camera (fractional
    rows and columns: through those points of the pixels, 0.5 past the centre being the next pixel's edge)."""
    x = 2.0 * (cols + 0.5) / camera.width - 1.0
    y = 1.0 - 2.0 * (rows + 0.5) / camera.height
    d = camera.forward[None, :] + x[:, None] * camera.right[None, :] + y[:, None] * camera.up[None, :]
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def pack_camera(scene, seed) -> Camera:
    """The scene's camera and image size as one records.Camera."""
    w, h, spp = scene.image.width, scene.image.height, scene.image.spp
    fwd, right, up = camera_basis(scene.camera, w, h)
    return Camera(position=np.array(scene.camera.position, np.float64), forward=fwd, right=right, up=up, width=w,
                  height=h, spp=spp, seed=seed)


# --- the quadrature of the in-scattering integral ----------------------------------------------------------

def gauss_legendre(nodes):
    """Nodes and weights on [0, 1]."""
    x, w = np.polynomial.legendre.leggauss(nodes)
    return 0.5 * (x + 1.0), 0.5 * w


#: points of the fine rule that integrates e^-(h y) L_k(y) for the product weights (exact to rounding
#: for steps of optical depth up to ~20)
FINE_POINTS = 24
#: the Gauss-Kronrod pair G7-K15 on [-1, 1], the non-negative half (QUADPACK's qk15): the Kronrod nodes
#: with the Gauss nodes at odd positions and 0
_K15_HALF = np.array([0.991455371120812639206854697526329, 0.949107912342758524526189684047851,
                      0.864864423359769072789712788640926, 0.741531185599394439863864773280788,
                      0.586087235467691130294144845693013, 0.405845151377397166906606412076961,
                      0.207784955007898467600689403773245, 0.0])
_G7_WEIGHTS_HALF = np.array([0.129484966168869693270611432679082, 0.279705391489276667901467771423780,
                             0.381830050505118944950369775488975, 0.417959183673469387755102040816327])


def _lagrange_at(x, y):
    """(len(x), len(y)): the Lagrange basis of the nodes x sampled at the points y."""
    basis = np.ones((len(x), len(y)))
    for k in range(len(x)):
        for j in range(len(x)):
            if j != k:
                basis[k] *= (y - x[j]) / (x[k] - x[j])
    return basis


def legendre_tail(x, w):
    """(2, n): maps values at the n Gauss nodes x (weights w, on [0, 1]) to the two highest Legendre
    coefficients c_{n-2}, c_{n-1} of their interpolant; the Gauss rule's discrete orthogonality makes
    c_j = (2j + 1) sum_k w_k f_k P_j(2 x_k - 1) exact for j < n."""
    n = len(x)
    return np.array([(2 * j + 1) * w * np.polynomial.legendre.Legendre.basis(j)(2.0 * x - 1.0)
                     for j in (n - 2, n - 1)])


def quadrature_rule():
    """The step rule of the in-scattering integral: 7 Gauss nodes, extended to the 15 Kronrod nodes where
    the light is rough, with everything the kernel needs to weight e^-u times their interpolant exactly
    (kernels.single._exp_weights). Returns (gauss_x, gauss_lag, kronrod_x, kronrod_lag, gauss_col, kronrod_col,
    tail, fine_y, fine_w) by name: a dict of the records.Quadrature fields that the rule fixes."""
    signed = np.concatenate([-_K15_HALF[:-1], _K15_HALF[::-1]])
    kronrod_x = 0.5 * (1.0 + signed)                       # increasing on [0, 1]
    is_gauss = np.zeros(15, bool)
    is_gauss[[1, 3, 5, 7, 9, 11, 13]] = True               # every other node, from the second
    gauss_col = np.flatnonzero(is_gauss).astype(np.int64)
    kronrod_col = np.flatnonzero(~is_gauss).astype(np.int64)
    gauss_x = kronrod_x[gauss_col]
    gauss_w = 0.5 * np.concatenate([_G7_WEIGHTS_HALF, _G7_WEIGHTS_HALF[-2::-1]])
    y, w = gauss_legendre(FINE_POINTS)
    return dict(gauss_x=gauss_x, gauss_lag=_lagrange_at(gauss_x, y), kronrod_x=kronrod_x,
                kronrod_lag=_lagrange_at(kronrod_x, y), gauss_col=gauss_col, kronrod_col=kronrod_col,
                tail=legendre_tail(gauss_x, gauss_w), fine_y=y, fine_w=w)


def quadrature(quality) -> Quadrature:
    """The rule and the resolved settings (a renderer.quality.Quality) as one records.Quadrature."""
    u_stop = -math.log(quality.cutoff) if quality.cutoff > 0.0 else math.inf
    shadows = ShadowMode(quality.shadows)
    return Quadrature(**quadrature_rule(), max_tau=float(quality.max_tau), max_length=float(quality.max_length),
                      max_angle=float(quality.max_angle), cutoff=float(quality.cutoff), u_stop=u_stop,
                      tol_t=float(quality.tol_t), tolerance=float(quality.tolerance),
                      light_scale=float(quality.light_scale), shadow_mode=np.int64(shadows.kernel_id),
                      map_tolerance=map_tolerance(quality), growth=float(quality.growth))


def map_tolerance(quality):
    """records.Quadrature.map_tolerance: with hybrid shadows, HYBRID_SHARE of the absolute tolerance (0 without a
    pilot's light scale: exact shadow rays then); 0 in the other modes, which do not read it."""
    if quality.shadows != ShadowMode.HYBRID:
        return 0.0
    return float(HYBRID_SHARE * quality.tolerance * quality.light_scale)


# --- the whole scene --------------------------------------------------------------------------------------

#: a scene packed once for every estimator: records.Camera, records.SceneRecords, records.Quadrature
#: ground: the clouds' shadow on a ground the scene places, H x W x 3 over the frame's tile (renderer.ground),
#: set by renderer.frame; None where there is none
Packed = namedtuple("Packed", ["camera", "records", "quadrature", "ground"], defaults=(None,))


def pack_scene(scene, seed, settings: FrameSettings | None = None) -> Packed:
    """The scene packed for the kernels at its FrameSettings (renderer.quality.resolve_settings, or ``settings``
    where the frame resolved them)."""
    settings = resolve_settings(scene) if settings is None else settings
    quad = quadrature(settings.quadrature)
    records = scene_records(scene, quad, settings.shadow_map)
    return Packed(camera=pack_camera(scene, seed), records=records, quadrature=quad)
