"""Render a scene: pack it into arrays once, then run the radiance kernel over bands of rows.

Quality settings (``render:`` in the scene, MODEL.md §9). ``quality`` picks a preset; any of the other
keys overrides that preset's value:

=============== ======= ======= ======= ========== ====================================================
key             draft   default fine    reference  meaning
=============== ======= ======= ======= ========== ====================================================
tolerance       1e-2    3e-3    1e-3    1e-6       error allowed in the light J per unit of optical
                                                   depth (weighted by the view transmittance), relative
                                                   to the brightest J on the ray
max_tau         4.0     2.0     1.0     0.1        thickest step, in optical depth
max_length      1/4     1/16    1/32    1/128      longest step, as a fraction of the scene's diagonal
                                                   (an explicit ``max_length`` is in scene units)
max_angle       0.4     0.2     0.1     0.025      widest angle (radians) of a step seen from a point light
cutoff          1e-2    1e-3    1e-4    0          stop shading once the view transmittance is below
root_tolerance  1e-9    1e-9    1e-9    1e-9       root tolerance, relative to the scene's diagonal
=============== ======= ======= ======= ========== ====================================================

Each step of the in-scattering integral takes 7 Gauss nodes; where the two highest Legendre coefficients
of J on them exceed the tolerance, the 8 Kronrod nodes join (G7-K15), and where the two rules still
disagree by more than the tolerance allows the step is halved (at most 6 times). The optical depth, the
view transmittance and the shadow transmittance are exact at every setting; the settings only trade the
quadrature of the in-scattering integral against time.

Opaque surfaces (``surfaces:``, MODEL.md §6) are exact at every setting too: the first root of each
surface's field along the camera ray, the analytic normal, and shadow rays that stop at the first surface
they meet. With ``shadows: map`` the maps hold the media only; surfaces still block every shadow ray
exactly (a first-root test per node and light), so their shadows are as sharp as with ``exact``. A surface
seen through less than ``cutoff`` of view transmittance is not shaded (like the media behind it).
"""
from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numba
import numpy as np

from .engine import DENSITY_MODES, n_chunks
from .kernels.optics import DOUBLE_HG, HG, ISOTROPIC, RAYLEIGH
from .kernels.radiance import DIRECTIONAL, POINT, render_pixels
from .kernels.shadowmap import trace_texels
from .scene import DirectionalLight, RenderSettings, Scene

PRESETS = {
    "draft": dict(tolerance=1e-2, max_tau=4.0, max_length=1 / 4, max_angle=0.4, cutoff=1e-2, root_tolerance=1e-9),
    "default": dict(tolerance=3e-3, max_tau=2.0, max_length=1 / 16, max_angle=0.2, cutoff=1e-3,
                    root_tolerance=1e-9),
    "fine": dict(tolerance=1e-3, max_tau=1.0, max_length=1 / 32, max_angle=0.1, cutoff=1e-4, root_tolerance=1e-9),
    "reference": dict(tolerance=1e-6, max_tau=0.1, max_length=1 / 128, max_angle=0.025, cutoff=0.0,
                      root_tolerance=1e-9),
}
PHASES = {"isotropic": ISOTROPIC, "hg": HG, "double_hg": DOUBLE_HG, "rayleigh": RAYLEIGH}
#: texels per side of a shadow map when render.shadow_map is not given
SHADOW_MAP_RESOLUTION = 384
#: the image is cut into bands of rows, about this many per thread (uneven rows balance out) and no
#: taller than MAX_BAND_ROWS; the progress bar moves once per band
BANDS_PER_THREAD = 16
MAX_BAND_ROWS = 16


@dataclass(frozen=True)
class Quality:
    """The resolved quadrature settings of one render (all lengths in scene units)."""
    tolerance: float
    max_tau: float
    max_length: float
    max_angle: float
    cutoff: float
    tol_t: float


def resolve_quality(settings: RenderSettings, diagonal: float) -> Quality:
    preset = PRESETS[settings.quality]
    pick = lambda key: preset[key] if getattr(settings, key) is None else getattr(settings, key)  # noqa: E731
    max_length = preset["max_length"] * diagonal if settings.max_length is None else settings.max_length
    return Quality(tolerance=float(pick("tolerance")), max_tau=float(pick("max_tau")), max_length=float(max_length),
                   max_angle=float(pick("max_angle")), cutoff=float(pick("cutoff")),
                   tol_t=float(pick("root_tolerance")) * diagonal)


@dataclass(frozen=True)
class PackedMedia:
    """Every medium's balls in one set of arrays, with per-medium parameters (what the kernels read)."""
    centers: np.ndarray
    frames: np.ndarray
    weights: np.ndarray
    start: np.ndarray      # (M + 1,) ball offsets
    kernel: np.ndarray
    threshold: np.ndarray
    mode: np.ndarray
    scale: np.ndarray
    albedo: np.ndarray
    phase: np.ndarray      # (M, 4): kind, g1, g2, w
    bvh: tuple             # node_box, node_a, node_b, node_n, items of all media; root (M,) per medium
    blobbiness: np.ndarray  # (M,) b of the blinn kernel (unused by the others)

    def args(self):
        """The ``med`` tuple of cloudmeta.kernels.radiance."""
        return (self.centers, self.frames, self.weights, self.start, self.kernel, self.threshold, self.mode,
                self.scale, self.albedo, self.phase, *self.bvh, self.blobbiness)


def merge_bvhs(blobs, starts):
    """One set of BVH arrays for several blobs: node and item indices shifted, one root per blob."""
    parts, roots, n_nodes = [], [], 0
    for blob, first in zip(blobs, starts):
        box, a, b, n, items = blob.bvh
        leaf = n > 0
        parts.append((box, np.where(leaf, a + first, a + n_nodes), np.where(leaf, b, b + n_nodes), n,
                      items + first))
        roots.append(n_nodes)
        n_nodes += len(box)
    if not parts:
        return (np.zeros((1, 6)), np.zeros(1, np.int64), np.zeros(1, np.int64), np.zeros(1, np.int64),
                np.zeros(0, np.int64), np.zeros(0, np.int64))
    cat = [np.ascontiguousarray(np.concatenate([p[k] for p in parts])) for k in range(5)]
    return (*cat, np.array(roots, np.int64))


@dataclass(frozen=True)
class PackedSurfaces:
    """Every surface's balls in one set of arrays, with per-surface parameters (what the kernels read)."""
    centers: np.ndarray
    frames: np.ndarray
    weights: np.ndarray
    start: np.ndarray       # (S + 1,) ball offsets
    kernel: np.ndarray
    threshold: np.ndarray
    blobbiness: np.ndarray
    colour: np.ndarray      # (S, 3) linear RGB
    bvh: tuple              # node_box, node_a, node_b, node_n, items of all surfaces; root (S,) per surface

    def args(self):
        """The ``surf`` tuple of cloudmeta.kernels.surfaces."""
        return (self.centers, self.frames, self.weights, self.start, self.kernel, self.threshold,
                self.blobbiness, self.colour, *self.bvh)


def _pack_blobs(blobs):
    """The arrays every packing shares: balls concatenated, ball offsets, per-blob kernel, threshold,
    blobbiness, and the merged BVH. Fresh contiguous arrays, also when there are no blobs (numba then
    sees the same types and compiles once)."""
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


def pack_media(media) -> PackedMedia:
    phase = np.zeros((len(media), 4))
    for i, m in enumerate(media):
        p = m.phase
        g1 = p.g if p.type == "hg" else p.g1
        phase[i] = (PHASES[p.type], g1, p.g2, p.w)
    return PackedMedia(
        **_pack_blobs([m.blob for m in media]),
        mode=np.array([DENSITY_MODES[m.density.mode] for m in media], np.int64),
        scale=np.array([m.density.scale for m in media], np.float64),
        albedo=np.array([m.albedo for m in media], np.float64), phase=phase)


def pack_surfaces(surfaces) -> PackedSurfaces:
    return PackedSurfaces(**_pack_blobs([s.blob for s in surfaces]),
                          colour=np.array([s.color for s in surfaces], np.float64).reshape(-1, 3))


def pack_lights(lights, maps=None):
    """The ``lights`` tuple of cloudmeta.kernels.radiance; ``maps`` from build_shadow_maps, or None for
    exact shadow rays towards every light."""
    kind = np.array([DIRECTIONAL if isinstance(l, DirectionalLight) else POINT for l in lights], np.int64).reshape(-1)
    vec = np.array([l.direction if isinstance(l, DirectionalLight) else l.position for l in lights],
                   np.float64).reshape(-1, 3)
    rgb = np.array([l.irradiance if isinstance(l, DirectionalLight) else l.intensity for l in lights],
                   np.float64).reshape(-1, 3)
    if maps is None:
        maps = (np.full(len(lights), -1, np.int64), np.zeros((0, 13)), np.zeros(0, np.int64),
                np.zeros(0, np.int64), np.zeros(1, np.int64), np.zeros(0), np.zeros(0), np.zeros((0, 7)),
                np.zeros(0), np.zeros(0))
    return (kind, vec, rgb, *maps)


def build_shadow_maps(lights, med, lo, hi, resolution, tol_t):
    """A shadow map per directional light over the bounding sphere of the box [lo, hi]
    (cloudmeta.kernels.shadowmap). Returns (map_of, geo, res, base, start, t0, t1, c, cum, reach)."""
    centre = 0.5 * (lo + hi)
    radius = 0.5 * float(np.linalg.norm(hi - lo)) * 1.01
    map_of = np.full(len(lights), -1, np.int64)
    geos, parts, bases, offset = [], [], [], 0
    for i, light in enumerate(lights):
        if not isinstance(light, DirectionalLight):
            continue
        l = np.asarray(light.direction, np.float64)
        helper = np.array([1.0, 0, 0]) if abs(l[0]) < 0.9 else np.array([0, 1.0, 0])
        e1 = np.cross(l, helper)
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(l, e1)
        origin = centre + l * radius - (e1 + e2) * radius
        geo = np.concatenate([origin, e1, e2, -l, [2 * radius / resolution]])
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
    cat = [np.ascontiguousarray(np.concatenate([a[k] for _, a in parts])) for k in range(5)]
    return (map_of, np.array(geos), np.full(len(geos), resolution, np.int64), np.array(bases, np.int64),
            start.astype(np.int64), *cat)


#: map pieces reserved per texel for the single tracing pass (a map that needs more is traced again)
MAP_PIECES_PER_TEXEL = 4


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
        arrays = (np.empty(rows), np.empty(rows), np.empty((rows, 7)), np.empty(rows), np.empty(rows))
        trace_texels(geo, resolution, med, tol_t, chunks, cap, counts, used, *arrays)
        if used.max() <= cap:
            break
        cap = int(used.max())  # a dense map: the second pass fits
    keep = np.concatenate([np.arange(ch * cap, ch * cap + used[ch]) for ch in range(chunks)])
    start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    return start, tuple(np.ascontiguousarray(a[keep]) for a in arrays)


def camera_basis(camera, width, height):
    """Forward, and right / up scaled to the image plane's half-extent at distance 1 (MODEL.md §8)."""
    fwd = camera.look_at - camera.position
    fwd = fwd / np.linalg.norm(fwd)
    right = np.cross(fwd, camera.up)
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    half_h = math.tan(math.radians(camera.fov) / 2)
    return fwd, right * half_h * width / height, up * half_h


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


def quadrature():
    """The step rule of the in-scattering integral: 7 Gauss nodes, extended to the 15 Kronrod nodes where
    the light is rough, with everything the kernel needs to weight e^-u times their interpolant exactly
    (radiance._exp_weights). Returns (gauss_x, gauss_lag, kronrod_x, kronrod_lag, gauss_col, kronrod_col,
    tail, fine_y, fine_w)."""
    signed = np.concatenate([-_K15_HALF[:-1], _K15_HALF[::-1]])
    kronrod_x = 0.5 * (1.0 + signed)                       # increasing on [0, 1]
    is_gauss = np.zeros(15, bool)
    is_gauss[[1, 3, 5, 7, 9, 11, 13]] = True               # every other node, from the second
    gauss_col = np.flatnonzero(is_gauss).astype(np.int64)
    kronrod_col = np.flatnonzero(~is_gauss).astype(np.int64)
    gauss_x = kronrod_x[gauss_col]
    gauss_w = 0.5 * np.concatenate([_G7_WEIGHTS_HALF, _G7_WEIGHTS_HALF[-2::-1]])
    y, w = gauss_legendre(FINE_POINTS)
    return (gauss_x, _lagrange_at(gauss_x, y), kronrod_x, _lagrange_at(kronrod_x, y), gauss_col, kronrod_col,
            legendre_tail(gauss_x, gauss_w), y, w)


def render(scene: Scene, progress=True, seed=0, depth=False):
    """Render the scene: an H x W x 4 float32 array, linear RGB of the working colourspace and alpha.

    With ``depth=True`` returns (image, depth): depth (H x W, float64) is, per pixel, the distance along
    the camera ray to the nearest surface hit among its samples (inf where no sample meets a surface).
    """
    multiple = _multiple_scattering(scene)
    lo, hi = scene.bbox()
    q = resolve_quality(scene.render, float(np.linalg.norm(hi - lo)))
    media = pack_media(scene.media)
    med = media.args()
    surf = pack_surfaces(scene.surfaces).args()
    maps = None
    if scene.render.shadows == "map" and scene.media:
        mlo, mhi = _media_bbox(scene)
        maps = build_shadow_maps(scene.lights, med, mlo, mhi, scene.render.shadow_map or SHADOW_MAP_RESOLUTION,
                                 q.tol_t)
    lights = pack_lights(scene.lights, maps)
    quad = (*quadrature(), q.max_tau, q.max_length, q.max_angle, q.cutoff, q.tol_t, q.tolerance)
    w, h, spp = scene.image.width, scene.image.height, scene.image.spp
    fwd, right, up = camera_basis(scene.camera, w, h)
    # fresh writable copies: numba types read-only arrays apart, and a second type means a second compile
    ambient = np.zeros(3) if scene.ambient is None else np.array(scene.ambient, np.float64)
    background = np.array(scene.background, np.float64)
    position = np.array(scene.camera.position, np.float64)
    image = np.zeros((h, w, 4), np.float64)
    nearest = np.full((h, w), np.inf)
    bar = _progress(h, progress)
    threads = numba.get_num_threads()
    rows = max(1, min(MAX_BAND_ROWS, -(-h // (BANDS_PER_THREAD * threads))))
    bands = [(r0, min(h, r0 + rows)) for r0 in range(0, h, rows)]

    def band(rows):
        r0, r1 = rows
        render_pixels(r0, w, h, spp, seed, position, fwd, right, up, 0, (r1 - r0) * w, med, surf, lights, quad,
                      background, ambient, image, nearest)
        return r1 - r0

    # each band is one call of a nogil kernel with its own work arrays, written to its own rows: threads
    # share nothing, so the image does not depend on their number or order
    with ThreadPoolExecutor(threads) as pool:
        for done in pool.map(band, bands):
            bar.update(done)
    bar.close()
    if multiple is not None:
        image, _ = multiple(scene, image, seed=seed, progress=progress)
    if depth:
        return image.astype(np.float32), nearest
    return image.astype(np.float32)


def _multiple_scattering(scene):
    """With ``render.scattering: multiple``, the hook that adds the Monte Carlo orders to the image
    (cloudmeta.multiple), after checking the scene for it; None for single scattering."""
    if scene.render.scattering != "multiple":
        return None
    from .multiple import add_multiple, check_multiple  # it imports this module
    check_multiple(scene)
    return add_multiple


def _media_bbox(scene):
    boxes = [m.blob.bbox for m in scene.media]
    return np.min([b[0] for b in boxes], axis=0), np.max([b[1] for b in boxes], axis=0)


class _NoBar:
    def update(self, n):
        pass

    def close(self):
        pass


def _progress(rows, enabled):
    if not enabled:
        return _NoBar()
    from tqdm import tqdm
    return tqdm(total=rows, unit="row", desc="render", leave=False, mininterval=0.5)
