"""uvbake.mesh.graph.components: scipy's undirected connected components, same labels; and the mesh
code's np.unique and np.split stand-ins (uvbake.mesh.arrays)."""

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from uvbake.mesh import graph
from uvbake.mesh.graph import components


def _scipy(n, i, j):
    return connected_components(sp.coo_matrix((np.ones(len(i)), (i, j)), shape=(n, n)), directed=False)


@pytest.mark.parametrize("direct_max", [10**9, 0])      # every graph the direct way, or none
def test_components_match_scipys_undirected_labels_exactly(monkeypatch, direct_max):
    monkeypatch.setattr(graph, "DIRECT_MAX_EDGES", direct_max)
    rng = np.random.default_rng(7)
    for trial in range(300):
        n = int(rng.integers(1, 200))
        m = int(rng.integers(0, 3 * n))
        i, j = rng.integers(0, n, m), rng.integers(0, n, m)
        if trial % 5 == 0 and m:                    # self-loops and repeated edges
            j[: m // 3] = i[: m // 3]
            i, j = np.concatenate([i, i]), np.concatenate([j, j])
        count, labels = components(n, i, j)
        ref_count, ref = _scipy(n, i, j)
        assert count == ref_count and labels.dtype == np.int32
        assert np.array_equal(labels, ref)


def test_components_of_a_graph_without_nodes_or_edges():
    assert components(0, [], [])[0] == 0
    count, labels = components(4, [], [])
    assert count == 4 and labels.tolist() == [0, 1, 2, 3]
    count, labels = components(5, [4, 1], [3, 4])                        # {0}, {1, 3, 4}, {2}
    assert count == 3 and labels.tolist() == [0, 1, 2, 1, 1]


def test_components_hand_graphs_that_need_more_rounds_to_scipy_with_the_same_labels(monkeypatch):
    # one round of propagation settles a star but not a path numbered out of order: that graph
    # falls back to scipy, and the labels are the same either way
    rng = np.random.default_rng(11)
    order = rng.permutation(60)
    i, j = order[:-1], order[1:]                                          # one path through all 60 nodes
    assert graph._propagate(60, i, j) is not None                         # settles within MAX_ROUNDS
    monkeypatch.setattr(graph, "MAX_ROUNDS", 1)
    assert graph._propagate(60, i, j) is None
    count, labels = components(60, i, j)
    assert count == 1 and np.array_equal(labels, _scipy(60, i, j)[1])
    count, labels = components(7, [0, 0, 0], [3, 5, 6])                    # a star and three lone nodes
    assert count == 4 and labels.tolist() == [0, 1, 2, 0, 3, 0, 0]


def test_unique_sorted_and_pieces_are_numpys():
    """The mesh code's np.unique (one sort) and np.split (slices) stand-ins give numpy's arrays exactly,
    for empty, one-element, 2-D, boolean and unsigned inputs; floats (NaNs) are left to np.unique."""
    from uvbake.mesh.arrays import pieces, unique_sorted

    rng = np.random.default_rng(1)
    cases = [np.zeros(0, np.int64), np.array([7]), rng.integers(-5, 5, (30, 3)), rng.integers(0, 10**9, 5000),
             rng.random(50) < 0.5, rng.integers(0, 300, 1000).astype(np.uint16),
             np.array([1.0, np.nan, 0.5, np.nan, 1.0])]
    for a in cases:
        got, want = unique_sorted(a), np.unique(a)
        assert got.dtype == want.dtype
        np.testing.assert_array_equal(got, want)
    a = rng.integers(0, 9, 100)
    for cut in ([], [0], [100], [3, 3, 50, 99], np.array([10, 20])):
        got, want = pieces(a, cut), np.split(a, cut)
        assert len(got) == len(want) and all(np.array_equal(g, w) for g, w in zip(got, want))


def test_dense_ranks_is_numpys_unique_with_inverse():
    """Relabelling ids in [0, n) by marking the used ones gives np.unique's values and inverse, for
    2-D and empty inputs and on both of its paths (n near the input's size, and n far larger)."""
    from uvbake.mesh.arrays import dense_ranks

    rng = np.random.default_rng(4)
    for n, shape in [(10, (10,)), (500, (300, 3)), (40000, (40000,)), (10**6, (50,)), (7, (0,))]:
        x = rng.integers(0, n, shape)
        uniq, inv = dense_ranks(x, n)
        want_u, want_i = np.unique(x, return_inverse=True)
        assert uniq.dtype == want_u.dtype
        np.testing.assert_array_equal(uniq, want_u)
        np.testing.assert_array_equal(inv, want_i.ravel())
        np.testing.assert_array_equal(uniq[inv], x.ravel())


def test_face_means_are_numpys_mean_over_the_corners_bit_for_bit():
    """Centroids written out as three adds and a divide equal X[F].mean(axis=1) exactly (same order of
    the sum), for 1-D and 2-D values at scales where rounding shows, and for no faces."""
    from uvbake.mesh.arrays import face_means

    rng = np.random.default_rng(6)
    F = rng.integers(0, 400, (3000, 3))
    for X in (rng.normal(size=(400, 2)) * 1e7 + 0.1, rng.normal(size=400) * 1e-9, rng.random((400, 3))):
        got, want = face_means(X, F), X[F].mean(axis=1)
        assert got.dtype == want.dtype and np.array_equal(got, want)
    assert face_means(np.zeros((3, 2)), np.zeros((0, 3), np.int64)).shape == (0, 2)
