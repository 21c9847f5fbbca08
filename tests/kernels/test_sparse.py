"""The fit's sparse kernels (cloudmeta.kernels.sparse) against numpy and scipy: the kernel columns equal a
dense evaluation at every voxel centre, the transpose and the products equal scipy's, and the products give
the same bits on one thread as on several."""
import numba
import numpy as np
import scipy.sparse as sp

from cloudmeta.kernels import sparse


def _dense_columns(idx, radius, h, shape):
    """Every voxel centre against every ball, in numpy (the twin of kernel_columns)."""
    a, b, c = np.meshgrid(*(np.arange(n) for n in shape), indexing="ij")
    vox = np.stack([a.ravel(), b.ravel(), c.ravel()], axis=1).astype(float)
    d = (vox[:, None, :] - idx[None, :, :]) * h
    u = (d ** 2).sum(axis=2) / radius[None, :] ** 2
    return np.where(u < 1.0, (1.0 - u) ** 2 * (1.0 - 4.0 * u / 9.0), 0.0)


def _random_columns(rng, n=40, shape=(9, 11, 7)):
    h = np.array([0.1, 0.12, 0.09])
    idx = rng.uniform(-1.5, np.array(shape) + 0.5, size=(n, 3))   # some centres outside the grid
    radius = rng.uniform(0.05, 0.45, size=n)
    return idx, radius, h, np.array(shape, dtype=np.int64)


def _gradient(ptr, idx, val, x, y, blocks):
    bounds = np.linspace(0, len(y), blocks + 1).astype(np.int64)
    r = np.empty(len(y), np.float32)
    g = np.empty(len(x), np.float32)
    sparse.gradient(ptr, idx.view(np.uint32), val, bounds, x, y, r, np.empty((blocks, len(x))), g)
    return r, g


def test_kernel_columns_equal_a_dense_evaluation():
    rng = np.random.default_rng(3)
    idx, radius, h, shape = _random_columns(rng)
    indptr, rows, vals = sparse.kernel_columns(idx, radius, h, shape)
    A = sp.csc_matrix((vals, rows, indptr), shape=(int(np.prod(shape)), len(radius))).toarray()
    want = _dense_columns(idx, radius, h, shape)
    np.testing.assert_allclose(A, want, rtol=1e-6, atol=1e-7)
    assert ((A > 0) == (want > 0)).all()
    for j in range(len(radius)):                                   # rows ascending within a column
        assert (np.diff(rows[indptr[j]:indptr[j + 1]]) > 0).all()
    assert indptr[-1] > 100


def test_compact_transpose_and_products_equal_scipy():
    rng = np.random.default_rng(5)
    idx, radius, h, shape = _random_columns(rng, n=60)
    indptr, rows, vals = sparse.kernel_columns(idx, radius, h, shape)
    used, local = sparse.compact_rows(rows, np.int64(np.prod(shape)))
    assert np.array_equal(used, np.unique(rows)) and np.array_equal(used[local], rows)
    m, n = len(used), len(radius)
    A = sp.csc_matrix((vals, local, indptr), shape=(m, n))
    tptr, tidx, tval = sparse.transpose(indptr, local, vals, np.int64(m), np.int64(7))
    R = sp.csr_matrix((tval, tidx, tptr), shape=(m, n))
    assert np.array_equal(R.toarray(), A.toarray())
    x = rng.random(n).astype(np.float32)
    y = rng.random(m).astype(np.float32)
    r, g = _gradient(tptr, tidx, tval, x, y, blocks=5)
    np.testing.assert_allclose(r, A.astype(float) @ x - y, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(g, A.T.astype(float) @ (A.astype(float) @ x - y), rtol=1e-5, atol=1e-5)
    scaled = np.empty_like(vals)
    norms = sparse.scale_columns(indptr, vals, scaled)
    want = np.sqrt((A.astype(float).power(2)).sum(axis=0)).A1
    assert (want == 0).any()                                        # an empty column's norm is taken as 1
    np.testing.assert_allclose(norms, np.where(want == 0, 1.0, want), rtol=1e-6)
    col = np.repeat(np.arange(n), np.diff(indptr))
    np.testing.assert_allclose(scaled, vals / norms[col], rtol=1e-6)
    w, v = rng.random(n), rng.random(m)
    out = np.empty(m)
    sparse.column_sum(indptr, local, vals, w, out)
    np.testing.assert_allclose(out, A.astype(float) @ w, rtol=1e-12)
    out = np.empty(n)
    sparse.column_dots(indptr, local, vals, v, out)
    np.testing.assert_allclose(out, A.T.astype(float) @ v, rtol=1e-12)
    keep = rng.random(n) < 0.6
    kp, ki, kv = sparse.select_columns(indptr, local, vals, keep)
    assert np.array_equal(sp.csc_matrix((kv, ki, kp), shape=(m, keep.sum())).toarray(), A.toarray()[:, keep])


def test_transpose_whatever_the_blocks():
    rng = np.random.default_rng(2)
    idx, radius, h, shape = _random_columns(rng, n=80)
    indptr, rows, vals = sparse.kernel_columns(idx, radius, h, shape)
    n_rows = np.int64(np.prod(shape))
    first = sparse.transpose(indptr, rows, vals, n_rows, np.int64(1))
    for blocks in (3, 64, 2000):                     # more blocks than rows holding entries
        again = sparse.transpose(indptr, rows, vals, n_rows, np.int64(blocks))
        assert all(np.array_equal(a, b) for a, b in zip(first, again))


def test_products_are_the_same_on_any_number_of_threads():
    rng = np.random.default_rng(8)
    idx, radius, h, shape = _random_columns(rng, n=300, shape=(20, 18, 16))
    radius *= 3
    indptr, rows, vals = sparse.kernel_columns(idx, radius, h, shape)
    used, local = sparse.compact_rows(rows, np.int64(np.prod(shape)))
    tptr, tidx, tval = sparse.transpose(indptr, local, vals, np.int64(len(used)), np.int64(16))
    x = rng.random(len(radius)).astype(np.float32)
    y = rng.random(len(used)).astype(np.float32)
    outs = []
    threads = numba.get_num_threads()
    try:
        for k in sorted({1, threads}):
            numba.set_num_threads(k)
            r, g = _gradient(tptr, tidx, tval, x, y, blocks=7)
            again = sparse.kernel_columns(idx, radius, h, shape)
            outs.append((r, g, again))
    finally:
        numba.set_num_threads(threads)
    for r, g, again in outs[1:]:
        assert np.array_equal(r, outs[0][0]) and np.array_equal(g, outs[0][1])
        assert all(np.array_equal(a, b) for a, b in zip(again, outs[0][2]))
