"""Overlap-freedom of one chart's map from its boundary alone.

    proven = boundary_proves_injective(uv, F)    # True: no two triangles of the chart overlap

For a map of a disk with holes that is linear on each triangle, the degree of the map at a point y
off the boundary's image is the winding number of the boundary's image around y, and it equals the
number of triangles covering y when every triangle is positively oriented. When the boundary loops'
images are simple and pairwise disjoint and exactly one of them encloses positive area (the outer
loop, counter-clockwise as a chart's boundary half-edges run; every hole's image clockwise), every
winding number is 0 or 1: no point is covered twice, so no pair of triangles overlaps. The
orientations are checked, not assumed: a hole whose image runs counter-clockwise has the chart on
both sides of it (winding 2 inside), with every triangle positive and every loop simple. Checking that costs a sweep over the b boundary segments instead of the
all-triangle exact check (annulus of 8,192 triangles: 35 ms per call before).

The test is conservative: a touching or collinear contact (other than a straight run of the
boundary), a repeated boundary position, a
degenerate or negative triangle, or too many candidate segment pairs answer False, and the caller
runs the full check (:func:`uvbake.validate.core.overlap_pairs`) for the pairs themselves.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from uvbake.mesh.arrays import unique_sorted
from uvbake.validate.predicates import _orient

#: Candidate boundary-segment pairs above which the sweep gives up (the full check is then cheaper).
MAX_SEGMENT_PAIRS = 2_000_000


def boundary_proves_injective(uv: ArrayLike, F: ArrayLike) -> bool:
    """True when every triangle of (uv, F) is positively oriented (exactly) and the boundary segments
    meet only at the endpoint two consecutive ones share, without folding back: then no two triangles
    overlap. False means "not proven" (run the full check), not "overlapping"."""
    return bool(proven_injective([uv], [F])[0])


def proven_injective(uvs: Sequence[ArrayLike], Fs: Sequence[ArrayLike]) -> np.ndarray:
    """:func:`boundary_proves_injective` of many charts at once (one vectorised pass; charts are
    independent): a (k,) bool array."""
    k = len(uvs)
    uv_list = [np.asarray(uv, dtype=np.float64) for uv in uvs]
    F_list = [np.asarray(F, dtype=np.int64) for F in Fs]
    if not any(len(F) for F in F_list):
        return np.zeros(k, bool)
    nv = np.array([len(uv) for uv in uv_list])
    off = np.concatenate([[0], np.cumsum(nv)[:-1]])
    uv = np.concatenate(uv_list)
    F = np.concatenate([F + o for F, o in zip(F_list, off)])
    face_chart = np.repeat(np.arange(k), [len(F) for F in F_list])
    return _proven(uv, F, face_chart, np.repeat(np.arange(k), nv), uv[np.minimum(off, len(uv) - 1)])


def _proven(uv, F, face_chart, vert_chart, origin, seg=None, sign=None):
    """proven_injective of the charts of one mesh (uv, F): ``face_chart`` and ``vert_chart`` number every
    face's and vertex's chart 0..k-1 (no vertex in two charts), ``origin`` (k,2) a point of each chart.
    ``seg`` (the boundary half-edges) and ``sign`` (each face's exact orientation) when known."""
    from uvbake.mesh.topology import boundary_edges

    k = len(origin)
    ok = np.bincount(face_chart, minlength=k) > 0
    if sign is None:
        A, B, C = uv[F[:, 0]], uv[F[:, 1]], uv[F[:, 2]]
        sign, _ = _orient(A[:, 0], A[:, 1], B[:, 0], B[:, 1], C[:, 0], C[:, 1])
    ok &= np.bincount(face_chart[sign <= 0], minlength=k) == 0
    seg = boundary_edges(F, len(uv)) if seg is None else seg
    seg_chart = vert_chart[seg[:, 0]]
    ok &= np.bincount(seg_chart, minlength=k) >= 3
    bv = unique_sorted(seg)                                # two boundary vertices of one chart at one position
    order = np.lexsort((uv[bv, 1], uv[bv, 0], vert_chart[bv]))
    c, u = vert_chart[bv[order]], uv[bv[order]]
    same = (c[1:] == c[:-1]) & (u[1:] == u[:-1]).all(axis=1)
    ok[c[1:][same]] = False
    i, j = _candidate_pairs(uv, seg, seg_chart)
    if i is None:
        return np.zeros(k, bool)
    shared = (seg[i, 1] == seg[j, 0]) | (seg[i, 0] == seg[j, 1])
    hit = _touch(uv, seg[i[~shared]], seg[j[~shared]])
    ok[seg_chart[i[~shared][hit]]] = False
    # consecutive segments p->q, q->r meet only at q unless r is on the line through p and q and
    # folds back over p->q (a straight continuation, r beyond q, is fine)
    a, b = seg[i[shared]], seg[j[shared]]
    first = a[:, 1] == b[:, 0]
    p = np.where(first, a[:, 0], b[:, 0])
    q = np.where(first, a[:, 1], b[:, 1])
    r = np.where(first, b[:, 1], a[:, 1])
    s, _ = _orient(uv[p, 0], uv[p, 1], uv[q, 0], uv[q, 1], uv[r, 0], uv[r, 1])
    back = np.einsum("ij,ij->i", uv[q] - uv[p], uv[r] - uv[q]) <= 0
    ok[seg_chart[i[shared][(s == 0) & back]]] = False
    ok &= _one_positive_loop(uv, seg, seg_chart, origin)
    return ok


def _one_positive_loop(uv, seg, seg_chart, origin):
    """(k,) whether each chart's boundary is loops of which exactly one encloses positive area: the
    outer one, counter-clockwise; the holes' images clockwise. Simple disjoint loops are not enough:
    a hole whose image runs counter-clockwise has the chart on both sides of it, covering the hole
    twice (a cow's part at --max-charts 1 --max-stretch 100: two loops, both positive, 47 overlapping
    triangle pairs). A vertex starting two boundary segments (a pinch) leaves its chart unproven."""
    from uvbake.mesh.graph import components

    k = len(origin)
    starts = np.bincount(seg[:, 0], minlength=len(uv))
    ok = np.bincount(seg_chart[starts[seg[:, 0]] > 1], minlength=k) == 0
    nxt = np.zeros(len(uv), np.int64)
    nxt[seg[:, 0]] = np.arange(len(seg))                   # the segment leaving each boundary vertex
    _, loop = components(len(seg), np.arange(len(seg)), nxt[seg[:, 1]])
    P, Q = uv[seg[:, 0]], uv[seg[:, 1]]
    # twice each loop's signed area, its segments' cross products summed about its chart's first vertex
    # (about (0, 0), a chart far from it would lose its small loops' digits)
    a, b = P - origin[seg_chart], Q - origin[seg_chart]
    area2 = np.bincount(loop, weights=a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
    loop_chart = np.zeros(len(area2), np.int64)
    loop_chart[loop] = seg_chart
    ok &= np.bincount(loop_chart[area2 > 0], minlength=k) == 1
    return ok


def _candidate_pairs(uv, seg, seg_chart):
    """Index pairs (i, j), i != j, of boundary segments of one chart whose bounding boxes meet (closed
    boxes), or (None, None) past MAX_SEGMENT_PAIRS: a sweep along x per chart, then the y test."""
    P, Q = uv[seg[:, 0]], uv[seg[:, 1]]
    lo, hi = np.minimum(P, Q), np.maximum(P, Q)
    order = np.lexsort((lo[:, 0], seg_chart))          # by chart, then by left end
    ch, xs = seg_chart[order], lo[order, 0]
    # the sorted segments of my chart starting by my right end: search within each chart's block
    block_end = np.searchsorted(ch, ch, side="right")
    end = np.empty(len(order), np.int64)
    starts = np.flatnonzero(np.r_[True, ch[1:] != ch[:-1]])
    stops = np.r_[starts[1:], len(ch)]
    for s0, s1 in zip(starts, stops):                  # one iteration per chart
        end[s0:s1] = s0 + np.searchsorted(xs[s0:s1], hi[order[s0:s1], 0], side="right")
    end = np.minimum(end, block_end)
    count = np.maximum(end - np.arange(len(order)) - 1, 0)
    total = int(count.sum())
    if total > MAX_SEGMENT_PAIRS:
        return None, None
    a = np.repeat(np.arange(len(order)), count)
    b = a + 1 + (np.arange(total) - np.repeat(np.cumsum(count) - count, count))
    i, j = order[a], order[b]
    keep = (lo[i, 1] <= hi[j, 1]) & (lo[j, 1] <= hi[i, 1])
    return i[keep], j[keep]


def _touch(uv, s, t):
    """Whether segments s[k] and t[k] (no shared endpoint) meet: cross, touch, or are collinear and
    overlapping (any zero orientation is taken as a contact: conservative)."""
    if not len(s):
        return np.zeros(0, bool)
    p, q, r, w = uv[s[:, 0]], uv[s[:, 1]], uv[t[:, 0]], uv[t[:, 1]]
    o1, _ = _orient(p[:, 0], p[:, 1], q[:, 0], q[:, 1], r[:, 0], r[:, 1])
    o2, _ = _orient(p[:, 0], p[:, 1], q[:, 0], q[:, 1], w[:, 0], w[:, 1])
    o3, _ = _orient(r[:, 0], r[:, 1], w[:, 0], w[:, 1], p[:, 0], p[:, 1])
    o4, _ = _orient(r[:, 0], r[:, 1], w[:, 0], w[:, 1], q[:, 0], q[:, 1])
    return (o1.astype(np.int64) * o2 <= 0) & (o3.astype(np.int64) * o4 <= 0)


def pair_faces(corners: np.ndarray, vid: np.ndarray, chart: np.ndarray, n_charts: int, twin: np.ndarray,
               dup: np.ndarray, sign: np.ndarray, live: np.ndarray) -> np.ndarray:
    """The faces of ``live`` that can be in an overlapping pair: a chart whose boundary proves it
    injective (:func:`_proven`, on the layout's own welded corners) has no pair inside it, so of its
    faces only those near another chart's (:func:`_near_other_charts`) are kept. The overlapping pairs
    among the faces kept are all those among ``live``.

    Only charts with at least FAR_SHARE of their faces away from the other charts are tried (the
    proof's cost grows with the chart, what it saves with those faces), none unless MIN_FAR_FACES
    faces would go, and not those with a face not live, a directed edge twice (``dup``: a fold or a
    non-manifold edge) or a vertex shared with another chart. corners (m,3,2), vid (m,3) welded corner
    ids, chart (m,) 0..n_charts-1, twin and dup (3m,) (uvbake.validate.candidates._half_edges), sign (m,)
    exact orientations, live (m,) bool.
    """
    from uvbake.validate.candidates import corner_boxes

    m = len(corners)
    bmin, bmax = corner_boxes(corners)
    near = _near_other_charts(bmin, bmax, chart, n_charts, live)
    far = np.bincount(chart[live & ~near], minlength=n_charts)
    tried = far >= FAR_SHARE * np.bincount(chart, minlength=n_charts)
    if far[tried].sum() < MIN_FAR_FACES:
        return live
    tried &= np.bincount(chart[~live], minlength=n_charts) == 0
    tried &= np.bincount(chart[dup.reshape(m, 3).any(axis=1)], minlength=n_charts) == 0
    corner_chart = np.repeat(chart, 3)
    lo_c = np.full(int(vid.max()) + 1, n_charts)
    hi_c = np.full(len(lo_c), -1)
    np.minimum.at(lo_c, vid.ravel(), corner_chart)
    np.maximum.at(hi_c, vid.ravel(), corner_chart)
    tried[chart[(lo_c[vid] != hi_c[vid]).any(axis=1)]] = False
    faces = np.flatnonzero(tried[chart])
    if len(faces) == 0:
        return live
    used, inv = np.unique(vid[faces], return_inverse=True)
    uv = np.zeros((len(used), 2))
    uv[inv.ravel()] = corners[faces].reshape(-1, 2)              # welded corners hold the same UVs
    vert_chart = np.zeros(len(used), np.int64)
    vert_chart[inv.ravel()] = np.repeat(chart[faces], 3)
    origin = np.zeros((n_charts, 2))
    ids, first = np.unique(chart[faces], return_index=True)
    origin[ids] = corners[faces[first], 0]                       # a corner of each chart's first face
    # boundary half-edges: those without a twin (half-edge 3 f + k runs from corner k to corner k + 1)
    F_loc = inv.reshape(-1, 3)
    edge = twin[(3 * faces[:, None] + np.arange(3)).ravel()] < 0
    seg = np.column_stack([F_loc.ravel()[edge], F_loc[:, [1, 2, 0]].ravel()[edge]])
    proven = tried & _proven(uv, F_loc, chart[faces], vert_chart, origin, seg, sign[faces])
    return live & (~proven[chart] | near)


#: pair_faces tries a chart's boundary proof when at least this share of its faces would be dropped,
#: and the proofs when they would drop this many faces at least (each face's box meets about 20 others'
#: in the candidate grid; below this the proofs' fixed cost is more than the pairs they spare).
FAR_SHARE = 0.25
MIN_FAR_FACES = 512


def _near_other_charts(bmin, bmax, chart, n_charts, live):
    """(m,) whether each face's box touches a cell of a grid (uvbake.validate.candidates.grid_cells)
    that another chart's live face touches too. Two faces whose interiors meet both touch the cell of
    the lower-left corner of their boxes' meeting, so a face touching only its own chart's cells is in
    no pair with another chart's."""
    from uvbake.validate.candidates import grid_cells

    near = np.zeros(len(bmin), bool)
    faces = np.flatnonzero(live)
    grid = grid_cells(bmin, bmax, faces, widen=NEAR_CELL) if len(faces) else None
    if grid is None:                         # every box one point: no two interiors meet
        return near
    f, key, _, _ = grid
    touch = unique_sorted(key * n_charts + chart[f])          # distinct (cell, chart)
    cells, count = np.unique(touch // n_charts, return_counts=True)
    shared = cells[count > 1]
    at = np.minimum(np.searchsorted(shared, key), max(len(shared) - 1, 0))
    near[f[shared[at] == key] if len(shared) else f[:0]] = True
    return near


#: Cells of _near_other_charts's grid, in typical face sizes.
NEAR_CELL = 2.0
