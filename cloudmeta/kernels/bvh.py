"""A bounding-volume hierarchy over the balls' supports (axis-aligned boxes), built and walked in numba.

Layout, flat: node_box (K, 6) = [lo, hi]; a leaf has node_n > 0 and holds items[node_a : node_a + node_n];
an inner node has node_n == 0 and children node_a (left) and node_b (right). ``items`` are ball indices
(global, so that the media can share one list of balls). A leaf's items are all candidates: testing each
ball's box would cost as much as the chord test that follows. The build splits at the middle of the longest axis of the centres' box (falling back to
the median when everything lands on one side), which is O(N log N) and needs no sort.
"""
import numpy as np
from numba import njit

from .config import NJIT, NJIT_INLINE

LEAF_SIZE = 4
STACK = 64


@njit(**NJIT)
def build_bvh(bounds, first_index):
    """BVH over boxes bounds (N, 6); items are first_index + local index. Returns
    (node_box, node_a, node_b, node_n, items)."""
    n = bounds.shape[0]
    items = np.arange(n) + first_index
    local = np.arange(n)
    cap = max(1, 2 * n)
    node_box = np.empty((cap, 6))
    node_a = np.zeros(cap, np.int64)
    node_b = np.zeros(cap, np.int64)
    node_n = np.zeros(cap, np.int64)
    centre = 0.5 * (bounds[:, :3] + bounds[:, 3:])
    # explicit stack of (node, start, end)
    st_node = np.empty(STACK * 2, np.int64)
    st_s = np.empty(STACK * 2, np.int64)
    st_e = np.empty(STACK * 2, np.int64)
    st_depth = np.empty(STACK * 2, np.int64)
    n_nodes = 1
    st_node[0] = 0
    st_s[0] = 0
    st_e[0] = n
    st_depth[0] = 0
    top = 1
    while top > 0:
        top -= 1
        node = st_node[top]
        s = st_s[top]
        e = st_e[top]
        depth = st_depth[top]
        lo = np.full(3, np.inf)
        hi = np.full(3, -np.inf)
        clo = np.full(3, np.inf)
        chi = np.full(3, -np.inf)
        for k in range(s, e):
            i = local[k]
            for c in range(3):
                lo[c] = min(lo[c], bounds[i, c])
                hi[c] = max(hi[c], bounds[i, 3 + c])
                clo[c] = min(clo[c], centre[i, c])
                chi[c] = max(chi[c], centre[i, c])
        for c in range(3):
            node_box[node, c] = lo[c]
            node_box[node, 3 + c] = hi[c]
        if e - s <= LEAF_SIZE or depth >= STACK - 2:  # the depth cap keeps the walk's stack bounded
            node_a[node] = s
            node_n[node] = e - s
            continue
        axis = 0
        for c in range(1, 3):
            if chi[c] - clo[c] > chi[axis] - clo[axis]:
                axis = c
        mid = 0.5 * (clo[axis] + chi[axis])
        # partition local[s:e] by centre < mid
        i = s
        j = e - 1
        while i <= j:
            if centre[local[i], axis] < mid:
                i += 1
            else:
                local[i], local[j] = local[j], local[i]
                j -= 1
        m = i
        if m == s or m == e:
            m = (s + e) // 2  # all centres coincide along the axis: split the list in half
        left = n_nodes
        right = n_nodes + 1
        n_nodes += 2
        node_a[node] = left
        node_b[node] = right
        node_n[node] = 0
        st_node[top] = right
        st_s[top] = m
        st_e[top] = e
        st_depth[top] = depth + 1
        top += 1
        st_node[top] = left
        st_s[top] = s
        st_e[top] = m
        st_depth[top] = depth + 1
        top += 1
    for k in range(n):
        items[k] = local[k] + first_index
    return node_box[:n_nodes].copy(), node_a[:n_nodes].copy(), node_b[:n_nodes].copy(), node_n[:n_nodes].copy(), items


@njit(**NJIT_INLINE)
def _slab(o, inv, lo, hi, t0, t1):
    """One axis of the slab test: the ray's [t0, t1] clipped to the slab [lo, hi] (a NaN bound, 0 * inf
    for a ray in the slab's plane, clips nothing)."""
    ta = (lo - o) * inv
    tb = (hi - o) * inv
    if ta > tb:
        ta, tb = tb, ta
    if ta > t0:
        t0 = ta
    if tb < t1:
        t1 = tb
    return t0, t1


@njit(**NJIT_INLINE)
def ray_box(ox, oy, oz, ix, iy, iz, node_box, k, tmin, tmax):
    """Slab test: does the ray (origin o, inverse direction i) meet box k within [tmin, tmax]?"""
    t0, t1 = _slab(ox, ix, node_box[k, 0], node_box[k, 3], tmin, tmax)
    if t0 > t1:
        return False
    t0, t1 = _slab(oy, iy, node_box[k, 1], node_box[k, 4], t0, t1)
    if t0 > t1:
        return False
    t0, t1 = _slab(oz, iz, node_box[k, 2], node_box[k, 5], t0, t1)
    return t0 <= t1


@njit(**NJIT_INLINE)
def _walk(o, ix, iy, iz, tmin, tmax, bvh, root, stack, cand):
    """Ball indices of the leaves whose boxes the ray (origin o, inverse direction i) meets within [tmin,
    tmax], into cand, depth first (right child first); returns their number."""
    ox, oy, oz = o[0], o[1], o[2]
    node_box, node_a, node_b, node_n, items = bvh.node_box, bvh.node_a, bvh.node_b, bvh.node_n, bvh.items
    n = 0
    if not ray_box(ox, oy, oz, ix, iy, iz, node_box, root, tmin, tmax):
        return 0
    stack[0] = root
    top = 1
    while top > 0:
        top -= 1
        node = stack[top]
        if node_n[node] > 0:
            for k in range(node_a[node], node_a[node] + node_n[node]):
                cand[n] = items[k]
                n += 1
            continue
        left = node_a[node]
        right = node_b[node]
        if ray_box(ox, oy, oz, ix, iy, iz, node_box, left, tmin, tmax):
            stack[top] = left
            top += 1
        if ray_box(ox, oy, oz, ix, iy, iz, node_box, right, tmin, tmax):
            stack[top] = right
            top += 1
    return n


@njit(**NJIT)
def bvh_candidates(o, d, tmin, tmax, bvh, root, stack, cand):
    """Ball indices whose boxes the ray meets within [tmin, tmax], into cand; returns their number.
    bvh: a records.BVH (its node arrays; ``root`` the node to start from)."""
    ix = 1.0 / d[0] if d[0] != 0.0 else np.inf
    iy = 1.0 / d[1] if d[1] != 0.0 else np.inf
    iz = 1.0 / d[2] if d[2] != 0.0 else np.inf
    return _walk(o, ix, iy, iz, tmin, tmax, bvh, root, stack, cand)


@njit(**NJIT)
def bvh_point_candidates(x, bvh, root, stack, cand):
    """Ball indices whose boxes hold the point x (bounds included), into cand; returns their number.
    The walk of a ray from x along (1, 1, 1) over t in [0, 0]: the slab test then reduces to
    lo - x <= 0 <= hi - x on every axis, exact in floating point."""
    return _walk(x, 1.0, 1.0, 1.0, 0.0, 0.0, bvh, root, stack, cand)


@njit(**NJIT_INLINE)
def misses_root_boxes(o, d, bvh):
    """Whether the ray misses the root box of every blob of a records.BVH."""
    ix = 1.0 / d[0] if d[0] != 0.0 else np.inf
    iy = 1.0 / d[1] if d[1] != 0.0 else np.inf
    iz = 1.0 / d[2] if d[2] != 0.0 else np.inf
    for m in range(bvh.root.shape[0]):
        if ray_box(o[0], o[1], o[2], ix, iy, iz, bvh.node_box, bvh.root[m], 0.0, np.inf):
            return False
    return True
