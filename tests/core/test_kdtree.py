"""The k-d tree of the registration path (mppf.core.kdtree) against brute-force nearest neighbours."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from mppf.core import kdtree
from mppf.core.kdtree import KDTree


def brute_force(data: np.ndarray, queries: np.ndarray, k: int, bound: float = np.inf):
    """(distances (m, k), indices (m, k)) by sorting every distance; missing: inf and len(data)."""
    dist = np.sqrt(((queries[:, None, :] - data[None, :, :]) ** 2).sum(axis=2))
    order = np.argsort(dist, axis=1, kind="stable")[:, :k]
    near = np.take_along_axis(dist, order, axis=1)
    if k > data.shape[0]:
        pad = k - data.shape[0]
        near = np.hstack([near, np.full((len(queries), pad), np.inf)])
        order = np.hstack([order, np.full((len(queries), pad), data.shape[0])])
    missing = ~(near < bound)
    return np.where(missing, np.inf, near), np.where(missing, data.shape[0], order)


@pytest.fixture(scope="module")
def cloud():
    rng = np.random.default_rng(7)
    data = rng.uniform(-500.0, 500.0, (1500, 3)) * [3.0, 1.5, 0.02]  # a plate-like cloud, mm
    return data, rng.uniform(-600.0, 600.0, (400, 3)) * [3.0, 1.5, 0.02]


def test_one_nearest_neighbour_is_the_brute_force_one(cloud):
    data, queries = cloud
    dist, idx = KDTree(data).query(queries)
    want_dist, want_idx = brute_force(data, queries, 1)
    assert dist.shape == idx.shape == (len(queries),) and idx.dtype == np.intp and dist.dtype == np.float64
    np.testing.assert_array_equal(idx, want_idx[:, 0])
    np.testing.assert_allclose(dist, want_dist[:, 0], rtol=1e-12)
    # the distances are the ones numpy computes from the pairs, bit for bit (icp.Nearest recomputes them)
    np.testing.assert_array_equal(dist, np.sqrt(((queries - data[idx]) ** 2).sum(axis=1)))


@pytest.mark.parametrize("k", [2, 5, 16])
def test_k_nearest_neighbours_in_order(cloud, k):
    data, queries = cloud
    dist, idx = KDTree(data).query(queries, k=k)
    want_dist, want_idx = brute_force(data, queries, k)
    assert dist.shape == idx.shape == (len(queries), k) and idx.dtype == np.intp
    np.testing.assert_array_equal(idx, want_idx)
    np.testing.assert_allclose(dist, want_dist, rtol=1e-12)
    assert np.all(np.diff(dist, axis=1) >= 0)


@pytest.mark.parametrize("k", [1, 4])
def test_distance_upper_bound_leaves_the_farther_neighbours_missing(cloud, k):
    data, queries = cloud
    tree = KDTree(data)
    bound = float(np.median(tree.query(queries, k=k)[0]))  # about half of the neighbours are beyond it
    dist, idx = tree.query(queries, k=k, distance_upper_bound=bound)
    want_dist, want_idx = brute_force(data, queries, k, bound)
    np.testing.assert_array_equal(idx, want_idx.reshape(idx.shape))
    np.testing.assert_allclose(dist, want_dist.reshape(dist.shape), rtol=1e-12)
    missing = idx == len(data)
    assert 0 < missing.mean() < 1 and np.all(np.isinf(dist[missing])) and np.all(dist[~missing] < bound)


def test_the_bound_is_strict_and_more_neighbours_than_points_are_missing():
    line = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [3.0, 0.0, 0.0]])
    tree = KDTree(line)
    dist, idx = tree.query(np.zeros((1, 3)), k=3, distance_upper_bound=1.0)  # the point 1.0 away is not closer
    np.testing.assert_array_equal(idx, [[0, 3, 3]])
    np.testing.assert_array_equal(dist, [[0.0, np.inf, np.inf]])
    dist, idx = tree.query(np.array([[2.9, 0.0, 0.0]]), k=5)
    np.testing.assert_array_equal(idx, [[2, 1, 0, 3, 3]])
    np.testing.assert_allclose(dist, [[0.1, 1.9, 2.9, np.inf, np.inf]])


def test_two_dimensional_float32_and_strided_inputs_are_queried_as_float64():
    rng = np.random.default_rng(2)
    data = rng.uniform(0.0, 100.0, (300, 4))[:, ::2]  # (300, 2), not contiguous
    queries = rng.uniform(0.0, 100.0, (50, 2)).astype(np.float32)
    tree = KDTree(data)
    assert tree.n == 300 and tree.data.dtype == np.float64 and tree.data.flags.c_contiguous
    dist, idx = tree.query(queries, k=3)
    want_dist, want_idx = brute_force(data, queries.astype(np.float64), 3)
    np.testing.assert_array_equal(idx, want_idx)
    np.testing.assert_allclose(dist, want_dist, rtol=1e-12)
    empty_dist, empty_idx = tree.query(np.empty((0, 2)), k=3)
    assert empty_dist.shape == empty_idx.shape == (0, 3)


def test_bad_shapes_are_refused():
    with pytest.raises(ValueError, match="non-empty"):
        KDTree(np.empty((0, 3)))
    tree = KDTree(np.eye(3))
    with pytest.raises(ValueError, match=r"\(m, 3\)"):
        tree.query(np.zeros((4, 2)))
    with pytest.raises(ValueError, match="at least 1"):
        tree.query(np.zeros((4, 3)), k=0)


def test_small_queries_run_on_one_openmp_thread_and_restore_it(monkeypatch, cloud):
    data, queries = cloud
    seen = []

    class Limiter:
        """Records the limit asked for around each query (threadpoolctl's limiter stands behind it)."""

        def __init__(self, real):
            self.real = real

        def limit(self, limits):
            seen.append((limits, threading.get_ident()))
            return self.real.limit(limits=limits)

    tree = KDTree(data)
    tree.query(queries[:2])  # makes the controller
    threads = [lib["num_threads"] for lib in kdtree._OPENMP[0].info()]
    monkeypatch.setattr(kdtree, "_OPENMP", [Limiter(kdtree._OPENMP[0])])
    want = tree.query(queries, k=2)
    worker = threading.Thread(target=tree.query, args=(queries,))
    worker.start()
    worker.join()
    assert [limit for limit, _ in seen] == [1, 1] and seen[0][1] != seen[1][1]  # each thread limits its own
    monkeypatch.setattr(kdtree, "PARALLEL_QUERY", 100)
    big = tree.query(queries, k=2)  # 400 >= 100: OpenMP's default threads, the same answers
    assert len(seen) == 2
    assert [lib["num_threads"] for lib in kdtree._OPENMP[0].real.info()] == threads  # restored
    np.testing.assert_array_equal(big[1], want[1])
    np.testing.assert_array_equal(big[0], want[0])


def test_the_spatial_order_walks_strips_and_queries_in_it_give_the_same_answers():
    from mppf.core.kdtree import spatial_order

    rng = np.random.default_rng(11)
    points = rng.uniform([-1500.0, -1000.0, -5.0], [1500.0, 1000.0, 5.0], (5000, 3))
    order = spatial_order(points)
    assert np.array_equal(np.sort(order), np.arange(5000))  # a permutation
    strip = np.floor(points[order, 0] / (np.ptp(points[:, 0]) / 64))
    assert np.all(np.diff(strip) >= 0)  # strips across the longest extent, in turn
    steps = np.linalg.norm(np.diff(points[order], axis=0), axis=1)
    assert np.median(steps) < 0.1 * np.median(np.linalg.norm(np.diff(points, axis=0), axis=1))  # neighbours follow
    tree = KDTree(rng.uniform(-1500.0, 1500.0, (20000, 3)))
    dist, idx = tree.query(points, k=2)
    sorted_dist, sorted_idx = tree.query(points[order], k=2)
    np.testing.assert_array_equal(sorted_dist, dist[order])
    np.testing.assert_array_equal(sorted_idx, idx[order])
    assert spatial_order(np.zeros((0, 3))).size == 0 and list(spatial_order(np.array([[2.0], [1.0]]))) == [1, 0]
