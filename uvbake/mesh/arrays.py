"""Checks of mesh arrays."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from uvbake.errors import InputError


def _list(ids, limit=5):
    ids = [int(i) for i in np.asarray(ids).ravel()[:limit + 1]]
    s = ", ".join(str(i) for i in ids[:limit])
    return s + (", ..." if len(ids) > limit else "")


def check_arrays(V: ArrayLike, F: ArrayLike, *, where: str = "mesh") -> tuple[np.ndarray, np.ndarray]:
    """Validate array shapes, types, finiteness and index range; return (V float64, F int64)."""
    try:
        V = np.asarray(V, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{where}: vertices are not numeric; pass V as an (n,3) float array") from None
    F = np.asarray(F)
    if V.ndim != 2 or V.shape[1] != 3:
        raise InputError(f"{where}: vertices have shape {V.shape}, expected (n,3); pass 3D positions")
    if F.ndim != 2 or F.shape[1] != 3:
        raise InputError(f"{where}: faces have shape {F.shape}, expected (m,3); triangulate the mesh first")
    if len(F) == 0:
        raise InputError(f"{where}: the mesh has no triangles; pass a surface mesh, not a point cloud")
    if not np.issubdtype(F.dtype, np.integer):
        if np.issubdtype(F.dtype, np.floating) and np.all(np.isfinite(F)) and np.all(F == np.round(F)):
            F = F.astype(np.int64)
        else:
            raise InputError(f"{where}: face indices are not integers; pass F as an (m,3) int array")
    F = F.astype(np.int64, copy=False)
    if F.min() < 0 or F.max() >= len(V):
        bad = np.flatnonzero((F < 0).any(1) | (F >= len(V)).any(1))
        raise InputError(f"{where}: triangles {_list(bad)} index vertices outside 0..{len(V) - 1}; fix the face list")
    bad = np.flatnonzero(~np.isfinite(V).all(axis=1))
    if len(bad):
        have = "vertex has" if len(bad) == 1 else "vertices have"
        raise InputError(f"{where}: {len(bad)} {have} NaN or infinite coordinates (vertices {_list(bad)}); "
                         "remove or repair them before unwrapping")
    return V, F


def unit_scale(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, float]:
    """V centred and scaled to unit mean edge length, and that mean edge length (the scale-free frame).

    F is invariant when mesh and map are scaled together, so solving there makes the gradient norm
    (the stopping rule) independent of the model's units; UVs scale back by the returned length.
    """
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    # a power of two first (exact): edge lengths neither overflow nor underflow at any finite scale
    k = unit_exponent(V)
    V = np.ldexp(V, -k)
    edges = V[F[:, [1, 2, 0]]] - V[F]
    unit = float(np.mean(np.linalg.norm(edges, axis=2)))
    return (V - V.mean(axis=0)) / unit, float(np.ldexp(unit, k))


def triangle_areas(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Areas (m,) of the triangles F of a 3D mesh V (n,3)."""
    X = np.asarray(V, dtype=np.float64)[F]
    return 0.5 * np.linalg.norm(np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0]), axis=1)


def unit_normals(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """(m,3) unit normal of every triangle (right-handed in its corner order; 0 for a degenerate one)."""
    X = V[F]
    nrm = np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0])
    return nrm / np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-300)


def face_means(X: np.ndarray, F: np.ndarray) -> np.ndarray:
    """``X[F].mean(axis=1)`` bit for bit (the same sum in the same order, then / 3), without numpy's
    reduction over a 3-long axis: 3x faster."""
    return (X[F[:, 0]] + X[F[:, 1]] + X[F[:, 2]]) / 3


def signed_areas(uv: np.ndarray, F: np.ndarray | None = None) -> np.ndarray:
    """Signed areas (m,) of the triangles F of a UV map uv (n,2), or of per-corner UVs (m,3,2) when F is
    None: positive = counter-clockwise."""
    U = np.asarray(uv, dtype=np.float64)
    U = U if F is None else U[F]
    e1, e2 = U[:, 1] - U[:, 0], U[:, 2] - U[:, 0]
    return 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])


def rigid_align(P: np.ndarray, Q: np.ndarray, X: np.ndarray | None = None
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """2D Kabsch without reflection: the rotation R (2x2, det +1) and translation t minimising
    sum |R p_i + t - q_i|^2, and X (default P) moved by them.

    Returns
    -------
    R : (2,2), t : (2,), moved : X @ R.T + t, computed as (X - mean P) @ R.T + mean Q.
    """
    P = np.asarray(P, dtype=np.float64)
    Q = np.asarray(Q, dtype=np.float64)
    X = P if X is None else np.asarray(X, dtype=np.float64)
    cp, cq = P.mean(axis=0), Q.mean(axis=0)
    U, _, Wt = np.linalg.svd((P - cp).T @ (Q - cq))
    d = np.sign(np.linalg.det(U @ Wt)) or 1.0          # no reflection
    Rm = U @ np.diag([1.0, d]) @ Wt                      # acts on row vectors: (x - cp) @ Rm
    return Rm.T, cq - cp @ Rm, (X - cp) @ Rm + cq


def unit_exponent(V: ArrayLike) -> int:
    """``k`` with ``max|V| * 2**-k`` in [0.5, 1), 0 for an empty, zero or non-finite V.

    Scaling by a power of two (``np.ldexp(V, -k)``) is exact, so meshes at any finite scale
    (1e300 or 1e-300) can be worked on near unit size without losing a bit, and scaled back.
    """
    V = np.asarray(V, dtype=np.float64)
    m = float(np.max(np.abs(V))) if V.size else 0.0
    if m == 0.0 or not np.isfinite(m):
        return 0
    return int(np.frexp(m)[1])


def pieces(a: np.ndarray, cut: ArrayLike) -> list[np.ndarray]:
    """``np.split(a, cut)`` (views of ``a`` between the sorted indices ``cut``), 4x faster on thousands
    of pieces: np.split's per-piece bookkeeping is most of its cost there."""
    b = [0, *np.asarray(cut, dtype=np.int64).tolist(), len(a)]
    return [a[i:j] for i, j in zip(b[:-1], b[1:])]


def unique_sorted(a: ArrayLike) -> np.ndarray:
    """``np.unique(a)`` (the sorted distinct values of ``a`` flattened), by one sort: numpy 2.4's
    np.unique without return_* options takes a hashing path 2-7x slower on integer arrays of 100 to
    40,000 entries, which the mesh code calls hundreds of times per mesh. Other dtypes (NaNs) take
    np.unique as it is."""
    a = np.asarray(a)
    if a.dtype.kind not in "iub":
        return np.unique(a)
    s = np.sort(a, axis=None)
    if len(s) < 2:
        return s
    keep = np.empty(len(s), bool)
    keep[0] = True
    np.not_equal(s[1:], s[:-1], out=keep[1:])
    return s[keep]


def dense_ranks(x: ArrayLike, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(x, return_inverse=True)`` for integers in ``[0, n)``, flattened inverse: by marking the
    values used when ``n`` is not much more than ``x``'s size (no sort: the mesh code relabels vertex and
    component ids hundreds of times per mesh), else np.unique as it is."""
    x = np.asarray(x).ravel()
    if n > 4 * len(x) + 64:
        uniq, inv = np.unique(x, return_inverse=True)
        return uniq, inv.ravel()
    used = np.zeros(n, bool)
    used[x] = True
    rank = np.cumsum(used) - 1
    return np.flatnonzero(used).astype(x.dtype, copy=False), rank[x]
