"""Charting: decide the charts before solving, under a distortion budget.

    charts, starts, log = make_charts(V, F, labels, max_stretch=4.0, max_charts=None)

1. One chart per user label and edge-connected piece (never across labels; the input's own cuts
   stay cuts). Closed pieces and pieces with handles are cut into disks (:func:`uvbake.mesh.cut.cut_to_disks`).
2. Each chart gets one conformal map (LSCM, one sparse solve). Its area factor per triangle,
   relative to the chart's mean, predicts the texels the triangle will get: a conformal map shrinks
   protrusions exponentially (legs, ears, horns). A chart is kept when every factor lies within
   [1/max_stretch, max_stretch] and nothing is flipped; the conformal map is then the solver's start.
3. Otherwise the chart is cut along an iso-contour of its (vertex-smoothed) log area factor: the
   sweep cut of that field with the least conductance (cut length / smaller side's area,
   :func:`uvbake.mesh.cut._sweep`), so the seam is a short loop around a protrusion. Every
   edge-connected piece on either side becomes a chart (all legs at once); slivers are given back to
   their longest-bordering neighbour. Pieces go back to step 2. All of this is counted work:
   ``max_charts`` (the user's chart budget) and a fixed cap on conformal solves end it, never time.

A piece's vertices are its corner fans (corners joined across the piece's own edges), so two parts of
a piece meeting at one vertex get their own copies of it and every piece is manifold.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from uvbake.atlas.conformal import _frames, conformal_factor, conformal_factors
from uvbake.atlas.guarantee import COLLAPSED
from uvbake.atlas.opening import nearly_closed, open_holes, slit
from uvbake.errors import ChartError, InputError
from uvbake.mesh.arrays import dense_ranks, face_means, triangle_areas, unique_sorted, unit_normals
from uvbake.mesh.charts import Chart, certified_disks, check_chart, split_charts
from uvbake.mesh.graph import components
from uvbake.mesh.topology import face_adjacency

#: Default distortion budget (area factor within [1/4, 4] of the chart's mean); see docs/decisions/atlas.md.
DEFAULT_MAX_STRETCH = 4.0
#: Pieces smaller than this share of their parent's area (or with fewer than MIN_PIECE_FACES
#: triangles) are given to a neighbour instead of becoming charts.
SLIVER_SHARE = 0.002
MIN_PIECE_FACES = 8
#: Rounds of overlap checks of the accepted conformal maps (each: one exact check, split, re-chart).
OVERLAP_ROUNDS = 4
#: Cap on conformal solves per initial chart (work count; a chart past it is kept as it is).
MAX_SOLVES_PER_CHART = 400


def check_budget(max_stretch: float, max_charts: int | None) -> tuple[float, int | None]:
    try:
        ms = float(max_stretch)
    except (TypeError, ValueError):
        raise InputError(f"max_stretch={max_stretch!r} is not a number; pass a factor above 1, e.g. 4") from None
    if not (np.isfinite(ms) and ms > 1.0):
        raise InputError(f"max_stretch={max_stretch!r} must be a number above 1 (each triangle keeps at least "
                         "1/max_stretch of its chart's texel density), e.g. 4")
    if max_charts is not None and (isinstance(max_charts, bool) or int(max_charts) != max_charts or max_charts < 1):
        raise InputError(f"max_charts={max_charts!r} must be a positive whole number (or None for no limit)")
    return ms, (None if max_charts is None else int(max_charts))


def disk_charts(V: ArrayLike, F: ArrayLike, labels: ArrayLike | None, *,
                auto_cut: bool = True, max_charts: int | None = None,
                creases: bool = False) -> tuple[list[Chart], list[dict]]:
    """Charts from labels and edge-connected pieces, with ``creases`` split along sharp creases (when
    that makes at most ``max_charts``: the budget's charting, which merges them back); closed pieces
    and handles cut into disks.

    Returns (charts, cuts): cuts lists one dict per piece that had to be cut."""
    from uvbake.mesh.cut import cut_to_disks, seam_length

    out, cuts = [], []
    pieces = split_charts(V, F, labels, check=False)
    if auto_cut and creases:
        creased = [p for c in pieces for p in _crease_parts(c)]
        # the creases are a preference, the chart budget a promise: no crease split past max_charts
        pieces = creased if max_charts is None or len(creased) <= max_charts else pieces
    certified, shut = certified_disks(pieces, closed=True)
    for c, sure, to_cut in zip(pieces, certified, shut):   # one iteration per piece; the checks ran on all at once
        # a piece in doubt asks check_chart (which raises for what no cut repairs); a closed one is cut
        disk = sure or (not (to_cut and auto_cut) and _is_disk(c, auto_cut))
        if disk:
            out.append(c)
            continue
        # check_chart found it manifold; every label of cut_to_disks is a disk with holes (its contract)
        sub = cut_to_disks(c.V, c.F, manifold=True)
        parts = sub_charts(c, sub)
        cuts.append(dict(chart=c.name, parts=len(parts), seam_length=seam_length(c.V, c.F, sub)))
        out.extend(parts)
    return out, cuts


def _is_disk(c, auto_cut):
    """check_chart's verdict on a piece: True for a disk with holes, False for a manifold piece that is
    closed or has handles (to be cut: only with ``auto_cut``, else a ChartError saying so); any other
    problem raises check_chart's ChartError."""
    try:
        check_chart(c.V, c.F, name=c.name)
        return True
    except ChartError as exc:
        if not ("closed" in str(exc) or "handle" in str(exc)):
            raise
        if not auto_cut:
            raise ChartError(f"{exc} (or leave auto_cut=False out to let uvbake cut it)") from None
    return False


#: Edges whose triangles' normals are at least this far apart split a piece into charts before anything
#: else (a box's faces, a machined part's patches); the charting merges them back where that stays
#: within the budget.
CREASE_SPLIT = np.radians(60.0)


def _crease_parts(chart: Chart) -> list[Chart]:
    """``chart`` split along its sharp creases (CREASE_SPLIT), parts below SLIVER_SHARE of its area or
    MIN_PIECE_FACES given to a neighbour; [chart] when it has no crease that separates anything."""
    F, n = chart.F, len(chart.V)
    if len(F) < 2 * MIN_PIECE_FACES:
        return [chart]
    adj = face_adjacency(F, n, return_halfedges=True)
    fi, fj = adj[:2]
    nrm = unit_normals(chart.V, F)
    smooth = np.einsum("ij,ij->i", nrm[fi], nrm[fj]) > np.cos(CREASE_SPLIT)
    m = len(F)
    nc, comp = components(m, fi[smooth], fj[smooth])
    if nc == 1:
        return [chart]
    lab = _absorb_slivers(F, n, comp, triangle_areas(chart.V, F), SLIVER_SHARE, adj)
    if len(unique_sorted(lab)) < 2:
        return [chart]
    return sub_charts(chart, lab, adj)


def sub_charts(chart: Chart, sub_labels: ArrayLike, adjacency: tuple | None = None) -> list[Chart]:
    """Split ``chart`` by per-face labels into edge-connected, manifold charts of the whole mesh.

    Each part's vertices are its corner fans, so parts touching themselves at a vertex get one copy
    of that vertex per fan. Parts are ordered by first triangle. ``adjacency``: the chart's
    ``face_adjacency(F, n, return_halfedges=True)``, when the caller has it."""
    F = chart.F
    m, n = len(F), len(chart.V)
    lab = np.asarray(sub_labels, dtype=np.int64)
    fi, fj, _, hi, hj = face_adjacency(F, n, return_halfedges=True) if adjacency is None else adjacency
    same = lab[fi] == lab[fj]
    nc, comp = components(m, fi[same], fj[same])
    from uvbake.mesh.cut import _corner_fans

    fan = _corner_fans(F, n, hi[same], hj[same]).reshape(-1, 3)
    first = np.full(nc, m)
    np.minimum.at(first, comp, np.arange(m))
    order = np.argsort(first, kind="stable")
    by = np.argsort(comp, kind="stable")
    bounds = np.searchsorted(comp[by], np.arange(nc + 1))
    parts = []
    for k, c in enumerate(order):                       # one iteration per part
        fidx = by[bounds[c]:bounds[c + 1]]
        fans, local = dense_ranks(fan[fidx], int(fan.max()) + 1)
        corner_of_fan = np.full(fan.max() + 1, -1)
        corner_of_fan[fan[fidx].ravel()] = F[fidx].ravel()
        verts = corner_of_fan[fans]
        parts.append(Chart(chart.V[verts], local.reshape(-1, 3).astype(np.int64), chart.vertex_map[verts],
                           chart.face_index[fidx], chart.label, f"{chart.name}.{k}"))
    return parts


#: Charts of at most BATCH_FACES triangles have their conformal maps solved together (BATCH_TRIANGLES
#: triangles a system) when there are at least BATCH_CHARTS of them: a kit of small parts paid one sparse
#: assembly and factorisation per part. Fewer small charts keep a solve each, as they always had.
BATCH_FACES = 512
BATCH_CHARTS = 32
BATCH_TRIANGLES = 20000

#: At most this many protrusion tips are slit open per conformal solve.
MAX_TIPS = 32


def _tips(chart, logf, area, bound):
    """Vertices at local minima of the vertex-smoothed log area factor that break the budget."""
    F, n = chart.F, len(chart.V)
    finite = np.isfinite(logf)
    low = logf[finite].min() - 1.0 if finite.any() else 0.0
    x = np.where(finite, logf, low)
    w = np.repeat(area, 3)
    xv = np.bincount(F.ravel(), weights=w * np.repeat(x, 3), minlength=n) / np.maximum(
        np.bincount(F.ravel(), weights=w, minlength=n), 1e-300)
    e = F[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    a, b = e[:, 0], e[:, 1]
    lower = (xv[b] < xv[a]) | ((xv[b] == xv[a]) & (b < a))
    is_min = np.ones(n, bool)
    is_min[a[lower]] = False
    lower = (xv[a] < xv[b]) | ((xv[a] == xv[b]) & (a < b))
    is_min[b[lower]] = False
    cand = np.flatnonzero(is_min & (xv < -bound))
    return cand[np.argsort(xv[cand], kind="stable")][:MAX_TIPS]


#: An interior vertex whose triangles' angles sum to less than this share of a full turn (or more than
#: its inverse) is a cone's tip (or a saddle) a conformal map cannot flatten without shear.
CONE_SHARE = 0.75


def _cone_tips(chart, uv, logf, area, bound):
    """Tips to slit open: when the conformal map ``uv`` shears a triangle past the budget (sigma1/sigma2
    above max_stretch^2, the guarantee's bound) or starves one, the chart's interior vertices whose angle
    sum is off a full turn by CONE_SHARE (cone tips and saddles, sharpest first), and the tips of the
    log factor (:func:`_tips`); none when the map keeps both bounds."""
    from uvbake.atlas.guarantee import shear_ratios
    from uvbake.mesh.topology import boundary_edges

    sheared = bool(np.any(shear_ratios(chart.V, chart.F, uv) > np.exp(2.0 * bound)))
    starved = not bool(np.all(np.isfinite(logf)) and logf.min() >= -bound)
    if not (sheared or starved):
        return np.zeros(0, np.int64)
    V, F, n = chart.V, chart.F, len(chart.V)
    X = V[F]
    total = np.zeros(n)
    for k in range(3):                                  # each corner's angle, summed per vertex
        a, b = X[:, (k + 1) % 3] - X[:, k], X[:, (k + 2) % 3] - X[:, k]
        cos = np.einsum("ij,ij->i", a, b) / np.maximum(np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1), 1e-300)
        np.add.at(total, F[:, k], np.arccos(np.clip(cos, -1.0, 1.0)))
    inner = np.ones(n, bool)
    inner[unique_sorted(boundary_edges(F, n))] = False
    turn = total / (2.0 * np.pi)
    cone = np.flatnonzero(inner & ((turn < CONE_SHARE) | (turn > 1.0 / CONE_SHARE)))
    cone = cone[np.argsort(-np.abs(np.log(turn[cone])), kind="stable")]
    return np.concatenate([cone, np.setdiff1d(_tips(chart, logf, area, bound), cone)])[:MAX_TIPS]


def _smoothed(F, n, logf, area):
    """The log factor averaged onto vertices (area-weighted) and back onto triangles."""
    finite = np.isfinite(logf)
    low = logf[finite].min() - 1.0 if finite.any() else 0.0
    x = np.where(finite, logf, low)
    w = np.repeat(area, 3)
    num = np.bincount(F.ravel(), weights=w * np.repeat(x, 3), minlength=n)
    den = np.bincount(F.ravel(), weights=w, minlength=n)
    xv = num / np.maximum(den, 1e-300)
    return face_means(xv, F)


def _absorb_slivers(F, n, comp_labels, area, min_share, adjacency=None):
    """Give pieces below ``min_share`` of the area (or MIN_PIECE_FACES) to their longest neighbour.
    ``adjacency``: ``face_adjacency(F, n, ...)``, when the caller has it."""
    m = len(F)
    fi, fj = face_adjacency(F, n)[:2] if adjacency is None else adjacency[:2]
    lab = comp_labels.copy()
    for _ in range(4):                                  # a few passes settle chains of slivers
        same = lab[fi] == lab[fj]
        nc, comp = components(m, fi[same], fj[same])
        size = np.bincount(comp, weights=area, minlength=nc)
        cnt = np.bincount(comp, minlength=nc)
        small = (size < min_share * area.sum()) | (cnt < MIN_PIECE_FACES)
        if not small.any() or nc == 1:
            return comp
        cross = comp[fi] != comp[fj]
        a, b = comp[fi[cross]], comp[fj[cross]]
        a, b = np.concatenate([a, b]), np.concatenate([b, a])
        keep = small[a]
        a, b = a[keep], b[keep]
        if len(a) == 0:
            return comp
        # prefer a neighbour that is not itself small, then the longest shared border (face count)
        key = a * nc + b
        uk, cnts = np.unique(key, return_counts=True)
        ua, ub = uk // nc, uk % nc
        score = cnts + np.where(small[ub], 0, m)
        best = np.lexsort((-score, ua))
        first = np.concatenate([[True], ua[best][1:] != ua[best][:-1]])
        target = np.arange(nc)
        target[ua[best][first]] = ub[best][first]
        # two slivers pointing at each other: the lower id wins, so nothing swaps forever
        mutual = target[target] == np.arange(nc)
        target[mutual & (np.arange(nc) < target)] = np.arange(nc)[mutual & (np.arange(nc) < target)]
        lab = target[comp]
    return lab


def _level_cut(field, fi, fj, w, area, lo, hi):
    """Labels (m,) in {0,1}: 0 below the level in [lo, hi] whose iso-contour is shortest.

    Triangles are sorted by ``field``; the seam of the prefix of size k is the total length of the
    dual edges with one end inside, for every k at once (sorting and cumulative sums)."""
    from uvbake.mesh.cut import prefix_cuts

    m = len(field)
    order, cut = prefix_cuts(field, fi, fj, w)         # cut[k]: seam of the prefix of size k
    fs = field[order]
    k = np.arange(m + 1)
    level = np.concatenate([[fs[0]], fs])              # the level just reached by prefix k
    ok = (k >= 1) & (k <= m - 1) & (level >= lo) & (level <= hi)
    if not ok.any():                                   # no triangle in the window: the nearest level
        mid = 0.5 * (lo + hi)
        kk = int(np.clip(np.searchsorted(fs, mid), 1, m - 1))
    else:
        kk = int(np.argmin(np.where(ok, cut, np.inf)))
    labels = np.ones(m, np.int64)
    labels[order[:kk]] = 0
    return labels


def _cut_by_factor(chart, logf, bound, *, area=None, adjacency=None):
    """Labels cutting ``chart`` along a short iso-contour of its log area factor.

    The level is searched on the side that breaks the budget, between a quarter and the whole of the
    budget away from the area-weighted median level; every piece on either side becomes a chart.
    ``adjacency``: the chart's ``face_adjacency(F, n, return_halfedges=True)``, when known."""
    from uvbake.mesh.cut import seam_costs, split_where

    V, F = chart.V, chart.F
    m, n = len(F), len(V)
    if area is None:
        X = V[F]
        area = 0.5 * np.linalg.norm(np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0]), axis=1)
    field = _smoothed(F, n, logf, area)
    o = np.argsort(field, kind="stable")
    ref = field[o][np.searchsorted(np.cumsum(area[o]), 0.5 * area.sum())]
    adjacency = face_adjacency(F, n, return_halfedges=True) if adjacency is None else adjacency
    fi, fj, e = adjacency[:3]
    w = seam_costs(V, F, fi, fj, e[:, 0], e[:, 1])
    if ref - field.min() >= field.max() - ref:
        # a folded map: no level below the budget (log factor -bound against the mean), so every
        # region starving against the mean is cut off in this one round, not one region per re-solve
        # of the rest (halftunnel: 42 of 237 starving triangles stayed with the median's window).
        # Levels from the mean throughout starved camelhead and cow at alpha 0 (least share 0.20-0.23).
        lo = max(ref - bound, -bound) if not np.all(np.isfinite(logf)) else ref - bound
        side = _level_cut(field, fi, fj, w, area, lo, max(ref - 0.25 * bound, lo))
    else:
        side = _level_cut(field, fi, fj, w, area, ref + 0.25 * bound, ref + bound)
    lab = _absorb_slivers(F, n, side, area, SLIVER_SHARE, adjacency)
    if len(unique_sorted(lab)) < 2:
        bad = np.flatnonzero(~np.isfinite(logf) | (logf < ref - bound))
        lab = split_where(V, F, bad) if m >= 2 else np.zeros(m, np.int64)
    return lab


@dataclass
class _Charting:
    """The charting stage's state, passed between its steps: the queue of candidate charts (each with
    the least log factor of the chart it was slit from, or None), the decided charts and their
    conformal maps, the log, and the work counts that end it."""

    bound: float                     # log(max_stretch)
    max_charts: int | None
    budget_solves: int
    queue: list
    frames: tuple                    # (Q, area) of every mesh triangle: a chart's are frames[k][face_index]
    done: list = dataclasses.field(default_factory=list)
    starts: list = dataclasses.field(default_factory=list)
    budget_cuts: list = dataclasses.field(default_factory=list)
    over: list = dataclasses.field(default_factory=list)
    solves: int = 0
    solved_triangles: int = 0        # triangles of every conformal solve (the stage's work count)
    solved: dict = dataclasses.field(default_factory=dict)   # id(chart) -> (chart, its conformal map), solved ahead
    pinch_keys: np.ndarray | None = None   # per mesh vertex (uvbake.flatten.pinches), or None: no pinch

    def keys(self, chart):
        """The pinch keys of ``chart``'s vertices, or None."""
        return None if self.pinch_keys is None else self.pinch_keys[chart.vertex_map]

    def chart_frames(self, chart):
        """(Q, area) of the chart's triangles: intrinsic to each triangle and its corner order, which
        cuts, slits and joins keep, so they are taken from the mesh's, computed once."""
        return self.frames[0][chart.face_index], self.frames[1][chart.face_index]

    def conformal(self, chart, frames=None):
        """:func:`conformal_factor` of ``chart`` (solved already when it was one of many small charts),
        counted."""
        self.solves += 1
        self.solved_triangles += len(chart.F)
        if id(chart) in self.solved:
            return self.solved.pop(id(chart))[1]
        return conformal_factor(chart.V, chart.F, frames=self.chart_frames(chart) if frames is None else frames,
                                keys=self.keys(chart))

    def solve_small_together(self, charts, at_least=None):
        """Solve the conformal maps of ``charts`` of at most BATCH_FACES triangles together, when there
        are at least ``at_least`` (default BATCH_CHARTS) of them (a kit's parts, a scan's fragments), in
        groups of at most BATCH_TRIANGLES triangles: one factorisation per group
        (:func:`conformal_factors`; each map equals its own solve's to rounding, about 1e-15 relative)."""
        small = [c for c in charts if len(c.F) <= BATCH_FACES and id(c) not in self.solved]
        if len(small) < (BATCH_CHARTS if at_least is None else at_least):
            return
        size = np.cumsum([len(c.F) for c in small])
        group = size // BATCH_TRIANGLES
        for g in unique_sorted(group):                      # one per group of charts
            part = [c for c, k in zip(small, group) if k == g]
            fr = [self.chart_frames(c) for c in part]
            keys = None if self.pinch_keys is None else [self.keys(c) for c in part]
            for c, res in zip(part, conformal_factors([c.V for c in part], [c.F for c in part], fr, keys)):
                self.solved[id(c)] = (c, res)           # the chart held: its id stays its own

    def full(self):
        return self.max_charts is not None and len(self.done) + len(self.queue) + 1 >= self.max_charts


def make_charts(V: ArrayLike, F: ArrayLike, labels: ArrayLike | None = None, *,
                max_stretch: float = DEFAULT_MAX_STRETCH, max_charts: int | None = None, auto_cut: bool = True,
                progress: Callable[[str, int, int], None] | None = None,
                pinch_keys: np.ndarray | None = None) -> tuple[list[Chart], list, dict]:
    """Charts of (V, F) that flatten within the distortion budget, with their conformal start maps.
    ``pinch_keys``: per vertex of V (:func:`uvbake.flatten.pinches.repair_copies`), or None: each
    pinch of a chart is one vertex of its conformal maps.

    Returns
    -------
    charts : list of Chart        ordered as they were decided (deterministic)
    starts : list of (k,2) arrays  each chart's conformal map (every triangle det > 0 when the chart is
                                   within the budget)
    log : dict                     JSON-ready: initial disk cuts, budget cuts, charts kept over budget
    """
    max_stretch, max_charts = check_budget(max_stretch, max_charts)
    note = progress or (lambda stage, done, total: None)
    disks, cuts = disk_charts(V, F, labels, auto_cut=auto_cut, max_charts=max_charts, creases=True)
    st = _Charting(float(np.log(max_stretch)), max_charts, MAX_SOLVES_PER_CHART * len(disks),
                   [(c, None) for c in disks], _frames(np.asarray(V, dtype=np.float64), np.asarray(F, dtype=np.int64)),
                   pinch_keys=pinch_keys)
    st.solve_small_together(disks)
    checked, rounds = 0, 0
    while True:                                         # rounds: conformal charts, then their overlaps
        while st.queue:                                 # one iteration per conformal solve
            _decide(st, *st.queue.pop(0))
            note("charts", len(st.done), len(st.done) + len(st.queue))
        # the queue is always drained after a separation (the parts of the last one were once dropped)
        if rounds == OVERLAP_ROUNDS or not _separate_overlaps(st, checked):
            break
        rounds, checked = rounds + 1, len(st.done)
    from uvbake.atlas.merge import merge_back

    merge_back(st)
    for i, c in enumerate(st.done):
        c.name = f"chart {i}" + (f" (label {c.label})" if c.label >= 0 else "")
    return st.done, st.starts, dict(cuts=cuts, budget_cuts=st.budget_cuts, over_budget=st.over,
                                    conformal_solves=st.solves, conformal_triangles=st.solved_triangles)


def _decide(st, chart, previous):
    """One conformal solve of ``chart``: keep it (within the budget, or a work count says stop), or
    slit it (while slits pay: the least factor at least doubles; a slit adds no chart), or cut it."""
    frames = st.chart_frames(chart)
    uv, logf = st.conformal(chart, frames)
    ok = bool(np.all(np.isfinite(logf)) and logf.min() >= -st.bound)
    small = len(chart.F) < 2 * MIN_PIECE_FACES
    if _slit_cone(st, chart, uv, logf, frames[1], previous, small or ok):
        return
    if _kept(st, chart, uv, logf, ok, small):
        return
    least = float(logf.min())
    halves = _halves(chart) if nearly_closed(chart) else None
    if halves is not None:                              # too many small holes to link: bisected like a sphere
        st.budget_cuts.append(dict(chart=chart.name, triangles=int(len(chart.F)), parts=len(halves), nearly_closed=True,
                                   least_factor=float(np.exp(least))))
        st.queue.extend((p, None) for p in halves)
        return
    holes = open_holes(chart)
    if holes is not None:                               # a tube or band: link its loops first (no new chart)
        st.budget_cuts.append(dict(chart=chart.name, triangles=int(len(chart.F)), parts=1, holes_linked=holes[2],
                                   seam_length=holes[1], least_factor=float(np.exp(least))))
        st.queue.insert(0, (holes[0], least))
        return
    slitted = None
    if previous is None or least > previous + np.log(2.0):
        slitted = slit(chart, _tips(chart, logf, frames[1], st.bound))
    if slitted is not None:
        chart2, length = slitted
        st.budget_cuts.append(dict(chart=chart.name, triangles=int(len(chart.F)), parts=1, slit=True,
                                   seam_length=length, least_factor=float(np.exp(least))))
        st.queue.insert(0, (chart2, least))
        return
    adj = face_adjacency(chart.F, len(chart.V), return_halfedges=True)
    parts = sub_charts(chart, _cut_by_factor(chart, logf, st.bound, area=frames[1], adjacency=adj), adj)
    st.budget_cuts.append(dict(chart=chart.name, triangles=int(len(chart.F)), parts=len(parts),
                               least_factor=float(np.exp(least))))
    for p in parts:
        inherited = _inherited_map(chart, uv, p, st.chart_frames(p)[1], st.bound)
        if inherited is None:
            st.queue.append((p, None))
        else:                                           # within the budget on the parent's map: no solve
            st.done.append(p)
            st.starts.append(inherited)


def _kept(st, chart, uv, logf, ok, small):
    """Keep ``chart`` with its map ``uv`` when it is within the budget (``ok``), too small to cut, past the
    chart budget, or a work count says stop (the last three recorded as over the budget); False when it
    is to be cut. Past the chart budget a chart is still cut while its map collapses triangles (area
    factor COLLAPSED or less: a validity matter, as a flip)."""
    full = st.full() and bool(np.all(np.isfinite(logf)) and logf.min() > np.log(COLLAPSED))
    if not (ok or small or full or st.solves >= st.budget_solves):
        return False
    if not ok:
        reason = "max_charts" if full else "too small to cut" if small else "work cap"
        st.over.append(dict(chart=chart.name, triangles=int(len(chart.F)),
                            least_factor=float(np.exp(logf.min())), reason=reason))
    st.done.append(chart)
    st.starts.append(uv)
    return True


def _slit_cone(st, chart, uv, logf, area, previous, keep):
    """Slit ``chart`` open from its cone tips (:func:`_cone_tips`) and queue it again; False when the
    chart would not be kept as it is (``keep``: within the budget or too small to cut; the budget's
    cuts come next), its map keeps the budget, no tip is found, a work count says stop, or an earlier
    slit did not pay.

    A cone's tip inside a chart: no discrete conformal map lays its fan flat without shearing it past
    the budget, and the solve only makes it worse, where a slit from the tip opens the fan into a
    wedge that lies flat (docs/decisions/atlas.md). A slit adds no chart, so small charts are slit too."""
    if not keep or st.full() or st.solves >= st.budget_solves or \
            not (previous is None or logf.min() > previous + np.log(2.0)):
        return False
    tips = _cone_tips(chart, uv, logf, area, st.bound)
    slitted = slit(chart, tips) if len(tips) else None
    if slitted is None:
        return False
    st.budget_cuts.append(dict(chart=chart.name, triangles=int(len(chart.F)), parts=1, slit=True,
                               seam_length=slitted[1], least_factor=float(np.exp(logf.min())), cone=True))
    st.queue.insert(0, (slitted[0], float(logf.min())))
    return True


def _halves(chart):
    """``chart`` cut in two like a closed piece (:func:`uvbake.mesh.cut.bisect`), or None when the
    bisection finds no two valid sides (holes can leave a side meeting itself at a vertex)."""
    from uvbake.mesh.cut import bisect

    try:
        lab = bisect(chart.V, chart.F)
    except ChartError:
        return None
    return sub_charts(chart, lab, face_adjacency(chart.F, len(chart.V), return_halfedges=True))


def _inherited_map(parent, uv, part, area, bound):
    """The parent's conformal map restricted to ``part`` when that alone keeps the part within the
    budget (every triangle's area factor against the part's own mean at least exp(-bound)), else
    None. A conformal map restricted to a piece is a conformal map of the piece, so the part is
    decided without a solve of its own (cow: 31 of 65 cut parts, fandisk 13 of 19)."""
    from uvbake.atlas.guarantee import _local_vertices

    sub = uv[_local_vertices(parent, part)]
    U = sub[part.F]
    e1, e2 = U[:, 1] - U[:, 0], U[:, 2] - U[:, 0]
    a2 = 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    if not np.all(a2 > 0):
        return None
    logf = np.log(a2 / area) - np.log(a2.sum() / area.sum())
    if logf.min() < -bound:
        return None
    from uvbake.atlas.guarantee import shear_ratios

    # a part holding a cone's tip, sheared by the parent's map, is decided on its own (_cone_tips)
    return sub if np.all(shear_ratios(part.V, part.F, sub) <= np.exp(2.0 * bound)) else None


def _separate_overlaps(st, checked):
    """Conformal maps that overlap themselves (mostly slit sides that cross instead of opening)
    predict the solve's overlaps: split the charts decided since ``checked`` between their two sheets
    now, before solving, and queue the parts. Returns whether anything was queued."""
    from uvbake.atlas.guarantee import overlapping_pairs, separating_split

    fresh = list(range(checked, len(st.done)))
    pairs = overlapping_pairs([st.done[i] for i in fresh], [st.starts[i] for i in fresh])
    bad = {i: p for i, p in zip(fresh, pairs) if len(p) and len(st.done[i].F) >= 2}
    if not bad or (st.max_charts is not None and len(st.done) + len(bad) > st.max_charts):
        return False
    keep = [i for i in range(len(st.done)) if i not in bad]
    for i in sorted(bad):
        parts, _, rec = separating_split(st.done[i], st.starts[i], bad[i])
        st.budget_cuts.append(rec)
        st.queue.extend((p, None) for p in parts)
    st.done, st.starts = [st.done[i] for i in keep], [st.starts[i] for i in keep]
    return True
