"""The approximate mode's shared method (``render: {scattering: approximate, method: shared}``, docs/approximate.md):
the light of orders >= 2 of the lights and >= 1 of the environment, estimated by the unbiased estimator's own
path tails on sparse camera rays and shared between neighbouring pixels at equal optical depth.

1. **Sample rays** through the centres of the pixels of a lattice of ``stride`` pixels (the frame's border
   rounded up to whole blocks). On each, at the optical depths TAUS (the first one at most half the ray's
   depth, so that every ray that meets a medium has a node), tails of the unbiased paths (kernels.shared)
   estimate Q(tau), the light that the point at depth tau scatters towards the camera, per unit of e^-tau d tau.
   The tails per node are spread by the node's weight in the integral below; their number per ray is the
   caller's, or planned to a target by ``plan_tails`` from a pilot over the whole frame.
2. **Refinement.** A block of the lattice is split into four, and the new sample rays traced, where its corners
   disagree: some corner misses the media while a pixel of the block meets them (the depth pass: every pixel's
   centre ray traced, no tails), or a pixel's optical depth differs from the one bilinear between the corners by
   more than a factor e^DEPTH_SPLIT (a puff or a gap no corner sees), or the spread of the corners' profiles at
   equal depth, weighted like the integral, exceeds ``threshold`` times their mean plus twice its noise. Down to
   blocks of one pixel.
3. **The gather.** Each pixel takes the profile of the smallest block it lies in, bilinear between its
   corners at equal tau (corners that do not reach a depth left out, and a depth no corner reaches holds the
   last value), piecewise linear in tau, and integrates e^-tau Q(tau) exactly up to its own optical depth
   U = -ln(1 - alpha), from the single-scattering image's alpha (antialiased like the image).

Every decision reads a block's corners and pixels alone, and a sample ray's random numbers are keyed by its
place in the lattice: any tile and any number of threads give the same pixels. The price is a bias where the
light changes within a block more than its corners show; ``render.error`` / ``--error`` measure the image's
error against unbiased pixels (renderer.approximate.approximation_error).
"""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numba
import numpy as np

from ..kernels.media import n_media
from ..kernels.records import PathSettings
from ..kernels.shared import NODE_KEYS, depth_tails
from ..kernels.tracking import alloc_track_work
from .fluence import no_cache
from .threads import progress_bar
from .tracking import RR_ORDER, majorant_grid, paths_volumes

#: the optical depths of a sample ray's nodes (the first at most half the ray's depth)
TAUS = np.array([0.02, 0.1, 0.25, 0.5, 0.8, 1.2, 1.8, 2.7, 4.0, 6.0, 9.0])
assert len(TAUS) <= NODE_KEYS
#: the optical depth where the gather stops (e^-60: nothing left)
MAX_DEPTH = 60.0
#: sample rays per call of the kernel
CHUNK = 64
#: the tails' streams are keyed by the render's seed with these bits flipped: the approximation's error estimate
#: (renderer.approximate) draws its unbiased paths from the render's seed, and must not share a number with them
TAIL_SEED = 0x5A1D5EED
#: and the photons of their cache (renderer.fluence.fluence_cache) with these
CACHE_SEED = 0xCAC4E5EED
#: a block is split where its corners' profiles differ by more than this share of their light (beyond noise)
SPLIT = 0.25
#: and where a pixel's optical depth differs from the one bilinear between the block's corners by more than the factor
#: e^DEPTH_SPLIT, depths below DEPTH_FLOOR counted as DEPTH_FLOOR (a puff or a gap that no corner sees: at 128 wide with
#: sample rays every 2 pixels, the pixels whose depth differed by a factor over e^0.1 held 75-83 % of the sharing's
#: squared error on the wisps and the bank, 5 and 12 % of the pixels)
DEPTH_SPLIT = 0.3
DEPTH_FLOOR = 0.05
#: the planned tails (``plan_tails``; render.shared without ``tails``): a pilot of PILOT_TAILS tails on the sample
#: rays of every other point of the coarsest lattice, over the whole frame, measures the light of orders >= 2 and
#: the tails' noise that a pixel takes from the coarsest rays; the tails per coarsest ray are those that bring
#: the image's noise to NOISE_SHARE of the target (the rest is the sharing's bias: sqrt(1 - 0.7^2) = 0.71 of it),
#: with MARGIN^2 for the pilot's own noise, at least MIN_TAILS. The finer rays near a silhouette have fewer tails
#: (in proportion to their stride) and raise the image's variance: by 1 + EDGE_REFINED x the share of the pilot's
#: variance in its blocks whose corners partly miss the media (fitted on the six report scenes of
#: docs/approximate.md, where it was 1.2-2.4; on the four fitting scenes the noise came out 0.88-1.00 of the plan's,
#: 0.90-1.08 with the rays that DEPTH_SPLIT adds, which the plan does not count: up to 1.15 on the wisps)
PILOT_TAILS = 256
NOISE_SHARE = 0.7
EDGE_REFINED = 4.0
MARGIN = 1.15
MIN_TAILS = 64
#: the share of the light beyond a preset's cache order (deep_share) is measured on DEEP_RAYS^2 sample rays over the
#: frame, DEEP_TAILS tails each; the preset builds its cache where the share is at least its own threshold
#: (renderer.quality: below it the photons cost more than the tails' walks they save; at `draft` a deck under a low
#: sun, 5 % beyond order 5: 14.2 s with the cache against 12.5 s without; wispy puffs, 19 %: 14.6 s against 15.7 s;
#: at `default` the wisps, 13 % beyond order 6: 151 s with it against 227 s without)
DEEP_RAYS = 16
DEEP_TAILS = 32
#: a pixel bilinear between four corners of equal noise keeps on average (2/3)^2 of one corner's variance
BILINEAR = 4.0 / 9.0


@dataclass(frozen=True)
class TailPlan:
    """Planned tails (``plan_tails``): ``tails`` per coarsest sample ray, for the image's noise to be
    NOISE_SHARE of ``target`` relative to the frame's scattered light; what the pilot measured (the frame's mean
    scattered light, single and shared, the target's denominator) and the relative noise it predicts; the order
    from which the tails read the cache of the deep orders (0: none), and the share of the light beyond the
    preset's order that decided it (deep_share; None: the scene set the order)."""
    tails: int
    target: float
    scattered_mean: float
    predicted: float
    cache_order: int = 0
    deep_share: float | None = None


def plan_tails(scene, packed, stride, target, single_mean, seed, max_tails, cache=None, tracks=None) -> TailPlan:
    """The tails per coarsest sample ray that bring the shared light's noise to NOISE_SHARE of ``target`` relative
    RMSE against the frame's scattered light (``single_mean``, the pilot's mean single-scattered radiance over
    pixels and RGB, plus the shared light's mean that this pilot measures), from a pilot on the sample rays every
    2 ``stride`` pixels of the whole frame: the same plan for every tile. cache: the tails' records.FluenceCache
    (renderer.fluence.fluence_cache; None: none); tracks: tail_tracks's (None: built here)."""
    h, w = scene.image.height, scene.image.width
    step = 2 * int(stride)
    rr, cc = np.meshgrid(np.arange(0, h, step), np.arange(0, w, step), indexing="ij")
    pilot = Lattice(scene, packed, seed, scene.render.max_order, cache, tracks)
    pilot.trace(np.stack([rr.ravel(), cc.ravel()], 1), tails_per_node(PILOT_TAILS))
    prof, prof_var, dw, depth = pilot.profiles(rr.ravel(), cc.ravel())
    light = float(np.einsum("nt,ntc->nc", dw, prof).mean())  # over the frame's pixels (a miss adds 0) and RGB
    var = np.einsum("nt,ntc->n", dw * dw, prof_var).reshape(rr.shape) / 3.0  # per ray, over RGB
    noise2 = BILINEAR * float(var.mean())  # per pixel and channel
    norm = float(single_mean) + light
    if not norm > 0.0 or not noise2 > 0.0:
        return TailPlan(tails=MIN_TAILS, target=float(target), scattered_mean=max(norm, 0.0), predicted=0.0)
    refined = 1.0 + EDGE_REFINED * _edge_share(var, depth.reshape(rr.shape) > 0.0)
    need = refined * MARGIN * MARGIN * noise2 * PILOT_TAILS / (NOISE_SHARE * target * norm) ** 2
    tails = int(min(max(np.ceil(need), MIN_TAILS), max_tails))
    predicted = float(np.sqrt(refined * noise2 * PILOT_TAILS / tails)) / norm
    return TailPlan(tails=tails, target=float(target), scattered_mean=norm, predicted=predicted)


def deep_share(scene, packed, seed, order, tracks=None) -> float:
    """The share of the light of orders >= 2 (and the environment's) that comes from orders beyond ``order``, over
    the frame: tails on a lattice of about DEEP_RAYS x DEEP_RAYS sample rays, cut at ``order`` and not (the same
    random numbers: the difference is the deep orders' light alone); 0 where the tails find no light. tracks:
    tail_tracks's (None: built here)."""
    h, w = scene.image.height, scene.image.width
    step = max(1, -(-max(h, w) // DEEP_RAYS))
    rr, cc = np.meshgrid(np.arange(0, h, step), np.arange(0, w, step), indexing="ij")
    tracks = tail_tracks(scene, packed) if tracks is None else tracks
    light = []
    for max_order in (min(int(order), scene.render.max_order), scene.render.max_order):
        lattice = Lattice(scene, packed, seed, max_order, tracks=tracks)
        lattice.trace(np.stack([rr.ravel(), cc.ravel()], 1), tails_per_node(DEEP_TAILS))
        prof, _, dw, _ = lattice.profiles(rr.ravel(), cc.ravel())
        light.append(float(np.einsum("nt,ntc->", dw, prof)))
    cut, full = light
    return max(0.0, 1.0 - cut / full) if full > 0.0 else 0.0


def _edge_share(var, hit):
    """The share of the variance ``var`` (rows x columns of lattice points) in the blocks between them whose
    corners partly miss the media (``hit``): where the refinement goes down to single pixels."""
    corners = [(slice(None, -1), slice(None, -1)), (slice(None, -1), slice(1, None)),
               (slice(1, None), slice(None, -1)), (slice(1, None), slice(1, None))]
    block = sum(var[c] for c in corners)
    hits = sum(hit[c].astype(np.int64) for c in corners)
    total = float(block.sum())
    return float(block[(hits > 0) & (hits < 4)].sum()) / total if total > 0.0 else 0.0


def node_weights(taus=TAUS):
    """w_a = the integral over [0, inf) of e^-tau times node a's hat function (the first held below it, the last
    above it): each node's share of a pixel's light where Q is even."""
    return depth_weights(np.array([np.inf]), taus)[0]


def depth_weights(depth, taus=TAUS):
    """(n, len(taus)): for optical depths depth (n,), the integral over [0, depth] of e^-tau times each node's
    hat function (piecewise linear through the nodes, constant below the first and above the last)."""
    u = np.minimum(np.asarray(depth, np.float64), MAX_DEPTH)[:, None]
    e = lambda x: -np.expm1(-x)  # noqa: E731  (the integral of e^-tau over [0, x])
    f = lambda x: 1.0 - (1.0 + x) * np.exp(-x)  # noqa: E731  (of tau e^-tau)
    n = len(taus)
    w = np.zeros((u.shape[0], n))
    w[:, 0] += e(np.minimum(u[:, 0], taus[0]))
    for a in range(n - 1):
        t0, t1 = taus[a], taus[a + 1]
        b = np.clip(u[:, 0], t0, t1)
        a0 = e(b) - e(t0)
        a1 = f(b) - f(t0)
        w[:, a] += (t1 * a0 - a1) / (t1 - t0)
        w[:, a + 1] += (a1 - t0 * a0) / (t1 - t0)
    w[:, n - 1] += e(np.maximum(u[:, 0], taus[-1])) - e(taus[-1])
    return w


def tails_per_node(tails, taus=TAUS):
    """About ``tails`` tails in all per sample ray, each node's in proportion to its weight (node_weights), at
    least 2 (a variance needs two)."""
    w = node_weights(taus)
    return np.maximum(np.rint(tails * w / w.sum()), 2).astype(np.int64)


def tail_tracks(scene, packed):
    """(majorant grid, light volumes) of the tails' tracked flights: the same for every lattice of a frame, whatever
    its order or cache, so built once. The tails are tracked from their first flight whatever render.track_from says
    (it places the unbiased paths' exact flights), so they are built here, not by tracking.paths_grid."""
    grid = majorant_grid(scene, packed.records.media)
    return grid, paths_volumes(scene, packed, tail_settings(scene.render.max_order))


def tail_settings(max_order):
    """The tails' records.PathSettings: one tail per call, tracked from the first flight, up to ``max_order``."""
    return PathSettings(max_order=int(max_order), rr_order=RR_ORDER, paths=1, track_from=2)


class Lattice:
    """The sample rays computed so far, by lattice point (row, column): their profiles and depths."""

    def __init__(self, scene, packed, seed, max_order, cache=None, tracks=None):
        self.packed = packed
        self.cache = no_cache(n_media(packed.records.media)) if cache is None else cache
        self.camera = packed.camera._replace(spp=1)
        self.seed = np.int64(seed ^ TAIL_SEED)
        self.grid, self.volumes = tail_tracks(scene, packed) if tracks is None else tracks
        self.path_settings = tail_settings(max_order)
        self.index = {}
        self.mean = np.zeros((0, len(TAUS), 3))
        self.var = np.zeros((0, len(TAUS), 3))
        self.depth = np.zeros(0)
        self.key_width = scene.image.width + 64 * 1024  # beyond any lattice column

    def trace(self, points, tails, progress=False, desc="tails"):
        """Trace the sample rays of ``points`` ((n, 2) rows and columns) not traced yet, with tails (per node)."""
        new = [(int(r), int(c)) for r, c in points if (int(r), int(c)) not in self.index]
        new = list(dict.fromkeys(new))
        if not new:
            return
        rows = np.array([p[0] for p in new], np.int64)
        cols = np.array([p[1] for p in new], np.int64)
        n = len(new)
        mean = np.empty((n, len(TAUS), 3))
        var = np.empty((n, len(TAUS), 3))
        depth = np.empty(n)
        keys = rows * self.key_width + cols
        p, rec, quad = self.camera, self.packed.records, self.packed.quadrature
        n_med = np.int64(n_media(rec.media))

        def run(lo):
            hi = min(lo + CHUNK, n)
            depth_tails(p, rec, quad, self.path_settings, self.grid, self.volumes, self.cache, rows[lo:hi],
                        cols[lo:hi], keys[lo:hi], TAUS, tails, self.seed, alloc_track_work(n_med), mean[lo:hi],
                        var[lo:hi], depth[lo:hi])
            return lo
        bar = progress_bar(n, progress, unit="ray", desc=desc)
        with ThreadPoolExecutor(numba.get_num_threads()) as pool:
            for lo in pool.map(run, range(0, n, CHUNK)):
                bar.update(min(CHUNK, n - lo))
        bar.close()
        base = len(self.depth)
        for q, point in enumerate(new):
            self.index[point] = base + q
        self.mean = np.concatenate([self.mean, mean])
        self.var = np.concatenate([self.var, var])
        self.depth = np.concatenate([self.depth, depth])

    def ids(self, rows, cols):
        return np.array([self.index[(int(r), int(c))] for r, c in zip(rows, cols)], np.int64)

    def profiles(self, rows, cols):
        """(profiles (n, T, 3), their variances, depth_weights (n, T), depths (n,)) of the traced points (rows[k],
        cols[k]), the nodes a ray does not reach filled (_filled)."""
        ids = self.ids(rows, cols)
        valid = ~np.isnan(self.mean[ids, :, 0])
        return (_filled(np.nan_to_num(self.mean[ids]), valid), _filled(np.nan_to_num(self.var[ids]), valid),
                depth_weights(self.depth[ids]), self.depth[ids])


def shared_light(scene, packed, window, alpha, seed, stride, tails, threshold, progress=False, cache=None,
                 tracks=None):
    """(light, stderr, sample rays): the shared method's light (tile_h x tile_w x 3) of the tile ``window``
    ((r_lo, r_hi), (c_lo, c_hi)), whose single-scattering alpha is ``alpha`` (tile_h x tile_w): the module
    docstring's three steps, with sample rays
    every ``stride`` pixels (a power of 2), about ``tails`` tails per sample ray, blocks split where their
    corners differ by more than ``threshold`` of their light, the tails reading ``cache`` (a records.FluenceCache,
    or None), their flights tracked through ``tracks`` (tail_tracks; None: built here); stderr: the tails' noise in
    it, per pixel."""
    (r_lo, r_hi), (c_lo, c_hi) = window
    h, w = scene.image.height, scene.image.width
    s0 = int(stride)
    lattice = Lattice(scene, packed, seed, scene.render.max_order, cache, tracks)
    # the depth pass: which pixels of the level-0 blocks that the tile touches meet a medium
    br0, br1 = r_lo // s0, (r_hi - 1) // s0 + 1
    bc0, bc1 = c_lo // s0, (c_hi - 1) // s0 + 1
    pr0, pr1, pc0, pc1 = br0 * s0, min(br1 * s0, h), bc0 * s0, min(bc1 * s0, w)
    pixel_depth = _pixel_depths(lattice, pr0, pr1, pc0, pc1)
    hits = pixel_depth > 0.0
    box = np.zeros((pr1 - pr0 + 1, pc1 - pc0 + 1), np.int64)  # summed-area table of the hits
    box[1:, 1:] = np.cumsum(np.cumsum(hits, axis=0), axis=1)

    def any_hit(r0, c0, s):  # per block (arrays): does a pixel of the block meet a medium
        a0, a1 = r0 - pr0, np.minimum(r0 + s, pr1) - pr0
        b0, b1 = c0 - pc0, np.minimum(c0 + s, pc1) - pc0
        return (box[a1, b1] - box[a0, b1] - box[a1, b0] + box[a0, b0]) > 0

    weights = node_weights()
    br, bc = np.meshgrid(np.arange(br0, br1), np.arange(bc0, bc1), indexing="ij")
    br, bc = br.ravel(), bc.ravel()
    refined = []  # per level: the frame's blocks of that level that were split (boolean, by block row and column)
    s = s0
    while len(br):
        corner_r = np.stack([br, br, br + 1, br + 1], 1) * s
        corner_c = np.stack([bc, bc + 1, bc, bc + 1], 1) * s
        # a ray of a finer level covers fewer pixels: for the same image noise at the least cost its tails go as
        # the square root of the pixels it covers (Lagrange), so as the stride
        lattice.trace(np.stack([corner_r.ravel(), corner_c.ravel()], 1), tails_per_node(tails * s / s0), progress,
                      f"shared light, every {s} px")
        split_of = np.zeros((-(-h // s) + 1, -(-w // s) + 1), bool)
        refined.append(split_of)
        if s == 1:
            break
        ids = lattice.ids(corner_r.ravel(), corner_c.ravel()).reshape(-1, 4)
        split = _disagree(lattice, ids, weights, threshold) | (
            np.any(lattice.depth[ids] <= 0.0, axis=1) & any_hit(br * s, bc * s, s)) | _unlike_corners(
            pixel_depth, pr0, pr1, pc0, pc1, br, bc, s, lattice.depth[ids])
        split_of[br[split], bc[split]] = True
        s //= 2
        cr = (2 * br[split])[:, None] + np.array([0, 0, 1, 1])
        cc = (2 * bc[split])[:, None] + np.array([0, 1, 0, 1])
        cr, cc = cr.ravel(), cc.ravel()
        keep = (cr * s < min(r_hi, h)) & ((cr + 1) * s > r_lo) & (cc * s < min(c_hi, w)) & ((cc + 1) * s > c_lo)
        br, bc = cr[keep], cc[keep]
    light, stderr = _gather(lattice, refined, s0, window, alpha)
    return light, stderr, len(lattice.depth)


def _unlike_corners(pixel_depth, pr0, pr1, pc0, pc1, br, bc, s, corner_depth, chunk=1 << 18):
    """Per block of size s (block rows br, columns bc; corner_depth (n, 4) its corners' optical depths): whether a
    pixel of the block has an optical depth more than e^DEPTH_SPLIT times, or less than e^-DEPTH_SPLIT times, the one
    bilinear between its corners (both at least DEPTH_FLOOR); pixel_depth: the centre rays' depths of the pixels
    [pr0, pr1) x [pc0, pc1), the only ones read. Blocks in chunks of about ``chunk`` pixels."""
    out = np.zeros(len(br), bool)
    if s <= 1:
        return out
    off = np.arange(s)
    f = off / s
    wr = np.stack([1 - f, f])  # (2, s): the top and bottom corners' weights by row within the block
    step = max(1, chunk // (s * s))
    for lo in range(0, len(br), step):
        hi = min(lo + step, len(br))
        rows = br[lo:hi, None] * s + off  # (n, s)
        cols = bc[lo:hi, None] * s + off
        inside = ((rows >= pr0) & (rows < pr1))[:, :, None] & ((cols >= pc0) & (cols < pc1))[:, None, :]
        u = pixel_depth[np.clip(rows - pr0, 0, pr1 - pr0 - 1)[:, :, None],
                        np.clip(cols - pc0, 0, pc1 - pc0 - 1)[:, None, :]]
        d = np.maximum(corner_depth[lo:hi], 0.0).reshape(-1, 2, 2)  # (n, top/bottom, left/right)
        bilinear = np.einsum("ai,nab,bj->nij", wr, d, wr)
        gap = np.abs(np.log(np.maximum(u, DEPTH_FLOOR) / np.maximum(bilinear, DEPTH_FLOOR)))
        out[lo:hi] = np.where(inside, gap, 0.0).max(axis=(1, 2)) > DEPTH_SPLIT
    return out


def _pixel_depths(lattice, r0, r1, c0, c1, chunk=4096):
    """(r1 - r0, c1 - c0): each pixel's centre ray's optical depth up to the first surface (0 where it misses the
    media; depth_tails without tails)."""
    rr, cc = np.meshgrid(np.arange(r0, r1), np.arange(c0, c1), indexing="ij")
    rows, cols = rr.ravel().astype(np.int64), cc.ravel().astype(np.int64)
    n = len(rows)
    depth = np.zeros(n)
    none = np.zeros(len(TAUS), np.int64)
    p, rec, quad = lattice.camera, lattice.packed.records, lattice.packed.quadrature
    n_med = np.int64(n_media(rec.media))

    def run(lo):
        hi = min(lo + chunk, n)
        unused = np.empty((hi - lo, len(TAUS), 3))  # no tails: the profiles stay NaN
        depth_tails(p, rec, quad, lattice.path_settings, lattice.grid, lattice.volumes, lattice.cache, rows[lo:hi],
                    cols[lo:hi], rows[lo:hi], TAUS, none, lattice.seed, alloc_track_work(n_med), unused, unused.copy(),
                    depth[lo:hi])
    with ThreadPoolExecutor(numba.get_num_threads()) as pool:
        list(pool.map(run, range(0, n, chunk)))
    return depth.reshape(r1 - r0, c1 - c0)


def _disagree(lattice, ids, weights, threshold):
    """Per block (ids: (n, 4) its corners' sample rays): whether the corners' profiles differ, at the nodes all
    four reach and weighted like the integral (luminance: the mean of RGB), by more than ``threshold`` (absolute)
    plus twice that difference's noise."""
    mean = lattice.mean[ids].mean(axis=3)  # (n, 4, T)
    valid = np.all(~np.isnan(mean), axis=1)  # (n, T)
    mean = np.nan_to_num(mean)
    var = np.nan_to_num(lattice.var[ids].mean(axis=3))
    spread = np.where(valid, mean.max(axis=1) - mean.min(axis=1), 0.0) @ weights
    level = np.where(valid, mean.mean(axis=1), 0.0) @ weights
    noise = np.sqrt(np.where(valid, 2.0 * var.max(axis=1), 0.0) @ (weights * weights))
    return spread > threshold * level + 2.0 * noise


def _gather(lattice, refined, s0, window, alpha, chunk=32768):
    """Each pixel of the tile: the integral of e^-tau Q up to its depth, Q bilinear between the corners of its
    smallest block (module docstring)."""
    (r_lo, r_hi), (c_lo, c_hi) = window
    out = np.zeros((r_hi - r_lo, c_hi - c_lo, 3))
    var = np.zeros_like(out)
    ii, jj = np.nonzero(alpha > 0.0)
    if len(ii) == 0:
        return out, var
    gi, gj = ii + r_lo, jj + c_lo
    with np.errstate(divide="ignore"):
        depth = np.minimum(-np.log1p(-np.minimum(alpha[ii, jj].astype(np.float64), 1.0)), MAX_DEPTH)
    # each pixel's smallest block
    size = np.full(len(gi), s0)
    for level, split_of in enumerate(refined):
        s = s0 >> level
        deeper = (size == s) & split_of[gi // s, gj // s]
        size[deeper] = s // 2
    r0, c0 = (gi // size) * size, (gj // size) * size
    fr, fc = (gi - r0) / size, (gj - c0) / size
    corner_r = np.stack([r0, r0, r0 + size, r0 + size], 1)
    corner_c = np.stack([c0, c0 + size, c0, c0 + size], 1)
    wts = np.stack([(1 - fr) * (1 - fc), (1 - fr) * fc, fr * (1 - fc), fr * fc], 1)
    ids = lattice.ids(corner_r.ravel(), corner_c.ravel()).reshape(-1, 4)
    for lo in range(0, len(gi), chunk):
        sl = slice(lo, lo + chunk)
        m = lattice.mean[ids[sl]]  # (n, 4, T, 3)
        ok = ~np.isnan(m[..., 0])
        wk = wts[sl][:, :, None] * ok  # (n, 4, T)
        # a pixel whose weighted corners all miss the media (its centre ray missed, a ray of its footprint did not)
        # takes its block's corners that meet them, equally
        lost = ~np.any(wk > 0.0, axis=(1, 2))
        wk[lost] = 0.25 * ok[lost]
        den = wk.sum(axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            wk = wk / den[:, None, :]
        prof = _filled(np.einsum("nkt,nktc->ntc", wk, np.where(ok[..., None], m, 0.0)), den > 0)
        prof_var = _filled(np.einsum("nkt,nktc->ntc", wk * wk, np.where(ok[..., None], lattice.var[ids[sl]], 0.0)),
                           den > 0)
        dw = depth_weights(depth[sl])
        out[ii[sl], jj[sl]] = np.einsum("nt,ntc->nc", dw, prof)
        var[ii[sl], jj[sl]] = np.einsum("nt,ntc->nc", dw * dw, prof_var)
    return out, np.sqrt(var)


def _filled(prof, valid):
    """The nodes of each profile (n, T, 3) not ``valid`` (n, T) take the last valid value before them (the first
    valid one before the first); a profile without any is 0."""
    t = np.arange(prof.shape[1])
    last = np.maximum.accumulate(np.where(valid, t, -1), axis=1)
    first = np.argmax(valid, axis=1)
    src = np.where(last >= 0, last, first[:, None])
    out = np.take_along_axis(prof, src[..., None], axis=1)
    out[~valid.any(axis=1)] = 0.0
    return out
