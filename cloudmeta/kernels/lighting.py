"""The light reaching a point, for every light kind (docs/model.md §5): the one module where a light kind is
evaluated. ``light_at_node`` gives, per light, l . v and E_l T_l (the light's irradiance at the point times
the shadow transmittance: blocked by surfaces, from a shadow map, or an exact shadow ray through the
media); ``angular_cuts`` the equal-angle cuts of a segment seen from the point light that sees it under
the widest angle (E ~ 1/r^2 near a point light). Both estimators (kernels.single, kernels.multiple) read
lights through these two functions alone; a new kind is one branch in each and an id in kernels.kinds.
"""
import math

import numpy as np
from numba import njit

from .config import NJIT, NJIT_INLINE
from .optional import light_map, map_depth, surfaces_blocking
from .kinds import DIRECTIONAL
from .media import shadow_transmittance
from .optics import phase

#: work.nodes.count: what the light at the nodes cost (renderer.single: per pixel, for the benchmarks)
COUNT_NODES = 0         # quadrature nodes (kernels.single.source_at)
COUNT_EXACT = 1         # exact shadow rays through the media
COUNT_LOOKUPS = 2       # shadow-map lookups
COUNT_TRUSTED = 3       # lookups whose interpolation was kept (no exact ray)
COUNT_STEPS = 4         # quadrature steps and parts of steps (kernels.single.step_in_scattering)
COUNT_KRONROD = 5       # of them, those that took the 8 Kronrod nodes
COUNT_SPLITS = 6        # of them, those split (halved, or cut at a fold)
COUNT_FOLDS = 7         # of the splits, those cut around a fold of the light's optical depth
N_COUNTS = 8


@njit(**NJIT_INLINE)
def light_weight(cos_lv, facing_only, med):
    """What an error in T_l is multiplied by (besides E_l) in the light a point sends on: cos / pi on a
    surface, and at a medium's node the largest albedo x phase of its media."""
    if facing_only:
        return max(cos_lv, 0.0) / math.pi
    w = 0.0
    for m in range(med.albedo.shape[0]):
        row = med.phase[m]
        w = max(w, med.albedo[m] * phase(row[0], row[1], row[2], row[3], cos_lv))
    return w


@njit(**NJIT_INLINE)
def light_geometry(lights, li, pos, l_dir):
    """Light li seen from pos: l_dir = the unit direction towards it; returns (the factor of its rgb at pos,
    the shadow ray's length): (1, inf) for a directional light, (1 / r^2, r) for a point light at distance r."""
    if lights.kind[li] == DIRECTIONAL:
        for c in range(3):
            l_dir[c] = lights.vec[li, c]
        return 1.0, np.inf
    for c in range(3):
        l_dir[c] = lights.vec[li, c] - pos[c]
    dist2 = l_dir[0] * l_dir[0] + l_dir[1] * l_dir[1] + l_dir[2] * l_dir[2]
    l_max = math.sqrt(dist2)
    for c in range(3):
        l_dir[c] /= l_max
    return 1.0 / dist2, l_max


#: inlined: a call per quadrature node would count references to every array of the scene records
@njit(**NJIT_INLINE)
def light_at_node(pos, shadow_from, v, facing_only, tau_stop, j_tol, scene, tol_t, scratch, work):
    """Per light: work.nodes.light[li, 0] = l . v, [li, 1:4] = E_l T_l at pos, [li, 4] = T_l, [li, 5] = the exact shadow
    ray's entries into the media (-1 where T_l came from a map or a surface blocked it). v is the view direction
    at a medium's node (l . v = cos theta of the phase function), the normal at a surface point; with
    facing_only, lights with l . v <= 0 get E_l T_l = 0 and no shadow ray (they cannot light the side of
    a surface facing away). The shadow ray starts at shadow_from (pos, or a surface point lifted off its
    surface) and runs along l; it stops counting once its optical depth exceeds tau_stop.
    A light with a shadow map takes T_l from the map (bilinear across texels): always for j_tol inf
    (``shadows: map``); else (``shadows: hybrid``, docs/model.md §11; j_tol 0: exact rays only) where the
    spread of the four texels' transmittances, times E_l (r + g + b) and light_weight, is at most j_tol, and
    from an exact shadow ray elsewhere. Returns scratch."""
    lights = scene.lights
    surf = scene.surfaces
    l_dir = work.nodes.l_dir
    light_buf = work.nodes.light
    count = work.nodes.count
    for li in range(lights.kind.shape[0]):
        e_scale, l_max = light_geometry(lights, li, pos, l_dir)
        cos_lv = l_dir[0] * v[0] + l_dir[1] * v[1] + l_dir[2] * v[2]
        light_buf[li, 0] = cos_lv
        light_buf[li, 5] = -1.0
        if facing_only and cos_lv <= 0.0:
            for c in range(4):
                light_buf[li, 1 + c] = 0.0
            continue
        scratch, blocked = surfaces_blocking(shadow_from, l_dir, l_max, surf, tol_t, scratch, work)
        mi = light_map(lights.maps, li) if j_tol > 0.0 else -1
        t_l = -1.0
        if blocked:
            t_l = 0.0
        elif mi >= 0:
            count[COUNT_LOOKUPS] += 1.0
            tau, tau_lo, tau_hi = map_depth(shadow_from, lights.maps, mi)
            t_l = math.exp(-tau)
            spread = math.exp(-tau_lo) - math.exp(-tau_hi)
            if j_tol != np.inf and spread > 0.0:
                # T_l lies between the four texels' transmittances where the depth is monotone across the
                # cell: their spread, in the light sent on (E_l (r + g + b) times light_weight), bounds the
                # error. (A bicubic lookup checked against the bilinear one was tried and refused: with the
                # whole tolerance as share, on the generated clouds' sub-texel puffs both agreed and both
                # missed, 6-8x the target.)
                weight = (lights.rgb[li, 0] + lights.rgb[li, 1] + lights.rgb[li, 2]) * e_scale * light_weight(
                    cos_lv, facing_only, scene.media)
                if spread * weight > j_tol:
                    t_l = -1.0
            if t_l >= 0.0:
                count[COUNT_TRUSTED] += 1.0
        if t_l < 0.0:
            count[COUNT_EXACT] += 1.0
            scratch, t_l, entries = shadow_transmittance(shadow_from, l_dir, l_max, scene.media, tol_t, tau_stop,
                                                         scratch, work.cand, work.stack)
            light_buf[li, 5] = entries
        for c in range(3):
            light_buf[li, 1 + c] = lights.rgb[li, c] * e_scale * t_l
        light_buf[li, 4] = t_l
    return scratch


@njit(**NJIT)
def angular_cuts(o, d, ta, tb, light_kind, light_vec, max_angle, tol_t):
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
