"""Splitting large charts where that packs the atlas denser.

    charts, results, packed, records = split_for_packing(charts, results, pack)

A few large charts fill a square atlas badly whatever the packer does (two charts of a closed
scan: 41-46 % against 50-65 % for atlases of more, smaller charts). A chart cut in two along a
straight line across its long axis, where the 3D seam is shortest, keeps its solved map on both
sides: the pieces have exactly the parent's distortion and validity (texel shares, orientation,
no overlap), so the cut costs only seam length. The cuts are kept when the atlas they pack into is
denser by at least MIN_GAIN (judged first on trial layouts, which may be a faster packer's, over up
to MAX_ROUNDS cuts, keeping the best number of them). Every decision is a packing efficiency or a
count, never a time.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from uvbake.atlas.maxrects import min_area_rect, min_area_rects
from uvbake.atlas.pack import _SHAPES_ONLY_FILL, PackResult, _check_gutter, _check_size, packed_result, place_boxes
from uvbake.cancel import check_cancelled
from uvbake.errors import InputError
from uvbake.flatten.solvers.result import ParamResult
from uvbake.mesh.arrays import face_means, signed_areas, unique_sorted
from uvbake.mesh.charts import Chart

#: Split rounds at most (each cuts one chart in two or three and makes one trial layout).
MAX_ROUNDS = 4
#: Only atlases packing below this efficiency are worth a split.
BELOW_EFFICIENCY = 0.66
#: Only charts with at least this share of the atlas's chart area are split (atlases of a few large charts).
MIN_SHARE = 0.25
#: Split rounds cutting a chart whose length alone keeps the atlas sparse (see _largest), besides MAX_ROUNDS.
MAX_LONG_ROUNDS = 8
#: Atlases of more charts than this are not split: one chart cut among many changes little, the others
#: fill around it (cow, 30 charts, the largest 26 % of the area: three rounds' trials 51.6 -> 52.3 %, never
#: the TRIAL_GAIN a round needs, for a third of its packing time); splits paid on 2-11 charts.
MAX_ATLAS_CHARTS = 16
#: Efficiency (absolute) the split charts' final layout must add to be kept.
MIN_GAIN = 0.01
#: Efficiency (absolute) a split must add in the trial layouts to be tried further.
TRIAL_GAIN = 0.02
#: Cut positions tried along the long axis (area quantiles).
POSITIONS = np.linspace(0.3, 0.7, 9)
#: A cut's seam length is weighed by 1 + IMBALANCE x |quantile - 1/2|: near-halves pack better.
IMBALANCE = 2.0


def split_for_packing(charts: Sequence[Chart], results: Sequence[ParamResult],
                      pack: Callable[[list, list], Any], *, boxes: Any = None,
                      max_charts: int | None = None) -> tuple[list[Chart], list[ParamResult], Any, list[dict]]:
    """Charts (some split), their results, the packing of them (``pack(uvs, Fs)``, a PackResult) and
    one record per kept split (chart, parts, seam length, efficiency before and after).

    Each round's split is judged by a trial layout of ``boxes`` (a :class:`BoxLayouts`,
    the fast rectangle packer, which finds each chart's rectangle once; None: ``pack`` judges); the
    split charts are then packed by ``pack`` too unless their boxes fill enough for boxes to compete
    (:func:`_boxes_suffice`), and the denser of that and the last trial layout is kept when it beats
    the first layout by MIN_GAIN (else the splits are dropped): at most two calls of ``pack``."""
    trial_pack = pack if boxes is None else boxes
    charts, results = list(charts), list(results)
    packed = pack([r.uv for r in results], [c.F for c in charts])
    rect = None if boxes is None else boxes.rect
    if packed.efficiency >= BELOW_EFFICIENCY or len(charts) > MAX_ATLAS_CHARTS or \
            _largest(charts, results, rect) is None:
        return charts, results, packed, []
    cur = trial_pack([r.uv for r in results], [c.F for c in charts]) if boxes is not None else packed
    cur_c, cur_r, cur, records = _rounds(charts, results, cur, trial_pack, max_charts, rect)
    if not records:
        return charts, results, packed, []
    final = cur                                          # the trial layout is a layout too: the denser is kept
    if boxes is not None and not _boxes_suffice(cur_c, cur_r, boxes):
        full = pack([r.uv for r in cur_r], [c.F for c in cur_c])
        final = full if full.efficiency >= cur.efficiency else cur
    if final.efficiency < packed.efficiency + MIN_GAIN:
        return charts, results, packed, []
    for rec in records:
        rec.update(efficiency_before=float(packed.efficiency), efficiency_after=float(final.efficiency))
    return cur_c, _own_energies(cur_c, cur_r, results), final, records


def _own_energies(charts, results, solved):
    """``results`` with every piece's own energy and flips (:func:`_with_energy`); the ``solved``
    results (not pieces) as they are."""
    ids = {id(r) for r in solved}
    return [r if id(r) in ids else _with_energy(c, r) for c, r in zip(charts, results)]


def _rounds(charts, results, cur, trial_pack, max_charts, rect=None):
    """Split rounds judged on trial layouts: every round splits the largest chart whether or not its
    layout gains (two halves may pay where one does not: sphere_cap's two half-caps 45.9 -> 45.9 ->
    63.8 %); the prefix of rounds with the densest trial layout is kept when it gains TRIAL_GAIN.
    ``rect(uv, F)``: a chart's minimum-area rectangle when known (the box layouts found it).
    Returns (charts, results, their trial layout, records)."""
    records: list[dict] = []
    best = (charts, results, cur, 0)
    shares = 0
    for _ in range(MAX_ROUNDS + MAX_LONG_ROUNDS):        # rounds: one split each
        check_cancelled()                                # Ctrl-C / SIGTERM: stop between rounds
        i, binding = _next_cut(charts, results, rect)
        if i is not None and not binding:
            shares += 1                                  # a cut by area share: at most MAX_ROUNDS of them
            if shares > MAX_ROUNDS:
                break
        cut = None if i is None else split_straight(
            charts[i], results[i], None if rect is None else rect(results[i].uv, charts[i].F)[0])
        if cut is None:
            break
        parts, part_results, seam = cut
        if max_charts is not None and len(charts) + len(parts) - 1 > max_charts:
            break
        records.append(dict(chart=charts[i].name, faces=int(len(charts[i].F)), parts=len(parts), seam_length=seam,
                            reason="packing"))
        charts = charts[:i] + parts + charts[i + 1:]
        results = results[:i] + part_results + results[i + 1:]
        trial = trial_pack([r.uv for r in results], [c.F for c in charts])
        if trial.efficiency >= best[2].efficiency + TRIAL_GAIN:
            best = (charts, results, trial, len(records))
    return best[0], best[1], best[2], records[:best[3]]


class BoxLayouts:
    """``uvbake.atlas.pack.pack_charts(uvs, faces, method="maxrects")`` for a caller that packs many
    sets sharing most charts (the split rounds): the same PackResult, each chart's minimum-area
    rectangle and area computed once, kept by the identity of its UV and face arrays (both held, so
    an id is never reused while kept; the arrays must not be changed in place meanwhile). A square
    atlas at a free scale.
    """

    def __init__(self, texture_size_px: int = 1024, gutter_px: int | None = None, mip_levels: int | None = None):
        W, H = _check_size(texture_size_px, None)
        if W != H:
            raise InputError(f"texture_size_px={texture_size_px!r}: box layouts are square; pass one size, e.g. 1024")
        self.N, self.g = W, _check_gutter(gutter_px, mip_levels, W, H)
        self._known: dict[tuple[int, int], tuple] = {}

    def _charts(self, uvs, faces):
        """(uvs as float arrays, faces, rects (n,3), total area), the rectangles and areas of unseen charts
        found together."""
        keys = [(id(u), id(F)) for u, F in zip(uvs, faces)]
        new = [i for i, k in enumerate(keys) if k not in self._known]
        if new:
            us = [np.asarray(uvs[i], dtype=np.float64) for i in new]
            Fs = [np.asarray(faces[i], dtype=np.int64) for i in new]
            for i, u, F, r in zip(new, us, Fs, min_area_rects(us)):
                self._known[keys[i]] = (uvs[i], faces[i], u, F, r, float(np.abs(signed_areas(u, F)).sum()))
        got = [self._known[k] for k in keys]
        return [c[2] for c in got], [c[3] for c in got], np.array([c[4] for c in got]).reshape(-1, 3), \
            sum(c[5] for c in got)

    def rect(self, uv: ArrayLike, F: ArrayLike) -> np.ndarray:
        """One chart's min_area_rect (theta, w, h)."""
        return self._charts([uv], [F])[2][0]

    def fill(self, uvs: Sequence[ArrayLike], faces: Sequence[ArrayLike]) -> float:
        """The charts' area over their minimum-area rectangles' (see _SHAPES_ONLY_FILL)."""
        _, _, rects, area = self._charts(uvs, faces)
        box = float((rects[:, 1] * rects[:, 2]).sum())
        return area / box if box > 0 else 1.0

    def __call__(self, uvs: Sequence[ArrayLike], faces: Sequence[ArrayLike]) -> PackResult:
        import time

        t0 = time.perf_counter()
        us, Fs, rects, area = self._charts(uvs, faces)
        N, g = self.N, self.g
        s, rotation, offset, out, gap = place_boxes(us, Fs, N, g, rects=rects)
        return packed_result(out, rotation, offset, gap, s * N, area, N, N, g, "maxrects", t0)


def _boxes_suffice(charts, results, boxes):
    """Whether the charts' minimum-area rectangles fill at least the share above which the packer
    lets boxes compete with shapes: there the trial (rectangle) layout is kept without packing the
    shapes (bumpy's pieces, fill 0.71: shapes 62.4 against boxes 64.5 %; sphere_cap's, 0.75: level),
    below it shapes win (beetle's, 0.57: 52.7 against 47.6 %)."""
    return boxes.fill([r.uv for r in results], [c.F for c in charts]) >= _SHAPES_ONLY_FILL


def _largest(charts, results, rect=None):
    """The chart to cut next (see _next_cut), or None."""
    return _next_cut(charts, results, rect)[0]


def _next_cut(charts, results, rect=None):
    """(chart to cut next or None, whether its length binds). The longest chart, when its minimum-area
    rectangle's long side alone keeps the atlas below BELOW_EFFICIENCY (a square holding a chart of
    length L packs at most area / L^2: a sphere's twelve latitude bands, one label each, packed at
    33 %); else the chart holding the most UV area, when it holds at least MIN_SHARE of the atlas's.
    Charts of under 8 triangles are never cut. ``rect(uv, F)``: a chart's min_area_rect, when known."""
    area = np.array([np.abs(signed_areas(r.uv, c.F)).sum() for c, r in zip(charts, results)])
    big = np.array([len(c.F) >= 8 for c in charts])
    rect = rect or (lambda uv, F: min_area_rect(np.asarray(uv)))
    length = np.array([rect(r.uv, c.F)[1] for c, r in zip(charts, results)])     # one rectangle per chart
    k = int(np.argmax(np.where(big, length, -1.0)))
    if big[k] and BELOW_EFFICIENCY * length[k] ** 2 > area.sum():
        return k, True
    i = int(np.argmax(area))
    return (i if area[i] >= MIN_SHARE * area.sum() and big[i] else None), False


def split_straight(chart: Chart, result: ParamResult,
                   theta: float | None = None) -> tuple[list[Chart], list[ParamResult], float] | None:
    """``chart`` cut across the long axis of its map's minimum-area rectangle (``theta``: that
    rectangle's angle, uvbake.atlas.maxrects.min_area_rect, when known), at the area quantile in
    POSITIONS whose 3D seam is shortest (slivers given back to a neighbour), each piece with the
    parent's map restricted to it (its energy and flips are the parent's until :func:`_with_energy`);
    None when no cut gives two pieces."""
    from uvbake.atlas.charting import SLIVER_SHARE, _absorb_slivers, sub_charts
    from uvbake.atlas.maxrects import min_area_rect
    from uvbake.mesh.cut import seam_costs
    from uvbake.mesh.topology import face_adjacency

    F, uv = chart.F, np.asarray(result.uv)
    m, n = len(F), len(chart.V)
    theta = min_area_rect(uv)[0] if theta is None else theta
    c = face_means(uv, F)
    x = np.cos(theta) * c[:, 0] - np.sin(theta) * c[:, 1]      # along the rectangle's long side
    a = np.abs(signed_areas(uv, F))
    order = np.argsort(x, kind="stable")
    cum = np.cumsum(a[order]) / a.sum()
    k = np.clip(np.searchsorted(cum, POSITIONS), 1, m - 1)
    side = x[:, None] > x[order][k][None, :]                   # (m, positions): the far side of each cut
    adj = face_adjacency(F, n, return_halfedges=True)
    fi, fj, e = adj[:3]
    ea, eb = e[:, 0], e[:, 1]
    cost = seam_costs(chart.V, F, fi, fj, ea, eb)
    w = np.linalg.norm(chart.V[ea] - chart.V[eb], axis=1)
    seams = ((side[fi] != side[fj]) * cost[:, None]).sum(axis=0)
    best = int(np.argmin(seams * (1.0 + IMBALANCE * np.abs(POSITIONS - 0.5))))
    lab = _absorb_slivers(F, n, side[:, best].astype(np.int64), a, SLIVER_SHARE, adj)
    if len(unique_sorted(lab)) < 2:
        return None
    parts = sub_charts(chart, lab, adj)
    if len(parts) < 2:
        return None
    seam = float(w[lab[fi] != lab[fj]].sum())
    return parts, [_piece_result(result, chart, p) for p in parts], seam


def _piece_result(result: ParamResult, chart: Chart, part: Chart) -> ParamResult:
    """The parent's result restricted to ``part``: its map; the solver's figures (iterations, history,
    certificate) stay the parent's. Its energy and flips are the parent's until :func:`_with_energy`
    (the pieces of rejected rounds, or cut again, never need theirs)."""
    from uvbake.atlas.guarantee import _local_vertices

    uv = np.asarray(result.uv)[_local_vertices(chart, part)]
    return dataclasses.replace(result, uv=uv, extra=dict(result.extra or {}) | {"split_for_packing_from": chart.name},
                               flip_free_uv=None)


def _with_energy(part: Chart, result: ParamResult) -> ParamResult:
    """A piece's result with its own triangles' share of the energy and of the flips."""
    from uvbake.atlas.guarantee import map_energy
    from uvbake.flatten.energy import jacobians, triangle_frames

    _, Q, _ = triangle_frames(part.V, part.F)
    A = jacobians(Q, part.F, result.uv)
    det = A[:, 0, 0] * A[:, 1, 1] - A[:, 0, 1] * A[:, 1, 0]
    return dataclasses.replace(result, energy=map_energy(A, result.alpha), n_flipped=int(np.count_nonzero(det <= 0)))
