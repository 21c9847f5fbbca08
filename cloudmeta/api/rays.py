"""The exact ray-metaball engine, vectorised over rays: roots, inside segments, optical depth, the first
hit of an opaque surface; and the field, its gradient and the surface normal at points.

Each function validates its input once, normalises the ray directions (t is arc length) and calls one
parallel numba kernel.
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..kernels.kinds import DENSITY_MODES
from ..kernels.records import BVH, BlobRecord, Rays, TraceOut
from ..kernels.batch import field_at, first_hits, gradient_at, trace_rays
from ..renderer.threads import n_chunks
from ..scene.blob import Blob, real_array, real_number
from ..scene.limits import LENGTH_RANGE

#: default root tolerance, relative to the blob's bounding-box diagonal (docs/model.md §3)
ROOT_TOLERANCE = 1e-9


def _points(name, value, bound=LENGTH_RANGE[1]):
    """(N, 3) float64 of finite numbers within +-``bound``, or InputError naming ``name`` and the row."""
    arr = real_array(name, value)
    if arr.ndim == 1:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise InputError(f"{name}: expected shape (N, 3) or (3,), got {arr.shape}")
    bad = np.flatnonzero(~np.isfinite(arr).all(axis=1))
    if len(bad):
        raise InputError(f"{name}[{bad[0]}]: expected finite coordinates, got {arr[bad[0]]}")
    far = np.flatnonzero(np.abs(arr).max(axis=1, initial=0.0) > bound)
    if len(far):
        raise InputError(f"{name}[{far[0]}]: expected coordinates within +-{bound:g}, got {arr[far[0]]}")
    return arr


def blob_record(blob):
    """The blob as the kernels read it (kernels.records.BlobRecord)."""
    return BlobRecord(blob.centers, blob.frames, blob.weights, blob.kernel_id, blob.blobbiness, blob.threshold)


def blob_bvh(blob):
    """The blob's BVH as a kernels.records.BVH with one root, node 0."""
    return BVH(*blob.bvh, np.zeros(1, np.int64))


def check_blob(blob):
    if not isinstance(blob, Blob):
        raise InputError(f"blob: expected a cloudmeta.Blob, got {type(blob).__name__}")
    return blob


def prepare_rays(origins, directions, t_max=np.inf):
    """Validated (N, 3) origins, unit (N, 3) directions and (N,) t_max, broadcast against each other as
    numpy does: one origin (or direction) goes with every direction (origin), none with one gives no rays."""
    o = _points("origins", origins)
    d = _points("directions", directions, bound=np.inf)  # any magnitude: normalised without overflow
    if len(o) != len(d) and len(o) != 1 and len(d) != 1:
        raise InputError(f"origins, directions: expected the same number of rays, got {len(o)} and {len(d)}")
    n = 0 if 0 in (len(o), len(d)) else max(len(o), len(d))
    # np.array copies: writable and contiguous every time, so numba sees one type and compiles once
    o = np.array(np.broadcast_to(o, (n, 3)))
    # |d| without overflow or underflow: [1e200, 0, 0] and [1e-160, 0, 0] are [1, 0, 0]
    biggest = np.abs(d).max(axis=1)
    bad = np.flatnonzero(biggest == 0.0)
    if len(bad):
        raise InputError(f"directions[{bad[0]}]: expected a non-zero vector")
    d = d / biggest[:, None]
    d = np.array(np.broadcast_to(d / np.linalg.norm(d, axis=1)[:, None], (n, 3)))
    tm = real_array("t_max", t_max)
    if tm.ndim == 0:
        tm = np.full(n, float(tm))
    if tm.shape != (n,):
        raise InputError(f"t_max: expected a number or shape ({n},), got {tm.shape}")
    bad = np.flatnonzero(np.isnan(tm) | (tm <= 0.0))
    if len(bad):
        raise InputError(f"t_max[{bad[0]}]: expected a number > 0 (inf allowed), got {tm[bad[0]]}")
    return o, d, np.array(tm)


def root_tolerance(blob, tolerance=ROOT_TOLERANCE):
    """Absolute tolerance on t: ``tolerance`` times the blob's length (Blob.scale: its bounding-box diagonal,
    unless some balls lie far from the rest)."""
    tolerance = real_number("tolerance", tolerance, lambda v: 0 < v <= 1e-3, "a number > 0 and <= 1e-3")
    return tolerance * blob.scale  # the diagonal, unless balls lie far from the rest


def _trace(blob, origins, directions, t_max, tolerance, density="field", scale=1.0, cap=16, lists=True):
    """tau (N,), and with ``lists`` the per-ray roots and segments (Python lists of arrays: costly for
    millions of rays, so optical_depth skips them)."""
    blob = check_blob(blob)
    if not (isinstance(density, str) and density in DENSITY_MODES):
        raise InputError(f"density: expected one of {', '.join(DENSITY_MODES)}, got {density!r}"[:200])
    scale = real_number("scale", scale, lambda v: 0 <= v <= 1e100, "a finite number >= 0 (and <= 1e100)")
    o, d, tm = prepare_rays(origins, directions, t_max)
    tol = root_tolerance(blob, tolerance)
    n = len(o)
    tau = np.empty(n)
    n_roots = np.empty(n, np.int64)
    n_seg = np.empty(n, np.int64)
    roots = np.empty((n, cap))
    segs = np.empty((n, cap, 2))
    args = (blob_record(blob), blob_bvh(blob), tol, DENSITY_MODES[density], float(scale))
    trace_rays(Rays(o, d, tm), *args, n_chunks(n), TraceOut(tau, n_roots, roots, n_seg, segs))
    if not lists:
        return tau, None, None
    roots_list = [roots[i, :n_roots[i]].copy() for i in range(n)]
    segs_list = [segs[i, :n_seg[i]].copy() for i in range(n)]
    over = np.flatnonzero((n_roots > cap) | (n_seg > cap))
    if len(over):  # rare: rays with many crossings are traced again with room for all of them
        big = int(max(n_roots[over].max(), n_seg[over].max()))
        t2, nr2, r2, ns2, s2 = (np.empty(len(over)), np.empty(len(over), np.int64), np.empty((len(over), big)),
                                np.empty(len(over), np.int64), np.empty((len(over), big, 2)))
        trace_rays(Rays(o[over], d[over], tm[over]), *args, n_chunks(len(over)), TraceOut(t2, nr2, r2, ns2, s2))
        for k, i in enumerate(over):
            roots_list[i] = r2[k, :nr2[k]].copy()
            segs_list[i] = s2[k, :ns2[k]].copy()
    return tau, roots_list, segs_list


def roots(blob, origins, directions, t_max=np.inf, tolerance=ROOT_TOLERANCE):
    """Per ray, the sorted t in (0, t_max) where the ray crosses the isosurface F = T.

    Tangent touches (double roots) are not crossings and are not listed. Returns a list of 1-D arrays.
    """
    return _trace(blob, origins, directions, t_max, tolerance)[1]


def segments(blob, origins, directions, t_max=np.inf, tolerance=ROOT_TOLERANCE):
    """Per ray, the inside intervals [t0, t1] (F >= T) within [0, t_max]: a list of (k, 2) arrays."""
    return _trace(blob, origins, directions, t_max, tolerance)[2]


def optical_depth(blob, origins, directions, t_max=np.inf, density="field", scale=1.0,
                  tolerance=ROOT_TOLERANCE):
    """(N,) exact tau over [0, t_max]: sigma_t = scale * rho, rho per ``density`` (docs/model.md §4)."""
    return _trace(blob, origins, directions, t_max, tolerance, density, scale, lists=False)[0]


def field(blob, points):
    """(N,) F(x) at the points."""
    blob = check_blob(blob)
    p = np.array(_points("points", points))
    out = np.empty(len(p))
    field_at(p, blob_record(blob), out)
    return out


def first_hit(blob, origins, directions, t_max=np.inf, tolerance=ROOT_TOLERANCE):
    """(N,) t where each ray first meets the blob drawn as an opaque surface (docs/model.md §6): the first
    root where F rises through T, 0 where the origin is inside (F >= T), inf where the ray misses it
    within [0, t_max]. Only the first root is searched for, so this is cheaper than ``roots``."""
    blob = check_blob(blob)
    o, d, tm = prepare_rays(origins, directions, t_max)
    out = np.empty(len(o))
    first_hits(Rays(o, d, tm), blob_record(blob), blob_bvh(blob), root_tolerance(blob, tolerance),
               n_chunks(len(o)), out)
    return out


def gradient(blob, points):
    """(N, 3) grad F(x) at the points, analytic: sum_i q_i k'(u_i) grad u_i (0 outside every support;
    ``blinn``'s jump at u = 1 contributes nothing)."""
    blob = check_blob(blob)
    p = np.array(_points("points", points))
    out = np.empty((len(p), 3))
    gradient_at(p, blob_record(blob), out)
    return out


def normal(blob, points):
    """(N, 3) the outward unit normal of the isosurface through each point, -grad F / |grad F| (docs/model.md
    §6: F decreases outwards); nan where the gradient vanishes."""
    g = gradient(blob, points)
    length = np.linalg.norm(g, axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(length > 0, -g / length, np.nan)
