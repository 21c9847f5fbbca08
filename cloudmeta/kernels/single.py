"""Single scattering along camera rays (docs/model.md §5), opaque surfaces on them (§6), and the image loop.

The seam: estimators
--------------------
The pixel loop (``render_pixels``) makes each camera ray and hands it to ONE estimator entry point,
``single_scattering(o, d, scene, quad, work, out) -> work``, which writes out = (r, g, b, T(0, t_end),
t_hit): the ray's radiance, its view transmittance (0 where it meets a surface: alpha 1) and where it
first meets a surface (inf if it does not). ``scene`` is a records.SceneRecords, ``quad`` a
records.Quadrature, ``work`` a records.RayWork (returned, because a ray that needs more room grows its
scratch). Another estimator (multiple scattering, say) is one more function with the same signature,
built from the same stages, and one more branch where render_pixels calls the estimator.

single_scattering runs five stages, each a function with one job:

1. ``surface_hit``: the first opaque surface on the ray, t_hit (kernels.surfaces);
2. ``collect_media``: every medium's inside pieces on [0, t_hit], as sigma_t (kernels.media);
3. ``elementary_intervals``: the ray cut at every piece end; per interval sigma_t of each medium and of
   all, as Bernstein polynomials, and the exact optical depth tau(0, t) from the ray's start;
4. ``in_scattering``: the in-scattering integral over each inside segment (``segment_in_scattering``: a
   run of adjacent intervals, cut at equal angles seen from point lights), step by step
   (``step_in_scattering``: the adaptive G7-K15 rule on one step, split around folds of the light's optical
   depth where its shadow rays' entries into the media change), J at each node (``source_at``) from
   the light reaching it (``light_at_node``: E_l T_l per light, exact shadow rays or shadow maps);
5. ``ray_end``: L_end T(0, t_end), the background or the shaded surface (``shade_surface``).

The quadrature
--------------
On each interval the view optical depth tau(0, t) is exact at any t (the antiderivative of a Bernstein
polynomial). The in-scattering integral is taken in optical depth u, where T sigma_s dt = e^-u
(sigma_s/sigma_t) du: product-integration weights (exact for e^-u times a polynomial, see _exp_weights)
on steps no thicker than ``max_tau`` and no longer than ``max_length`` (both times e^(growth u) at view depth u:
a step seen through e^-u may be that much rougher); each step takes 7 Gauss nodes,
the 8 Kronrod nodes of G7-K15 where J's Legendre tail (a tenth of it, TAIL_SHARE, where no fold lies among the
Gauss nodes) exceeds ``tolerance``, and is split where the two rules disagree (docs/model_notes.md); an exact
shadow ray goes from every node to every light; near point lights the segment is first cut at equal angles (at
most ``max_angle``) seen from the light, which tames their 1/r^2.

With opaque surfaces, the media are traced over [0, t_hit] only, and the hit, shaded as Lambertian,
takes the background's place: L = L_surface T(0, t_hit) + in-scattering over [0, t_hit], alpha 1. Shadow
rays, from quadrature nodes and from surface points, are blocked by any surface (T_l = 0), and then
trace no media. A scene without surfaces traces nothing more: every surface loop runs over zero surfaces.

Inlining: ``source_at`` and ``light_at_node`` run once per quadrature node and are inlined at numba's IR
level (NJIT_INLINE), so that no call boundary, with the reference counting of every array of the
records, remains per node. The estimator's stages with one caller each (``single_scattering``,
``in_scattering``, ``segment_in_scattering``, ``step_in_scattering``, ``ray_end``) are inlined into
``render_pixels`` too, for compile time: numba links every separately compiled callee into its caller's
module and optimises and generates machine code for the whole module again, so each level of the call
chain above the shadow-ray and sweep code compiled all of that code once more (cumulus cold compile,
process CPU: 375 s with the stages separate, 300 s inlined; docs/compile.md). The
quadrature's loops carry only the sweep scratch (which a shadow ray may grow), not the whole RayWork:
every record a loop carries becomes LLVM phi nodes for each field of each of its arrays, and carrying
the 44 arrays of RayWork through three nested loops cost 40 s of compile (§2c).

What a scene lacks is not compiled: a scene with neither surfaces nor shadow maps has None in their
places, and the helpers of kernels.features (and ``surface_radiance`` here) compile to their trivial
case for it.
"""
import math

import numpy as np
from numba import njit
from numba.core import types
from numba.extending import overload

from .config import NJIT, NJIT_INLINE, OVERLOAD
from .bernstein import bernstein_eval
from .borrow import borrow, hold_grown, release
from .bvh import misses_root_boxes
from .camera import background_radiance, background_sample, camera_ray
from .optional import grid_light, has_grid, misses_surfaces, surface_hit
from .lighting import (COUNT_FOLDS, COUNT_KRONROD, COUNT_NODES, COUNT_SPLITS, COUNT_STEPS, angular_cuts,
                       light_at_node)
from .media import collect_media
from .optics import phase
from .records import SHADOWS_HYBRID, SHADOWS_MAP, RayWork, StepState
from .sampling import invert_depth
from .intervals import alloc_ray_work, depth_at, elementary_intervals
from .surfaces import SHADOW_OFFSET, surface_normal

#: a step is split at most this deep where its Kronrod and Gauss results disagree (the pending parts, at most
#: 2 per level, fit the MAX_NODES slots of a work row)
MAX_SPLITS = 6
#: the share of J's Legendre tail that the Gauss-only test counts as the step's error where no fold lies among the
#: Gauss nodes (their shadow rays all enter the media alike). The two highest Legendre coefficients of J's degree-6
#: interpolant say how far J is from a lower degree, but the 7 Gauss nodes integrate exactly to degree 13: on a smooth
#: J they err far less than the tail. Across a fold J has a square-root kink, and there the whole tail counts
#: (CHANGELOG.md, "The Gauss test's share of the tail")
TAIL_SHARE = 0.1


@njit(**NJIT)
def _depth_to_s(S, w, u, s0, u0):
    """s in [s0, 1] where the optical depth w * int_0^s S reaches u, given that it is u0 at s0 (the
    previous node): sampling.invert_depth from a Newton step off the previous node."""
    slope = w * bernstein_eval(S, s0)
    s = s0 + (u - u0) / slope if slope > 0.0 else 0.5 * (s0 + 1.0)
    if not (s0 < s < 1.0):
        s = 0.5 * (s0 + 1.0)
    return invert_depth(S, w, u, s0, s, 1e-14, np.int64(60), np.bool_(True))


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


@njit(**NJIT_INLINE)
def octave_phase(octaves, phase_row, cos_lv, t_l):
    """The factor of E_l T_l at a node: the phase function p(cos_lv) for single scattering (one octave,
    exactly as it is), else Wrenninge's octaves sum_i c^i T_l^(a^i - 1) p(cos_lv; g b^i) (docs/approximate.md):
    octave i sees the light through a^i times the optical depth, with b^i times the phase's asymmetry."""
    kind, g1, g2, w = phase_row[0], phase_row[1], phase_row[2], phase_row[3]
    if octaves.shape[0] == 1:
        return phase(kind, g1, g2, w, cos_lv)
    if t_l <= 0.0:
        return 0.0
    total = 0.0
    for i in range(octaves.shape[0]):
        a, b, c = octaves[i, 0], octaves[i, 1], octaves[i, 2]
        total += c * t_l ** (a - 1.0) * phase(kind, g1 * b, g2 * b, w, cos_lv)
    return total


@njit(**NJIT_INLINE)
def node_topology(light_buf):
    """One number for the shadow rays' entries into the media at a node, every light's count in its own digits
    (base 4096); -1 where a light's T_l did not come from an exact ray. Two nodes with different numbers have
    a fold of some light's optical depth between them."""
    signature = 0.0
    place = 1.0
    for li in range(light_buf.shape[0]):
        if light_buf[li, 5] < 0.0:
            return -1.0
        signature += place * min(light_buf[li, 5], 4095.0)
        place *= 4096.0
    return signature


@njit(**NJIT_INLINE)
def fold_between(a, b):
    """Whether a fold of the light's optical depth lies between two nodes whose node_topology are a and b: both
    known (from exact shadow rays) and different."""
    return a >= 0.0 and b >= 0.0 and a != b


@njit(**NJIT_INLINE)
def fold_bracket(topo_row, n):
    """The first i < n - 1 where nodes i and i + 1 (in increasing u) both know their shadow rays' entries
    (node_topology) and these differ: a fold of the light's optical depth lies between them. -1 where none
    does. (Only where exactly one pair differed, the splits measured the same: 40.7 against 40.4 nodes per
    media pixel on the bank.)"""
    for q in range(n - 1):
        if fold_between(topo_row[q], topo_row[q + 1]):
            return q
    return -1


@njit(**NJIT_INLINE)
def tail_share(topo_row, cols, n):
    """TAIL_SHARE where no two neighbouring nodes among cols[:n] (in increasing u) both know their shadow rays'
    entries (node_topology) and differ in them; else 1: a fold lies among them."""
    for q in range(n - 1):
        if fold_between(topo_row[cols[q]], topo_row[cols[q + 1]]):
            return 1.0
    return TAIL_SHARE


@njit(**NJIT_INLINE)
def push_fold_parts(split_u, split_h, split_depth, top, u_step, hh, depth, x_lo, x_hi):
    """Push the parts [x_hi, 1], [x_lo, x_hi] and [0, x_lo] of the part [u_step, u_step + hh] (in units of hh) on
    the work row's pending parts, the first to be done last; depth grows by log2 of each part's share (a
    narrow part counts as several halvings). Returns the new top."""
    split_u[top + 1] = u_step + x_hi * hh
    split_h[top + 1] = (1.0 - x_hi) * hh
    split_depth[top + 1] = depth - math.log2(1.0 - x_hi)
    split_u[top + 2] = u_step + x_lo * hh
    split_h[top + 2] = (x_hi - x_lo) * hh
    split_depth[top + 2] = depth - math.log2(x_hi - x_lo)
    split_u[top + 3] = u_step
    split_h[top + 3] = x_lo * hh
    split_depth[top + 3] = depth - math.log2(x_lo)
    return top + 3


@njit(**NJIT_INLINE)
def source_at(u, k_b, cursor, o, d, scene, quad, scratch, work, col):
    """work.nodes.j_val[:3, col] = J at optical depth u of the view ray: sum over media of
    (sigma_s / sigma_t) times (sum over lights of phase E_l T_l, plus the ambient radiance); j_val[3, col] =
    node_topology of its shadow rays.
    cursor = (k, s_prev, u_prev) locates the previous node (nodes come in increasing u, within the
    segment's intervals below k_b); returns (scratch, the cursor of this node)."""
    k, s_prev, u_prev = cursor
    med = scene.view_media
    rp = work.pieces
    j_val = work.nodes.j_val
    light_buf = work.nodes.light
    el_t0, el_t1, el_u0, el_S, el_sig = rp.el_t0, rp.el_t1, rp.el_u0, rp.el_S, rp.el_sig
    while k < k_b - 1 and el_u0[k + 1] <= u:
        k += 1
        s_prev = 0.0
        u_prev = el_u0[k]
    w = el_t1[k] - el_t0[k]
    s = _depth_to_s(el_S[k], w, u - el_u0[k], s_prev, u_prev - el_u0[k])
    for c in range(3):
        j_val[c, col] = 0.0
    j_val[3, col] = -1.0
    sigma_t = bernstein_eval(el_S[k], s)
    if sigma_t <= 0.0:
        return scratch, (k, s, u)
    t = el_t0[k] + s * w
    pos = work.nodes.pos
    for c in range(3):
        pos[c] = o[c] + t * d[c]
    octaves = scene.octaves
    work.nodes.count[COUNT_NODES] += 1.0
    # a map's error at this node is seen through e^-u; the octaves' T_l^(a^i) would amplify it: exact rays
    j_tol = 0.0  # kernels.lighting.light_at_node: 0 traces exact shadow rays, inf always takes the map
    if quad.shadow_mode == SHADOWS_MAP:
        j_tol = np.inf
    elif quad.shadow_mode == SHADOWS_HYBRID and octaves.shape[0] == 1:
        j_tol = quad.map_tolerance * math.exp(min(u, 700.0))
    # the last octave sees the least optical depth (a^i tau): the shadow ray counts until that one is dark
    scratch = light_at_node(pos, pos, d, False, quad.u_stop / octaves[octaves.shape[0] - 1, 0], j_tol, scene,
                            quad.tol_t, scratch, work)
    j_val[3, col] = node_topology(light_buf)
    for m in range(med.albedo.shape[0]):
        if med.albedo[m] == 0.0:
            continue
        ratio = med.albedo[m] * bernstein_eval(el_sig[k, m], s) / sigma_t
        if ratio == 0.0:
            continue
        for li in range(scene.lights.kind.shape[0]):
            ph = octave_phase(octaves, med.phase[m], light_buf[li, 0], light_buf[li, 4])
            for c in range(3):
                j_val[c, col] += ratio * ph * light_buf[li, 1 + c]
        for c in range(3):
            j_val[c, col] += ratio * scene.ambient[c]
        # the approximate mode's grid: the orders a node's exact T_l does not count (black in other scenes)
        g_r, g_g, g_b = grid_light(scene.radiance, pos, m)
        j_val[0, col] += ratio * g_r
        j_val[1, col] += ratio * g_g
        j_val[2, col] += ratio * g_b
    return scratch, (k, s, u)


@njit(**NJIT_INLINE)
def step_in_scattering(o, d, u0, h, k_b, state, scene, quad, work, out):
    """out[:3] += the in-scattering integral over the step [u0, u0 + h] of view optical depth: 7 Gauss
    nodes; where the tail of their Legendre expansion says J is rougher than the tolerance allows (``tail_share``:
    a tenth of the tail counts where their shadow rays show no fold), the 8 Kronrod nodes join them (15, the 7
    reused); where the two rules still disagree the step is split (at most MAX_SPLITS halvings deep), left part
    first, so that the nodes come in increasing u: around the first fold of the light's optical depth that the
    nodes' shadow rays bracket (their entries into the media differ between two neighbours), into the parts
    before, between and after those two nodes, so that the kink J has there is confined to the narrow middle
    part; else halved. Parts seen through less than ``cutoff`` are dropped. state: a records.StepState. Returns
    the state after the step."""
    k, s_prev, u_prev, j_max, scratch = state.k, state.s_prev, state.u_prev, state.j_max, state.scratch
    nodes = work.nodes
    node_w, j_val, count = nodes.node_w, nodes.j_val, nodes.count
    split_u, split_h, split_depth = nodes.split_u, nodes.split_h, nodes.split_depth
    gauss_col, kronrod_col, kronrod_x, tail = quad.gauss_col, quad.kronrod_col, quad.kronrod_x, quad.tail
    n_g = quad.gauss_x.shape[0]
    n_k = kronrod_x.shape[0]
    split_u[0] = u0
    split_h[0] = h
    split_depth[0] = 0.0
    top = 0
    while top >= 0:
        u_step = split_u[top]
        hh = split_h[top]
        depth = split_depth[top]
        top -= 1
        if u_step >= quad.u_stop:
            break  # the rest is seen through less than `cutoff`
        count[COUNT_STEPS] += 1.0
        k_0, s_0, up_0 = k, s_prev, u_prev
        e0 = math.exp(-u_step)
        c_lo = 0.0
        c_hi = 0.0
        i_gauss = 0.0
        allowed = 0.0
        gauss_done = False
        # the 7 Gauss nodes, then (unless they suffice) the 8 Kronrod nodes: one loop, so that the inlined
        # node code is compiled once
        for g in range(n_g + kronrod_col.shape[0]):
            if g == n_g:
                _exp_weights(hh, quad.gauss_lag, quad.fine_y, quad.fine_w, node_w)
                # J's error, weighted by e^-u, is then below tolerance times the frame's scattered-light
                # scale (the pilot's; else the ray's brightest J): deep steps may be rougher
                allowed = quad.tolerance * (quad.light_scale if quad.light_scale > 0.0 else j_max)
                if (abs(c_lo) + abs(c_hi)) * tail_share(j_val[3], gauss_col, n_g) * e0 <= allowed:
                    gauss_done = True
                    break
                i_gauss = _rule_sum(node_w, j_val, gauss_col, n_g)
                k, s_prev, u_prev = k_0, s_0, up_0  # the Kronrod nodes, again in increasing u
                count[COUNT_KRONROD] += 1.0
            col = gauss_col[g] if g < n_g else kronrod_col[g - n_g]
            scratch, (k, s_prev, u_prev) = source_at(u_step + kronrod_x[col] * hh, k_b, (k, s_prev, u_prev), o, d,
                                                     scene, quad, scratch, work, col)
            j_sum = j_val[0, col] + j_val[1, col] + j_val[2, col]
            j_max = max(j_max, j_sum)
            if g < n_g:
                c_lo += tail[0, g] * j_sum
                c_hi += tail[1, g] * j_sum
        if gauss_done:
            _add_rule(out, e0, node_w, j_val, gauss_col, n_g)
            continue
        # (the last Kronrod node is the part's last node: the search goes on from there)
        _exp_weights(hh, quad.kronrod_lag, quad.fine_y, quad.fine_w, node_w)
        i_kronrod = 0.0
        for g in range(n_k):
            i_kronrod += node_w[g] * (j_val[0, g] + j_val[1, g] + j_val[2, g])
        # (depth: log2 of the step's width over the part's; the pending parts must fit the work row)
        if abs(i_kronrod - i_gauss) * e0 > allowed * hh and depth < MAX_SPLITS and top + 3 < split_u.shape[0]:
            k, s_prev, u_prev = k_0, s_0, up_0
            count[COUNT_SPLITS] += 1.0
            i_fold = fold_bracket(j_val[3], n_k)
            if i_fold >= 0:
                # a fold lies between nodes i_fold and i_fold + 1: J's kink there would keep every half rough
                count[COUNT_FOLDS] += 1.0
                top = push_fold_parts(split_u, split_h, split_depth, top, u_step, hh, depth, kronrod_x[i_fold],
                                      kronrod_x[i_fold + 1])
            else:
                split_u[top + 1] = u_step + 0.5 * hh
                split_h[top + 1] = 0.5 * hh
                split_u[top + 2] = u_step
                split_h[top + 2] = 0.5 * hh
                split_depth[top + 1] = depth + 1.0
                split_depth[top + 2] = depth + 1.0
                top += 2
            continue
        for g in range(n_k):
            for c in range(3):
                out[c] += e0 * node_w[g] * j_val[c, g]
    return StepState(k, s_prev, u_prev, j_max, scratch)


@njit(**NJIT_INLINE)
def _rule_sum(node_w, j_val, cols, n):
    """sum_g node_w[g] (r + g + b of J at node cols[g]), over the n nodes of a rule."""
    acc = 0.0
    for g in range(n):
        col = cols[g]
        acc += node_w[g] * (j_val[0, col] + j_val[1, col] + j_val[2, col])
    return acc


@njit(**NJIT_INLINE)
def _add_rule(out, e0, node_w, j_val, cols, n):
    """out[:3] += e0 sum_g node_w[g] J at node cols[g], over the n nodes of a rule."""
    for g in range(n):
        for c in range(3):
            out[c] += e0 * node_w[g] * j_val[c, cols[g]]


@njit(**NJIT_INLINE)
def segment_in_scattering(o, d, k_a, k_b, j_max, scene, quad, work, out, scratch):
    """out[:3] += the in-scattering integral over the inside segment of intervals k_a .. k_b - 1 (adjacent
    end to start): cut at equal angles seen from the point light that sees it under the widest angle,
    each part cut into steps of at most ``max_tau`` and ``max_length``, times e^(growth u) at view depth u
    (records.Quadrature). j_max: the largest J met on this
    ray so far. Returns (work, j_max)."""
    rp = work.pieces
    ta = rp.el_t0[k_a]
    tb = rp.el_t1[k_b - 1]
    # near a point light E ~ 1/r^2 peaks: cut at equal angles seen from the light that sees the segment
    # under the widest angle (t = t_c + h tan(theta) makes dt / r^2 = d(theta) / h)
    n_sub, t_c, h_l, th_a, d_th = angular_cuts(o, d, ta, tb, scene.lights.kind, scene.lights.vec, quad.max_angle,
                                                quad.tol_t)
    state = StepState(k_a, 0.0, rp.el_u0[k_a], j_max, scratch)
    u_end = rp.el_u0[k_a]
    t_end = ta
    for sub in range(n_sub):
        u_start = u_end
        t_start = t_end
        if sub == n_sub - 1:
            t_end = tb
            u_end = rp.el_u0[k_b]
        else:
            t_end = t_c + h_l * math.tan(th_a + (sub + 1) * d_th)
            u_end, _ = depth_at(t_end, state.k, k_b, rp)
        sub_u = u_end - u_start
        if sub_u <= 0.0:
            continue
        # in optical depth u: T sigma_s dt = e^-u (sigma_s / sigma_t) du, with weights exact for e^-u times
        # a polynomial: the nodes follow only how the light J varies
        n_steps = max(1, int(math.ceil(max(sub_u / quad.max_tau, (t_end - t_start) / quad.max_length))))
        h = sub_u / n_steps
        # a step's error is seen through e^-u: steps grow as e^(growth u) with the view depth u, so that each
        # may err about as much in the image (growth 0: equal steps); one short of the end takes the rest
        u = u_start
        while u < u_end and u < quad.u_stop:
            h_u = h * math.exp(min(quad.growth * u, 700.0))
            if u + 1.25 * h_u >= u_end:
                h_u = u_end - u
            state = step_in_scattering(o, d, u, h_u, k_b, state, scene, quad, work, out)
            u += h_u
    return state.scratch, state.j_max


@njit(**NJIT_INLINE)
def segment_end(rp, k_a, n_el):
    """The end k_b of the inside segment that starts at interval k_a: intervals k_a .. k_b - 1 are
    adjacent end to start."""
    k_b = k_a + 1
    while k_b < n_el and rp.el_t0[k_b] == rp.el_t1[k_b - 1]:
        k_b += 1
    return k_b


@njit(**NJIT_INLINE)
def scatters_light(scene):
    """Whether any medium scatters (albedo > 0) and there is light to scatter (lights, ambient or a radiance
    grid)."""
    ambient = scene.ambient
    has_ambient = ambient[0] > 0.0 or ambient[1] > 0.0 or ambient[2] > 0.0
    scatters = False
    for m in range(scene.media.albedo.shape[0]):
        scatters = scatters or scene.media.albedo[m] > 0.0
    return (scene.lights.kind.shape[0] > 0 or has_ambient or has_grid(scene.radiance)) and scatters


@njit(**NJIT_INLINE)
def constant_source(scene):
    """Whether J is the same at every point of every ray: no lights and no radiance grid (ambient light only),
    and one albedo shared by all media, so that J = albedo * ambient wherever there is medium (sum over media of
    albedo sigma_t,m / sigma_t)."""
    if scene.lights.kind.shape[0] > 0 or has_grid(scene.radiance):
        return False
    albedo = scene.media.albedo
    for m in range(1, albedo.shape[0]):
        if albedo[m] != albedo[0]:
            return False
    return True


@njit(**NJIT_INLINE)
def j_const_rgb(scene, c):
    """Channel c of the constant J of a scene for which constant_source holds."""
    return scene.media.albedo[0] * scene.ambient[c]


@njit(**NJIT_INLINE)
def in_scattering(o, d, n_el, scene, quad, work, out):
    """out[:3] += the single-scattering integral over the ray's n_el elementary intervals (in
    work.pieces), segment after segment, up to where the view transmittance falls below ``cutoff``; in
    closed form where J is constant (``constant_source``: ambient light alone).
    The quadrature runs over each inside segment (a run of adjacent intervals) as a whole, so that chord
    ends, which the light does not see, cost no nodes. Returns work."""
    if constant_source(scene):
        # J the same everywhere: the integral of e^-u J du along the ray is J (1 - T), exact, and no node
        fade = -math.expm1(-work.pieces.el_u0[n_el])
        for c in range(3):
            out[c] += fade * j_const_rgb(scene, c)
        return work
    j_max = 0.0
    k_a = np.int64(0)  # not the literal 0: _depth_at would compile once more for Literal[int](0)
    scratch = work.scratch
    while k_a < n_el and work.pieces.el_u0[k_a] < quad.u_stop:
        k_b = segment_end(work.pieces, k_a, n_el)
        scratch, j_max = segment_in_scattering(o, d, k_a, k_b, j_max, scene, quad, work, out, scratch)
        k_a = k_b
    return RayWork(scratch, work.pieces, work.cand, work.stack, work.nodes)


@njit(**NJIT)
def shade_surface(o, d, t_hit, s, scene, quad, scratch, work):
    """Lambertian radiance of surface s hit at o + t_hit d (docs/model.md §6):
    colour / pi * sum_lights max(0, n . l) E_l T_l + colour * L_amb. Returns (scratch, r, g, b)."""
    nodes = work.nodes
    x, nrm, x_off = nodes.x, nodes.normal, nodes.x_off
    for c in range(3):
        x[c] = o[c] + t_hit * d[c]
    surface_normal(x, d, scene.surfaces, s, work.cand, work.stack, nrm)
    for c in range(3):
        x_off[c] = x[c] + SHADOW_OFFSET * quad.tol_t * nrm[c]
    j_tol = np.inf if quad.shadow_mode == SHADOWS_MAP else (
        quad.map_tolerance if quad.shadow_mode == SHADOWS_HYBRID else 0.0)
    scratch = light_at_node(x, x_off, nrm, True, quad.u_stop, j_tol, scene, quad.tol_t, scratch, work)
    e0 = 0.0
    e1 = 0.0
    e2 = 0.0
    light_buf = nodes.light
    for li in range(scene.lights.kind.shape[0]):
        cos_nl = light_buf[li, 0]
        if cos_nl > 0.0:
            e0 += cos_nl * light_buf[li, 1]
            e1 += cos_nl * light_buf[li, 2]
            e2 += cos_nl * light_buf[li, 3]
    colour = scene.surfaces.colour[s]
    ambient = scene.ambient
    return (scratch, colour[0] * (e0 / math.pi + ambient[0]), colour[1] * (e1 / math.pi + ambient[1]),
            colour[2] * (e2 / math.pi + ambient[2]))


def surface_radiance(surf, o, d, t_hit, s, scene, quad, work):
    """shade_surface's (scratch, r, g, b) for the hit s, work.scratch and black for a scene without
    surfaces (surf None: never asked, and then not compiled; see kernels.features)."""
    if surf is None:
        return work.scratch, 0.0, 0.0, 0.0
    return shade_surface(o, d, t_hit, s, scene, quad, work.scratch, work)


@overload(surface_radiance, **OVERLOAD)
def _surface_radiance(surf, o, d, t_hit, s, scene, quad, work):
    if isinstance(surf, types.NoneType):
        return lambda surf, o, d, t_hit, s, scene, quad, work: (work.scratch, 0.0, 0.0, 0.0)
    return lambda surf, o, d, t_hit, s, scene, quad, work: shade_surface(o, d, t_hit, s, scene, quad, work.scratch,
                                                                           work)


@njit(**NJIT_INLINE)
def ray_end(o, d, t_hit, s_hit, u_total, scene, quad, work, out):
    """out[:3] += L_end T(0, t_end): the background for an escaping ray, the shaded surface for a hit
    (not shaded where it is seen through less than ``cutoff``). out[3] = T(0, t_end), 0 for a hit (alpha 1).
    Returns work."""
    t_view = math.exp(-u_total)
    if s_hit < 0:
        r, g, b = background_radiance(scene.background, d)
        out[0] += r * t_view
        out[1] += g * t_view
        out[2] += b * t_view
        out[3] = t_view
        return work
    out[3] = 0.0
    if u_total < quad.u_stop:
        scratch, r, g, b = surface_radiance(scene.surfaces, o, d, t_hit, s_hit, scene, quad, work)
        out[0] += r * t_view
        out[1] += g * t_view
        out[2] += b * t_view
        work = RayWork(scratch, work.pieces, work.cand, work.stack, work.nodes)
    return work


@njit(**NJIT_INLINE)
def single_scattering(o, d, scene, quad, work, out):
    """The single-scattering estimator (docs/model.md §5-6) of the camera ray o + t d: out[:3] = its radiance,
    out[3] = its transmittance T(0, t_end) (0 where it meets a surface), out[4] = t_hit, where it first
    meets a surface (inf if it does not). Returns work, grown if this ray needed more room."""
    scratch, t_hit, s_hit = surface_hit(o, d, scene.surfaces, quad.tol_t, work)
    rp = work.pieces
    n = 0
    if t_hit > 0.0:  # a camera inside a surface sees no media
        scratch, rp, n = collect_media(o, d, t_hit, scene.view_media, quad.tol_t, scratch, rp, work.cand, work.stack)
    work = RayWork(scratch, rp, work.cand, work.stack, work.nodes)
    for c in range(3):
        out[c] = 0.0
    out[4] = t_hit
    u_total = 0.0
    if n > 0:
        n_el = elementary_intervals(n, rp)
        u_total = rp.el_u0[n_el]
        if scatters_light(scene):
            work = in_scattering(o, d, n_el, scene, quad, work, out)
    return ray_end(o, d, t_hit, s_hit, u_total, scene, quad, work, out)


@njit(**NJIT)
def render_pixels(camera, scene, quad, row0, p0, p1, image, depth, counts):
    """Pixels p0 .. p1 - 1, counted row by row from the start of row row0, into image (H x W x 4, row 0
    at the top), depth (H x W: per pixel, the nearest surface hit t over its samples, inf where none
    hits) and counts (H x W x N_COUNTS: per pixel what its light cost, kernels.lighting.COUNT_*), with their own
    work arrays. nogil: cloudmeta.renderer.single runs bands of rows on several threads.

    camera: a records.Camera (right and up scaled to the half-extent of the image plane at distance 1);
    scene: a records.SceneRecords; quad: a records.Quadrature. With spp > 1 the samples are stratified
    on a ceil(sqrt(spp))^2 grid and jittered by a hash of (pixel, sample). Each sample's radiance comes
    from the estimator (the module docstring's seam): single_scattering.
    """
    width, spp = camera.width, camera.spp
    strata = int(math.ceil(math.sqrt(spp)))
    # borrowed records cost no reference counting in the per-node loops (kernels.borrow): the scene and
    # the rule outlive this call, ``own`` holds the work arrays until its end
    own = alloc_ray_work(scene)
    work = borrow(own)
    scene = borrow(scene)
    quad = borrow(quad)
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
            camera_ray(camera, i, j, s, strata, d)
            if misses_root_boxes(camera.position, d, scene.media.bvh) and misses_surfaces(camera.position, d,
                                                                                           scene.surfaces):
                background_sample(scene.background, d, px_out)  # nothing on the ray: the background, at once
            else:
                work = single_scattering(camera.position, d, scene, quad, work, px_out)
            acc0 += px_out[0]
            acc1 += px_out[1]
            acc2 += px_out[2]
            acc3 += px_out[3]
            nearest = min(nearest, px_out[4])
        own, work = hold_grown(own, work)
        depth[i, j] = nearest
        tally = work.nodes.count
        for q in range(tally.shape[0]):
            counts[i, j, q] = tally[q]
            tally[q] = 0.0
        image[i, j, 0] = acc0 / spp
        image[i, j, 1] = acc1 / spp
        image[i, j, 2] = acc2 / spp
        image[i, j, 3] = 1.0 - acc3 / spp  # alpha = 1 - T(0, t_end)
    release(own)


