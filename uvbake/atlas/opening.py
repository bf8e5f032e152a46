"""Cutting a chart open without making a new chart: the charting's slits and hole links.

    opened, seam = slit(chart, tips)          # shortest paths from protrusion tips to the boundary
    opened, seam, k = open_holes(chart)       # a disk with holes linked into one disk (a tube -> a strip)
    nearly_closed(chart)                      # too many small holes to link: to be cut like a closed piece

Both cut interior edges only, so the chart stays one piece; its vertices on a cut get one copy per side.
The charting (:mod:`uvbake.atlas.charting`) decides when; seams follow :func:`uvbake.mesh.cut.seam_costs`.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from uvbake.mesh.arrays import unique_sorted
from uvbake.mesh.charts import Chart
from uvbake.mesh.graph import components
from uvbake.mesh.topology import boundary_loops, face_adjacency


def slit(chart: Chart, tips: np.ndarray) -> tuple[Chart, float] | None:
    """``chart`` cut open along the shortest edge paths from the vertices ``tips`` to its boundary.

    The path's vertices (but the tip) get one copy per side, so the chart stays one disk with holes:
    a finger-like protrusion, which a conformal map shrinks exponentially towards its tip, becomes a
    strip that flattens with little distortion. The paths come from one shortest-path forest rooted on
    the boundary, so together they form no loop and the chart stays a disk with holes. Returns
    (chart, seam length), or None when no tip is inside the chart.

    In a chart with holes the paths run to the outer border (the longest loop) and through no hole's
    border, when every tip reaches it so: a slit ending at a small hole must open that hole to open at
    all, and the conformal map keeps a hole small, so the slit's sides crossed instead (Open3D's
    ball-pivoting knot: 107 of 119 slits ended at holes; docs/decisions/atlas.md, 2026-12-02)."""
    from scipy.sparse.csgraph import dijkstra

    from uvbake.mesh.topology import boundary_edges

    V, F = chart.V, chart.F
    n = len(V)
    b = boundary_edges(F, n)
    bnd = unique_sorted(b)
    tips = np.setdiff1d(np.asarray(tips, dtype=np.int64), bnd)
    if len(tips) == 0:
        return None
    e, hi, hj, length, g = _seam_graph(chart)
    dist = None
    outer = _outer_border(V, b)
    if outer is not None:                                # a chart with holes: to the outer border, around holes
        dist, pred, src = dijkstra(_without(g, np.setdiff1d(bnd, outer)), directed=False, indices=outer,
                                   min_only=True, return_predecessors=True)
        dist = dist if np.all(np.isfinite(dist[tips])) else None
    if dist is None:
        dist, pred, src = dijkstra(g, directed=False, indices=bnd, min_only=True, return_predecessors=True)
    tips = tips[np.isfinite(dist[tips])]
    if len(tips) == 0:
        return None
    on = np.zeros(n, bool)                               # vertices on some tip's path
    cur = tips
    while len(cur):                                      # one step per path length (~sqrt(n)), vectorised over tips
        on[cur] = True
        cur = pred[cur]
        cur = unique_sorted(cur[(cur >= 0)])
        cur = cur[~on[cur]]
    a = np.flatnonzero(on & (pred >= 0))
    cut = np.isin(e[:, 0] * n + e[:, 1], np.minimum(a, pred[a]) * n + np.maximum(a, pred[a]))
    return _opened(chart, cut, hi, hj), float(length[cut].sum())


def _outer_border(V, b):
    """The vertices of the longest boundary loop (boundary half-edges ``b``), or None when there is
    one loop only."""
    loop, length = boundary_loops(V, b)
    return None if len(length) < 2 else unique_sorted(b[loop == int(np.argmax(length))])


def _without(g, vertices):
    """The graph ``g`` (csr) without the edges at ``vertices``."""
    c = g.tocoo()
    keep = ~(np.isin(c.row, vertices) | np.isin(c.col, vertices))
    return sp.csr_matrix((c.data[keep], (c.row[keep], c.col[keep])), shape=g.shape)


def _seam_graph(chart: Chart) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, sp.csr_matrix]:
    """The chart's interior edges (face_adjacency's ``e``, half-edges ``hi``, ``hj``), their 3D lengths
    and the sparse graph weighing each by its seam cost (:func:`uvbake.mesh.cut.seam_costs`)."""
    from uvbake.mesh.cut import seam_costs

    V, F, n = chart.V, chart.F, len(chart.V)
    fi, fj, e, hi, hj = face_adjacency(F, n, return_halfedges=True)
    length = np.linalg.norm(V[e[:, 0]] - V[e[:, 1]], axis=1)
    cost = np.maximum(seam_costs(V, F, fi, fj, e[:, 0], e[:, 1]), 1e-12 * max(length.max(), 1e-300))
    return e, hi, hj, length, sp.coo_matrix((cost, (e[:, 0], e[:, 1])), shape=(n, n)).tocsr()


def _opened(chart: Chart, cut: np.ndarray, hi: np.ndarray, hj: np.ndarray) -> Chart:
    """``chart`` with its interior edges ``cut`` (a mask over face_adjacency's edges, whose half-edges
    are ``hi``, ``hj``) opened: every vertex gets one copy per fan of triangles left around it."""
    from uvbake.mesh.cut import _corner_fans

    F, n = chart.F, len(chart.V)
    keep = ~cut
    fan = _corner_fans(F, n, hi[keep], hj[keep]).reshape(-1, 3)
    fans, local = np.unique(fan, return_inverse=True)
    corner_of_fan = np.full(fan.max() + 1, -1)
    corner_of_fan[fan.ravel()] = F.ravel()
    verts = corner_of_fan[fans]
    return Chart(chart.V[verts], local.reshape(-1, 3).astype(np.int64), chart.vertex_map[verts], chart.face_index,
                 chart.label, chart.name)


#: open_holes links at most this many loops (the largest); nearly_closed looks at charts with more.
MAX_OPENED_LOOPS = 16


def open_holes(chart: Chart) -> tuple[Chart, float, int] | None:
    """``chart`` (a disk with holes) cut open into a disk along the cheapest seams (seam_costs) that link
    each of its boundary loops to the others: a tube or a band, whose conformal map folds or shrinks one
    end exponentially, becomes a strip that flattens with little distortion, without a new chart.
    Loops are linked one at a time to the set already linked (the first loop), each by one shortest
    path, so the seams form a tree over the loops. Returns (chart, seam length, loops linked), or None
    when fewer than two loops qualify or the chart is not a disk afterwards.

    Only the large loops are linked: those spanning (_loop_spans) at least LINKED_LOOP_SHARE of the
    largest, at most MAX_OPENED_LOOPS of them (a tube's ends, a band's borders). A small hole stays a
    hole (the solve fills it with light fans, :mod:`uvbake.flatten.holes`): linked, it was torn open
    along a long seam, and the chart was cut anyway (halftunnel: links 7.95 long before, 3.94 now,
    two charts either way; docs/decisions/atlas.md, 2026-12-02)."""
    from scipy.sparse.csgraph import dijkstra

    from uvbake.mesh.topology import topology

    V = chart.V
    n = len(V)
    b, loop = _boundary_loops(chart)
    if not len(b):
        return None
    verts = unique_sorted(b)
    ids, loop_of = np.unique(loop[verts], return_inverse=True)
    small = 0
    if len(ids) > 1:                                           # the large loops only: small holes stay holes
        spans = _loop_spans(V, b, np.searchsorted(ids, loop[b[:, 0]]), len(ids))
        big = spans >= LINKED_LOOP_SHARE * spans.max()
        big[np.argsort(-spans, kind="stable")[MAX_OPENED_LOOPS:]] = False     # the largest ones only
        small = len(ids) - int(big.sum())
        keep = big[loop_of]
        verts, loop_of, ids = verts[keep], (np.cumsum(big) - 1)[loop_of[keep]], ids[big]
    if not 2 <= len(ids) <= MAX_OPENED_LOOPS:
        return None
    on_loop = np.full(n, -1)
    on_loop[verts] = loop_of                                   # loops numbered 0..k-1 (small holes: -1)
    e, hi, hj, length, g = _seam_graph(chart)
    linked = np.zeros(len(ids), bool)
    linked[0] = True
    cut_keys = []
    while not linked.all():                                    # one shortest path per loop linked (at most 15)
        src = verts[linked[on_loop[verts]]]
        dist, pred = dijkstra(g, directed=False, indices=src, min_only=True, return_predecessors=True)[:2]
        far = verts[~linked[on_loop[verts]]]
        far = far[np.isfinite(dist[far])]
        if not len(far):
            return None
        path = [int(far[np.argmin(dist[far])])]
        while pred[path[-1]] >= 0:                             # one step per path vertex
            path.append(int(pred[path[-1]]))
        p = np.array(path)
        linked[on_loop[p[on_loop[p] >= 0]]] = True             # every loop the path touches is linked
        cut_keys.append(np.minimum(p[:-1], p[1:]) * n + np.maximum(p[:-1], p[1:]))
    cut = np.isin(e[:, 0] * n + e[:, 1], np.concatenate(cut_keys))
    opened = _opened(chart, cut, hi, hj)
    topo = topology(opened.F, len(opened.V))
    if topo.n_components != 1 or topo.genus != 0 or topo.n_boundary_loops > 1 + small:
        return None
    return opened, float(length[cut].sum()), len(ids) - 1


#: A chart with more boundary loops than open_holes links is cut like a closed piece when its holes
#: (each bounded by the disk of its perimeter) cover at most this share of its area: a scan or a sphere
#: with many small holes, whose conformal map blows one hole up into the outer boundary.
NEARLY_CLOSED_SHARE = 0.05
#: open_holes links only the loops spanning at least this share of the largest loop's span (a quarter
#: of its length): a holey tube's two ends, not a hole that a link to the boundary would tear open.
LINKED_LOOP_SHARE = 1.0 / 16.0


def _area(chart):
    from uvbake.mesh.arrays import triangle_areas

    return float(triangle_areas(chart.V, chart.F).sum())


def _loop_spans(V, b, which, k):
    """(k,) area each of ``k`` boundary loops may span (``which``: the loop of each boundary half-edge
    ``b``): L^2 / (4 pi) for a loop of length L, the disk of its perimeter, which bounds the area of the
    least surface filling it (the isoperimetric inequality; a loop's vector area would not: a tube's
    two ends, opened into one loop, cancel)."""
    length = np.bincount(which, weights=np.linalg.norm(V[b[:, 1]] - V[b[:, 0]], axis=1), minlength=k)
    return length ** 2 / (4.0 * np.pi)


def nearly_closed(chart: Chart) -> bool:
    """Whether ``chart`` (a disk with holes) has more than MAX_OPENED_LOOPS boundary loops that together
    span (_loop_spans) at most NEARLY_CLOSED_SHARE of its area: closed but for small holes."""
    b, loop = _boundary_loops(chart)
    ids, which = np.unique(loop[b[:, 0]], return_inverse=True)
    if len(ids) <= MAX_OPENED_LOOPS:
        return False
    return bool(_loop_spans(chart.V, b, which, len(ids)).sum() <= NEARLY_CLOSED_SHARE * _area(chart))


def _boundary_loops(chart):
    """(boundary half-edges (b,2), each vertex's boundary-loop label (n,)) of ``chart``."""
    from uvbake.mesh.topology import boundary_edges

    n = len(chart.V)
    b = boundary_edges(chart.F, n)
    return b, components(n, b[:, 0], b[:, 1])[1]
