"""Multiple scattering: the orders >= 2 of the light sources, and every order of the environment, by Monte
Carlo path tracing on the exact optical depth (README, "Multiple scattering").

The deterministic single-scattering renderer (kernels.radiance) already gives order 1 of every light
exactly; these paths add what it does not count:

- Free flights are sampled by inverting the exact, piecewise-polynomial optical depth of the ray (no
  majorant, no null collisions): the ray's media are cut into elementary intervals as for the camera
  ray (radiance.elementary_intervals), the interval where the depth crosses the target is found, and the
  degree-7 antiderivative is solved there (sampling.free_flight). Every flight is a *forced collision*:
  the target is drawn inside the segment's optical depth U and the path weight is multiplied by
  1 - e^-U, so no path is wasted on escaping.
- The environment (the uniform background radiance) is estimated where a path would escape: after each
  vertex, the background times the segment's transmittance e^-U (0 where the segment ends on an opaque
  surface). This counts every order >= 1 of the environment; order 0 (the background seen straight
  through) is the deterministic renderer's.
- Next-event estimation towards every light at vertices 2, 3, ...: the exact shadow transmittance
  (media.shadow_transmittance, blocked by any surface) times sum_m (sigma_s,m / sigma_t) p_m(l . d).
  Vertex 1 gets none: that is single scattering, counted exactly already.
- At a vertex the path weight takes sigma_s / sigma_t (all media); the medium whose phase function turns
  the path is picked with probability sigma_s,m / sigma_s, and the new direction is drawn exactly from
  that phase function, so the phase and its density cancel.
- Russian roulette from vertex ``rr_order`` on (survival probability min(1, weight)); no vertex beyond
  ``max_order``.
- Opaque surfaces end a path (they are black to multiply scattered light; see README).

Random numbers come from sampling.uniform keyed by (pixel, path, vertex, dimension): a pixel's result
does not depend on any other pixel, nor on the threads.

The packed scene tuples are read only through the accessors below (one place to adapt when their
layout changes): ``med``, ``surf`` and ``lights`` as cloudmeta.render packs them, ``rp`` as
media.alloc_ray_pieces lays it out.
"""
import math

import numpy as np
from numba import njit

from ..config import NJIT, NJIT_INLINE
from .bernstein import bernstein_eval, bernstein_mean
from .media import alloc_ray_pieces, collect_media, shadow_transmittance
from .optics import phase
from .radiance import DIRECTIONAL, alloc_work, elementary_intervals, jitter, misses_media
from .sampling import free_flight, sample_phase_cos, turn, uniform
from .surfaces import first_surface_hit, surfaces_block
from .sweep import alloc_scratch

#: random dimensions of one vertex (the stream's last key)
DIM_FLIGHT = 0
DIM_MEDIUM = 1
DIM_ROULETTE = 2
DIM_LOBE = 3
DIM_COS = 4
DIM_PHI = 5
#: a shadow ray stops once its optical depth passes this (T < 2e-22)
TAU_STOP = 50.0


# ------------------------------------------------------------------ accessors of the packed tuples

@njit(**NJIT_INLINE)
def n_media(med):
    return med[3].shape[0] - 1


@njit(**NJIT_INLINE)
def n_media_balls(med):
    return med[0].shape[0]


@njit(**NJIT_INLINE)
def medium_albedo(med, m):
    return med[8][m]


@njit(**NJIT_INLINE)
def medium_phase(med, m):
    """(kind, g1, g2, w) of medium m."""
    p = med[9]
    return p[m, 0], p[m, 1], p[m, 2], p[m, 3]


@njit(**NJIT_INLINE)
def media_roots(med):
    """(node_box, root) of the media's BVH: what radiance.misses_media reads."""
    return med[10], med[15]


@njit(**NJIT_INLINE)
def n_surface_balls(surf):
    return surf[0].shape[0]


@njit(**NJIT_INLINE)
def n_surfaces(surf):
    return surf[3].shape[0] - 1


@njit(**NJIT_INLINE)
def n_lights(lights):
    return lights[0].shape[0]


@njit(**NJIT_INLINE)
def light_arrays(lights):
    """(kind, vec, rgb): per light its kind, direction towards it or position, irradiance or intensity."""
    return lights[0], lights[1], lights[2]


@njit(**NJIT_INLINE)
def interval_arrays(rp):
    """The elementary intervals of a ray (radiance.elementary_intervals): t0, t1, optical depth from the
    ray's start to t0, sigma_t of all media, and of each."""
    return rp[7], rp[8], rp[9], rp[10], rp[11]


# --------------------------------------------------------------------------------------- kernels

@njit(**NJIT)
def trace_segment(o, d, med, surf, tol_t, scratch, rp, cand, stack):
    """The media on o + t d up to the first opaque surface, as elementary intervals.
    Returns (scratch, rp, n_intervals, optical depth of the whole segment, whether it ends on a surface)."""
    t_hit = np.inf
    s_hit = -1
    if n_surfaces(surf) > 0:
        scratch, t_hit, s_hit = first_surface_hit(o, d, surf, tol_t, scratch, cand, stack)
    n = 0
    if t_hit > 0.0:
        scratch, rp, n = collect_media(o, d, t_hit, med, tol_t, scratch, rp, cand, stack)
    if n == 0:
        return scratch, rp, 0, 0.0, s_hit >= 0
    n_el = elementary_intervals(n, rp)
    return scratch, rp, n_el, interval_arrays(rp)[2][n_el], s_hit >= 0


@njit(**NJIT)
def locate_depth(target, n_el, rp):
    """(interval k, s in [0, 1] on it, t) where the segment's optical depth reaches target (< its total)."""
    el_t0, el_t1, el_u0, el_S, _ = interval_arrays(rp)
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
    s = free_flight(el_S[k], w, min(target - el_u0[k], el_u0[k + 1] - el_u0[k]))
    return k, s, el_t0[k] + s * w


@njit(**NJIT)
def scattering_mix(k, s, rp, med, u):
    """At s on interval k: (sigma_s / sigma_t over all media, the medium picked with probability
    sigma_s,m / sigma_s by u). Where sigma_t vanishes at the point itself (an `excess` edge, probability
    zero), the interval's mean control values stand in."""
    el_sig = interval_arrays(rp)[4]
    sigma_t = 0.0
    sigma_s = 0.0
    for m in range(n_media(med)):
        sig = bernstein_eval(el_sig[k, m], s)
        sigma_t += sig
        sigma_s += medium_albedo(med, m) * sig
    use_mean = not sigma_t > 0.0
    if use_mean:
        sigma_t = 0.0
        sigma_s = 0.0
        for m in range(n_media(med)):
            sig = bernstein_mean(el_sig[k, m])
            sigma_t += sig
            sigma_s += medium_albedo(med, m) * sig
    if not (sigma_t > 0.0 and sigma_s > 0.0):
        return 0.0, 0
    pick = u * sigma_s
    acc = 0.0
    chosen = 0
    for m in range(n_media(med)):
        sig = bernstein_mean(el_sig[k, m]) if use_mean else bernstein_eval(el_sig[k, m], s)
        part = medium_albedo(med, m) * sig
        if part > 0.0:
            chosen = m
            acc += part
            if pick < acc:
                break
    return sigma_s / sigma_t, chosen


@njit(**NJIT)
def next_event(x, d, k, s, rp, med, surf, lights, tol_t, scratch, cand, stack, l_dir, out):
    """out[:3] += sum over lights of E_l T_l sum_m (sigma_s,m / sigma_t) p_m(l . d) at x (s on interval k
    of the ray with direction d): the light scattered once more at x. Exact shadow rays. Returns scratch."""
    kind, vec, rgb = light_arrays(lights)
    el_sig = interval_arrays(rp)[4]
    sigma_t = 0.0
    for m in range(n_media(med)):
        sigma_t += bernstein_eval(el_sig[k, m], s)
    if not sigma_t > 0.0:
        return scratch
    for li in range(n_lights(lights)):
        if kind[li] == DIRECTIONAL:
            for c in range(3):
                l_dir[c] = vec[li, c]
            e_scale = 1.0
            l_max = np.inf
        else:
            for c in range(3):
                l_dir[c] = vec[li, c] - x[c]
            dist2 = l_dir[0] * l_dir[0] + l_dir[1] * l_dir[1] + l_dir[2] * l_dir[2]
            l_max = math.sqrt(dist2)
            for c in range(3):
                l_dir[c] /= l_max
            e_scale = 1.0 / dist2
        cos_ld = l_dir[0] * d[0] + l_dir[1] * d[1] + l_dir[2] * d[2]
        mix = 0.0
        for m in range(n_media(med)):
            a = medium_albedo(med, m)
            if a > 0.0:
                kd, g1, g2, w = medium_phase(med, m)
                mix += a * bernstein_eval(el_sig[k, m], s) / sigma_t * phase(kd, g1, g2, w, cos_ld)
        if mix <= 0.0:
            continue
        if n_surfaces(surf) > 0:
            scratch, blocked = surfaces_block(x, l_dir, l_max, surf, tol_t, scratch, cand, stack)
            if blocked:
                continue
        scratch, t_l = shadow_transmittance(x, l_dir, l_max, med, tol_t, TAU_STOP, scratch, cand, stack)
        for c in range(3):
            out[c] += mix * e_scale * t_l * rgb[li, c]
    return scratch


@njit(**NJIT)
def path_radiance(o_cam, d_cam, key, med, surf, lights, params, background, work, out):
    """out[:3] = one path's estimate of the radiance the deterministic renderer leaves out (orders >= 2
    of the lights, orders >= 1 of the environment) along the camera ray o_cam + t d_cam.
    key = (seed, pixel, path); params = (max_order, rr_order, tol_t); work = (scratch, rp, cand, stack,
    vec3 rows). Returns (scratch, rp), grown if a ray needed more room."""
    seed, pixel, path = key
    max_order, rr_order, tol_t = params
    scratch, rp, cand, stack, rows = work
    o = rows[0]
    d = rows[1]
    d_new = rows[2]
    l_dir = rows[3]
    light = rows[4]
    for c in range(3):
        o[c] = o_cam[c]
        d[c] = d_cam[c]
        out[c] = 0.0
    has_env = background[0] > 0.0 or background[1] > 0.0 or background[2] > 0.0
    weight = 1.0
    for n_vert in range(max_order + 1):
        if n_vert == max_order and not has_env:
            break
        scratch, rp, n_el, u_total, on_surface = trace_segment(o, d, med, surf, tol_t, scratch, rp, cand, stack)
        transmittance = math.exp(-u_total)
        if n_vert > 0 and has_env and not on_surface:
            for c in range(3):
                out[c] += weight * transmittance * background[c]  # the environment, order n_vert
        if n_vert == max_order or n_el == 0:
            break
        # a forced collision inside the segment: the flight's target depth is drawn in [0, U)
        xi = uniform(seed, pixel, path, n_vert, DIM_FLIGHT)
        escape = -math.expm1(-u_total)
        weight *= escape
        k, s, t = locate_depth(-math.log1p(-xi * escape), n_el, rp)
        for c in range(3):
            o[c] = o[c] + t * d[c]
        if n_vert > 0:  # vertex 1 is single scattering: counted exactly by the deterministic renderer
            for c in range(3):
                light[c] = 0.0
            scratch = next_event(o, d, k, s, rp, med, surf, lights, tol_t, scratch, cand, stack, l_dir, light)
            for c in range(3):
                out[c] += weight * light[c]
        ratio, m = scattering_mix(k, s, rp, med, uniform(seed, pixel, path, n_vert, DIM_MEDIUM))
        weight *= ratio
        if weight <= 0.0:
            break
        if n_vert + 1 >= rr_order:
            survive = min(1.0, weight)
            if uniform(seed, pixel, path, n_vert, DIM_ROULETTE) >= survive:
                break
            weight /= survive
        kd, g1, g2, w = medium_phase(med, m)
        cos_theta = sample_phase_cos(kd, g1, g2, w, uniform(seed, pixel, path, n_vert, DIM_LOBE),
                                     uniform(seed, pixel, path, n_vert, DIM_COS))
        turn(d, cos_theta, uniform(seed, pixel, path, n_vert, DIM_PHI), d_new)
        for c in range(3):
            d[c] = d_new[c]
    return scratch, rp


@njit(**NJIT)
def render_paths(row0, width, height, spp, paths, seed, camera, p0, p1, med, surf, lights, params, background,
                 mean, stderr):
    """Pixels p0 .. p1 - 1 (row by row from the start of row row0): per pixel, the mean of ``paths``
    path estimates into mean (H x W x 3), and its standard error into stderr. Path i starts on camera
    ray i mod spp of the deterministic renderer (the pixel centre for spp = 1, else its stratified
    jittered points). camera = (position, forward, right, up), right and up scaled to the image
    plane's half-extent at distance 1. nogil, with its own work arrays: cloudmeta.multiple runs bands of
    rows on several threads."""
    cam_pos, cam_fwd, cam_right, cam_up = camera
    strata = int(math.ceil(math.sqrt(spp)))
    scratch = alloc_scratch(64)
    rp = alloc_ray_pieces(64, n_media(med))
    cand, stack, _ = alloc_work(max(n_media_balls(med), n_surface_balls(surf)), 0)
    rows = np.empty((5, 3))
    d = np.empty(3)
    est = np.empty(3)
    acc = np.empty(3)
    acc2 = np.empty(3)
    box_m, root_m = media_roots(med)
    for p in range(p0, p1):
        i = row0 + p // width
        j = p % width
        pix = i * width + j
        for c in range(3):
            acc[c] = 0.0
            acc2[c] = 0.0
        for path in range(paths):
            # the camera rays of the deterministic renderer (radiance.render_pixels), in turn: its pixel
            # is the mean over those rays, and so is this estimate (the two add up ray by ray)
            sample = path % spp
            if spp == 1:
                jx = 0.5
                jy = 0.5
            else:
                jx = ((sample % strata) + jitter(seed, pix, sample, 0)) / strata
                jy = (((sample // strata) % strata) + jitter(seed, pix, sample, 1)) / strata
            x = 2.0 * (j + jx) / width - 1.0
            y = 1.0 - 2.0 * (i + jy) / height
            for c in range(3):
                d[c] = cam_fwd[c] + x * cam_right[c] + y * cam_up[c]
            norm = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
            for c in range(3):
                d[c] /= norm
            if misses_media(cam_pos, d, box_m, root_m):
                continue  # no medium on the camera ray: nothing scatters, the estimate is 0
            scratch, rp = path_radiance(cam_pos, d, (seed, pix, path), med, surf, lights, params, background,
                                        (scratch, rp, cand, stack, rows), est)
            for c in range(3):
                acc[c] += est[c]
                acc2[c] += est[c] * est[c]
        for c in range(3):
            mu = acc[c] / paths
            mean[i, j, c] = mu
            if paths > 1:
                var = max(0.0, (acc2[c] - paths * mu * mu) / (paths - 1))
                stderr[i, j, c] = math.sqrt(var / paths)
            else:
                stderr[i, j, c] = np.inf
