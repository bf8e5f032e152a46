"""Connected components of a graph given as an edge list, with little per-call overhead.

    count, labels = components(n, i, j)

The same partition and the same numbering as
``scipy.sparse.csgraph.connected_components(coo_matrix((ones, (i, j)), shape=(n, n)), directed=False)``
(components numbered by their lowest node), which the mesh code calls thousands of times on small
graphs (two per piece cut, one per merge tried, ...), where scipy's conversions and input checks cost
more than the traversal. Up to DIRECT_MAX_EDGES edges the labels are propagated with numpy instead:
every edge lowers the root of its larger label to its smaller one, then pointer jumping to the roots,
until no edge joins two labels. Larger graphs, and the rare graph that needs more than MAX_ROUNDS
rounds, take scipy's undirected call as it is (measurements: docs/decisions/atlas-speed.md).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike
from scipy.sparse.csgraph import connected_components

from uvbake.mesh.arrays import dense_ranks

#: Edge lists up to this length are labelled with numpy; longer ones take scipy's undirected call as it is
#: (6,000 edges: 0.49 ms against scipy's 0.42).
DIRECT_MAX_EDGES = 2048
#: Rounds of label propagation before a graph is handed to scipy (meshes' pieces settle in a few).
MAX_ROUNDS = 32


def components(n: int, i: ArrayLike, j: ArrayLike) -> tuple[int, np.ndarray]:
    """(number of components, (n,) int32 label of each node) of the undirected graph on nodes 0..n-1
    with edges (i[k], j[k]); labels numbered by each component's lowest node."""
    i = np.asarray(i, dtype=np.int64).ravel()
    j = np.asarray(j, dtype=np.int64).ravel()
    n = int(n)
    if n == 0:
        return 0, np.zeros(0, np.int32)
    if len(i) > DIRECT_MAX_EDGES:
        return _undirected(n, i, j)
    labels = _propagate(n, i, j)
    if labels is None:
        return _undirected(n, i, j)
    roots, labels = dense_ranks(labels, n)                   # roots are each component's lowest node
    return len(roots), labels.astype(np.int32)


def _propagate(n: int, i: np.ndarray, j: np.ndarray) -> np.ndarray | None:
    """(n,) lowest node of each node's component, or None after MAX_ROUNDS rounds. Labels only
    decrease and stay in their component, so the fixed point labels every node with its component's
    lowest node (that node keeps its own label)."""
    lab = np.arange(n)
    for _ in range(MAX_ROUNDS):
        li, lj = lab[i], lab[j]
        lo, hi = np.minimum(li, lj), np.maximum(li, lj)
        join = lo != hi
        if not join.any():
            return lab
        np.minimum.at(lab, hi[join], lo[join])       # hi is a root: its tree hangs under lo now
        while True:                                  # pointer jumping until every node points at a root
            up = lab[lab]
            if np.array_equal(up, lab):
                break
            lab = up
    return None


def _undirected(n: int, i: np.ndarray, j: np.ndarray) -> tuple[int, np.ndarray]:
    count, labels = connected_components(sp.coo_matrix((np.ones(len(i)), (i, j)), shape=(n, n)), directed=False)
    return int(count), labels
