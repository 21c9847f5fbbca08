"""A blob: metaballs that share one kernel and one threshold (docs/model.md §1).

The constructor validates everything once and packs the balls into the flat arrays the kernels read:
each ball becomes a centre and a 3x3 matrix ``frame`` = S^-1 Q^T that maps a point into the ball's unit
frame, where u(x) = |frame (x - c)|^2. Spheres are the case S = R I, Q = I, so one code path serves both.
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..kernels.kinds import FALLOFFS
from .limits import LENGTH_RANGE, MAX_BLOBBINESS, MAX_WEIGHT, THRESHOLD_RANGE


def is_real(x):
    """True for an int or float (numpy's too); bool is not a number."""
    return isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, (bool, np.bool_))


def real_number(name, value, check=None, expect="a finite number"):
    """``value`` as a float, or InputError naming ``name``: a finite int or float (not a bool, not text)
    that passes ``check``."""
    ok = is_real(value)
    if ok:
        try:
            ok = bool(np.isfinite(value)) and (check is None or bool(check(value)))
        except (OverflowError, TypeError):
            ok = False
    if not ok:
        raise InputError(f"{name}: expected {expect}, got {value!r}"[:200])
    return float(value)


def real_array(name, value, dtype=np.float64):
    """``value`` as a float64 array of real numbers, or InputError naming ``name`` (ragged lists, text and
    booleans are refused rather than converted)."""
    try:
        raw = np.asarray(value)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected an array of numbers, got a ragged or mixed sequence") from None
    if raw.dtype.kind not in "iuf" and not (raw.dtype.kind == "O" and all(is_real(v) for v in raw.flat)):
        what = "booleans" if raw.dtype.kind == "b" else f"dtype {raw.dtype}"
        raise InputError(f"{name}: expected an array of real numbers, got {what}")
    try:
        with np.errstate(over="ignore"):
            return raw.astype(dtype)
    except (TypeError, ValueError, OverflowError) as exc:
        raise InputError(f"{name}: expected an array of numbers ({exc})"[:200]) from None


def _finite_array(name, value, shape_tail, dtype=np.float64):
    arr = real_array(name, value, dtype)
    if shape_tail is not None:
        want = len(shape_tail) + 1
        if arr.ndim != want or tuple(arr.shape[1:]) != tuple(shape_tail):
            tail = "".join(f", {s}" for s in shape_tail)
            raise InputError(f"{name}: expected shape (N{tail}), got {arr.shape}")
    bad = np.argwhere(~np.isfinite(arr))
    if len(bad):
        raise InputError(f"{name}[{', '.join(str(int(i)) for i in bad[0])}]: expected a finite number, got {arr[tuple(bad[0])]}")
    return arr


def rotation_matrix(angles_deg):
    """Q = Rz(az) Ry(ay) Rx(ax) for angles [ax, ay, az] in degrees (docs/model.md §9); accepts (..., 3)."""
    a = np.radians(np.asarray(angles_deg, dtype=np.float64))
    cx, cy, cz = np.cos(a[..., 0]), np.cos(a[..., 1]), np.cos(a[..., 2])
    sx, sy, sz = np.sin(a[..., 0]), np.sin(a[..., 1]), np.sin(a[..., 2])
    q = np.empty(a.shape[:-1] + (3, 3))
    q[..., 0, 0] = cz * cy
    q[..., 0, 1] = cz * sy * sx - sz * cx
    q[..., 0, 2] = cz * sy * cx + sz * sx
    q[..., 1, 0] = sz * cy
    q[..., 1, 1] = sz * sy * sx + cz * cx
    q[..., 1, 2] = sz * sy * cx - cz * sx
    q[..., 2, 0] = -sy
    q[..., 2, 1] = cy * sx
    q[..., 2, 2] = cy * cx
    return q


class Blob:
    """Metaballs with one kernel and one threshold T; the inside is F(x) >= T.

    Parameters
    ----------
    centers : (N, 3) ball centres.
    radii : (N,) sphere radii, or (N, 3) ellipsoid radii along the columns of each rotation.
    weights : (N,) weights q_i (any real; negative weights carve). A scalar applies to every ball.
    kernel : ``wyvill6`` (default), ``murakami4``, ``nishimura`` or ``blinn`` (docs/model.md §1).
    threshold : T > 0 (default 0.5).
    rotations : optional (N, 3) angles [ax, ay, az] in degrees, Q = Rz Ry Rx, or (N, 3, 3) matrices.
    blobbiness : b of the ``blinn`` kernel, k(u) = exp(-b u) (default 4).
    """

    def __init__(self, centers, radii, weights=1.0, kernel="wyvill6", threshold=0.5, rotations=None,
                 blobbiness=4.0):
        centers = _finite_array("centers", centers, (3,))
        n = len(centers)
        if n == 0:
            raise InputError("centers: a blob needs at least one ball")
        radii = _finite_array("radii", radii, None)
        if radii.ndim == 1 and radii.shape == (n,):
            radii3 = np.repeat(radii[:, None], 3, axis=1)
        elif radii.shape == (n, 3):
            radii3 = radii
        else:
            raise InputError(f"radii: expected shape ({n},) or ({n}, 3) to match centers, got {radii.shape}")
        bad = np.argwhere(radii3 <= 0)
        if len(bad):
            i = int(bad[0][0])
            raise InputError(f"radii[{i}]: expected a radius > 0, got {radii[i]}")
        weights = _finite_array("weights", weights, None)
        if weights.ndim == 0:
            weights = np.full(n, float(weights))
        if weights.shape != (n,):
            raise InputError(f"weights: expected shape ({n},) to match centers, got {weights.shape}")
        if not (isinstance(kernel, str) and kernel in FALLOFFS):
            raise InputError(f"kernel: expected one of {', '.join(FALLOFFS)}, got {kernel!r}"[:200])
        lo, hi = THRESHOLD_RANGE
        threshold = real_number("threshold", threshold, lambda v: lo <= v <= hi,
                                f"a finite number > 0, from {lo:g} to {hi:g}")
        blobbiness = real_number("blobbiness", blobbiness, lambda v: 0 < v <= MAX_BLOBBINESS,
                                 f"a finite number > 0 and <= {MAX_BLOBBINESS:g}")
        # the numeric domain (docs/model_notes.md): every square and ratio of squares of lengths stays far
        # inside the double range, and F - T is resolved to far better than the threshold
        far = np.flatnonzero(np.abs(centers).max(axis=1) > LENGTH_RANGE[1])
        if len(far):
            raise InputError(f"centers[{far[0]}]: expected coordinates within +-{LENGTH_RANGE[1]:g}, "
                             f"got {centers[far[0]].tolist()}")
        bad = np.argwhere((radii3 < LENGTH_RANGE[0]) | (radii3 > LENGTH_RANGE[1]))
        if len(bad):
            i = int(bad[0][0])
            raise InputError(f"radii[{i}]: expected a radius from {LENGTH_RANGE[0]:g} to {LENGTH_RANGE[1]:g}, "
                             f"got {radii[i]}")
        heavy = np.flatnonzero(np.abs(weights) > MAX_WEIGHT * threshold)
        if len(heavy):
            raise InputError(f"weights[{heavy[0]}]: expected |weight| <= {MAX_WEIGHT:g} x threshold, "
                             f"got {weights[heavy[0]]:g}")
        if rotations is None:
            q = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
        else:
            rot = _finite_array("rotations", rotations, None)
            if rot.shape == (n, 3):
                q = rotation_matrix(rot)
            elif rot.shape == (n, 3, 3):
                q = rot
                err = np.abs(np.einsum("nji,njk->nik", q, q) - np.eye(3)).max(axis=(1, 2))
                bad = np.flatnonzero(err > 1e-9)
                if len(bad):
                    raise InputError(f"rotations[{bad[0]}]: expected an orthonormal 3x3 matrix")
            else:
                raise InputError(f"rotations: expected shape ({n}, 3) in degrees or ({n}, 3, 3), got {rot.shape}")

        if rotations is not None and rot.shape == (n, 3) and np.abs(rot).max() > 1e6:
            raise InputError("rotations: expected angles in degrees within +-1e6")

        self.kernel = kernel
        self.kernel_id = FALLOFFS[kernel]
        self.threshold = float(threshold)
        self.blobbiness = float(blobbiness)
        self.centers = np.ascontiguousarray(centers)
        self.radii = np.ascontiguousarray(radii3)
        self.weights = np.ascontiguousarray(weights)
        self.rotations = np.ascontiguousarray(q)
        # u(x) = |frame (x - c)|^2 with frame = S^-1 Q^T
        self.frames = np.ascontiguousarray(self.rotations.transpose(0, 2, 1) / self.radii[:, :, None])
        # axis-aligned box of each support: half-width along axis k is |row k of Q S|
        half = np.sqrt(np.einsum("nkj,nj->nk", self.rotations ** 2, self.radii ** 2))
        self.bounds = np.ascontiguousarray(np.concatenate([centers - half, centers + half], axis=1))
        self._bvh = None
        for arr in (self.centers, self.radii, self.weights, self.rotations, self.frames, self.bounds):
            arr.setflags(write=False)

    def __len__(self):
        return len(self.centers)

    def __repr__(self):
        return f"Blob({len(self)} balls, kernel={self.kernel!r}, threshold={self.threshold})"

    @property
    def is_sphere(self):
        """(N,) True where a ball is a sphere (equal radii)."""
        return np.all(self.radii == self.radii[:, :1], axis=1)

    @property
    def bbox(self):
        """(lo, hi) of the union of the balls' supports."""
        return self.bounds[:, :3].min(axis=0), self.bounds[:, 3:].max(axis=0)

    def inside_bbox(self):
        """(lo, hi) of the union of the supports of the balls of positive weight: the inside F >= T (T > 0)
        lies within it, since outside every positive ball F <= 0. A cloud cut flat by one wide negative ball
        (cloudmeta generate) is boxed tightly. The bbox when no ball is positive (nothing is inside)."""
        positive = self.bounds[self.weights > 0]
        if len(positive) == 0:
            return self.bbox
        return positive[:, :3].min(axis=0), positive[:, 3:].max(axis=0)

    @property
    def bvh(self):
        """(node_box, node_a, node_b, node_n, items): the BVH over the supports, built on first use."""
        if self._bvh is None:
            from ..kernels.bvh import build_bvh  # here: numba loads only when a BVH is first built
            self._bvh = build_bvh(self.bounds, 0)
        return self._bvh

    @property
    def diagonal(self):
        lo, hi = self.bbox
        return float(np.linalg.norm(hi - lo))

    @property
    def scale(self):
        """The length that root tolerances are relative to: length_scale of the balls' supports (the
        diagonal, unless some balls lie far from the rest)."""
        return length_scale(self.bounds)


#: a gap along an axis this many times wider than the groups on either side of it separates them: the
#: geometry beyond it sets no tolerance of the geometry here
FAR_GAP = 10.0


def length_scale(bounds):
    """The scale of root tolerances and of quadrature steps for balls whose supports have the boxes
    ``bounds`` (N, 6) = [lo, hi]: the largest bounding-box diagonal among the groups that far gaps separate.
    The balls are split, axis by axis and again within each part, wherever the gap between the parts is
    more than FAR_GAP times wider than either part along that axis; a stray ball far from a cloud then does
    not loosen the cloud's tolerances. Without such a gap this is the diagonal itself, bit for
    bit."""
    bounds = np.asarray(bounds, np.float64)
    lo_all, hi_all = bounds[:, :3].min(axis=0), bounds[:, 3:].max(axis=0)
    diagonal = float(np.linalg.norm(hi_all - lo_all))
    groups, parts = [], [np.arange(len(bounds))]
    while parts:
        idx = parts.pop()
        cut = _far_cut(bounds, idx)
        if cut is None:
            groups.append(idx)
        else:
            parts.extend(cut)
    if len(groups) == 1:
        return diagonal
    return max(float(np.linalg.norm(bounds[g, 3:].max(axis=0) - bounds[g, :3].min(axis=0))) for g in groups)


def _far_cut(bounds, idx):
    """The two parts of the balls ``idx`` on either side of the first far gap along x, y or z, or None."""
    for axis in range(3):
        lo, hi = bounds[idx, axis], bounds[idx, 3 + axis]
        order = np.argsort(lo, kind="stable")
        lo, hi = lo[order], hi[order]
        reach = np.maximum.accumulate(hi)                  # the right end of everything so far
        after = np.maximum.accumulate(hi[::-1])[::-1]      # the right end of everything from k on
        gaps = lo[1:] - reach[:-1]
        left = reach[:-1] - lo[0]                          # the left part's extent along the axis
        right = after[1:] - lo[1:]                         # the right part's extent
        far = np.flatnonzero(gaps > FAR_GAP * np.maximum(left, right))
        if len(far):
            k = int(far[0]) + 1
            return [idx[order[:k]], idx[order[k:]]]
    return None
