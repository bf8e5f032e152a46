"""Compaction of a finished shape packing at full resolution: every chart slides down and left.

A packing found on a coarse raster (uvbake.atlas.fit) keeps each chart's coarse footprint: up to a
coarse texel of slack on every side and a gutter rounded up to whole coarse texels. Here every chart is
rasterised once at the packing's own density and sub-texel position (the footprint of the chart where
it is, uvbake.atlas.footprint.footprint), and then, one chart at a time in the order of their bottom
edges, the chart is taken out of the atlas and put back at the lowest free position in its own column
band no higher than where it was, then the leftmost free position in its row no further right, until it
stops moving. Moves are whole texels, so the footprints stay exact, and a chart's old position is
always free when it is taken out: no coordinate ever grows and every gutter holds (the same blocked
texels as the packer's: other charts' footprints dilated by the gutter, and the border margin). The
compacted layout is then scaled about the origin to the border (uvbake.atlas.fit.scale_to_border).
"""

from __future__ import annotations

import numpy as np

from uvbake.atlas.footprint import _EPS, footprint
from uvbake.atlas.shapepack import (
    _RUN,
    ShapePacker,
    ShapePacking,
    _Atlas,
    _dilate,
    _free_runs,
    _runs,
    update_runs,
)


def _placed_footprint(packer, i, density, theta, offset):
    """Footprint of chart i at ``texels = density R(theta) uv + offset`` and its integer corner (x, y):
    texel ``fp[r, c]`` is atlas texel ``(x + c, y + r)``."""
    co, si = np.cos(theta), np.sin(theta)
    q = density * (packer.uvs[i] @ np.array([[co, si], [-si, co]])) + offset
    corner = np.floor(q.min(axis=0) - 2 * _EPS)
    fp = footprint(q - corner, packer.faces[i], packer.bedges[i], packer.flipped[i])
    return fp, int(corner[0]), int(corner[1])


class _Grid:
    """How many dilated footprints cover each texel of a ``width x height`` atlas, with free-run tables."""

    def __init__(self, width, height, margin):
        self.count = np.zeros((height, width), np.int32)
        self.border = np.zeros((height, width), bool)
        self.border[:margin], self.border[height - margin:] = True, True
        self.border[:, :margin], self.border[:, width - margin:] = True, True
        # the packer's searches on these tables: rows (lowest top edge) and, transposed, columns
        self.atlas = self._searcher(self.border, width, height, margin)
        self.atlasT = self._searcher(self.border.T, height, width, margin)
        self.run = self.atlas.run[:height]

    @staticmethod
    def _searcher(blocked, width, height, margin):
        """An _Atlas on ``blocked`` (tables filled by refresh()), with ``height`` more blocked rows above
        it: its search reads up to ``top + h`` rows and would grow the tables otherwise; ``limit`` keeps
        charts below ``height``."""
        a = _Atlas.__new__(_Atlas)
        a.w, a.limit, a.m, a.top = width, height, margin, height - margin - 1
        a.blocked = np.ones((2 * height, width), bool)
        a.blocked[:height] = blocked
        a.run = np.zeros((2 * height, width), _RUN)
        a.rowmax = np.zeros(2 * height, _RUN)
        return a

    def add(self, dil, x, y, g, sign, tables=2):
        """Add (sign 1) or remove (-1) a dilated footprint whose undilated corner is at (x, y); update
        the first ``tables`` run tables (rows, then columns; the others: refresh() later)."""
        H, W = dil.shape
        y0, x0 = y - g, x - g
        cy0, cx0 = max(y0, 0), max(x0, 0)
        cy1, cx1 = min(y0 + H, self.count.shape[0]), min(x0 + W, self.count.shape[1])
        self.count[cy0:cy1, cx0:cx1] += sign * dil[cy0 - y0:cy1 - y0, cx0 - x0:cx1 - x0]
        if tables == 0:
            return
        # only the texels under the footprint changed: blocked flags there, run tables around them
        b = (self.count[cy0:cy1, cx0:cx1] > 0) | self.border[cy0:cy1, cx0:cx1]
        a = self.atlas
        a.blocked[cy0:cy1, cx0:cx1] = b
        update_runs(a.blocked, a.run, a.rowmax, cy0, cy1, cx0, cx1)
        if tables == 1:
            return
        t = self.atlasT
        t.blocked[cx0:cx1, cy0:cy1] = b.T
        update_runs(t.blocked, t.run, t.rowmax, cx0, cx1, cy0, cy1)

    def _box(self, dil, x, y, g):
        H, W = dil.shape
        y0, x0 = y - g, x - g
        return max(y0, 0), max(x0, 0), min(y0 + H, self.count.shape[0]), min(x0 + W, self.count.shape[1])

    def snapshot(self, dil, x, y, g):
        """The row tables under a dilated footprint (rows it covers), for restore()."""
        cy0, cx0, cy1, cx1 = self._box(dil, x, y, g)
        a = self.atlas
        return a.blocked[cy0:cy1].copy(), a.run[cy0:cy1].copy(), a.rowmax[cy0:cy1].copy()

    def restore(self, snap, dil, x, y, g):
        """Put back a footprint removed (add(..., -1, tables=1)) at the same place: counts added, row
        tables copied from its snapshot() (a copy instead of recomputing the runs)."""
        cy0, cx0, cy1, cx1 = self._box(dil, x, y, g)
        y0, x0 = y - g, x - g
        self.count[cy0:cy1, cx0:cx1] += dil[cy0 - y0:cy1 - y0, cx0 - x0:cx1 - x0]
        a = self.atlas
        a.blocked[cy0:cy1], a.run[cy0:cy1], a.rowmax[cy0:cy1] = snap

    def refresh(self, tables=(0, 1)):
        """Recompute run tables from the counts (0: rows, 1: columns)."""
        b = (self.count > 0) | self.border
        for k in tables:
            a, bk = (self.atlas, b) if k == 0 else (self.atlasT, b.T)
            hk = bk.shape[0]
            a.blocked[:hk] = bk
            a.run[:hk] = _free_runs(a.blocked[:hk])
            a.rowmax[:hk] = a.run[:hk].max(axis=1)

    @staticmethod
    def search(atlas, runs, h, w, top_bound, right):
        """The packer's lowest-then-leftmost search, top edge at most ``top_bound``, right edge at most
        ``right`` (the run tables are only read left of it)."""
        full = atlas.w
        atlas.w = min(right, full)
        try:
            return atlas.find(runs, h, w, top_bound=top_bound)
        finally:
            atlas.w = full

    def fits(self, runs, xs, ys):
        """Which positions ``(xs[k], ys[k])`` leave every footprint run on free texels."""
        dy, a, L = runs
        stride = self.atlas.run.shape[1]
        flat, off = self.atlas.run.reshape(-1), dy * stride + a     # one index array per gather
        at = ys * stride + xs
        ok = np.ones(len(xs), bool)
        for k0 in range(0, len(dy), 32):          # blocks of runs; candidates shrink
            idx = np.flatnonzero(ok)
            if len(idx) == 0:
                break
            sl = slice(k0, k0 + 32)
            ok[idx] = (flat[at[idx, None] + off[None, sl]] >= L[None, sl]).all(axis=1)
        return ok


def _layout(packer, p, width, height, gutter_px):
    """Every chart's footprint where ``p`` puts it, on a _Grid; None when one is outside the atlas."""
    g = int(gutter_px)
    fps, xy = [], np.zeros((len(packer.uvs), 2), np.int64)
    for i in range(len(packer.uvs)):                  # one rasterisation per chart
        fp, x, y = _placed_footprint(packer, i, p.density, p.rotation[i], p.offset[i])
        fps.append(fp)
        xy[i] = x, y
    if (xy < 0).any() or any(x + fp.shape[1] > width or y + fp.shape[0] > height for fp, (x, y) in zip(fps, xy)):
        return None
    grid = _Grid(width, height, (g + 1) // 2)
    dil = [_dilate(fp, g) for fp in fps]
    for i in range(len(fps)):
        grid.add(dil[i], xy[i, 0], xy[i, 1], g, 1, tables=0)
    return fps, dil, xy, grid


def slide(fps: list[np.ndarray], dil: list[np.ndarray], xy: np.ndarray, grid: _Grid, g: int,
          passes: int = 2) -> None:
    """Slides every chart (footprints ``fps``, dilated ``dil``, corners ``xy``, updated in place) down,
    then left, as far as free texels allow, bottom edges first, ``passes`` times over all charts (fewer
    when nothing moves). Needs the grid's row tables fresh; leaves them fresh."""
    m = grid.atlas.m
    runs = [_runs(fp) for fp in fps]               # spread rows first: most positions fail sooner
    for _ in range(passes):
        moved = False
        for i in np.lexsort((xy[:, 0], xy[:, 1])):    # bottom edges first; one iteration per chart
            x, y = int(xy[i, 0]), int(xy[i, 1])
            snap = grid.snapshot(dil[i], x, y, g)
            grid.add(dil[i], x, y, g, -1, tables=1)
            x0, y0 = x, y
            for _ in range(8):                        # down, left, until it stops
                ys = np.arange(m, y + 1)
                ok = grid.fits(runs[i], np.full(len(ys), x), ys)
                ny = int(ys[np.argmax(ok)]) if ok.any() else y
                xs = np.arange(m, x + 1)
                ok = grid.fits(runs[i], xs, np.full(len(xs), ny))
                nx = int(xs[np.argmax(ok)]) if ok.any() else x
                if (nx, ny) == (x, y):
                    break
                x, y, moved = nx, ny, True
            xy[i] = x, y
            if (x, y) == (x0, y0):                    # not moved: the tables as they were
                grid.restore(snap, dil[i], x, y, g)
            else:
                grid.add(dil[i], x, y, g, 1, tables=1)
        if not moved:
            break


def lower_far_edge(fps: list[np.ndarray], dil: list[np.ndarray], xy: np.ndarray, grid: _Grid, g: int,
                   steps: int = 50) -> None:
    """Moves the chart reaching furthest along the layout's limiting side (the far edge nearest the
    atlas's, right or top) to the lowest-then-leftmost free place whose far edge on that side is smaller
    and whose other far edge stays inside the layout's box; repeated ``steps`` times at most, it stops at
    the first chart that finds no such place. The box never grows. Needs fresh row and column tables."""
    n = len(fps)
    size = np.array(grid.count.shape[::-1], float)
    shape = np.array([fp.shape[::-1] for fp in fps])          # (w, h) of every footprint
    sruns = [(_runs(fp), _runs(np.ascontiguousarray(fp.T))) for fp in fps]
    for _ in range(steps):
        far = xy + shape
        ext = far.max(axis=0)
        d = int(np.argmax(ext / size))                        # 0: right edges, 1: top edges
        i = int(np.lexsort((np.arange(n), -far[:, d]))[0])
        x, y = int(xy[i, 0]), int(xy[i, 1])
        w, h = shape[i]
        grid.add(dil[i], x, y, g, -1)
        if d == 1:
            pos = grid.search(grid.atlas, sruns[i][0], h, w, y + h - 1, int(ext[0]))
        else:                                                 # the same search on the transposed tables
            pos = grid.search(grid.atlasT, sruns[i][1], w, h, x + w - 1, int(ext[1]))
            pos = None if pos is None else pos[::-1]
        if pos is None:
            grid.add(dil[i], x, y, g, 1)
            break
        xy[i] = pos
        grid.add(dil[i], int(pos[0]), int(pos[1]), g, 1)


def compact(packer: ShapePacker, p: ShapePacking, width: int, height: int, gutter_px: int, *, passes: int = 2,
            steps: int = 50) -> ShapePacking:
    """The packing ``p`` (full resolution, inside the ``width x height`` atlas) compacted: slide(), then
    lower_far_edge() (see the module text); ``p`` itself when a chart lies outside the atlas."""
    g = int(gutter_px)
    lay = _layout(packer, p, width, height, g)
    if lay is None:
        return p
    fps, dil, xy, grid = lay
    start = xy.copy()
    grid.refresh((0,))
    slide(fps, dil, xy, grid, g, passes)
    if steps:
        grid.refresh((1,))
        lower_far_edge(fps, dil, xy, grid, g, steps)
    return ShapePacking(density=p.density, rotation=p.rotation, offset=p.offset + (xy - start),
                        height_used=p.height_used, complete=p.complete)
