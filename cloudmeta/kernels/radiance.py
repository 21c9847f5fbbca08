"""Single scattering along camera rays (MODEL.md §5), opaque surfaces on them (§6), and the image loop.

A camera ray is traced through every medium by the engine; each inside piece carries sigma_t as a
Bernstein polynomial. Where pieces of several media overlap, the ray is cut into elementary intervals
and their polynomials are added, exactly as the engine composites balls. On each interval:

- the view optical depth tau(0, t) is exact at any t (the antiderivative of a Bernstein polynomial);
- the in-scattering integral is taken in optical depth u, where T sigma_s dt = e^-u (sigma_s/sigma_t) du:
  product-integration weights (exact for e^-u times a polynomial, see _exp_weights) on steps no thicker
  than ``max_tau`` and no longer than ``max_length``; each step takes 7 Gauss nodes, the 8 Kronrod nodes
  of G7-K15 where J's Legendre tail exceeds ``tolerance``, and is halved where the two rules disagree
  (docs/model_notes.md); an exact shadow ray goes from every node to every light; near point lights the
  interval is first cut at equal angles (at most ``max_angle``) seen from the light, which tames their
  1/r^2.

With opaque surfaces, the camera ray first finds its first surface hit t_hit (kernels.surfaces); the
media are traced over [0, t_hit] only, and the hit, shaded as Lambertian, takes the background's place:
L = L_surface T(0, t_hit) + in-scattering over [0, t_hit], alpha 1. Shadow rays, from quadrature nodes
and from surface points, are blocked by any surface (T_l = 0), and then trace no media. A scene without
surfaces traces nothing more than before: every surface loop runs over zero surfaces.

Four tuples carry the scene (see cloudmeta.render.PackedMedia.args for the order):
  med    = (centers, frames, weights, start, kernel, threshold, mode, scale, albedo, phase,
            node_box, node_a, node_b, node_n, items, root, blobbiness) -- every medium's balls, its BVH
  surf   = (centers, frames, weights, start, kernel, threshold, blobbiness, colour,
            node_box, node_a, node_b, node_n, items, root) -- every surface's (cloudmeta.render.PackedSurfaces)
  lights = (kind, vec, rgb, map_of, <one shadowmap's arrays: geo, res, base, start, t0, t1, c, cum,
            reach>): kind 0 directional (vec towards the light, rgb irradiance), kind 1 point (vec its
            position, rgb intensity); map_of[l] is the light's shadow map (media only: surfaces are
            always tested by an exact shadow ray), or -1 for exact shadow rays
  quad   = (gauss_x, gauss_lag, kronrod_x, kronrod_lag, gauss_col, kronrod_col, tail, fine_y, fine_w,
            max_tau, max_length, max_angle, cutoff, tol_t, tolerance): the 7 Gauss and 15 Kronrod nodes on
           [0, 1] with their Lagrange bases at a fine Gauss rule (fine_y, fine_w); where the Gauss nodes and
           the other 8 sit among the 15; the map from J at the Gauss nodes to its two highest Legendre
           coefficients; and the settings (cloudmeta.render.quadrature)
"""
import math

import numpy as np
from numba import njit

from ..config import NJIT, NJIT_INLINE
from .bernstein import NCOEF, bernstein_cumulative, bernstein_eval, bernstein_mean, subdivide
from .optics import phase
from .bvh import STACK, ray_box
from .media import alloc_ray_pieces, collect_media, shadow_transmittance
from .shadowmap import map_optical_depth
from .surfaces import SHADOW_OFFSET, first_surface_hit, n_surfaces, surface_normal, surfaces_block
from .sweep import advance_active, alloc_scratch, sort_breakpoints

DIRECTIONAL = 0
POINT = 1
#: most nodes per step (the work rows are sized by it)
MAX_NODES = 16
#: a step is halved at most this often where its Kronrod and Gauss results disagree (the pending halves
#: fit the MAX_NODES slots of a work row)
MAX_SPLITS = 6


@njit(**NJIT)
def _depth_to_s(S, w, u, s0, u0):
    """s in [s0, 1] where the optical depth w * int_0^s S reaches u, given that it is u0 at s0 (the
    previous node): Newton on the exact antiderivative from the previous node, kept in a shrinking
    bracket (the depth is monotone, S >= 0)."""
    lo = s0
    hi = 1.0
    slope = w * bernstein_eval(S, s0)
    s = s0 + (u - u0) / slope if slope > 0.0 else 0.5 * (s0 + 1.0)
    if not (lo < s < hi):
        s = 0.5 * (lo + hi)
    for _ in range(60):
        f = w * bernstein_cumulative(S, s) - u
        if f < 0.0:
            lo = s
        else:
            hi = s
        slope = w * bernstein_eval(S, s)
        sn = s - f / slope if slope > 0.0 else 0.5 * (lo + hi)
        if not (lo < sn < hi):
            sn = 0.5 * (lo + hi)
        if abs(sn - s) <= 1e-14 or hi - lo <= 1e-14:
            return sn
        s = sn
    return s


@njit(**NJIT)
def _exp_weights(h, lagrange, fine_y, fine_w, out):
    """Product-integration weights of a step of optical depth h: out[k] = int_0^h e^-x L_k(x / h) dx, with
    L_k the Lagrange basis of the Gauss nodes. The rule is exact for e^-x times any polynomial of degree
    < nodes, so the steps need resolve only how the light J varies, not the exponential."""
    for k in range(lagrange.shape[0]):
        out[k] = 0.0
    for q in range(fine_y.shape[0]):
        e = fine_w[q] * math.exp(-h * fine_y[q])
        for k in range(lagrange.shape[0]):
            out[k] += e * lagrange[k, q]
    for k in range(lagrange.shape[0]):
        out[k] *= h


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


#: inlined: a call per quadrature node would count references to every array of med, surf and lights
@njit(**NJIT_INLINE)
def _light_at_node(pos, shadow_from, v, med, surf, lights, tol_t, tau_stop, facing_only, scratch, cand, stack,
                   l_dir, light_buf):
    """Per light: light_buf[li, 0] = l . v, light_buf[li, 1:4] = E_l T_l at pos. v is the view direction
    at a medium's node (l . v = cos theta of the phase function), the normal at a surface point; with
    facing_only, lights with l . v <= 0 get E_l T_l = 0 and no shadow ray (they cannot light the side of
    a surface facing away). The shadow ray starts at shadow_from (pos, or a surface point lifted off its
    surface) and runs along l."""
    light_kind, light_vec, light_rgb, map_of = lights[0], lights[1], lights[2], lights[3]
    geo, res, base, start, t0, t1, c_map, cum, reach = (lights[4], lights[5], lights[6], lights[7], lights[8],
                                                        lights[9], lights[10], lights[11], lights[12])
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
        cos_lv = l_dir[0] * v[0] + l_dir[1] * v[1] + l_dir[2] * v[2]
        light_buf[li, 0] = cos_lv
        if facing_only and cos_lv <= 0.0:
            for c in range(3):
                light_buf[li, 1 + c] = 0.0
            continue
        blocked = False
        if n_surfaces(surf) > 0:
            scratch, blocked = surfaces_block(shadow_from, l_dir, l_max, surf, tol_t, scratch, cand, stack)
        mi = map_of[li]
        if blocked:
            t_l = 0.0
        elif mi >= 0:
            t_l = math.exp(-map_optical_depth(shadow_from, geo[mi], res[mi], base[mi], start, t0, t1, c_map, cum,
                                              reach))
        else:
            scratch, t_l = shadow_transmittance(shadow_from, l_dir, l_max, med, tol_t, tau_stop, scratch, cand,
                                                stack)
        for c in range(3):
            light_buf[li, 1 + c] = light_rgb[li, c] * e_scale * t_l
    return scratch


@njit(**NJIT)
def elementary_intervals(n, rp):
    """Cut the ray at every piece end; per interval, sigma_t of each medium and of all, and the optical
    depth from the ray's start. Returns the number of intervals."""
    p_t0, p_t1, p_c, p_m, bp, order, act = rp[0], rp[1], rp[2], rp[3], rp[4], rp[5], rp[6]
    el_t0, el_t1, el_u0, el_S, el_sig = rp[7], rp[8], rp[9], rp[10], rp[11]
    sort_breakpoints(p_t0, p_t1, n, bp, order)
    n_act = 0
    i_s = 0
    n_el = 0
    el_u0[0] = 0.0
    for k in range(2 * n - 1):
        ta = bp[k]
        tb = bp[k + 1]
        if tb <= ta:
            continue
        n_act, i_s = advance_active(ta, p_t0, p_t1, order, act, n_act, i_s, n)
        if n_act == 0:
            continue
        el_S[n_el, :] = 0.0
        el_sig[n_el, :, :] = 0.0
        for q in range(n_act):
            i = act[q]
            span = p_t1[i] - p_t0[i]
            s0 = min(max((ta - p_t0[i]) / span, 0.0), 1.0)
            s1 = min(max((tb - p_t0[i]) / span, 0.0), 1.0)
            sig = el_sig[n_el, p_m[i]]
            subdivide(p_c[i], s0, s1, sig)  # pieces of one medium never overlap
            for c in range(NCOEF):
                el_S[n_el, c] += sig[c]
        el_t0[n_el] = ta
        el_t1[n_el] = tb
        el_u0[n_el + 1] = el_u0[n_el] + (tb - ta) * bernstein_mean(el_S[n_el])
        n_el += 1
    return n_el


@njit(**NJIT)
def _depth_at(t, k, n_el, rp):
    """(optical depth at t, the interval holding t), searching forward from interval k."""
    el_t0, el_t1, el_u0, el_S = rp[7], rp[8], rp[9], rp[10]
    while k < n_el - 1 and el_t1[k] <= t:
        k += 1
    w = el_t1[k] - el_t0[k]
    s = min(max((t - el_t0[k]) / w, 0.0), 1.0)
    return el_u0[k] + w * bernstein_cumulative(el_S[k], s), k


@njit(**NJIT_INLINE)
def _source_at(u, k, k_b, s_prev, u_prev, o, d, med, surf, lights, ambient, tol_t, u_stop, rp, scratch, cand, stack,
               pos, l_dir, light_buf, j_val, col):
    """j_val[:3, col] = J at optical depth u of the view ray: sum over media of (sigma_s / sigma_t) times
    (sum over lights of phase E_l T_l, plus the ambient radiance). (k, s_prev, u_prev) locate the previous
    node (nodes come in increasing u); returns them for this node, with the scratch."""
    med_albedo, med_phase = med[8], med[9]
    el_t0, el_t1, el_u0, el_S, el_sig = rp[7], rp[8], rp[9], rp[10], rp[11]
    while k < k_b - 1 and el_u0[k + 1] <= u:
        k += 1
        s_prev = 0.0
        u_prev = el_u0[k]
    w = el_t1[k] - el_t0[k]
    s = _depth_to_s(el_S[k], w, u - el_u0[k], s_prev, u_prev - el_u0[k])
    for c in range(3):
        j_val[c, col] = 0.0
    sigma_t = bernstein_eval(el_S[k], s)
    if sigma_t <= 0.0:
        return k, s, u, scratch
    t = el_t0[k] + s * w
    for c in range(3):
        pos[c] = o[c] + t * d[c]
    scratch = _light_at_node(pos, pos, d, med, surf, lights, tol_t, u_stop, False, scratch, cand, stack, l_dir,
                             light_buf)
    for m in range(med_albedo.shape[0]):
        if med_albedo[m] == 0.0:
            continue
        ratio = med_albedo[m] * bernstein_eval(el_sig[k, m], s) / sigma_t
        if ratio == 0.0:
            continue
        for li in range(lights[0].shape[0]):
            ph = phase(med_phase[m, 0], med_phase[m, 1], med_phase[m, 2], med_phase[m, 3], light_buf[li, 0])
            for c in range(3):
                j_val[c, col] += ratio * ph * light_buf[li, 1 + c]
        for c in range(3):
            j_val[c, col] += ratio * ambient[c]
    return k, s, u, scratch


@njit(**NJIT)
def _shade_surface(o, d, t_hit, s, med, surf, lights, ambient, tol_t, tau_stop, scratch, cand, stack,
                   light_buf):
    """Lambertian radiance of surface s hit at o + t_hit d (MODEL.md §6):
    colour / pi * sum_lights max(0, n . l) E_l T_l + colour * L_amb. Returns (scratch, r, g, b)."""
    x = light_buf[-2, 0:3]
    nrm = light_buf[-2, 3:6]
    x_off = light_buf[-2, 6:9]
    l_dir = light_buf[-3, 3:6]
    for c in range(3):
        x[c] = o[c] + t_hit * d[c]
    surface_normal(x, d, surf, s, cand, stack, nrm)
    for c in range(3):
        x_off[c] = x[c] + SHADOW_OFFSET * tol_t * nrm[c]
    scratch = _light_at_node(x, x_off, nrm, med, surf, lights, tol_t, tau_stop, True, scratch, cand, stack, l_dir,
                             light_buf)
    e0 = 0.0
    e1 = 0.0
    e2 = 0.0
    for li in range(lights[0].shape[0]):
        cos_nl = light_buf[li, 0]
        if cos_nl > 0.0:
            e0 += cos_nl * light_buf[li, 1]
            e1 += cos_nl * light_buf[li, 2]
            e2 += cos_nl * light_buf[li, 3]
    colour = surf[7][s]
    return (scratch, colour[0] * (e0 / math.pi + ambient[0]), colour[1] * (e1 / math.pi + ambient[1]),
            colour[2] * (e2 / math.pi + ambient[2]))


@njit(**NJIT)
def _add_ray_end(o, d, t_hit, s_hit, u_total, u_stop, med, surf, lights, background, ambient, tol_t, scratch,
                 cand, stack, light_buf, out):
    """out[:3] += L_end T(0, t_end): the background for an escaping ray, the shaded surface for a hit
    (not shaded where it is seen through less than ``cutoff``). out[3] = T(0, t_end), 0 for a hit (alpha 1).
    Returns scratch."""
    t_view = math.exp(-u_total)
    if s_hit < 0:
        for c in range(3):
            out[c] += background[c] * t_view
        out[3] = t_view
        return scratch
    out[3] = 0.0
    if u_total < u_stop:
        scratch, r, g, b = _shade_surface(o, d, t_hit, s_hit, med, surf, lights, ambient, tol_t, u_stop, scratch,
                                          cand, stack, light_buf)
        out[0] += r * t_view
        out[1] += g * t_view
        out[2] += b * t_view
    return scratch


@njit(**NJIT)
def ray_radiance(o, d, med, surf, lights, quad, background, ambient, scratch, rp, cand, stack, light_buf, out):
    """out[:3] = radiance of the camera ray o + t d, out[3] = its transmittance T(0, t_end) (0 where it
    meets a surface), out[4] = t_hit, where it first meets a surface (inf if it does not).

    The ray's sigma_t is tabulated on elementary intervals (exact optical depth at any t); the quadrature
    then runs over each inside segment (a run of adjacent intervals) as a whole, so that chord ends,
    which the light does not see, cost no nodes. Returns (scratch, rp), grown if this ray needed more room.
    """
    med_albedo = med[8]
    light_kind = lights[0]
    (gauss_x, gauss_lag, kronrod_x, kronrod_lag, gauss_col, kronrod_col, tail, fine_y, fine_w,
     max_tau, max_length, max_angle, cutoff, tol_t, tolerance) = quad
    u_stop = -math.log(cutoff) if cutoff > 0.0 else np.inf
    t_hit = np.inf
    s_hit = -1
    if n_surfaces(surf) > 0:
        scratch, t_hit, s_hit = first_surface_hit(o, d, surf, tol_t, scratch, cand, stack)
    n = 0
    if t_hit > 0.0:  # a camera inside a surface sees no media
        scratch, rp, n = collect_media(o, d, t_hit, med, tol_t, scratch, rp, cand, stack)
    for c in range(3):
        out[c] = 0.0
    out[4] = t_hit
    if n == 0:
        scratch = _add_ray_end(o, d, t_hit, s_hit, 0.0, u_stop, med, surf, lights, background, ambient, tol_t,
                               scratch, cand, stack, light_buf, out)
        return scratch, rp
    n_el = elementary_intervals(n, rp)
    el_t0, el_t1, el_u0 = rp[7], rp[8], rp[9]
    u_total = el_u0[n_el]
    n_lights = light_kind.shape[0]
    n_media = med_albedo.shape[0]
    node_w = light_buf[-4]       # the last rows of light_buf are this ray's small work vectors
    j_val = light_buf[-7:-4]     # J (r, g, b) at the Kronrod nodes of a step, in order
    split_u = light_buf[-9]      # the parts of a step still to do: where each starts, and how often halved
    split_depth = light_buf[-8]
    j_max = 0.0                  # the largest J (r + g + b) met on this ray: the scale of the tolerance
    pos = light_buf[-3, :3]
    l_dir = light_buf[-3, 3:6]
    has_ambient = ambient[0] > 0.0 or ambient[1] > 0.0 or ambient[2] > 0.0
    scatters = False
    for m in range(n_media):
        scatters = scatters or med_albedo[m] > 0.0
    if (n_lights > 0 or has_ambient) and scatters:
        k_a = 0
        while k_a < n_el and el_u0[k_a] < u_stop:
            # the inside segment: intervals k_a .. k_b - 1, adjacent end to start
            k_b = k_a + 1
            while k_b < n_el and el_t0[k_b] == el_t1[k_b - 1]:
                k_b += 1
            ta = el_t0[k_a]
            tb = el_t1[k_b - 1]
            # near a point light E ~ 1/r^2 peaks: cut at equal angles seen from the light that sees the
            # segment under the widest angle (t = t_c + h tan(theta) makes dt / r^2 = d(theta) / h)
            n_sub, t_c, h_l, th_a, d_th = _angular_cuts(o, d, ta, tb, light_kind, lights[1], max_angle, tol_t)
            k = k_a
            u_end = el_u0[k_a]
            t_end = ta
            s_prev = 0.0
            u_prev = el_u0[k_a]
            for sub in range(n_sub):
                u_start = u_end
                t_start = t_end
                if sub == n_sub - 1:
                    t_end = tb
                    u_end = el_u0[k_b]
                else:
                    t_end = t_c + h_l * math.tan(th_a + (sub + 1) * d_th)
                    u_end, _ = _depth_at(t_end, k, k_b, rp)
                sub_u = u_end - u_start
                if sub_u <= 0.0:
                    continue
                # in optical depth u: T sigma_s dt = e^-u (sigma_s / sigma_t) du, with weights exact for
                # e^-u times a polynomial: the nodes follow only how the light J varies. Each step takes
                # 7 Gauss nodes; where the tail of their Legendre expansion says J is rougher than the
                # tolerance allows, 8 Kronrod nodes join them (15, the 7 reused)
                n_steps = max(1, int(math.ceil(max(sub_u / max_tau, (t_end - t_start) / max_length))))
                h = sub_u / n_steps
                for st in range(n_steps):
                    # the step, or the halves of a part whose Kronrod and Gauss results disagree, left
                    # part first (the nodes must come in increasing u)
                    split_u[0] = u_start + st * h
                    split_depth[0] = 0.0
                    top = 0
                    while top >= 0:
                        u_step = split_u[top]
                        depth = int(split_depth[top])
                        top -= 1
                        if u_step >= u_stop:
                            break  # the rest is seen through less than `cutoff`
                        hh = h * 0.5 ** depth
                        k_0, s_0, up_0 = k, s_prev, u_prev
                        e0 = math.exp(-u_step)
                        c_lo = 0.0
                        c_hi = 0.0
                        i_gauss = 0.0
                        allowed = 0.0
                        gauss_done = False
                        n_g = gauss_x.shape[0]
                        # the 7 Gauss nodes, then (unless they suffice) the 8 Kronrod nodes: one loop, so
                        # that the inlined node code is compiled once
                        for g in range(n_g + kronrod_col.shape[0]):
                            if g == n_g:
                                _exp_weights(hh, gauss_lag, fine_y, fine_w, node_w)
                                # J's error, weighted by e^-u, is then below tolerance * j_max: deep steps
                                # may be rougher
                                allowed = tolerance * j_max
                                if (abs(c_lo) + abs(c_hi)) * e0 <= allowed:
                                    gauss_done = True
                                    break
                                for q in range(n_g):
                                    col = gauss_col[q]
                                    i_gauss += node_w[q] * (j_val[0, col] + j_val[1, col] + j_val[2, col])
                                k, s_prev, u_prev = k_0, s_0, up_0  # the Kronrod nodes, again in increasing u
                            col = gauss_col[g] if g < n_g else kronrod_col[g - n_g]
                            k, s_prev, u_prev, scratch = _source_at(
                                u_step + kronrod_x[col] * hh, k, k_b, s_prev, u_prev, o, d, med, surf, lights,
                                ambient, tol_t, u_stop, rp, scratch, cand, stack, pos, l_dir, light_buf, j_val, col)
                            j_sum = j_val[0, col] + j_val[1, col] + j_val[2, col]
                            j_max = max(j_max, j_sum)
                            if g < n_g:
                                c_lo += tail[0, g] * j_sum
                                c_hi += tail[1, g] * j_sum
                        if gauss_done:
                            for g in range(n_g):
                                for c in range(3):
                                    out[c] += e0 * node_w[g] * j_val[c, gauss_col[g]]
                            continue
                        # (the last Kronrod node is the part's last node: the search goes on from there)
                        _exp_weights(hh, kronrod_lag, fine_y, fine_w, node_w)
                        i_kronrod = 0.0
                        for g in range(kronrod_x.shape[0]):
                            i_kronrod += node_w[g] * (j_val[0, g] + j_val[1, g] + j_val[2, g])
                        if abs(i_kronrod - i_gauss) * e0 > allowed * hh and depth < MAX_SPLITS:
                            k, s_prev, u_prev = k_0, s_0, up_0
                            split_u[top + 1] = u_step + 0.5 * hh
                            split_depth[top + 1] = depth + 1.0
                            split_u[top + 2] = u_step
                            split_depth[top + 2] = depth + 1.0
                            top += 2
                            continue
                        for g in range(kronrod_x.shape[0]):
                            for c in range(3):
                                out[c] += e0 * node_w[g] * j_val[c, g]
            k_a = k_b
    scratch = _add_ray_end(o, d, t_hit, s_hit, u_total, u_stop, med, surf, lights, background, ambient, tol_t,
                           scratch, cand, stack, light_buf, out)
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
    """Per-chunk work arrays of the image loop: candidate list (n_balls: the most balls of media or of
    surfaces), BVH stack, light buffer (a row per light, then rows of small work vectors)."""
    return (np.empty(max(n_balls, 1), np.int64), np.empty(2 * STACK, np.int64),
            np.empty((n_lights + 9, max(NCOEF + 1, MAX_NODES))))


@njit(**NJIT_INLINE)
def misses_media(o, d, node_box, root):
    """Whether the ray misses the root box of every medium's BVH."""
    ix = 1.0 / d[0] if d[0] != 0.0 else np.inf
    iy = 1.0 / d[1] if d[1] != 0.0 else np.inf
    iz = 1.0 / d[2] if d[2] != 0.0 else np.inf
    for m in range(root.shape[0]):
        if ray_box(o[0], o[1], o[2], ix, iy, iz, node_box, root[m], 0.0, np.inf):
            return False
    return True


@njit(**NJIT)
def render_pixels(row0, width, height, spp, seed, cam_pos, cam_fwd, cam_right, cam_up, p0, p1, med, surf,
                  lights, quad, background, ambient, image, depth):
    """Pixels p0 .. p1 - 1, counted row by row from the start of row row0, into image (H x W x 4, row 0
    at the top) and depth (H x W: per pixel, the nearest surface hit t over its samples, inf where none
    hits), with their own work arrays. nogil: cloudmeta.render runs bands of rows on several threads.

    cam_right and cam_up are scaled to the half-extent of the image plane at distance 1. With spp > 1
    the samples are stratified on a ceil(sqrt(spp))^2 grid and jittered by a hash of (pixel, sample).
    """
    strata = int(math.ceil(math.sqrt(spp)))
    scratch = alloc_scratch(64)
    rp = alloc_ray_pieces(64, med[3].shape[0] - 1)
    cand, stack, light_buf = alloc_work(max(med[0].shape[0], surf[0].shape[0]), lights[0].shape[0])
    px_out = np.empty(5)
    d = np.empty(3)
    for p in range(p0, p1):
        i = row0 + p // width
        j = p % width
        acc0 = 0.0
        acc1 = 0.0
        acc2 = 0.0
        acc3 = 0.0
        nearest = np.inf
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
            if misses_media(cam_pos, d, med[10], med[15]) and misses_media(cam_pos, d, surf[8], surf[13]):
                for c in range(3):
                    px_out[c] = background[c]  # nothing on the ray: the background, at once
                px_out[3] = 1.0
                px_out[4] = np.inf
            else:
                scratch, rp = ray_radiance(cam_pos, d, med, surf, lights, quad, background, ambient, scratch,
                                           rp, cand, stack, light_buf, px_out)
            acc0 += px_out[0]
            acc1 += px_out[1]
            acc2 += px_out[2]
            acc3 += px_out[3]
            nearest = min(nearest, px_out[4])
        depth[i, j] = nearest
        image[i, j, 0] = acc0 / spp
        image[i, j, 1] = acc1 / spp
        image[i, j, 2] = acc2 / spp
        image[i, j, 3] = 1.0 - acc3 / spp  # alpha = 1 - T(0, t_end)
