"""Initial maps for the solver: ``lscm`` (default), ``tutte`` (one boundary loop), ``random``,
``isomap`` and ``laplacian`` (the paper's Fig. 6 starts).

All return per-vertex UVs in the chart's own length units; the solver rescales them by the
closed-form optimal factor of :func:`uvbake.flatten.energy.optimal_scale` before iterating.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp

from uvbake.errors import InputError
from uvbake.flatten.energy import DistortionEnergy
from uvbake.flatten.options import INITS
from uvbake.mesh.arrays import signed_areas, triangle_areas, unique_sorted
from uvbake.mesh.topology import boundary_edges, topology

# Landmarks of the Isomap start (de Silva and Tenenbaum 2003). Time is linear in them; on beetle
# 50 / 100 / 200 landmarks gave 19 / 17 / 18 flipped start triangles (of 38,656), so 64.
ISOMAP_LANDMARKS = 64


def farthest_boundary_pair(V: np.ndarray, F: np.ndarray, *, boundary: np.ndarray | None = None) -> tuple[int, int]:
    """Two boundary vertices far apart: the farthest from an arbitrary one, then the farthest from it.
    ``boundary``: the (b,2) boundary half-edges, when the caller has them."""
    bnd = unique_sorted(boundary_edges(F, len(V)) if boundary is None else boundary)
    p = bnd[np.argmax(np.linalg.norm(V[bnd] - V[bnd[0]], axis=1))]
    q = bnd[np.argmax(np.linalg.norm(V[bnd] - V[p], axis=1))]
    return int(p), int(q)


def lscm(V: np.ndarray, F: np.ndarray, *, pins: tuple[int, int] | None = None) -> np.ndarray:
    """Least squares conformal map (Levy et al. 2002) with two pinned boundary vertices.

    Minimises sum_t area_t * D_angle_t, which is LSCM's conformal energy, with the two pins placed
    at their 3D distance apart on the u axis. The energy is quadratic, so one sparse solve gives it.

    Returns
    -------
    uv : (n,2) float array
    """
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    p, q = farthest_boundary_pair(V, F) if pins is None else pins
    uv0 = np.zeros((len(V), 2))
    uv0[q, 0] = np.linalg.norm(V[q] - V[p])
    fixed = np.zeros(2 * len(V), bool)
    fixed[[2 * p, 2 * p + 1, 2 * q, 2 * q + 1]] = True
    area = triangle_areas(V, F)
    E = DistortionEnergy(V, F, alpha=0.0, weights=area, fixed=fixed)
    _, g, H = E.evaluate(uv0)
    x = -_spd_solve(H, g)
    return E.to_uv(x, uv0)


def tutte(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Tutte's barycentric embedding: boundary on a circle by arc length, interior at neighbour means.

    Bijective for any chart with one boundary loop (Tutte 1963; Floater 1997). The circle's
    circumference equals the boundary's 3D length.
    """
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    n = len(V)
    topo = topology(F, n)
    if topo.n_boundary_loops != 1:
        raise InputError(f"init='tutte' needs a chart with exactly one boundary loop, this one has "
                         f"{topo.n_boundary_loops}; use init='lscm' for charts with holes")
    be = topo.boundary_edges
    nxt = np.full(n, -1)
    nxt[be[:, 0]] = be[:, 1]
    order = _cycle_order(nxt, be[0, 0])
    seg = np.linalg.norm(V[nxt[order]] - V[order], axis=1)
    t = np.concatenate([[0.0], np.cumsum(seg)[:-1]]) / seg.sum() * 2 * np.pi
    radius = seg.sum() / (2 * np.pi)
    uv = np.zeros((n, 2))
    uv[order] = radius * np.stack([np.cos(t), np.sin(t)], axis=1)
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    A = sp.coo_matrix((np.ones(len(E)), (E[:, 0], E[:, 1])), shape=(n, n)).tocsr()
    A = ((A + A.T) > 0).astype(np.float64)
    L = sp.diags(np.asarray(A.sum(axis=1)).ravel()) - A
    inner = np.setdiff1d(np.arange(n), order)
    if len(inner):
        Lii = L[inner][:, inner].tocsc()
        rhs = -(L[inner][:, order] @ uv[order])
        uv[inner] = _spd_solve(Lii, rhs)
    return uv


def random_map(V: np.ndarray, F: np.ndarray, *, seed: int = 0) -> np.ndarray:
    """Uniform random UVs in a square of the chart's own area: an invalid, mostly flipped start."""
    V = np.asarray(V, dtype=np.float64)
    area = triangle_areas(V, np.asarray(F, dtype=np.int64))
    side = np.sqrt(area.sum())
    return np.random.default_rng(seed).uniform(0.0, side, size=(len(V), 2))


def edge_graph(V: np.ndarray, F: np.ndarray) -> sp.csr_matrix:
    """The mesh's own graph: a symmetric sparse (n,n) matrix of 3D edge lengths."""
    E = np.unique(np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1), axis=0)
    w = np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1)
    n = len(V)
    return sp.coo_matrix((np.concatenate([w, w]), (np.concatenate([E[:, 0], E[:, 1]]),
                                                   np.concatenate([E[:, 1], E[:, 0]]))), shape=(n, n)).tocsr()


def isomap(V: np.ndarray, F: np.ndarray, *, landmarks: int = ISOMAP_LANDMARKS) -> np.ndarray:
    """Landmark Isomap (de Silva and Tenenbaum, NIPS 2003) on the mesh's edge graph.

    Landmarks by geodesic farthest-point sampling (each Dijkstra run both picks the next landmark and
    gives its distance row), classical MDS on the landmarks' squared geodesic distances, and every
    other vertex placed by distance-based triangulation: x = -1/2 L# (delta_x - mean delta). Cost:
    ``landmarks`` Dijkstra runs, O(landmarks n log n), never an n x n matrix.
    scikit-learn's Isomap does not do this job: it builds its own k-nearest-neighbour graph on the
    points (not the mesh's edges) and its landmark-free geodesic step is O(n^2) memory.
    """
    from scipy.sparse.csgraph import dijkstra

    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    G = edge_graph(V, F)
    n = len(V)
    k = min(int(landmarks), n)
    D = np.empty((k, n))
    nearest = np.full(n, np.inf)
    cur = int(np.argmax(np.linalg.norm(V - V.mean(axis=0), axis=1)))   # a deterministic first landmark
    picked = []
    for i in range(k):          # sequential by nature: each landmark is the farthest from the previous ones
        picked.append(cur)
        D[i] = dijkstra(G, directed=False, indices=cur)
        nearest = np.minimum(nearest, D[i])
        cur = int(np.argmax(nearest))
    if not np.all(np.isfinite(D)):
        raise InputError("init='isomap' needs a connected chart; split it into connected charts first")
    D2 = D ** 2
    DL = D2[:, picked]
    J = np.eye(k) - 1.0 / k
    B = -0.5 * J @ DL @ J
    lam, vec = np.linalg.eigh(B)
    lam, vec = lam[::-1][:2], vec[:, ::-1][:, :2]
    lam = np.maximum(lam, 1e-300)
    pinv = vec / np.sqrt(lam)                                   # L# transposed, (k,2)
    uv = -0.5 * (D2 - DL.mean(axis=1)[:, None]).T @ pinv
    return _orient(V, F, uv)


def laplacian_eigenmap(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Laplacian eigenmap (Belkin and Niyogi 2003) with the mesh's cotangent Laplacian L and lumped
    mass matrix M: the two eigenvectors of L x = lambda M x after the constant one, by shift-invert
    Lanczos (scipy's eigsh, sigma just below 0 so L - sigma M is positive definite and uvbake's sparse
    Cholesky applies its inverse), each scaled by
    1/sqrt(lambda) (the heat-kernel weighting, which keeps the slower mode larger).
    scikit-learn's SpectralEmbedding does not do this job: it builds an affinity graph from point
    distances (k nearest neighbours in R^3), not the surface's Laplacian.
    """
    import scipy.sparse.linalg as spla

    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    n = len(V)
    L, area = cotangent_laplacian(V, F)
    M = sp.diags(np.bincount(F.ravel(), weights=np.repeat(area / 3.0, 3), minlength=n))
    scale = float(L.diagonal().mean() / M.diagonal().mean())
    v0 = np.random.default_rng(0).standard_normal(n)        # seeded: same input, same map
    from uvbake.flatten.solvers.linalg import make_solver

    sigma = -1e-8 * scale
    A = (L - sigma * M).tocsc()                 # positive definite: the sparse Cholesky applies it
    solver = make_solver(A)
    solver.factor(A, 0.0)
    op = spla.LinearOperator(A.shape, matvec=solver.solve, dtype=np.float64)
    lam, vec = spla.eigsh(L.tocsc(), k=3, M=M.tocsc(), sigma=sigma, which="LM", v0=v0, OPinv=op)
    order = np.argsort(lam)
    lam, vec = lam[order][1:], vec[:, order][:, 1:]
    vec = vec * np.sign(vec[np.argmax(np.abs(vec), axis=0), [0, 1]])   # eigsh's sign is arbitrary
    uv = vec / np.sqrt(np.maximum(lam, 1e-300))
    return _orient(V, F, uv)


def cotangent_laplacian(V: np.ndarray, F: np.ndarray) -> tuple[sp.csr_matrix, np.ndarray]:
    """The cotangent Laplacian (positive semi-definite, rows sum to 0) and the triangle areas."""
    n = len(V)
    area = triangle_areas(V, F)
    cots: Any = []                                  # per corner, then stacked (m,3)
    for k in range(3):                              # the angle at corner k faces edge (k+1, k+2)
        a = V[F[:, (k + 1) % 3]] - V[F[:, k]]
        b = V[F[:, (k + 2) % 3]] - V[F[:, k]]
        cots.append(np.einsum("ij,ij->i", a, b) / np.maximum(2.0 * area, 1e-300))
    cots = np.stack(cots, axis=1)                   # (m,3)
    i = np.concatenate([F[:, 1], F[:, 2], F[:, 0]])
    j = np.concatenate([F[:, 2], F[:, 0], F[:, 1]])
    w = 0.5 * np.concatenate([cots[:, 0], cots[:, 1], cots[:, 2]])
    W = sp.coo_matrix((np.concatenate([w, w]), (np.concatenate([i, j]), np.concatenate([j, i]))),
                      shape=(n, n)).tocsr()
    return sp.diags(np.asarray(W.sum(axis=1)).ravel()) - W, area


def _orient(V, F, uv):
    """Mirror the map when most of the surface's area maps with negative orientation."""
    if np.dot(triangle_areas(V, F), np.sign(signed_areas(uv, F))) < 0:
        uv = uv * np.array([1.0, -1.0])
    return np.ascontiguousarray(uv)


def initial_map(V: np.ndarray, F: np.ndarray, init: str, *, seed: int = 0) -> np.ndarray:
    """The start map named by ``init`` (one of ``INITS``)."""
    if init == "lscm":
        return lscm(V, F)
    if init == "tutte":
        return tutte(V, F)
    if init == "random":
        return random_map(V, F, seed=seed)
    if init == "isomap":
        return isomap(V, F)
    if init == "laplacian":
        return laplacian_eigenmap(V, F)
    raise InputError(f"init={init!r} is not one of {', '.join(repr(i) for i in INITS)}")


def _cycle_order(nxt, start):
    """Vertices of the cycle through ``start`` in successor order, by pointer doubling (no per-vertex loop)."""
    members = np.flatnonzero(nxt >= 0)
    # rank each member by its distance from start along the cycle: break the cycle before start
    pred_start = members[nxt[members] == start]
    succ = nxt.copy()
    succ[pred_start] = pred_start               # the end points to itself
    dist = np.where(np.arange(len(nxt)) == pred_start[0], 0, 1)
    dist[nxt < 0] = 0
    jump = np.where(nxt >= 0, succ, np.arange(len(nxt)))
    for _ in range(int(np.ceil(np.log2(max(len(members), 2)))) + 1):
        dist = dist + dist[jump]
        jump = jump[jump]
    # dist = number of steps to the end; the cycle through start has its own members only
    on_cycle = members[_reach(nxt, start, members)]
    return on_cycle[np.argsort(-dist[on_cycle], kind="stable")]


def _reach(nxt, start, members):
    """Mask over ``members`` of those on the cycle through ``start`` (connected components)."""
    from uvbake.mesh.graph import components

    n = len(nxt)
    _, lab = components(n, members, nxt[members])
    return lab[members] == lab[start]


def _spd_solve(A, b):
    from uvbake.flatten.solvers.linalg import make_solver

    A = sp.csc_matrix(A)
    s = make_solver(A)
    s.factor(A, 0.0)
    return s.solve(b)
