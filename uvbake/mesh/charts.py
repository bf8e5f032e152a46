"""Charts: split a mesh by segment labels and connected components, and check each is a disk with holes.

A chart is what one parameterization flattens: a connected, manifold, consistently oriented triangle
mesh with at least one boundary loop and no handles (genus 0). Every check is vectorised over
half-edges and corners; errors name the chart, the offending elements and the way out.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from uvbake.errors import ChartError, InputError, NotDiskError
from uvbake.mesh.arrays import _list, check_arrays, dense_ranks, unique_sorted, unit_exponent
from uvbake.mesh.graph import components
from uvbake.mesh.topology import Topology, face_adjacency, nonmanifold_vertices, topology


@dataclass
class Chart:
    """One chart of a mesh.

    Attributes
    ----------
    V : (k,3) float array       the chart's vertices
    F : (t,3) int array         its triangles, indexing V
    vertex_map : (k,) int array index of each chart vertex in the whole mesh
    face_index : (t,) int array index of each chart triangle in the whole mesh
    label : int                 the segment label it came from (-1 when there were none)
    name : str                  how errors and reports refer to it
    """

    V: np.ndarray
    F: np.ndarray
    vertex_map: np.ndarray
    face_index: np.ndarray
    label: int = -1
    name: str = "chart 0"


def check_chart(V: ArrayLike, F: ArrayLike, *, name: str = "chart 0") -> Topology:
    """Raise a :class:`ChartError` unless (V, F) is one connected, manifold disk with holes.

    Checks, in order: degenerate triangles (repeated indices or zero area), unreferenced vertices,
    non-manifold edges, inconsistently oriented neighbours, non-manifold (bowtie) vertices, several
    components, no boundary (closed), handles (genus > 0). Returns the chart's :class:`Topology`.
    """
    V, F = check_arrays(V, F, where=name)
    # exact: areas neither overflow nor underflow at any scale
    V = np.asarray(np.ldexp(V, -unit_exponent(V)), dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    n = len(V)
    rep = (F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 2] == F[:, 0])
    X = V[F]
    e = np.linalg.norm(X[:, [1, 2, 0]] - X, axis=2)
    dbl = np.linalg.norm(np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0]), axis=1)
    scale = max(float(np.mean(e)), np.finfo(float).tiny)
    # twice the area against the longest edge squared: zero for needles and caps alike
    degenerate = rep | (dbl <= 1e-12 * np.maximum(e.max(axis=1), scale) ** 2)
    if degenerate.any():
        bad = np.flatnonzero(degenerate)
        raise ChartError(f"{name}: {len(bad)} degenerate triangles (zero area or repeated vertex: triangles "
                         f"{_list(bad)}); remove them (e.g. trimesh's update_faces(nondegenerate_faces()))")
    unref = np.setdiff1d(np.arange(n), F.ravel())
    if len(unref):
        raise ChartError(f"{name}: {len(unref)} vertices are used by no triangle (vertices {_list(unref)}); "
                         "remove them (e.g. trimesh's remove_unreferenced_vertices())")
    he = F[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    key = np.sort(he, axis=1)
    ek = key[:, 0] * n + key[:, 1]
    uniq, inv, cnt = np.unique(ek, return_inverse=True, return_counts=True)
    if (cnt > 2).any():
        bad = uniq[cnt > 2]
        pairs = ", ".join(f"({k // n},{k % n})" for k in bad[:5])
        raise ChartError(f"{name}: {len(bad)} non-manifold edges shared by more than two triangles ({pairs}); "
                         "split the chart there or repair the mesh")
    # a manifold edge's two half-edges must run in opposite directions
    dk = he[:, 0] * n + he[:, 1]
    du, dcnt = np.unique(dk, return_counts=True)
    if (dcnt > 1).any():
        bad = du[dcnt > 1]
        pairs = ", ".join(f"({k // n},{k % n})" for k in bad[:5])
        raise ChartError(f"{name}: neighbouring triangles have opposite orientation across {len(bad)} edges "
                         f"({pairs}); make the winding consistent (e.g. trimesh's fix_winding())")
    bowtie = nonmanifold_vertices(F, n)
    if len(bowtie):
        raise ChartError(f"{name}: {len(bowtie)} non-manifold vertices where separate triangle fans meet "
                         f"(vertices {_list(bowtie)}); duplicate those vertices per fan or split the chart")
    topo = topology(F, n)
    if topo.n_components != 1:
        raise ChartError(f"{name}: has {topo.n_components} connected components; pass one component, "
                         "or split it with uvbake.split_charts")
    if topo.n_boundary_loops == 0:
        raise NotDiskError(f"{name}: is closed (no boundary), so it cannot be flattened; cut it open along a seam "
                         "or give it several segment labels")
    if topo.genus != 0:
        raise NotDiskError(f"{name}: has {topo.genus} handle(s) (genus {topo.genus}, {topo.n_boundary_loops} boundary "
                         "loops), not a disk with holes; cut each handle or split the chart with segment labels")
    return topo


def certified_disks(charts: list[Chart], *, closed: bool = False) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """(k,) bool: which charts :func:`check_chart` certainly accepts, decided for all charts at once;
    with ``closed``, also which it certainly rejects only as closed or with handles (a manifold piece
    in one component: what the charting cuts into disks).

    The same tests on the charts laid end to end (no edge joins two charts, so every count splits by
    chart): a kit of hundreds of small parts paid check_chart's two dozen numpy calls per part. False
    means "ask check_chart" (it raises, or accepts a chart this test left in doubt: the degenerate-
    triangle threshold is taken a hair higher here, as its per-chart mean edge is summed differently).
    """
    k = len(charts)
    if k == 0:
        return (np.zeros(0, bool), np.zeros(0, bool)) if closed else np.zeros(0, bool)
    ok, shut = _disk_tests(charts, k)
    return (ok, shut) if closed else ok


def _disk_tests(charts, k):
    """certified_disks' two masks: (a disk, manifold in one piece but closed or with handles)."""
    nv = np.array([len(c.V) for c in charts], np.int64)       # one per chart
    nf = np.array([len(c.F) for c in charts], np.int64)
    ok = (nv > 0) & (nf > 0)
    if not ok.all():
        return ok & False, ok & False
    voff = np.cumsum(nv) - nv
    cv, cf = np.repeat(np.arange(k), nv), np.repeat(np.arange(k), nf)
    V = np.concatenate([np.asarray(c.V, dtype=np.float64) for c in charts])
    F = np.concatenate([np.asarray(c.F, dtype=np.int64) for c in charts])
    if V.ndim != 2 or V.shape[1] != 3 or F.ndim != 2 or F.shape[1] != 3:
        return ok & False, ok & False
    ok &= np.bincount(cf, weights=((F < 0) | (F >= nv[cf][:, None])).any(axis=1), minlength=k) == 0
    if not ok.all():                                  # out-of-range indices: check_chart names them
        return ok & False, ok & False
    F = F + voff[cf][:, None]
    n = len(V)
    absmax = np.maximum.reduceat(np.abs(V).max(axis=1), voff)
    ok &= np.isfinite(absmax)
    e_exp = np.where(np.isfinite(absmax) & (absmax > 0), np.frexp(np.where(np.isfinite(absmax), absmax, 1.0))[1], 0)
    Vs = np.ldexp(np.where(np.isfinite(V), V, 0.0), -e_exp[cv][:, None])      # check_chart's exact scaling
    rep = (F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 2] == F[:, 0])
    X = Vs[F]
    e = np.linalg.norm(X[:, [1, 2, 0]] - X, axis=2)
    dbl = np.linalg.norm(np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0]), axis=1)
    scale = np.maximum(np.bincount(cf, weights=e.sum(axis=1), minlength=k) / (3 * nf) * (1 + 1e-9),
                       np.finfo(float).tiny)
    degenerate = rep | (dbl <= 1e-12 * np.maximum(e.max(axis=1), scale[cf]) ** 2)
    ok &= np.bincount(cf, weights=degenerate, minlength=k) == 0
    ok &= np.bincount(cv, weights=np.bincount(F.ravel(), minlength=n) == 0, minlength=k) == 0   # unreferenced
    he = F[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    und, cnt = np.unique(np.minimum(he[:, 0], he[:, 1]) * n + np.maximum(he[:, 0], he[:, 1]), return_counts=True)
    ok &= np.bincount(cv[und // n], weights=cnt > 2, minlength=k) == 0       # non-manifold edges
    dk, dcnt = np.unique(he[:, 0] * n + he[:, 1], return_counts=True)
    ok &= np.bincount(cv[dk // n], weights=dcnt > 1, minlength=k) == 0       # opposite orientation
    bow = nonmanifold_vertices(F, n)
    ok[cv[bow]] = False
    # topology per chart: one component, at least one boundary loop, genus 0 (as topology() counts them)
    _, lab = components(n, he[:, 0], he[:, 1])
    comps = unique_sorted(cv.astype(np.int64) * n + lab)
    ok &= np.bincount(comps // n, minlength=k) == 1
    once = np.isin(np.minimum(he[:, 0], he[:, 1]) * n + np.maximum(he[:, 0], he[:, 1]), und[cnt == 1])
    bnd = he[once]
    loops = np.zeros(k, np.int64)
    if len(bnd):
        _, blab = components(n, bnd[:, 0], bnd[:, 1])
        bv = unique_sorted(bnd)
        loops = np.bincount(unique_sorted(cv[bv].astype(np.int64) * n + blab[bv]) // n, minlength=k)
    chi = nv - np.bincount(cv[und // n], minlength=k) + nf
    disk = (loops >= 1) & ((2 - chi - loops) // 2 == 0)             # topology()'s genus, one component
    return ok & disk, ok & ~disk


def chart_numbers(F: np.ndarray, n: int, labels: np.ndarray) -> np.ndarray:
    """(m,) each face's chart in :func:`split_charts`'s numbering: faces of one label joined by edges
    are one chart; charts ordered by (label, first face)."""
    m = len(F)
    fi, fj, _ = face_adjacency(F, n)
    keep = labels[fi] == labels[fj]
    _, comp = components(m, fi[keep], fj[keep])
    first = np.full(comp.max() + 1, m)
    np.minimum.at(first, comp, np.arange(m))
    chart_order = np.lexsort((first, labels[first]))
    rank = np.empty_like(chart_order)
    rank[chart_order] = np.arange(len(chart_order))
    return rank[comp]


def split_charts(V: ArrayLike, F: ArrayLike, labels: ArrayLike | None = None, *,
                 check: bool = True) -> list[Chart]:
    """Split a mesh into charts: one per segment label and edge-connected component.

    Parameters
    ----------
    V : (n,3) float array
    F : (m,3) int array
    labels : (m,) int array, optional
        Per-face segment label; faces of one label that are not edge-connected become separate charts.
    check : bool
        Run :func:`check_chart` on every chart (raising on the first invalid one).

    Returns
    -------
    list of :class:`Chart`, ordered by (label, first face).
    """
    V, F = check_arrays(V, F)
    m = len(F)
    if labels is None:
        labels = np.zeros(m, dtype=np.int64)
        named = False
    else:
        labels = np.asarray(labels)
        if labels.shape != (m,) or not np.issubdtype(labels.dtype, np.integer):
            raise InputError(f"segment labels have shape {labels.shape} and type {labels.dtype}; "
                             f"pass one integer per triangle ({m})")
        named = True
    comp = chart_numbers(F, len(V), labels)
    faces_by_chart = np.argsort(comp, kind="stable")
    bounds = np.searchsorted(comp[faces_by_chart], np.arange(comp.max() + 2))
    charts = []
    for c in range(len(bounds) - 1):           # one iteration per chart, not per triangle
        fidx = faces_by_chart[bounds[c]:bounds[c + 1]]
        Fc = F[fidx]
        vmap, local = dense_ranks(Fc, len(V))
        lab = int(labels[fidx[0]]) if named else -1
        name = f"chart {c}" + (f" (label {lab})" if named else "")
        chart = Chart(V[vmap], local.reshape(-1, 3).astype(np.int64), vmap, fidx, lab, name)
        if check:
            check_chart(chart.V, chart.F, name=name)
        charts.append(chart)
    return charts
