"""Merging charts back: the charting stage's last step (:func:`uvbake.atlas.charting.make_charts`).

    merge_back(state)          # state: the charting's _Charting (decided charts, their conformal maps)
    joined = join_charts(a, b) # one chart of two neighbours, or None when it would not be a disk

The budget loop cuts greedily, one chart at a time, and some parts do not need their own chart once
their neighbour is cut too. Measurements: docs/decisions/atlas-speed.md.
"""

from __future__ import annotations

import bisect
from typing import TYPE_CHECKING

import numpy as np

from uvbake.mesh.arrays import pieces, unique_sorted
from uvbake.mesh.charts import Chart
from uvbake.mesh.graph import components

if TYPE_CHECKING:
    from uvbake.atlas.charting import _Charting

#: Merge attempts per chart (each one conformal solve of the merged chart and one overlap check).
MERGE_TRIES = 2
#: A merged chart's least area factor must be at least max_stretch ** -MERGE_SHARE_OF_BUDGET.
MERGE_SHARE_OF_BUDGET = 0.5


def merge_back(st: _Charting) -> None:
    """Merge charts back into a neighbour when the merged chart still flattens within the budget
    with no overlap: budget cuts and overlap separations are decided greedily, one chart at a time,
    and some of their parts turn out not to need their own chart once their neighbour is cut too
    (halftunnel: 13 charts, 4 of them from separating small overlapping sheets). Smallest charts
    first, each tried against its MERGE_TRIES neighbours of the same label with the longest shared
    border; a merged chart is tried again later as a whole. Counted work: at most MERGE_TRIES
    attempts per chart, never time. Charts keep their slot in ``st.done`` until the end (a merge puts
    the joined chart in the lower slot and empties the other), so a merge costs what its neighbourhood
    costs, not the whole atlas."""
    from uvbake.atlas.guarantee import area_factors, overlapping_pairs

    serial = list(range(len(st.done)))                 # identity of each chart (merged ones get new numbers)
    fresh = len(st.done)                               # the next merged chart's number
    tried: set[tuple[int, int]] = set()
    cache: dict = {}                                   # boundary of each chart, computed once
    _fill_boundaries(st.done, cache)
    borders = _Borders(st.done, cache)
    # only charts with a neighbour are ever ranked or merged: a chart alone (a kit's part, a scan's
    # fragment) needs neither its area nor its least factor (0 keeps the others' relative ranks)
    area = [_area(c) if len(borders.out[k][0]) else 0.0 for k, c in enumerate(st.done)]
    least: list = [None] * len(st.done)                # each chart's least area factor, when first needed
    order = _MergeOrder(borders, area, serial, tried)
    ahead: dict = {}                                   # pair of charts (ids) -> the two and their join, made ahead
    while (pair := order.first()) is not None:
        i, j = pair
        key = _pair(id(st.done[i]), id(st.done[j]))
        if key not in ahead:
            _join_ahead(st, order.walk(), cache, ahead)
        tried.add(_pair(serial[i], serial[j]))         # a pair is tried once, from either side
        _, _, merged, proven = ahead.pop(key)
        if merged is None:
            continue
        uv, logf = st.conformal(merged)
        # within half the budget (in log terms), or no worse than the worse of the two: the LM moves
        # factors after the merge (camelhead at alpha 0: least share 0.19 against 0.31 with the whole budget)
        # (a chart kept over budget may be folded: its least factor is <= 0, and the budget decides)
        for k in (i, j):
            if least[k] is None:
                least[k] = float(area_factors(st.done[k], st.starts[k]).min())
        floor = min(-MERGE_SHARE_OF_BUDGET * st.bound, np.log(max(min(least[i], least[j]), np.finfo(float).tiny)))
        if not (np.all(np.isfinite(logf)) and logf.min() >= max(-st.bound, floor)):
            continue
        if not proven and len(overlapping_pairs([merged], [uv])[0]):
            continue
        keep, drop = min(i, j), max(i, j)
        st.budget_cuts.append(dict(merged=[st.done[i].name, st.done[j].name], triangles=int(len(merged.F)),
                                   least_factor=float(np.exp(logf.min()))))
        st.done[keep], st.starts[keep], area[keep] = merged, uv, area[i] + area[j]
        least[keep], serial[keep], fresh = float(np.exp(logf.min())), fresh, fresh + 1
        st.done[drop] = st.starts[drop] = None
        order.merged(keep, drop, borders.merged(keep, drop))
    live = [k for k, c in enumerate(st.done) if c is not None]     # the slots a merge did not empty
    st.done[:] = [st.done[k] for k in live]
    st.starts[:] = [st.starts[k] for k in live]


#: Pairs joined ahead of their turn: their small merged charts' conformal maps are solved together.
MERGE_AHEAD = 16


def _join_ahead(st, pairs, cache, ahead):
    """Join the first of the untried ``pairs`` (merge_back's order, from the pair tried next) and the
    next MERGE_AHEAD - 1 whose merged chart would have at most BATCH_FACES triangles and share no chart
    with the first into ``ahead`` (the pair's chart ids -> (chart, chart, merged chart or None, proven
    overlap-free)) and solve the small merged charts' conformal maps together (a kit or a spiky surface
    tries dozens of merges of a few dozen triangles each; should the first pair merge, a pair holding
    one of its charts would be wasted work). A merge replaces its charts by a new one, and an entry
    holds its two charts (their ids stay theirs), so a pair made ahead is exactly what its turn would
    make."""
    from uvbake.atlas.charting import BATCH_FACES

    made, busy = [], set()                             # busy: the charts of the first pair
    for n, (i, j) in enumerate(pairs):                 # one per pair, at most MERGE_AHEAD made
        a, b = st.done[i], st.done[j]
        key = _pair(id(a), id(b))
        if key in ahead:
            continue
        if n and (len(a.F) + len(b.F) > BATCH_FACES or id(a) in busy or id(b) in busy):
            continue                                   # joined in its turn (a merge before may waste it)
        if not n:
            busy.update((id(a), id(b)))
        ahead[key] = (a, b, join_charts(a, b, cache), False)
        made.append(key)
        if len(made) == MERGE_AHEAD:
            break
    st.solve_small_together([ahead[k][2] for k in made if ahead[k][2] is not None], at_least=2)
    _prove_ahead(st, ahead, made)


def _prove_ahead(st, ahead, keys):
    """Mark the merged charts made ahead (``ahead[key]``'s last field) whose conformal map, solved
    ahead, is within the budget and whose boundary proves it overlap-free: one pass of
    :func:`uvbake.validate.boundary.proven_injective` for all of them (each chart's verdict is its own),
    so their turn skips overlapping_pairs' own (about 1 ms a chart: most of a small merge's check). A
    chart not proven here is checked in its turn as before."""
    from uvbake.validate.boundary import proven_injective

    todo = []
    for k in keys:                                     # one per pair made ahead
        m = ahead[k][2]
        if m is not None and id(m) in st.solved:
            logf = st.solved[id(m)][1][1]
            if np.all(np.isfinite(logf)) and logf.min() >= -st.bound:
                todo.append(k)
    if len(todo) < 2:
        return
    sure = proven_injective([st.solved[id(ahead[k][2])][1][0] for k in todo], [ahead[k][2].F for k in todo])
    for k, ok in zip(todo, sure):
        if ok:
            ahead[k] = (*ahead[k][:3], True)


class _MergeOrder:
    """Every (small chart, neighbour) pair merge_back may try, in the order it tries them: charts by
    area, smallest first (equal areas by slot); each chart's neighbours of the same label by shared
    border length, longest first (equal lengths by slot), at most MERGE_TRIES each; pairs already
    tried (``tried``, by ``serial`` numbers, from either side) are passed over. Kept through merges:
    only the merged chart and its neighbours are ranked again, and a chart whose pairs were all tried
    leaves the order until its borders change (ranking every pair after each merge and walking the
    order from its start was quadratic in the chart count: docs/decisions/atlas-speed.md)."""

    def __init__(self, borders: _Borders | _Table, area: list, serial: list, tried: set):
        self.borders, self.area, self.serial, self.tried = borders, area, serial, tried
        self.top = [self._top(k) for k in range(len(area))]
        self.active = sorted((area[k], k) for k in range(len(area)) if self.top[k])
        self.key: list[tuple[float, int] | None] = [None] * len(area)   # each chart's entry in `active`
        for e in self.active:
            self.key[e[1]] = e

    def _top(self, k: int) -> tuple[int, ...]:
        j, w = self.borders.out[k]
        return tuple(int(x) for x in j[np.lexsort((j, -w))[:MERGE_TRIES]]) if len(j) else ()

    def walk(self):
        """The untried pairs, in order."""
        for _, k in self.active:                      # one per chart with untried pairs
            for j in self.top[k]:
                if _pair(self.serial[k], self.serial[j]) not in self.tried:
                    yield k, j

    def first(self) -> tuple[int, int] | None:
        """The first untried pair, or None; charts found with every pair tried leave the order."""
        while self.active:                            # one per chart found spent
            k = self.active[0][1]
            for j in self.top[k]:
                if _pair(self.serial[k], self.serial[j]) not in self.tried:
                    return k, j
            self._drop(k)
        return None

    def _drop(self, k: int) -> None:
        key = self.key[k]
        if key is not None:
            del self.active[bisect.bisect_left(self.active, key)]
            self.key[k] = None

    def merged(self, keep: int, drop: int, changed: list) -> None:
        """Rank again after ``keep`` became the merge of itself and ``drop`` (now empty); ``changed``:
        the charts whose borders changed (_Borders.merged)."""
        self._drop(drop)
        self.top[drop] = ()
        for k in changed:                             # the merged chart and its neighbours
            self._drop(k)
            self.top[k] = self._top(k)
            if self.top[k]:
                self.key[k] = (self.area[k], k)
                bisect.insort(self.active, self.key[k])


def _next_merge(border: np.ndarray, area: list, serial: list, tried: set) -> tuple[int, int] | None:
    """The next (small chart, neighbour) pair to try for charts 0..len(area)-1 with chart_borders'
    rows ``border`` (see _MergeOrder), or None."""
    return _MergeOrder(_Table(border, len(area)), area, serial, tried).first()


class _Table:
    """chart_borders' rows as _Borders.out: per chart, its neighbours (ascending) and border lengths."""

    def __init__(self, border: np.ndarray, n: int):
        i = border[:, 0].astype(np.int64)
        cut = np.searchsorted(i, np.arange(1, n))      # rows are sorted by (i, j)
        self.out = list(zip(pieces(border[:, 1].astype(np.int64), cut), pieces(border[:, 2], cut)))


def _pair(a, b):
    return (a, b) if a < b else (b, a)


def _area(chart):
    X = chart.V[chart.F]
    return 0.5 * float(np.linalg.norm(np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0]), axis=1).sum())


def _fill_boundaries(charts, cache):
    """Put every chart's :func:`_boundary_global` part in ``cache``, found for all charts at once (the
    charts laid end to end: no edge joins two of them, so each chart's boundary half-edges are the
    same, in the same order, as found alone)."""
    from uvbake.mesh.topology import boundary_edges

    todo = [c for c in charts if id(c) not in cache]
    if not todo:
        return
    nv = np.array([len(c.V) for c in todo])                  # one per chart
    off = np.cumsum(nv) - nv
    F = np.concatenate([c.F for c in todo]) + np.repeat(off, [len(c.F) for c in todo])[:, None]
    b = boundary_edges(F, int(nv.sum()))
    owner = np.searchsorted(off, b[:, 0], side="right") - 1
    V = np.concatenate([c.V for c in todo])
    vmap = np.concatenate([c.vertex_map for c in todo])
    rows = np.column_stack([b - off[owner][:, None], vmap[b]])
    length = np.linalg.norm(V[b[:, 0]] - V[b[:, 1]], axis=1)
    cut = np.searchsorted(owner, np.arange(1, len(todo)))
    for c, r, w in zip(todo, pieces(rows, cut), pieces(length, cut)):    # one per chart: a slice each
        cache[id(c)] = (c, r, w)


def _boundary_global(charts, cache=None):
    """Every chart's boundary half-edges: (chart, local a, local b, mesh a, mesh b) rows, and their
    lengths. ``cache`` (a dict) keeps each chart's part between calls: keyed by id(chart), and the
    entry holds the chart itself, so no other chart can take that id while the entry lives."""
    from uvbake.mesh.topology import boundary_edges

    cache = {} if cache is None else cache
    rows, length = [], []
    for c in charts:                                   # one iteration per chart
        if id(c) not in cache:
            b = boundary_edges(c.F, len(c.V))
            cache[id(c)] = (c, np.column_stack([b, c.vertex_map[b]]), np.linalg.norm(c.V[b[:, 0]] - c.V[b[:, 1]], axis=1))
        _, r, w = cache[id(c)]
        rows.append(r)
        length.append(w)
    if not rows:
        return np.zeros((0, 5), np.int64), np.zeros(0)
    owner = np.repeat(np.arange(len(rows)), [len(r) for r in rows])
    return np.column_stack([owner, np.concatenate(rows)]), np.concatenate(length)


def chart_borders(charts: list[Chart], cache: dict | None = None) -> np.ndarray:
    """(p,3) rows (chart i, chart j, shared border length) for every ordered pair of charts of the
    same label that share mesh edges (i != j), sorted by (i, j). ``cache``: see :func:`_boundary_global`."""
    h, length = _boundary_global(charts, cache)
    if not len(h):
        return np.zeros((0, 3))
    n = int(h[:, 3:].max()) + 1
    key = h[:, 3] * n + h[:, 4]
    twin = h[:, 4] * n + h[:, 3]
    o = np.argsort(key, kind="stable")
    at = np.clip(np.searchsorted(key[o], twin), 0, len(o) - 1)
    hit = key[o][at] == twin
    i, j = h[hit, 0], h[o[at[hit]], 0]
    label = np.array([c.label for c in charts])
    ok = (i != j) & (label[i] == label[j])
    i, j, length = i[ok], j[ok], length[hit][ok]
    k = len(charts)
    up, inv = np.unique(i * k + j, return_inverse=True)
    return np.column_stack([up // k, up % k, np.bincount(inv, weights=length)])


class _Borders:
    """:func:`chart_borders` of merge_back's charts kept up to date through merges, per chart: ``out[k]``
    is (its neighbours' slots, ascending; the shared border lengths), the same pairs and the same sums
    as chart_borders' rows of chart k (each pair's length added up in the order chart_borders adds it),
    at a cost per merge that follows the merged charts' neighbourhoods instead of the whole atlas.

    ``charts`` is merge_back's list: a merge leaves the joined chart in the lower slot and None in the
    other, so slots keep their order. A merge only welds boundary half-edges away, so the boundary
    half-edges (keyed by their mesh vertices) are a fixed universe; ``owner`` says which slot holds
    each one now. Meshes where two charts hold the same boundary half-edge (not manifold) take
    chart_borders of every chart after each merge.
    """

    def __init__(self, charts: list[Chart], cache: dict):
        self.charts, self.cache = charts, cache
        h, _ = _boundary_global(charts, cache)
        self.n = int(h[:, 3:].max()) + 1 if len(h) else 1
        self.keys = unique_sorted(h[:, 3] * self.n + h[:, 4])
        self.exact = len(self.keys) == len(h)               # every half-edge in one chart only
        if not self.exact:
            self.out = self._rebuilt()
            return
        self.label = np.array([c.label for c in charts])
        self.rows = [self._rows(c) for c in charts]       # per chart: (key index, twin index or -1, length)
        self.owner = np.full(len(self.keys), -1, np.int64)
        for k, (at, _, _) in enumerate(self.rows):        # one iteration per chart, once
            self.owner[at] = k
        self.out = [self._out(k) for k in range(len(charts))]

    def _rebuilt(self):
        """out of every slot from chart_borders of the charts left."""
        slots = np.array([k for k, c in enumerate(self.charts) if c is not None], np.int64)
        b = chart_borders([self.charts[k] for k in slots], self.cache)
        i, j = slots[b[:, 0].astype(np.int64)], slots[b[:, 1].astype(np.int64)]
        cut = np.searchsorted(i, np.arange(1, len(self.charts)))
        return list(zip(pieces(j, cut), pieces(b[:, 2], cut)))

    def _rows(self, chart):
        _boundary_global([chart], self.cache)              # fills the cache
        _, r, w = self.cache[id(chart)]
        key, twin = r[:, 2] * self.n + r[:, 3], r[:, 3] * self.n + r[:, 2]
        if not len(self.keys):
            return np.zeros(0, np.int64), np.zeros(0, np.int64), w
        at = np.searchsorted(self.keys, key)
        tw = np.minimum(np.searchsorted(self.keys, twin), len(self.keys) - 1)
        return at, np.where(self.keys[tw] == twin, tw, -1), w

    def _out(self, k):
        """chart_borders' rows of chart k: (neighbour slots ascending, shared lengths)."""
        _, tw, w = self.rows[k]
        j = np.where(tw >= 0, self.owner[np.maximum(tw, 0)], -1)
        ok = (j >= 0) & (j != k)
        if ok.any():
            ok[ok] &= self.label[j[ok]] == self.label[k]
        if not ok.any():
            return np.zeros(0, np.int64), np.zeros(0)
        up, inv = np.unique(j[ok], return_inverse=True)
        return up, np.bincount(inv, weights=w[ok])

    def merged(self, keep: int, drop: int) -> list[int]:
        """Update after ``charts[keep]`` became the merge of itself and ``charts[drop]`` (now None, keep <
        drop); the slots whose rows changed (the merged chart and its neighbours), ascending."""
        if not self.exact:
            self.out = self._rebuilt()
            return [k for k, c in enumerate(self.charts) if c is not None]
        near = unique_sorted(np.concatenate([[keep], self.out[keep][0], self.out[drop][0]])).astype(np.int64)
        self.owner[self.rows[keep][0]] = -1
        self.owner[self.rows[drop][0]] = -1
        self.rows[drop] = None
        self.out[drop] = (np.zeros(0, np.int64), np.zeros(0))
        self.rows[keep] = self._rows(self.charts[keep])
        self.label[keep] = self.charts[keep].label
        self.owner[self.rows[keep][0]] = keep
        changed = [int(k) for k in near if k != drop]
        for k in changed:                                  # the merged chart and its neighbours
            self.out[k] = self._out(k)
        return changed


def join_charts(a: Chart, b: Chart, cache: dict | None = None) -> Chart | None:
    """One chart of ``a`` and ``b`` (same label) joined along the mesh edges they share, or None when
    the result is not a disk with holes (it would close a loop into a handle, or meet at a bowtie)."""
    h = _boundary_global([a, b], cache)[0]
    n = int(h[:, 3:].max()) + 1
    ha, hb = h[h[:, 0] == 0], h[h[:, 0] == 1]
    _, ia, ib = np.intersect1d(ha[:, 3] * n + ha[:, 4], hb[:, 4] * n + hb[:, 3], return_indices=True)
    if not len(ia) or len(ia) == len(ha) == len(hb):
        return None                                    # nothing shared, or all: the two would close a surface
    na = len(a.V)
    # a's edge (x, y) is b's (y, x): weld a's x with b's y and a's y with b's x
    u = np.concatenate([ha[ia, 1], ha[ia, 2]])
    v = np.concatenate([hb[ib, 2], hb[ib, 1]]) + na
    nc, comp = components(na + len(b.V), u, v)
    # a weld joining two vertices of one chart would pinch it (or collapse an edge): not a merge
    if np.bincount(comp[:na], minlength=nc).max() > 1 or np.bincount(comp[na:], minlength=nc).max() > 1:
        return None
    _, first, new = np.unique(comp, return_index=True, return_inverse=True)
    V = np.concatenate([a.V, b.V])[first]
    vmap = np.concatenate([a.vertex_map, b.vertex_map])[first]
    F = new[np.concatenate([a.F, b.F + na])]
    # two disks with holes welded along whole edges, one vertex of each per weld: manifold, one fan
    # per vertex, one piece; it is a disk with holes unless the weld closed it or made a handle
    he = F[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    directed = np.sort(he[:, 0] * len(V) + he[:, 1])
    if (directed[1:] == directed[:-1]).any():          # an edge used twice the same way
        return None
    if not _disk_with_holes(F, len(V)):
        return None
    return Chart(V, F.astype(np.int64), vmap, np.concatenate([a.face_index, b.face_index]), a.label, a.name)


def _disk_with_holes(F, n):
    """topology(F, n)'s verdict ``genus == 0 and n_boundary_loops > 0`` for a join: one piece (two
    connected charts sharing an edge) whose n vertices are all used, so only the edges and the
    boundary loops are counted (the whole mesh's components were most of topology's cost)."""
    from uvbake.mesh.topology import _edges

    _, uniq, bnd = _edges(F, n)
    if not len(bnd):
        return False
    _, blab = components(n, bnd[:, 0], bnd[:, 1])
    loops = len(unique_sorted(blab[unique_sorted(bnd)]))
    chi = n - len(uniq) + len(F)
    return (2 - chi - loops) // 2 == 0
