"""Batches of rays through one blob, in parallel: the kernels behind cloudmeta.roots / segments /
optical_depth / first_hit / field / gradient. Each chunk of rays has its own scratch; every ray is independent, so results do
not depend on the number of threads."""
import numpy as np
from numba import njit, prange

from .config import NJIT_INLINE, NJIT_PARALLEL
from .metaball import field_sum, gradient_sum
from .bvh import STACK, bvh_candidates
from .records import BVH, BlobRecord
from .sweep import alloc_scratch, first_entry, pieces_optical_depth, trace_blob

#: chords a fresh scratch holds; rays that meet more grow their chunk's scratch once
INITIAL_CAPACITY = 64


@njit(**NJIT_PARALLEL)
def trace_rays(rays, blob, bvh, tol_t, mode, scale, n_chunks, out):
    """For each ray (a records.Rays) through ``blob`` (a records.BlobRecord; ``bvh`` a records.BVH, root
    0): tau (exact optical depth), the transitions (first cap_out) and the inside segments (adjacent
    pieces merged; first cap_out), into ``out`` (a records.TraceOut). Counts are the true counts, so a
    count above cap_out tells the caller to trace that ray again with more room. Rays are split into
    n_chunks contiguous chunks, one scratch each."""
    # records are unpacked before a prange loop and rebuilt inside it: numba's parfors (0.68) drop the
    # writes made through a record that the loop captures
    origins, dirs, tmax = rays
    centers, frames, weights, kernel, blobbiness, threshold = blob
    node_box, node_a, node_b, node_n, items, root = bvh
    tau, n_roots, roots, n_seg, segs = out
    n_rays = origins.shape[0]
    n_balls = centers.shape[0]
    for chunk in prange(n_chunks):
        blob_c = BlobRecord(centers, frames, weights, kernel, blobbiness, threshold)
        bvh_c = BVH(node_box, node_a, node_b, node_n, items, root)
        scratch = alloc_scratch(min(INITIAL_CAPACITY, n_balls))
        cand = np.empty(n_balls, np.int64)
        stack = np.empty(2 * STACK, np.int64)
        for r in range(chunk * n_rays // n_chunks, (chunk + 1) * n_rays // n_chunks):
            n_cand = bvh_candidates(origins[r], dirs[r], 0.0, tmax[r], bvh_c, 0, stack, cand)
            scratch, n_out, n_tr = trace_blob(origins[r], dirs[r], 0.0, tmax[r], blob_c, tol_t, cand, n_cand, False,
                                              scratch)
            tau[r] = pieces_optical_depth(n_out, mode, threshold, scale, scratch)
            n_roots[r] = n_tr
            for k in range(min(n_tr, roots.shape[1])):
                roots[r, k] = scratch.roots[k]
            n_seg[r] = merge_segments(scratch.out_t0, scratch.out_t1, n_out, segs[r])


@njit(**NJIT_INLINE)
def merge_segments(o_t0, o_t1, n_out, segs):
    """The inside segments of n_out pieces (adjacent pieces merged), the first len(segs) into segs (k, 2);
    returns their number."""
    cap_out = segs.shape[0]
    m = 0
    last_end = -np.inf
    for k in range(n_out):
        if m > 0 and o_t0[k] <= last_end:
            # continues the previous segment across a composite boundary
            last_end = o_t1[k]
            if m <= cap_out:
                segs[m - 1, 1] = last_end
            continue
        if m < cap_out:
            segs[m, 0] = o_t0[k]
            segs[m, 1] = o_t1[k]
        last_end = o_t1[k]
        m += 1
    return m


@njit(**NJIT_PARALLEL)
def field_at(points, blob, out):
    """F(x) = sum_i q_i k(u_i(x)) at every point (all balls of ``blob``, a records.BlobRecord; the grid
    sampler culls)."""
    centers, frames, weights, kernel, blobbiness, threshold = blob  # rebuilt in the loop (see trace_rays)
    n = centers.shape[0]
    items = np.arange(n)
    for p in prange(points.shape[0]):
        out[p] = field_sum(points[p], BlobRecord(centers, frames, weights, kernel, blobbiness, threshold), items,
                           0, n)


@njit(**NJIT_PARALLEL)
def first_hits(rays, blob, bvh, tol_t, n_chunks, out):
    """For each ray (a records.Rays), where it is first inside the blob within [0, t_max]: 0 if it
    starts inside, inf if never (the first root only: what an opaque surface needs)."""
    origins, dirs, tmax = rays  # unpacked before the prange loop, rebuilt in it (see trace_rays)
    centers, frames, weights, kernel, blobbiness, threshold = blob
    node_box, node_a, node_b, node_n, items, root = bvh
    n_rays = origins.shape[0]
    n_balls = centers.shape[0]
    for chunk in prange(n_chunks):
        blob_c = BlobRecord(centers, frames, weights, kernel, blobbiness, threshold)
        bvh_c = BVH(node_box, node_a, node_b, node_n, items, root)
        scratch = alloc_scratch(min(INITIAL_CAPACITY, n_balls))
        cand = np.empty(n_balls, np.int64)
        stack = np.empty(2 * STACK, np.int64)
        for r in range(chunk * n_rays // n_chunks, (chunk + 1) * n_rays // n_chunks):
            n_cand = bvh_candidates(origins[r], dirs[r], 0.0, tmax[r], bvh_c, 0, stack, cand)
            out[r] = np.inf
            if n_cand > 0:
                scratch, out[r] = first_entry(origins[r], dirs[r], 0.0, tmax[r], blob_c, tol_t, cand, n_cand,
                                              scratch)


@njit(**NJIT_PARALLEL)
def gradient_at(points, blob, out):
    """grad F(x) = sum_i q_i k'(u_i) grad u_i at every point (all balls of ``blob``), into out (N, 3)."""
    centers, frames, weights, kernel, blobbiness, threshold = blob  # rebuilt in the loop (see trace_rays)
    n = centers.shape[0]
    items = np.arange(n)
    for p in prange(points.shape[0]):
        gx, gy, gz = gradient_sum(points[p], BlobRecord(centers, frames, weights, kernel, blobbiness, threshold),
                                  items, 0, n)
        out[p, 0] = gx
        out[p, 1] = gy
        out[p, 2] = gz
