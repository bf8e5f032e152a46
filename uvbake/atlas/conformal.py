"""Conformal maps for the charting stage: least squares conformal maps (Levy et al. 2002) assembled
straight into their free unknowns and factored once, one chart or many as one block-diagonal system,
and each triangle's log area factor under them (what the distortion budget reads).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike

from uvbake.flatten.pinches import pinch_representatives, welded
from uvbake.mesh.arrays import pieces, unique_sorted

#: The half-edge (0: 0->1, 1: 1->2, 2: 2->0) each entry of a triangle's row-major 3x3 block lies on;
#: 3 (never a boundary edge) for the diagonal.
_BLOCK_EDGE = np.array([3, 0, 2, 0, 3, 1, 2, 1, 3])


def lscm(V: ArrayLike, F: ArrayLike, *, frames: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """Least squares conformal map (Levy et al. 2002), assembled and solved in one shot.

    The same map as :func:`uvbake.flatten.starts.lscm` (area-weighted conformal energy, the two farthest
    boundary vertices pinned at their 3D distance), but assembled straight into the free unknowns as
    one Hermitian system in z = u + iv and factored once with an AMD ordering: charting solves it for
    every candidate chart, where building the solver's full energy object and nested-dissection
    analysis cost three quarters of the time. ``frames``: (Q, area) of :func:`uvbake.flatten.energy.triangle_frames`,
    when the caller has them. Returns uv (n,2)."""
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    return lscm_many([V], [F], [_frames(V, F) if frames is None else frames])[0]


def lscm_many(Vs: list, Fs: list, frames: list, keys: list | None = None) -> list:
    """:func:`lscm` of several charts as one block-diagonal system, one factorisation: each chart's
    unknowns (one complex z = u + iv per vertex) are a block of their own, with the entries, pins and
    right side it has alone (a kit's hundred small parts paid a sparse assembly and a factorisation each).
    ``keys``: per chart, None or its vertices' pinch keys (:mod:`uvbake.flatten.pinches`): each
    pinch is one vertex of the solve, and its copies get its UV."""
    from uvbake.mesh.topology import _edges

    k = len(Vs)
    nv = np.array([len(V) for V in Vs], np.int64)              # one per chart
    nf = np.array([len(F) for F in Fs], np.int64)
    voff = np.cumsum(nv) - nv
    V = np.concatenate(Vs)
    F = np.concatenate(Fs) + np.repeat(voff, nf)[:, None]
    cv = np.repeat(np.arange(k), nv)
    ends = np.cumsum(nv)[:-1]
    back, rep = None, None
    edges = _edges(F, len(V), mask=True)
    if keys is not None and any(kk is not None for kk in keys):
        K = np.concatenate([np.full(len(V), -1) if kk is None else kk for V, kk in zip(Vs, keys)])
        rep = pinch_representatives(K, F, cv, boundary=edges[2])
    if rep is not None:                                  # each pinch's copies: one vertex for the solve
        kept, F, back = welded(F, rep)
        V, cv = V[kept], cv[kept]
        nv = np.bincount(cv, minlength=k)
        edges = _edges(F, len(V), mask=True)
    n = len(V)
    Q = np.concatenate([f[0] for f in frames])
    area = np.concatenate([f[1] for f in frames])
    a, b = Q[:, :, 0], Q[:, :, 1]                        # (m,3): A = U Q, dA/du_k = (a_k, b_k)
    w = (2.0 * area)[:, None, None]
    r = np.repeat(F, 3, axis=1).ravel()
    c = np.tile(F, (1, 3)).ravel()
    # D_angle = (a.u - b.v)^2 + (b.u + a.v)^2: Huu = Hvv = 2w (a a^T + b b^T), Huv = 2w (b a^T - a b^T)
    duu = (w * (a[:, :, None] * a[:, None, :] + b[:, :, None] * b[:, None, :])).ravel()
    duv = (w * (b[:, :, None] * a[:, None, :] - a[:, :, None] * b[:, None, :])).ravel()
    # Huv is the Hessian of -4 x the signed UV area, a sum over boundary edges: its entries on interior
    # edges cancel between the edge's two triangles (camelhead: |Huv| 1 on the boundary, at most 7e-13
    # inside); they are left out (exact zeros), as rounding they would only add.
    # entry (k, l) of a triangle's 3x3 block lies on its edge k-l; the diagonal on no edge (unless a
    # triangle repeats a vertex: then the plain test below)
    he, _, bnd, alone = edges
    on = np.column_stack([alone.reshape(-1, 3), np.zeros(len(F), bool)])[:, _BLOCK_EDGE].reshape(-1)
    if (he[:, 0] == he[:, 1]).any():                     # a degenerate triangle: the plain test
        on = np.isin(np.minimum(r, c) * n + np.maximum(r, c), np.sort(bnd, axis=1) @ np.array([n, 1]))
    # the system in complex unknowns z = u + iv: per triangle D_angle = |(a + ib).z|^2, whose Hessian is the
    # Hermitian 2w conj(c) c^T (c = a + ib): Re = Huu = Hvv, Im = -Huv. Half the unknowns of the real
    # u/v system and a quarter of its entries; the factor does about half the work (docs/decisions/atlas-speed.md)
    rows = np.concatenate([r, r[on]])
    cols = np.concatenate([c, c[on]])
    data = np.concatenate([duu, -1j * duv[on]])
    p, q = _farthest_pairs(V, unique_sorted(bnd), cv, k)
    x = np.zeros(n, complex)
    x[q] = [np.linalg.norm(V[j] - V[i]) for i, j in zip(p, q)]     # one per chart: lscm's own norm
    # vertex k -> its index among the free ones (-1: pinned); the pinned ones move to the right side
    index = np.arange(n)
    pinned = unique_sorted(np.concatenate([p, q]))
    index = index - np.searchsorted(pinned, index, side="right")
    index[pinned] = -1
    ri, ci = index[rows], index[cols]
    both = (ri >= 0) & (ci >= 0)
    m = n - len(pinned)
    A = sp.csc_matrix((data[both], (ri[both], ci[both])), shape=(m, m))
    right = (ri >= 0) & (ci < 0)
    w_right = data[right] * x[cols[right]]
    rhs = -(np.bincount(ri[right], weights=w_right.real, minlength=m)
            + 1j * np.bincount(ri[right], weights=w_right.imag, minlength=m))
    x[index >= 0] = _spd_solve_once(A, rhs, 2 * int(nv.max()))
    uv = np.stack([x.real, x.imag], axis=1)
    return pieces(uv if back is None else uv[back], ends)


def _farthest_pairs(V, bv, cv, k):
    """Each chart's :func:`uvbake.flatten.starts.farthest_boundary_pair`: the boundary vertex farthest
    from the chart's first one, then the one farthest from it (the first of equals), for all charts
    at once (``bv``: the sorted boundary vertices, ``cv``: each vertex's chart)."""
    bc = cv[bv]
    start = np.searchsorted(bc, np.arange(k))
    p = bv[_first_max(np.linalg.norm(V[bv] - V[bv[start]][bc], axis=1), bc, k)]
    q = bv[_first_max(np.linalg.norm(V[bv] - V[p][bc], axis=1), bc, k)]
    return p, q


def _first_max(x, group, k):
    """Per group (``group`` sorted, every group present): the index of its first largest ``x``."""
    top = np.full(k, -np.inf)
    np.maximum.at(top, group, x)
    hit = np.flatnonzero(x == top[group])
    _, first = np.unique(group[hit], return_index=True)
    return hit[first]


def _frames(V, F):
    """(Q, area) of every triangle (:func:`uvbake.flatten.energy.triangle_frames`)."""
    from uvbake.flatten.energy import triangle_frames

    _, Q, area = triangle_frames(V, F)
    return Q, area


def _spd_solve_once(A, b, largest):
    """One Hermitian positive definite solve (CHOLMOD with AMD when installed, else SuperLU);
    ``largest``: the unknowns of the largest chart (the system is block diagonal), counted as real ones
    (two per complex unknown), the count SUPERNODAL_FROM is measured in."""
    from uvbake.flatten.solvers.linalg import cholmod_available, cholmod_mode

    if cholmod_available():
        import warnings

        from sksparse.cholmod import cholesky

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return cholesky(A, ordering_method="amd", mode=cholmod_mode(largest))(b)
    import scipy.sparse.linalg as spla

    return spla.splu(A, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                     options=dict(SymmetricMode=True)).solve(b)


def conformal_factor(V: np.ndarray, F: np.ndarray, *, frames: tuple[np.ndarray, np.ndarray] | None = None,
                     keys: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """LSCM map of a chart and each triangle's log area factor relative to the chart's mean.

    Returns (uv (n,2), logf (m,)): logf = log(UV area / 3D area) - log(total UV / total 3D), -inf where
    the conformal map flips or collapses the triangle. ``frames`` as in :func:`lscm`, ``keys`` (pinch
    keys) as in :func:`lscm_many`."""
    frames = _frames(V, F) if frames is None else frames
    return conformal_factors([V], [F], [frames], None if keys is None else [keys])[0]


def conformal_factors(Vs: list, Fs: list, frames: list, keys: list | None = None) -> list:
    """:func:`conformal_factor` of several charts, their maps solved together (:func:`lscm_many`)."""
    out = []
    for F, uv, (_, a3) in zip(Fs, lscm_many(Vs, Fs, frames, keys), frames):      # one per chart: its own sums
        U = uv[F]
        e1, e2 = U[:, 1] - U[:, 0], U[:, 2] - U[:, 0]
        a2 = 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
        if a2.sum() < 0:                               # a mirrored map: orientation is the chart's
            uv = uv.copy()
            uv[:, 1] *= -1
            a2 = -a2
        mean = a2.sum() / a3.sum()
        with np.errstate(divide="ignore", invalid="ignore"):
            logf = np.where(a2 > 0, np.log(a2 / a3 / mean), -np.inf)
        out.append((uv, logf))
    return out
