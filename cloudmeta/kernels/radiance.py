"""Single scattering along camera rays (MODEL.md §5), and the image loop.

A camera ray is traced through every medium by the engine; each inside piece carries sigma_t as a
Bernstein polynomial. Where pieces of several media overlap, the ray is cut into elementary intervals
and their polynomials are added, exactly as the engine composites balls. On each interval:

- the view optical depth tau(0, t) is exact at any t (the antiderivative of a Bernstein polynomial);
- the in-scattering integral is taken in optical depth u, where T sigma_s dt = e^-u (sigma_s/sigma_t) du:
  a Gauss-Legendre rule on steps no thicker than ``max_tau`` and no longer than ``max_length``, with an
  exact shadow ray from every node to every light; near point lights the interval is first cut at equal
  angles (at most ``max_angle``) seen from the light, which tames their 1/r^2.

Three tuples carry the scene (see cloudmeta.render.PackedMedia.args for the order):
  med    = (centers, frames, weights, start, kernel, threshold, mode, scale, albedo, phase,
            node_box, node_a, node_b, node_n, items, root)       -- every medium's balls and its BVH
  lights = (kind, vec, rgb, map_of, <one shadowmap's arrays: geo, res, base, start, t0, t1, c, cum,
            reach>): kind 0 directional (vec towards the light, rgb irradiance), kind 1 point (vec its
            position, rgb intensity); map_of[l] is the light's shadow map, or -1 for exact shadow rays
  quad   = (gl_x, gl_w, max_tau, max_length, max_angle, cutoff, tol_t)
"""
import math

import numpy as np
from numba import njit, prange

from ..config import NJIT, NJIT_PARALLEL
from .bernstein import NCOEF, bernstein_cumulative, bernstein_mean, subdivide
from .optics import phase
from .bvh import STACK
from .media import alloc_ray_pieces, collect_media, shadow_transmittance
from .shadowmap import map_optical_depth
from .sweep import alloc_scratch, heap_argsort, heap_sort

DIRECTIONAL = 0
POINT = 1


@njit(**NJIT)
def _bernstein_at(c, s, work):
    for i in range(NCOEF):
        work[i] = c[i]
    for r in range(1, NCOEF):
        for i in range(NCOEF - r):
            work[i] = (1.0 - s) * work[i] + s * work[i + 1]
    return work[0]


@njit(**NJIT)
def _depth_to_s(S, w, u, s_lo, cum, work):
    """s in [s_lo, 1] where the optical depth w * int_0^s S reaches u: Newton on the exact antiderivative,
    kept inside a shrinking bracket (the depth is monotone, S >= 0)."""
    lo = s_lo
    hi = 1.0
    s = s_lo
    for _ in range(60):
        f = w * bernstein_cumulative(S, s, cum) - u
        if f < 0.0:
            lo = s
        else:
            hi = s
        slope = w * _bernstein_at(S, s, work)
        step_ok = slope > 0.0
        if step_ok:
            sn = s - f / slope
            step_ok = lo < sn < hi
        sn = sn if step_ok else 0.5 * (lo + hi)
        if abs(sn - s) <= 1e-14 or hi - lo <= 1e-14:
            return sn
        s = sn
    return s


@njit(**NJIT)
def _angular_cuts(o, d, ta, tb, light_kind, light_vec, max_angle, tol_t):
    """Equal-angle cuts of [ta, tb] as seen from the point light that sees it under the widest angle:
    returns (n_sub, t_c, h, theta_a, d_theta), t = t_c + h tan(theta); n_sub = 1 without point lights."""
    best = 1
    t_c = 0.0
    h_best = 1.0
    th_a = 0.0
    d_th = 0.0
    for li in range(light_kind.shape[0]):
        if light_kind[li] == DIRECTIONAL:
            continue
        tc = 0.0
        for c in range(3):
            tc += (light_vec[li, c] - o[c]) * d[c]
        h2 = 0.0
        for c in range(3):
            q = o[c] + tc * d[c] - light_vec[li, c]
            h2 += q * q
        h = max(math.sqrt(h2), tol_t)
        a = math.atan((ta - tc) / h)
        b = math.atan((tb - tc) / h)
        n = int(math.ceil((b - a) / max_angle))
        if n > best:
            best = n
            t_c = tc
            h_best = h
            th_a = a
            d_th = (b - a) / n
    return best, t_c, h_best, th_a, d_th


@njit(**NJIT)
def _light_at_node(pos, d, med, lights, tol_t, tau_stop, scratch, cand, stack, l_dir, light_buf):
    """Per light: light_buf[li, 0] = cos theta = l . d, light_buf[li, 1:4] = E_l T_l at pos."""
    light_kind, light_vec, light_rgb, map_of = lights[0], lights[1], lights[2], lights[3]
    geo, res, base, start, t0, t1, c_map, cum, reach = (lights[4], lights[5], lights[6], lights[7], lights[8],
                                                        lights[9], lights[10], lights[11], lights[12])
    work = light_buf[-1]
    for li in range(light_kind.shape[0]):
        if light_kind[li] == DIRECTIONAL:
            for c in range(3):
                l_dir[c] = light_vec[li, c]
            e_scale = 1.0
            l_max = np.inf
        else:
            for c in range(3):
                l_dir[c] = light_vec[li, c] - pos[c]
            dist2 = l_dir[0] * l_dir[0] + l_dir[1] * l_dir[1] + l_dir[2] * l_dir[2]
            l_max = math.sqrt(dist2)
            for c in range(3):
                l_dir[c] /= l_max
            e_scale = 1.0 / dist2
        light_buf[li, 0] = l_dir[0] * d[0] + l_dir[1] * d[1] + l_dir[2] * d[2]
        mi = map_of[li]
        if mi >= 0:
            t_l = math.exp(-map_optical_depth(pos, geo[mi], res[mi], base[mi], start, t0, t1, c_map, cum, reach,
                                              work))
        else:
            scratch, t_l = shadow_transmittance(pos, l_dir, l_max, med, tol_t, tau_stop, scratch, cand, stack)
        for c in range(3):
            light_buf[li, 1 + c] = light_rgb[li, c] * e_scale * t_l
    return scratch


@njit(**NJIT)
def ray_radiance(o, d, med, lights, quad, background, ambient, scratch, rp, cand, stack, light_buf, out):
    """out[:3] = radiance of the camera ray o + t d, out[3] = its transmittance T(0, inf).

    Returns (scratch, rp): the work arrays, grown if this ray needed more room.
    """
    med_albedo, med_phase = med[8], med[9]
    light_kind = lights[0]
    gl_x, gl_w, max_tau, max_length, max_angle, cutoff, tol_t = quad
    scratch, rp, n = collect_media(o, d, np.inf, med, tol_t, scratch, rp, cand, stack)
    out[0] = 0.0
    out[1] = 0.0
    out[2] = 0.0
    if n == 0:
        out[0] = background[0]
        out[1] = background[1]
        out[2] = background[2]
        out[3] = 1.0
        return scratch, rp
    p_t0, p_t1, p_c, p_m, bp, order, act, act_c = rp
    work = scratch[17][0]
    cum = light_buf[-1]          # the last rows of light_buf are this ray's small work vectors
    S = light_buf[-2, :NCOEF]
    pos = light_buf[-3, :3]
    l_dir = light_buf[-3, 3:6]
    n_lights = light_kind.shape[0]
    has_ambient = ambient[0] > 0.0 or ambient[1] > 0.0 or ambient[2] > 0.0
    tau_stop = -math.log(cutoff) if cutoff > 0.0 else np.inf
    for k in range(n):
        bp[2 * k] = p_t0[k]
        bp[2 * k + 1] = p_t1[k]
    heap_sort(bp, 2 * n)
    heap_argsort(p_t0, order, n)
    n_act = 0
    i_s = 0
    tau_acc = 0.0
    shading = n_lights > 0 or has_ambient
    for k in range(2 * n - 1):
        ta = bp[k]
        tb = bp[k + 1]
        if tb <= ta:
            continue
        j = 0
        for q in range(n_act):
            if p_t1[act[q]] > ta:
                act[j] = act[q]
                j += 1
        n_act = j
        while i_s < n and p_t0[order[i_s]] <= ta:
            act[n_act] = order[i_s]
            n_act += 1
            i_s += 1
        if n_act == 0:
            continue
        # sigma_t of every active piece on [ta, tb], and their sum
        S[:] = 0.0
        scatters = False
        for q in range(n_act):
            i = act[q]
            span = p_t1[i] - p_t0[i]
            s0 = min(max((ta - p_t0[i]) / span, 0.0), 1.0)
            s1 = min(max((tb - p_t0[i]) / span, 0.0), 1.0)
            subdivide(p_c[i], s0, s1, act_c[q])
            for c in range(NCOEF):
                S[c] += act_c[q, c]
            scatters = scatters or med_albedo[p_m[i]] > 0.0
        w = tb - ta
        tau_iv = w * bernstein_mean(S)
        if shading and scatters and tau_iv > 0.0:
            # near a point light E ~ 1/r^2 peaks: cut the interval at equal angles seen from the light
            # whose angle is widest (t = t_c + h tan(theta) makes dt / r^2 = d(theta) / h smooth)
            n_sub, t_c, h_l, th_a, d_th = _angular_cuts(o, d, ta, tb, light_kind, lights[1], max_angle, tol_t)
            u_end = 0.0
            s_prev = 0.0
            for sub in range(n_sub):
                u_start = u_end
                if sub == n_sub - 1:
                    s_end = 1.0
                    u_end = tau_iv
                else:
                    s_end = (t_c + h_l * math.tan(th_a + (sub + 1) * d_th) - ta) / w
                    u_end = w * bernstein_cumulative(S, s_end, cum)
                sub_tau = u_end - u_start
                if sub_tau <= 0.0:
                    continue
                # in optical depth u: T sigma_s dt = e^-u (sigma_s / sigma_t) du, so the nodes need not
                # resolve the exponential; t(u) is found on the exact antiderivative
                n_steps = max(1, int(math.ceil(max(sub_tau / max_tau, (s_end * w - s_prev * w) / max_length))))
                h = sub_tau / n_steps
                for st in range(n_steps):
                    for g in range(gl_x.shape[0]):
                        u = u_start + (st + gl_x[g]) * h
                        s = _depth_to_s(S, w, u, s_prev, cum, work)
                        s_prev = s
                        sigma_t = _bernstein_at(S, s, work)
                        if sigma_t <= 0.0:
                            continue
                        t = ta + s * w
                        for c in range(3):
                            pos[c] = o[c] + t * d[c]
                        scratch = _light_at_node(pos, d, med, lights, tol_t, tau_stop, scratch, cand, stack,
                                                 l_dir, light_buf)
                        weight = gl_w[g] * h * math.exp(-(tau_acc + u)) / sigma_t
                        for q in range(n_act):
                            m = p_m[act[q]]
                            sigma_s = med_albedo[m] * _bernstein_at(act_c[q], s, work)
                            if sigma_s == 0.0:
                                continue
                            for li in range(n_lights):
                                ph = phase(med_phase[m, 0], med_phase[m, 1], med_phase[m, 2], med_phase[m, 3],
                                           light_buf[li, 0])
                                for c in range(3):
                                    out[c] += weight * sigma_s * ph * light_buf[li, 1 + c]
                            for c in range(3):
                                out[c] += weight * sigma_s * ambient[c]
        tau_acc += tau_iv
        if tau_acc > tau_stop:
            shading = False  # the rest of the ray is seen through less than `cutoff`
    t_end = math.exp(-tau_acc)
    for c in range(3):
        out[c] += background[c] * t_end
    out[3] = t_end
    return scratch, rp


@njit(**NJIT)
def _mix64(z):
    """splitmix64's finaliser: a counter-based hash, so jitter depends only on (pixel, sample)."""
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


@njit(**NJIT)
def jitter(seed, pixel, sample, dim):
    key = (np.uint64(seed) * np.uint64(0x9E3779B97F4A7C15) + np.uint64(pixel) * np.uint64(0x632BE59BD9B4E019)
           + np.uint64(sample) * np.uint64(0x85EBCA77C2B2AE63) + np.uint64(dim))
    return float(_mix64(key) >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@njit(**NJIT)
def alloc_work(n_balls, n_lights):
    """Per-chunk work arrays of the image loop: candidate list, BVH stack, light buffer."""
    return (np.empty(max(n_balls, 1), np.int64), np.empty(2 * STACK, np.int64),
            np.empty((n_lights + 3, NCOEF + 1)))


@njit(**NJIT_PARALLEL)
def render_rows(row0, row1, width, height, spp, seed, cam_pos, cam_fwd, cam_right, cam_up, n_chunks,
                med, lights, quad, background, ambient, image):
    """Rows [row0, row1) of the image (H x W x 4, row 0 at the top), written into image[row0:row1].

    cam_right and cam_up are scaled to the half-extent of the image plane at distance 1. With spp > 1
    the samples are stratified on a ceil(sqrt(spp))^2 grid and jittered by a hash of (pixel, sample).
    """
    n_pix = (row1 - row0) * width
    strata = int(math.ceil(math.sqrt(spp)))
    for chunk in prange(n_chunks):
        scratch = alloc_scratch(64)
        rp = alloc_ray_pieces(64)
        cand, stack, light_buf = alloc_work(med[0].shape[0], lights[0].shape[0])
        px_out = np.empty(4)
        d = np.empty(3)
        for p in range(chunk * n_pix // n_chunks, (chunk + 1) * n_pix // n_chunks):
            i = row0 + p // width
            j = p % width
            acc0 = 0.0
            acc1 = 0.0
            acc2 = 0.0
            acc3 = 0.0
            for s in range(spp):
                if spp == 1:
                    jx = 0.5
                    jy = 0.5
                else:
                    pix = i * width + j
                    jx = ((s % strata) + jitter(seed, pix, s, 0)) / strata
                    jy = (((s // strata) % strata) + jitter(seed, pix, s, 1)) / strata
                x = 2.0 * (j + jx) / width - 1.0
                y = 1.0 - 2.0 * (i + jy) / height
                for c in range(3):
                    d[c] = cam_fwd[c] + x * cam_right[c] + y * cam_up[c]
                norm = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
                for c in range(3):
                    d[c] /= norm
                scratch, rp = ray_radiance(cam_pos, d, med, lights, quad, background, ambient, scratch, rp,
                                           cand, stack, light_buf, px_out)
                acc0 += px_out[0]
                acc1 += px_out[1]
                acc2 += px_out[2]
                acc3 += px_out[3]
            image[i, j, 0] = acc0 / spp
            image[i, j, 1] = acc1 / spp
            image[i, j, 2] = acc2 / spp
            image[i, j, 3] = 1.0 - acc3 / spp  # alpha = 1 - T(0, t_end)
