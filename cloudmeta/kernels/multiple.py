"""Multiple scattering: the orders >= 2 of the light sources, and every order of the environment, by Monte
Carlo path tracing (README, "Multiple scattering"; docs/model.md §10 and §10.1).

The deterministic single-scattering renderer (kernels.single) already gives order 1 of every light
exactly; these paths add what it does not count. A path's flights up to vertex ``track_from`` - 1 are
*exact* (exact_vertex), the later ones *tracked* (tracked_vertex):

- Exact flights invert the exact, piecewise-polynomial optical depth of the ray (no majorant): the ray's
  media are cut into elementary intervals as for the camera ray (raywork.elementary_intervals), the
  interval where the depth crosses the target is found, and the degree-7 antiderivative is solved there
  (sampling.free_flight). Every exact flight is a *forced collision*: the target is drawn inside the
  segment's optical depth U and the path weight is multiplied by 1 - e^-U. The environment (the
  background's radiance, uniform or a sky table over elevation) is counted after each such vertex as the
  background times e^-U (0 where the segment ends on an opaque surface); next-event estimation towards
  every light at vertices 2, 3, ... takes the exact shadow transmittance (media.shadow_transmittance,
  blocked by any surface) times sum_m (sigma_s,m / sigma_t) p_m(l . d). Vertex 1 gets none: that is
  single scattering, counted exactly already.
- Tracked flights are delta-tracked against the majorant grid (kernels.tracking): the vertex has the same
  distribution, at a few point evaluations of the field instead of an exact sweep. A flight that gets
  through sees the environment and ends the path (the escape's probability is the transmittance). Next-event
  estimation takes an unbiased estimate of T_l (light_transmittance): the shadow map's T as a control
  variate with an exact shadow ray now and then for a directional light, ratio tracking for a point light.
- At a vertex the path weight takes sigma_s / sigma_t (all media); the medium whose phase function turns
  the path is picked with probability sigma_s,m / sigma_s, and the new direction is drawn exactly from
  that phase function, so the phase and its density cancel.
- Russian roulette from vertex ``rr_order`` on (survival probability min(1, weight / the weight at vertex 1):
  the camera segment's forced collision is shared by all the paths of a camera ray); no vertex beyond
  ``max_order``.
- Opaque surfaces end a path (they are black to multiply scattered light; see README).

Random numbers: each vertex's flight, lobe and direction come from the quasi-random stream sampling.sobol4
keyed by (seed, pixel, path, vertex), the medium, the roulette and the tracked walks from sampling.uniform keyed
by (seed, pixel, path, vertex, dimension): a pixel's result does not depend on any other pixel, nor on the threads.

The scene is the records.SceneRecords that cloudmeta.renderer.pack packs for the single-scattering renderer
(one packing for both estimators), the quadrature record gives the root tolerance, and one thread's
work arrays are the camera rays' records.RayWork: the shared stages (kernels.features, media, raywork,
lighting, camera: the first surface hit, the media on the ray, their elementary intervals, the light at a
node with its shadow rays) are called as they are, not copied.
"""
import math

import numpy as np
from numba import njit

from .config import NJIT, NJIT_INLINE
from .bernstein import bernstein_eval, bernstein_mean
from .media import collect_media, medium_blob, n_media, shadow_transmittance
from .shadowmap import volume_optical_depth
from .metaball import gradient_sum
from .optics import phase
from .bvh import bvh_point_candidates, misses_root_boxes
from .optional import surface_hit, surfaces_blocking
from .camera import background_radiance, camera_ray, background_gives_light
from .lighting import light_at_node, light_geometry
from .intervals import alloc_ray_work, elementary_intervals
from .borrow import borrow, hold_grown, release
from .records import SHADOWS_MAP, CameraSegment, PathKey, PathVectors, RayWork
from .sampling import free_flight, sample_phase_cos, sobol4, turn, uniform
from .tracking import (DIM_LIGHT, DIM_SPAN, alloc_track_work, delta_flight, pick_medium, release_track,
                       tracked_transmittance)

#: the independent random dimensions of one vertex (the stream's last key); the flight, the phase's lobe
#: and its direction come from the vertex's block of the quasi-random stream (sampling.sobol4)
DIM_MEDIUM = 1
DIM_ROULETTE = 2
#: a shadow ray stops once its optical depth passes this (T < 2e-22)
TAU_STOP = 50.0
#: the control variate of a light's transmittance at a tracked vertex (light_transmittance)
CV_PROBABILITY = 0.02
FOUR_PI = 4.0 * math.pi


@njit(**NJIT)
def trace_segment(o, d, scene, tol_t, work):
    """The media on o + t d up to the first opaque surface, as elementary intervals in work.pieces.
    Returns (work, n_intervals, optical depth of the whole segment, whether it ends on a surface)."""
    scratch, t_hit, s_hit = surface_hit(o, d, scene.surfaces, tol_t, work)
    rp = work.pieces
    n = 0
    if t_hit > 0.0:
        scratch, rp, n = collect_media(o, d, t_hit, scene.media, tol_t, scratch, rp, work.cand, work.stack)
    work = RayWork(scratch, rp, work.cand, work.stack, work.nodes)
    if n == 0:
        return work, 0, 0.0, s_hit >= 0
    n_el = elementary_intervals(n, rp)
    return work, n_el, rp.el_u0[n_el], s_hit >= 0


@njit(**NJIT)
def locate_depth(target, n_el, rp):
    """(interval k, s in [0, 1] on it, t) where the segment's optical depth reaches target (< its total)."""
    el_t0, el_t1, el_u0 = rp.el_t0, rp.el_t1, rp.el_u0
    lo = 0
    hi = n_el - 1
    while lo < hi:  # the last interval whose start depth is <= target
        mid = (lo + hi + 1) // 2
        if el_u0[mid] <= target:
            lo = mid
        else:
            hi = mid - 1
    k = lo
    w = el_t1[k] - el_t0[k]
    s = free_flight(rp.el_S[k], w, min(target - el_u0[k], el_u0[k + 1] - el_u0[k]))
    return k, s, el_t0[k] + s * w


@njit(**NJIT)
def _sigma_at(rp, k, m, s, use_mean):
    return bernstein_mean(rp.el_sig[k, m]) if use_mean else bernstein_eval(rp.el_sig[k, m], s)


@njit(**NJIT)
def scattering_mix(k, s, rp, med, u):
    """At s on interval k: (sigma_s / sigma_t over all media, the medium picked with probability
    sigma_s,m / sigma_s by u). Where sigma_t vanishes at the point itself (an `excess` edge, probability
    zero), the interval's mean control values stand in."""
    use_mean = False
    sigma_t = 0.0
    sigma_s = 0.0
    for attempt in range(2):
        use_mean = attempt == 1
        sigma_t = 0.0
        sigma_s = 0.0
        for m in range(n_media(med)):
            sig = _sigma_at(rp, k, m, s, use_mean)
            sigma_t += sig
            sigma_s += med.albedo[m] * sig
        if sigma_t > 0.0:
            break
    if not (sigma_t > 0.0 and sigma_s > 0.0):
        return 0.0, 0
    pick = u * sigma_s
    acc = 0.0
    chosen = 0
    for m in range(n_media(med)):
        part = med.albedo[m] * _sigma_at(rp, k, m, s, use_mean)
        if part > 0.0:
            chosen = m
            acc += part
            if pick < acc:
                break
    return sigma_s / sigma_t, chosen


@njit(**NJIT)
def next_event(x, d, k, s, scene, tol_t, j_tol, work, out):
    """out[:3] += sum over lights of E_l T_l sum_m (sigma_s,m / sigma_t) p_m(l . d) at x (s on interval k
    of work.pieces, the ray with direction d): the light scattered once more at x, with the shadow rays
    of the single-scattering renderer (lighting.light_at_node; j_tol its trust in a shadow map). Returns
    work."""
    med = scene.media
    el_sig = work.pieces.el_sig
    sigma_t = 0.0
    sigma_s = 0.0
    for m in range(n_media(med)):
        sig = bernstein_eval(el_sig[k, m], s)
        sigma_t += sig
        sigma_s += med.albedo[m] * sig
    if not (sigma_t > 0.0 and sigma_s > 0.0):
        return work
    # paths stay unbiased: a hybrid map is not trusted here (j_tol 0), a plain map always (inf)
    scratch = light_at_node(x, x, d, False, TAU_STOP, j_tol, scene, tol_t, work.scratch, work)
    light = work.nodes.light
    for m in range(n_media(med)):
        ratio = med.albedo[m] * bernstein_eval(el_sig[k, m], s) / sigma_t
        if ratio == 0.0:
            continue
        for li in range(light.shape[0]):
            ph = phase(med.phase[m, 0], med.phase[m, 1], med.phase[m, 2], med.phase[m, 3], light[li, 0])
            for c in range(3):
                out[c] += ratio * ph * light[li, 1 + c]
    return RayWork(scratch, work.pieces, work.cand, work.stack, work.nodes)


#: inlined: a call that passes the scene's records cost 8 % of a tracked render (one thread, cumulus)
@njit(**NJIT_INLINE)
def tracked_next_event(x, d, sigma_t, scene, grid, volumes, key, vertex, tol_t, work, track, out):
    """next_event at a tracked vertex x (records.TrackWork track.at_vertex: each medium's sigma_t there,
    sigma_t their sum): the same sum over lights, each T_l an unbiased estimate (light_transmittance);
    surfaces still block exactly. Returns work."""
    med = scene.media
    lights = scene.lights
    l_dir = work.nodes.l_dir
    scratch = work.scratch
    for li in range(lights.kind.shape[0]):
        e_scale, l_max = light_geometry(lights, li, x, l_dir)
        scratch, blocked = surfaces_blocking(x, l_dir, l_max, scene.surfaces, tol_t, scratch, work)
        if blocked:
            continue
        cos_ld = l_dir[0] * d[0] + l_dir[1] * d[1] + l_dir[2] * d[2]
        scattered = 0.0
        for m in range(n_media(med)):
            sig = track.at_vertex[m]
            if sig > 0.0:
                scattered += med.albedo[m] * sig / sigma_t * phase(med.phase[m, 0], med.phase[m, 1], med.phase[m, 2],
                                                                   med.phase[m, 3], cos_ld)
        if scattered == 0.0:
            continue
        # the control variate's correction is weighted by the phase: where it peaks, correct more often
        gain = max(1.0, FOUR_PI * scattered)
        scratch, t_l = light_transmittance(x, l_dir, l_max, li, gain, scene, grid, volumes, key, vertex, tol_t, scratch,
                                           work, track)
        if t_l == 0.0:
            continue
        for c in range(3):
            out[c] += scattered * lights.rgb[li, c] * e_scale * t_l
    return RayWork(scratch, work.pieces, work.cand, work.stack, work.nodes)


@njit(**NJIT_INLINE)
def light_transmittance(x, l_dir, l_max, li, gain, scene, grid, volumes, key, vertex, tol_t, scratch, work, track):
    """An unbiased estimate of light li's transmittance from x along l_dir (up to l_max): (scratch, T_l).
    With a light volume (volumes, records.LightVolumes: a directional light), its T_map is a control variate:
    T_l = T_map + (T - T_map) / p with probability p, T being an exact shadow ray, and T_map otherwise;
    p = (CV_PROBABILITY + the spread of the four texel columns' transmittances) x ``gain`` (at most 1): gain
    is 4 pi times the vertex's phase-weighted albedo towards the light, at least 1, so that where a map's
    error would be multiplied by a forward peak of the phase the correction's weight 1 / p is not (a map
    that missed a puff's shadow, corrected at p = 0.02 through an HG 0.8 peak, gave single paths 500 times a
    pixel's mean, and negative pixels). (A ratio-tracked T
    in the correction was tried: its noise, divided by p, doubled the variance.) Without one (a point
    light), residual ratio tracking (kernels.tracking)."""
    dim = np.int64(DIM_LIGHT + li * DIM_SPAN)
    vi = volumes.map_of[li]
    if vi < 0:
        return scratch, tracked_transmittance(x, l_dir, l_max, grid, scene.media, key, vertex, dim, track)
    tau, tau_lo, tau_hi = volume_optical_depth(x, volumes, vi)
    t_map = math.exp(-tau)
    # the four columns' spread bounds |T - T_map| where the depth is monotone across the cell: correct there
    p = min(1.0, (CV_PROBABILITY + (math.exp(-tau_lo) - math.exp(-tau_hi))) * gain)
    if uniform(key.seed, key.pixel, key.path, vertex, dim - 1) >= p:
        return scratch, t_map
    scratch, t_l, _ = shadow_transmittance(x, l_dir, l_max, scene.media, tol_t, TAU_STOP, scratch, work.cand,
                                           work.stack)
    return scratch, t_map + (t_l - t_map) / p


@njit(**NJIT_INLINE)
def exact_vertex(o, d, n_vert, weight, key, camera_segment, scene, tol_t, map_trust, has_env, max_order, work,
                 light, out):
    """One exact step of ray_paths: the segment from o along d traced exactly (the camera's for
    n_vert 0), the environment seen through it, a forced collision in it (o moves there), the light
    scattered there and the scattering mix. Returns (work, weight, the medium that turns the path, the
    direction's three random numbers, whether the path ends)."""
    seed, pixel, path = key.seed, key.pixel, key.path
    if n_vert == 0:
        rp, n_el, u_total = camera_segment.pieces, camera_segment.n_el, camera_segment.u_total
        on_surface = False  # (the environment is not counted at vertex 0)
    else:
        work, n_el, u_total, on_surface = trace_segment(o, d, scene, tol_t, work)
        rp = work.pieces
    if n_vert > 0 and has_env and not on_surface:
        transmittance = math.exp(-u_total)
        r, g, b = background_radiance(scene.background, d)  # the environment, order n_vert, seen along d
        out[0] += weight * transmittance * r
        out[1] += weight * transmittance * g
        out[2] += weight * transmittance * b
    if n_vert == max_order or n_el == 0:
        return work, weight, 0, 0.0, 0.0, 0.0, True
    # a forced collision inside the segment: the flight's target depth is drawn in [0, U)
    xi, u_cos, u_phi, u_lobe = sobol4(seed, pixel, path, n_vert)
    escape = -math.expm1(-u_total)
    weight *= escape
    k, s, t = locate_depth(-math.log1p(-xi * escape), n_el, rp)
    for c in range(3):
        o[c] = o[c] + t * d[c]
    if n_vert > 0:  # vertex 1 is single scattering: counted exactly by the deterministic renderer
        light[:] = 0.0
        work = next_event(o, d, k, s, scene, tol_t, map_trust, work, light)
        for c in range(3):
            out[c] += weight * light[c]
    ratio, m = scattering_mix(k, s, rp, scene.media, uniform(seed, pixel, path, n_vert, DIM_MEDIUM))
    return work, weight * ratio, m, u_cos, u_phi, u_lobe, False


@njit(**NJIT_INLINE)
def tracked_vertex(o, d, n_vert, weight, key, scene, grid, volumes, tol_t, has_env, max_order, work, track, light, out):
    """One tracked step of ray_paths (kernels.tracking): the next vertex by delta tracking along d (no
    forced collision); a flight that gets through sees the environment (its probability is the
    transmittance: the estimate is unbiased, and it costs no second walk) and ends the path. Otherwise o
    moves to the vertex, and the light scattered there (tracked_next_event) and the scattering mix follow.
    Returns what exact_vertex returns. Call it from a kernel that receives ``track`` as an argument: inlined
    into the function that allocated the TrackWork, the copy into ``track.at_vertex`` was lost and every
    next-event estimate came out 0 (not understood; docs/benchmarks.md, the sharing prototype)."""
    seed, pixel, path = key.seed, key.pixel, key.path
    scratch, t_hit, s_hit = surface_hit(o, d, scene.surfaces, tol_t, work)
    work = RayWork(scratch, work.pieces, work.cand, work.stack, work.nodes)
    t, sigma_t, sigma_s = delta_flight(o, d, t_hit, grid, scene.media, key, n_vert, track)
    if t == np.inf:
        if has_env and s_hit < 0:
            r, g, b = background_radiance(scene.background, d)  # the environment, order n_vert, seen along d
            out[0] += weight * r
            out[1] += weight * g
            out[2] += weight * b
        return work, weight, 0, 0.0, 0.0, 0.0, True
    if n_vert == max_order:
        return work, weight, 0, 0.0, 0.0, 0.0, True
    for c in range(3):
        o[c] = o[c] + t * d[c]
    for m in range(track.sigma.shape[0]):
        track.at_vertex[m] = track.sigma[m]
    light[:] = 0.0
    work = tracked_next_event(o, d, sigma_t, scene, grid, volumes, key, n_vert, tol_t, work, track, light)
    for c in range(3):
        out[c] += weight * light[c]
    m = pick_medium(track.at_vertex, scene.media, sigma_s, uniform(seed, pixel, path, n_vert, DIM_MEDIUM))
    _, u_cos, u_phi, u_lobe = sobol4(seed, pixel, path, n_vert)
    return work, weight * sigma_s / sigma_t, m, u_cos, u_phi, u_lobe, False


@njit(**NJIT)
def ray_paths(o_cam, d_cam, seed, pixel, first, step, camera_segment, scene, quad, settings, grid, volumes, work,
              track, vectors, out, acc, acc2):
    """Paths first, first + step, first + 2 step, ... (< settings.paths; step: the camera's rays per pixel) on one
    camera ray o_cam + t d_cam: each path's estimate of the radiance the deterministic renderer leaves out
    (orders >= 2 of the lights, orders >= 1 of the environment), added to acc[:3], its square to acc2 (out
    holds the last one). The paths of a ray share one call: a call that passes the scene's records cost
    1.4 us, 6 % of a path on the cumulus.
    camera_segment: a records.CameraSegment, trace_segment of the camera ray, traced once for all its
    paths; settings a records.PathSettings; grid a records.MajorantGrid and track a records.TrackWork for
    the tracked flights (from vertex settings.track_from on); vectors a records.PathVectors. Returns work,
    grown if a ray needed more room."""
    max_order, rr_order, tol_t = settings.max_order, settings.rr_order, quad.tol_t
    track_from = settings.track_from
    map_trust = np.inf if quad.shadow_mode == SHADOWS_MAP else 0.0
    has_env = background_gives_light(scene.background)
    o, d, d_new, light = vectors.o, vectors.d, vectors.d_new, vectors.light
    for path in range(first, settings.paths, step):
        key = PathKey(seed, pixel, path)
        for c in range(3):
            o[c] = o_cam[c]
            d[c] = d_cam[c]
            out[c] = 0.0
        weight = 1.0
        weight_1 = 1.0
        for n_vert in range(max_order + 1):
            if n_vert == max_order and not has_env:
                break
            if n_vert > 0 and n_vert + 1 >= track_from:
                work, weight, m, u_cos, u_phi, u_lobe, done = tracked_vertex(
                    o, d, n_vert, weight, key, scene, grid, volumes, tol_t, has_env, max_order, work, track, light, out)
                if done:
                    break
            else:
                work, weight, m, u_cos, u_phi, u_lobe, done = exact_vertex(
                    o, d, n_vert, weight, key, camera_segment, scene, tol_t, map_trust, has_env, max_order, work,
                    light, out)
                if done:
                    break
            if weight <= 0.0:
                break
            if n_vert == 0:
                weight_1 = weight  # the camera's forced collision: the same for every path of the camera ray
            if n_vert + 1 >= rr_order:
                # relative to vertex 1: an edge pixel's thin camera segment does not make its paths die early
                survive = min(1.0, weight / weight_1)
                if uniform(seed, pixel, path, n_vert, DIM_ROULETTE) >= survive:
                    break
                weight /= survive
            ph = scene.media.phase[m]
            cos_theta = sample_phase_cos(ph[0], ph[1], ph[2], ph[3], u_lobe, u_cos)
            turn(d, cos_theta, u_phi, d_new)
            for c in range(3):
                d[c] = d_new[c]
        for c in range(3):
            acc[c] += out[c]
            acc2[c] += out[c] * out[c]
    return work


@njit(**NJIT)
def _store_mean(acc, acc2, paths, i, j, mean, stderr):
    """mean[i, j] and stderr[i, j] of ``paths`` estimates with sums acc and sums of squares acc2."""
    for c in range(3):
        mu = acc[c] / paths
        mean[i, j, c] = mu
        if paths > 1:
            var = max(0.0, (acc2[c] - paths * mu * mu) / (paths - 1))
            stderr[i, j, c] = math.sqrt(var / paths)
        else:
            stderr[i, j, c] = np.inf


@njit(**NJIT)
def render_paths(camera, scene, quad, settings, grid, volumes, row0, p0, p1, mean, stderr):
    """Pixels p0 .. p1 - 1 (row by row from the start of row row0): per pixel, the mean of
    ``settings.paths`` path estimates into mean (H x W x 3), and its standard error into stderr. Path i
    starts on camera ray i mod spp of the deterministic renderer (camera.camera_ray), so the two add up
    ray by ray. camera, scene, quad: the records of single.render_pixels; grid: the records.MajorantGrid of
    the tracked flights (from vertex settings.track_from on; any grid when none is tracked). nogil, with its own work
    arrays: cloudmeta.renderer.multiple runs bands of rows on several threads. The camera ray's own segment is
    traced once per ray, into work arrays of its own, for all the paths that start on it (ray by ray:
    paths r, r + spp, r + 2 spp, ...)."""
    width, spp, paths = camera.width, camera.spp, settings.paths
    strata = int(math.ceil(math.sqrt(spp)))
    # borrowed records, as in single.render_pixels (kernels.borrow)
    own = alloc_ray_work(scene)
    camera_own = alloc_ray_work(scene)
    work = borrow(own)
    camera_work = borrow(camera_own)
    track_own = alloc_track_work(n_media(scene.media))
    track = borrow(track_own)
    scene = borrow(scene)
    quad = borrow(quad)
    grid = borrow(grid)
    volumes = borrow(volumes)
    # the path's small vectors too: owned, each vertex's helpers counted them with atomic operations
    vectors_own = PathVectors(np.empty(3), np.empty(3), np.empty(3), np.empty(3))
    d_own = np.empty(3)  # the camera ray's direction, a path's estimate, the sums of the estimates and squares
    est_own = np.empty(3)
    sums_own = np.empty(6)
    vectors = borrow(vectors_own)
    d = borrow(d_own)
    est = borrow(est_own)
    acc = borrow(sums_own[:3])
    acc2 = borrow(sums_own[3:])
    for p in range(p0, p1):
        i = row0 + p // width
        j = p % width
        for c in range(3):
            acc[c] = 0.0
            acc2[c] = 0.0
        for r in range(min(spp, paths)):
            camera_ray(camera, i, j, r, strata, d)
            if misses_root_boxes(camera.position, d, scene.media.bvh):
                continue  # no medium on the camera ray: nothing scatters, the estimate is 0
            camera_work, n_el, u_total, _ = trace_segment(camera.position, d, scene, quad.tol_t, camera_work)
            if n_el == 0:
                continue
            segment = CameraSegment(camera_work.pieces, n_el, u_total)
            work = ray_paths(camera.position, d, camera.seed, i * width + j, r, spp, segment, scene, quad, settings,
                             grid, volumes, work, track, vectors, est, acc, acc2)
        own, work = hold_grown(own, work)
        camera_own, camera_work = hold_grown(camera_own, camera_work)
        _store_mean(acc, acc2, paths, i, j, mean, stderr)
    release(own)
    release(camera_own)
    release_track(track_own)
    vectors_own.o[0] += 0.0  # the last uses of the borrowed vectors' owners (kernels.borrow.release)
    d_own[0] += 0.0
    est_own[0] += 0.0
    sums_own[0] += 0.0


@njit(**NJIT)
def aux_pixels(camera, scene, quad, row0, p0, p1, albedo, normal):
    """The denoiser's auxiliary images (renderer.denoise), pixels p0 .. p1 - 1 as in render_pixels: on each
    pixel's first camera ray, where it first enters a medium (before any surface), albedo[i, j] = that
    medium's albedo (grey) and normal[i, j] = the unit outward normal of its isosurface there, -grad F /
    |grad F|; both 0 where the ray meets no medium. nogil, with its own work arrays."""
    width = camera.width
    strata = int(math.ceil(math.sqrt(camera.spp)))
    own = alloc_ray_work(scene)
    work = borrow(own)
    scene = borrow(scene)
    med = scene.media
    d = np.empty(3)
    x = np.empty(3)
    for p in range(p0, p1):
        i = row0 + p // width
        j = p % width
        for c in range(3):
            albedo[i, j, c] = 0.0
            normal[i, j, c] = 0.0
        camera_ray(camera, i, j, np.int64(0), strata, d)
        if misses_root_boxes(camera.position, d, med.bvh):
            continue
        scratch, t_hit, _ = surface_hit(camera.position, d, scene.surfaces, quad.tol_t, work)
        scratch, rp, n = collect_media(camera.position, d, t_hit, med, quad.tol_t, scratch, work.pieces, work.cand,
                                       work.stack)
        own, work = hold_grown(own, RayWork(scratch, rp, work.cand, work.stack, work.nodes))
        if n == 0:
            continue
        first = 0
        for k in range(1, n):
            if rp.t0[k] < rp.t0[first]:
                first = k
        m = rp.medium[first]
        for c in range(3):
            x[c] = camera.position[c] + rp.t0[first] * d[c]
        n_cand = bvh_point_candidates(x, med.bvh, med.bvh.root[m], work.stack, work.cand)
        gx, gy, gz = gradient_sum(x, medium_blob(med, m), work.cand, 0, n_cand)
        size = math.sqrt(gx * gx + gy * gy + gz * gz)
        for c in range(3):
            albedo[i, j, c] = med.albedo[m]
        if size > 0.0:
            normal[i, j, 0] = -gx / size
            normal[i, j, 1] = -gy / size
            normal[i, j, 2] = -gz / size
    release(own)
