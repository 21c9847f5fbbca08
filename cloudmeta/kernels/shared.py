"""The approximate mode's shared method (docs/approximate.md, "Shared"): the light of orders >= 2 (and >= 1 of the
environment) that a point of a camera ray scatters towards the camera, estimated at fixed optical depths of
sparse camera rays by the tails of the unbiased estimator's paths (kernels.multiple), for the driver
(renderer.shared) to share between neighbouring pixels at equal optical depth.

A tail is what a path of kernels.multiple.ray_paths adds after its first vertex, started at the point x of
the camera ray where its optical depth is tau instead of at a random depth: the weight sigma_s / sigma_t at
x, a direction from the phase function of a medium picked by sigma_s,m, then tracked vertices with their
next-event estimates and the environment seen by an escaping flight, Russian roulette relative to the
weight at x. Its mean is Q(tau) = sigma_s / sigma_t J(x), and a pixel's multiply scattered light is the
integral of e^-tau Q(tau) over its ray's optical depth. With a cache of the deep orders (records.FluenceCache),
a tail stops at its vertex of order cache.order and adds what that vertex scatters of the cached light instead.

Random numbers are keyed by (seed, the sample ray's key, node, tail): a sample ray's tails depend on
nothing else, so any number of threads and any tile give the same values.
"""
import numpy as np
from numba import njit

from .config import NJIT
from .bvh import misses_root_boxes
from .camera import camera_ray, background_gives_light
from .fluence import SH_TERMS, cached_light
from .intervals import alloc_ray_work
from .multiple import DIM_MEDIUM, DIM_ROULETTE, locate_depth, scattering_mix, trace_segment, tracked_vertex
from .records import PathKey
from .sampling import sample_phase_cos, sobol4, turn, uniform

#: the stream's keys of a sample ray's nodes: key = ray key x NODE_KEYS + node (more nodes than this are refused
#: by the driver)
NODE_KEYS = 64


@njit(**NJIT)
def depth_tails(camera, scene, quad, settings, grid, volumes, cache, rows, cols, keys, taus, tails, seed, track, q_mean,
                q_var, depth):
    """For each sample camera ray q through the centre of pixel (rows[q], cols[q]) (any integers: the
    frame's border may lie beyond the last row): depth[q] its optical depth up to the first surface, and at
    each node a with taus[a] < depth[q], the mean of tails[a] tails started where the ray's optical depth is
    taus[a] into q_mean[q, a] (RGB) and the variance of that mean into q_var[q, a]; NaN at nodes the ray does
    not reach. keys[q] keys the ray's random streams. camera: spp 1; settings a records.PathSettings (paths
    unused); grid, volumes: the tracked flights' records; cache a records.FluenceCache (order 0: none); track a
    records.TrackWork (received, not allocated here: kernels.multiple.tracked_vertex says why)."""
    work = alloc_ray_work(scene)
    camera_work = alloc_ray_work(scene)
    d = np.empty(3)
    o = np.empty(3)
    dd = np.empty(3)
    d_new = np.empty(3)
    light = np.empty(3)
    est = np.empty(3)
    x0 = np.empty(3)
    sums = np.empty(6)  # a node's sums of the tails' estimates and their squares
    harmonics = np.empty(SH_TERMS)
    has_env = background_gives_light(scene.background)
    max_order, rr_order, tol_t = settings.max_order, settings.rr_order, quad.tol_t
    n_tau = taus.shape[0]
    for q in range(rows.shape[0]):
        depth[q] = 0.0
        for a in range(n_tau):
            for c in range(3):
                q_mean[q, a, c] = np.nan
                q_var[q, a, c] = np.nan
        camera_ray(camera, rows[q], cols[q], 0, 1, d)
        if misses_root_boxes(camera.position, d, scene.media.bvh):
            continue
        camera_work, n_el, u_total, _ = trace_segment(camera.position, d, scene, tol_t, camera_work)
        depth[q] = u_total
        if n_el == 0:
            continue
        rp = camera_work.pieces
        for a in range(n_tau):
            n_tails = tails[a]
            if taus[a] >= u_total or n_tails == 0:
                continue
            k, s, t = locate_depth(taus[a], n_el, rp)
            for c in range(3):
                x0[c] = camera.position[c] + t * d[c]
            sums[:] = 0.0
            stream = keys[q] * NODE_KEYS + a
            for tail in range(n_tails):
                key = PathKey(seed, stream, tail)
                for c in range(3):
                    est[c] = 0.0
                ratio, m = scattering_mix(k, s, rp, scene.media, uniform(seed, stream, tail, 0, DIM_MEDIUM))
                if ratio > 0.0:
                    work = _tail(x0, d, ratio, m, key, scene, grid, volumes, cache, tol_t, has_env, max_order, rr_order,
                                 work, track, o, dd, d_new, light, est, harmonics)
                for c in range(3):
                    sums[c] += est[c]
                    sums[3 + c] += est[c] * est[c]
            for c in range(3):
                mu = sums[c] / n_tails
                q_mean[q, a, c] = mu
                var = (sums[3 + c] - n_tails * mu * mu) / (n_tails - 1) if n_tails > 1 else np.inf
                q_var[q, a, c] = max(var, 0.0) / n_tails


@njit(**NJIT)
def _tail(x0, d, ratio, m, key, scene, grid, volumes, cache, tol_t, has_env, max_order, rr_order, work, track, o,
          dd, d_new, light, est, harmonics):
    """One tail from x0 (the camera ray's direction d, the weight ratio = sigma_s / sigma_t there, the medium m
    that turns it) into est; kernels.multiple.ray_paths's loop after its first vertex, up to the vertex whose
    next event is order cache.order, where what it scatters of the cached light (records.FluenceCache) stands in
    for the rest of the walk. Returns work, grown if a flight needed more room."""
    seed, stream, tail = key.seed, key.pixel, key.path
    for c in range(3):
        o[c] = x0[c]
        dd[c] = d[c]
    _, u_cos, u_phi, u_lobe = sobol4(seed, stream, tail, 0)
    weight = ratio
    for n_vert in range(1, max_order + 1):
        if n_vert == max_order and not has_env:
            return work
        if n_vert >= rr_order:  # ray_paths's roulette after vertex n_vert - 1, relative to the weight at x0
            survive = min(1.0, weight / ratio)
            if uniform(seed, stream, tail, n_vert - 1, DIM_ROULETTE) >= survive:
                return work
            weight /= survive
        ph = scene.media.phase[m]
        cos_theta = sample_phase_cos(ph[0], ph[1], ph[2], ph[3], u_lobe, u_cos)
        turn(dd, cos_theta, u_phi, d_new)
        for c in range(3):
            dd[c] = d_new[c]
        work, weight, m, u_cos, u_phi, u_lobe, done = tracked_vertex(
            o, dd, n_vert, weight, key, scene, grid, volumes, tol_t, has_env, max_order, work, track, light, est)
        if done or weight <= 0.0:
            return work
        if n_vert + 1 == cache.order:  # the walk's expected rest: what the vertex scatters of the cached light
            r, g, b = cached_light(cache, o, dd, m, harmonics)
            est[0] += weight * r
            est[1] += weight * g
            est[2] += weight * b
            return work
    return work
