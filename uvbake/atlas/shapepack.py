"""Shape-aware chart packing on a texel raster: conservative footprints, rotations, bottom-left fill.

Every chart is rasterised at the atlas's texel resolution into its *footprint* (uvbake.atlas.footprint):
every texel whose closed square meets one of the chart's triangles; holes stay free for other charts.
Placing footprints at integer texel offsets keeps them exact. Two texels ``(i, j)`` and
``(i + di, j + dj)`` are ``sqrt(max(|di|-1,0)^2 + max(|dj|-1,0)^2)``
apart at least, so once a chart is placed, the texels within that distance ``< gutter_px`` of its
footprint (a 3x3 dilation, then a Euclidean distance transform) are blocked for every later chart:
any two charts end up at least ``gutter_px`` texels apart in exact geometry, every chart
``ceil(gutter_px / 2)`` texels from the atlas border. Mirroring is never used: only rotations.

Placement is bottom-left fill (the lowest, then leftmost, free position; among a chart's rotations the
one whose top edge is lowest), biggest chart first. The search keeps, for every atlas row, the length
of the free run starting at each texel (``run``) and each row's longest run: a footprint row made of
runs ``(dy, a, L)`` fits at ``(x, y)`` iff ``run[y+dy, x+a] >= L`` for all its runs, so candidate rows
are pruned by the row maxima and candidate positions are filtered one run at a time, all in numpy
(the idea of xatlas's bitmap packer, written independently as run-length tests).

The common scale is searched in uvbake.atlas.fit (strips of the atlas width at several scales, or one
raster in strips of several widths scaled to the atlas); with a fixed texel density the strip is
packed once.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np

from uvbake.atlas.distance import boundary_halfedges
from uvbake.atlas.footprint import _BATCH_CELLS, _EPS, footprints
from uvbake.mesh.arrays import pieces, signed_areas

_CHUNK = 16          # candidate rows tested together at first; each chunk without a fit doubles it
_CHUNK_MAX = 256     # up to this many
_BATCH = 512         # surviving positions whose other runs are tested together
_RUN = np.int16      # free-run lengths (atlases are at most 16384 texels wide): half the memory traffic of int32
_NOWHERE = 1 << 40   # find()'s `searched` for a footprint wider than the strip: no row fits
_PROGRESS = 64       # charts placed between two progress calls


def _raw_runs(fp):
    """Horizontal runs of a footprint: rows ``dy``, starts ``a`` and lengths ``L``, row-major order."""
    return _raw_runs_many([fp])[0]


def _raw_runs_many(fps):
    """_raw_runs of several footprints in one pass: each padded with a free column either side and all
    laid end to end in one flat array. Every padded row starts and ends free, so the changes along
    the flat array alternate: a run's start, then its end (one 1-D pass: 10x faster than 2-D
    np.nonzero of a row difference). Groups of about _BATCH_CELLS texels bound the memory."""
    size = np.array([f.shape[0] * (f.shape[1] + 2) for f in fps], np.int64)   # one per footprint
    out, i0 = [], 0
    while i0 < len(fps):                      # one iteration per group of footprints
        i1 = i0 + max(1, int(np.searchsorted(np.cumsum(size[i0:]), _BATCH_CELLS, side="right")))
        out += _raw_runs_group(fps[i0:i1])
        i0 = i1
    return out


def _raw_runs_group(fps):
    """_raw_runs_many of one group: the footprints end to end in one flat array."""
    h = np.array([f.shape[0] for f in fps], np.int64)              # one per footprint
    w = np.array([f.shape[1] for f in fps], np.int64) + 2
    size = h * w
    off = np.cumsum(size) - size
    flat = np.zeros(int(size.sum()), bool)
    for f, o, hi, wi in zip(fps, off, h, w):                       # one copy per footprint
        flat[o:o + hi * wi].reshape(hi, wi)[:, 1:-1] = f
    ch = np.flatnonzero(flat[1:] != flat[:-1])
    s, e = ch[0::2], ch[1::2]
    owner = np.searchsorted(off, s, side="right") - 1
    sr, sc = np.divmod(s - off[owner], w[owner])
    cut = np.searchsorted(owner, np.arange(1, len(fps)))
    return list(zip(pieces(sr, cut), pieces(sc, cut), pieces(e - s, cut)))


def _runs(fp, raw=None):
    """Runs of a footprint (``raw``: _raw_runs(fp) when known) in the order the search tests them: the
    longest run first, then runs spread over the footprint's rows (neighbouring rows agree, spread ones
    reject more candidates sooner; a fixed order, no randomness)."""
    return _runs_many([_raw_runs(fp) if raw is None else raw])[0]


def _runs_many(raws):
    """_runs of several footprints' raw runs, ordered in one pass (each footprint's runs stay its own:
    the sort's first key is the footprint)."""
    n = np.array([len(r[0]) for r in raws], np.int64)              # one per footprint
    owner = np.repeat(np.arange(len(raws)), n)
    dy = np.concatenate([r[0] for r in raws])
    a = np.concatenate([r[1] for r in raws])
    L = np.concatenate([r[2] for r in raws])
    spread = np.mod(dy * 0.6180339887498949, 1.0)
    start = np.cumsum(n) - n
    has = n > 0
    top = np.zeros(len(raws), L.dtype)
    top[has] = np.maximum.reduceat(L, start[has])
    longest = np.flatnonzero(L == top[owner])
    _, first = np.unique(owner[longest], return_index=True)         # each footprint's first longest run
    spread[longest[first]] = -1.0
    order = np.lexsort((a, spread, owner))
    cut = np.cumsum(n)[:-1]
    return list(zip(pieces(dy[order], cut), pieces(a[order], cut), pieces(L[order].astype(_RUN), cut)))


def gutter_element(gutter_px: int) -> np.ndarray:
    """Offsets ``(di, dj)`` of texels closer than ``gutter_px`` to texel (0, 0), as a boolean square."""
    g = int(gutter_px)
    d = np.maximum(np.abs(np.arange(-g, g + 1)) - 1, 0)
    el = d[:, None] ** 2 + d[None, :] ** 2 < g * g
    el[g, g] = True
    return el


def _dilate(fp, g):
    """Texels closer than ``g`` to the footprint (see gutter_element), on a canvas grown by ``g``.

    The element is the 3x3 square (closed texels) widened by the disk of radius ``g``; it is applied as
    one horizontal segment per row offset (maximum filters are linear in the canvas size).
    """
    h, w = fp.shape
    out = np.zeros((h + 2 * g, w + 2 * g), bool)
    out[g:g + h, g:g + w] = fp
    if g == 0:
        return out
    el = gutter_element(g)
    half = el.sum(axis=1) // 2                     # half-width of each row of the element
    widened = {}
    res = np.zeros_like(out)
    for dy in range(-g, g + 1):                    # 2g+1 row offsets, not a loop over texels
        r = int(half[dy + g])
        if r not in widened:
            widened[r] = _widen_rows(out, r) if r else out
        src = widened[r]
        if dy >= 0:
            res[dy:] |= src[:len(src) - dy]
        else:
            res[:dy] |= src[-dy:]
    return res


def _widen_rows(a, r):
    """Boolean rows dilated by ``r`` texels either side (zero outside), from a running count of set
    texels: numpy for what scipy.ndimage's maximum_filter1d does, whose import costs more CPU than a
    small mesh's whole packing."""
    c = np.zeros((a.shape[0], a.shape[1] + 2 * r + 1), np.int32)
    np.cumsum(a, axis=1, out=c[:, r + 1:a.shape[1] + r + 1])
    c[:, a.shape[1] + r + 1:] = c[:, a.shape[1] + r:a.shape[1] + r + 1]
    return c[:, 2 * r + 1:] > c[:, :a.shape[1]]


# ------------------------------------------------------------------------------------- the atlas

def _free_runs(blocked, after=None):
    """Length of the free run starting at every texel of each row (0 on blocked texels); ``after`` (one
    per row): the run starting just right of the last column, for a slice of wider rows (0: the end)."""
    h, w = blocked.shape
    idx = blocked * (np.arange(w, dtype=_RUN) - _RUN(w))[None, :]      # column on blocked texels, else w:
    idx += _RUN(w)                                                     # 15x faster than a broadcast np.where
    nxt = np.minimum.accumulate(idx[:, ::-1], axis=1)[:, ::-1]
    run = nxt - np.arange(w, dtype=_RUN)[None, :]
    if after is not None:
        run += np.where(nxt == w, after[:, None], 0).astype(_RUN)
    return run


def update_runs(blocked: np.ndarray, run: np.ndarray, rowmax: np.ndarray, r0: int, r1: int, c0: int,
                c1: int) -> None:
    """Refresh the free-run tables of rows ``r0:r1`` after their blocked texels changed in columns
    ``c0:c1`` only: those columns are recomputed; left of ``c0`` only the runs starting right of a row's
    last blocked texel change, each by what the run starting at ``c0`` changed (a run through free
    texels up to ``c0`` continues with it); a run starting right of ``c1`` does not change."""
    w = blocked.shape[1]
    b = blocked[r0:r1]
    after = run[r0:r1, c1] if c1 < w else np.zeros(r1 - r0, _RUN)
    new = _free_runs(b[:, c0:c1], after)
    if c0 > 0 and c1 > c0:
        delta = new[:, 0] - run[r0:r1, c0]
        rows = np.flatnonzero(delta)
        if len(rows):
            left = b[rows, :c0]
            # per changed row, the last blocked column left of c0 (-1: none)
            last = np.where(left.any(axis=1), c0 - 1 - np.argmax(left[:, ::-1], axis=1), -1)
            lo = int(last.min()) + 1
            if lo < c0:
                shift = (np.arange(lo, c0)[None, :] > last[:, None]) * delta[rows, None]
                run[r0 + rows, lo:c0] += shift.astype(_RUN)
    run[r0:r1, c0:c1] = new
    rowmax[r0:r1] = run[r0:r1].max(axis=1)


class _Atlas:
    """Blocked texels of a strip ``width`` wide, grown upwards on demand, with free-run tables."""

    def __init__(self, width, height, margin, rows=64):
        self.w, self.limit, self.m = width, height, margin
        self.blocked = np.zeros((0, width), bool)
        self.run = np.zeros((0, width), _RUN)
        self.rowmax = np.zeros(0, _RUN)
        self.top = margin                # first row above every placed chart's blocked texels
        self._grow(max(int(rows), 64))

    def _grow(self, rows):
        """Append ``rows`` free rows (their borders blocked); a free row's run table is one template."""
        add = np.zeros((rows, self.w), bool)
        add[:, :self.m] = True
        add[:, self.w - self.m:] = True
        tmpl = _free_runs(add[:1])
        run = np.repeat(tmpl, rows, axis=0)
        rowmax = np.full(rows, tmpl.max(), _RUN)   # every new row is the template
        if len(self.blocked) == 0:                 # the bottom margin; the first rows need no copy
            add[:self.m] = True
            run[:self.m] = 0
            rowmax[:self.m] = 0
            self.blocked, self.run, self.rowmax = add, run, rowmax
            return
        self.blocked = np.vstack([self.blocked, add])
        self.run = np.vstack([self.run, run])
        self.rowmax = np.concatenate([self.rowmax, rowmax])

    def find(self, runs, h, w, top_bound=None, start=0):
        """Lowest, then leftmost, (x, y) where a footprint with ``runs`` fits; None if nowhere, or if its
        top edge ``y + h`` would exceed ``top_bound`` (a rotation already found does better). Rows below
        ``start`` are known not to fit. ``self.searched`` is then the first row not ruled out: the row
        found, or where the search stopped."""
        dy, a, L = runs
        nx = self.w - w + 1
        self.searched = _NOWHERE
        if nx <= 0 or w > self.w - 2 * self.m:
            return None
        if self.top + h + 1 > len(self.blocked):
            self._grow(max(self.top + h + 1 - len(self.blocked), len(self.blocked)))   # doubling
        ny = self.top + 1                     # every row above `top` is free: y = top always fits
        if self.limit:
            ny = min(ny, self.limit - self.m - h + 1)
        if top_bound is not None:
            ny = min(ny, top_bound - h + 1)
        self.searched = max(ny, start)
        start = max(start, self.m)
        if ny <= start:
            return None
        # rows where every footprint row finds a long enough free run somewhere
        Lrow = np.zeros(h, _RUN)
        np.maximum.at(Lrow, dy, L)
        # a (ny - start, h) window view of the (contiguous) row maxima, made directly: sliding_window_view
        # and as_strided take 15-30 us a call, more than the test (the rows exist: the strip grew to top + h + 1)
        rm = self.rowmax[start:ny + h - 1]
        if len(rm) != ny + h - 1 - start or not rm.flags.c_contiguous:
            raise RuntimeError("shape packer: row table shorter than the search window")
        win = np.ndarray((ny - start, h), rm.dtype, rm, 0, (rm.itemsize, rm.itemsize))
        ys = np.flatnonzero((win >= Lrow[None, :]).all(axis=1)) + start
        k0, stride, chunk = 0, self.run.shape[1], _CHUNK
        while k0 < len(ys):                   # candidate rows, bottom up, a chunk at a time
            yc = ys[k0:k0 + chunk]
            k0 += chunk
            chunk = min(2 * chunk, _CHUNK_MAX)   # the first fit is the lowest row's wherever chunks end
            # dense phase: runs tested on every position of the chunk (consecutive candidate rows, the
            # usual case, are a view of the run table; others a row gather), then a column slice
            y0, n = int(yc[0]), len(yc)
            rows = (lambda d: slice(y0 + d, y0 + d + n)) if int(yc[-1]) - y0 == n - 1 else (lambda d: yc + d)
            ok = self.run[rows(dy[0]), a[0]:a[0] + nx] >= L[0]
            k = 1
            while k < len(dy):
                ok &= self.run[rows(dy[k]), a[k]:a[k] + nx] >= L[k]
                k += 1
                if k % 4 == 0 and (k >= 16 or np.count_nonzero(ok) < nx):
                    break                     # survivors go to the sparse phase, which stops at the first fit
            yi, xi = np.divmod(np.flatnonzero(ok), nx)       # row-major: bottom-left first
            if len(yi):
                pos = self._first_fit(yc[yi] * stride + xi, runs, k)
                if pos is not None:
                    self.searched = pos[1]
                    return pos
        return None

    def _first_fit(self, at, runs, k):
        """find()'s sparse phase: the first of the flat positions ``at`` (row-major) where runs ``k:`` fit
        too, as (x, y), or None. The runs are tested as offsets into the flat run table (one index array
        per gather), in growing blocks while the candidates shrink, a batch of positions at a time."""
        dy, a, L = runs
        stride = self.run.shape[1]
        flat, off = self.run.reshape(-1), dy * stride + a       # a view: the table is contiguous
        for b0 in range(0, len(at), _BATCH):
            cand, j, step = at[b0:b0 + _BATCH], k, 4
            while j < len(dy) and len(cand):
                sel = slice(j, j + step)
                cand = cand[(flat[cand[:, None] + off[None, sel]] >= L[None, sel]).all(axis=1)]
                j, step = j + step, step * 4
            if len(cand):
                y, x = divmod(int(cand[0]), stride)
                return x, y
        return None

    def place(self, fp_dilated, x, y, g, top):
        """Block the dilated footprint whose undilated corner sits at (x, y); update the run tables."""
        H, W = fp_dilated.shape
        y0, x0 = y - g, x - g
        if y0 + H > len(self.blocked):             # rows for the whole gutter above the chart first
            self._grow(max(y0 + H - len(self.blocked), len(self.blocked)))
        cy0, cx0 = max(y0, 0), max(x0, 0)
        cy1, cx1 = min(y0 + H, len(self.blocked)), min(x0 + W, self.w)
        self.blocked[cy0:cy1, cx0:cx1] |= fp_dilated[cy0 - y0:cy1 - y0, cx0 - x0:cx1 - x0]
        update_runs(self.blocked, self.run, self.rowmax, cy0, cy1, cx0, cx1)
        self.top = max(self.top, top)


# ----------------------------------------------------------------------------------------- packing

@dataclass
class ShapePacking:
    """Placement of every chart: ``texels_i = density * R(rotation_i) @ uv_i + offset_i``.

    ``density`` is texels per world unit (the same for every chart); ``height_used`` the rows the strip
    needed, including the top margin.
    """

    density: float
    rotation: np.ndarray
    offset: np.ndarray
    height_used: int
    complete: bool = True


class ShapePacker:
    """Packs fixed charts at any texel density; the per-chart data that does not depend on scale is kept.

    Parameters
    ----------
    uvs, faces : lists of (k_i,2) float and (t_i,3) int arrays   the charts, in world units
    angles : list of (r_i,) float arrays                         base rotations to try for each chart
    quarter_turns : bool                                         also try each base rotation + 90, 180, 270
    hulls : list of int arrays, optional                         each chart's uvbake.atlas.maxrects.chart_hulls
    progress : callable, optional                                ``progress(placed, total)`` every _PROGRESS charts
    """

    def __init__(self, uvs, faces, angles, *, quarter_turns=True, hulls=None, progress=None):
        self.uvs, self.faces, self.angles, self.quarter_turns = uvs, faces, angles, quarter_turns
        self.progress = progress
        self.bedges = [boundary_halfedges(F) for F in faces]
        self.flipped = []
        self.area = np.zeros(len(uvs))

        for i, (uv, F) in enumerate(zip(uvs, faces)):
            sa = signed_areas(uv, F)
            major = 1.0 if sa.sum() >= 0 else -1.0
            self.flipped.append(np.flatnonzero(sa * major <= 0))
            self.area[i] = np.abs(sa).sum()
        self.order = np.lexsort((np.arange(len(uvs)), -self.area))      # biggest first, ties by index
        self.orders = [self.order]
        for key in self._order_keys():                                   # other orders, distinct ones only
            o = np.lexsort((np.arange(len(uvs)), -key))
            if not any(np.array_equal(o, q) for q in self.orders):
                self.orders.append(o)
        self._density, self._cands, self._dilated = None, {}, {}          # candidates at the last density
        self._order_tried: dict = {}
        self._hull_idx, self._hulls = hulls, None

    def hull_points(self) -> tuple[np.ndarray, np.ndarray]:
        """Every chart's convex hull vertices stacked (charts of under 3 vertices: all of them), and the
        chart each belongs to; computed once."""
        if self._hulls is None:
            from uvbake.atlas.maxrects import chart_hulls

            hulls = chart_hulls(self.uvs) if self._hull_idx is None else self._hull_idx
            pts = [uv[h] for uv, h in zip(self.uvs, hulls)]
            self._hulls = (np.concatenate(pts), np.repeat(np.arange(len(pts)), [len(q) for q in pts]))
        return self._hulls

    def _order_keys(self):
        """Keys of the other chart orders the searches may try (biggest first by each): boundary length,
        then the short side of the chart's box (the extent across its principal direction)."""
        perim, short = np.zeros(len(self.uvs)), np.zeros(len(self.uvs))
        for i, (uv, b) in enumerate(zip(self.uvs, self.bedges)):       # one iteration per chart
            perim[i] = np.linalg.norm(uv[b[:, 0]] - uv[b[:, 1]], axis=1).sum()
            c = uv - uv.mean(axis=0)
            ev = np.linalg.eigvalsh(c.T @ c / max(len(uv), 1))
            short[i] = np.sqrt(max(ev[0], 0.0))
        return [perim, short]

    def _cached(self, i, density):
        """Chart i's candidates at ``density`` with their runs; kept while the density stays the same
        (the width search packs one density several times). Every chart's candidates at a new density
        are made together (footprints(), _raw_runs_many(), _runs_many())."""
        if density != self._density:
            self._density, self._dilated, self._order_tried = density, {}, {}
            self._cands = self._all_candidates(density)
        return self._cands[i]

    def _all_candidates(self, density):
        """{chart: [(footprint, angle, offset, runs, footprint number) per rotation tried]}: each base
        angle's footprint, then its quarter turns as the footprint turned on the texel grid (exact: a
        quarter turn about a grid point maps texels onto texels), so ``texels = density * R(angle) @ uv
        + offset``. A half turn's runs are its footprint's mirrored. Equal footprints share a number,
        found by shape and a 128-bit digest of the texels (not the texels themselves: a large atlas's
        large footprints would be copied per rotation; a collision could only cost a memo's rows,
        never validity: find() tests every position it returns)."""
        base = self._base_footprints(density)
        turns = 4 if self.quarter_turns else 1
        items = [(i, fp, theta, t) for i in range(len(self.uvs)) for fp, theta, t in base[i]]
        fps = []
        for _, fp, _, _ in items:                   # one per chart and base angle: views, no copies
            r1 = fp.T[:, ::-1]                        # np.rot90(fp, -1), without its 30 us of argument handling
            fps.append((fp, r1, fp[::-1, ::-1], r1[::-1, ::-1])[:turns])
        raw = _raw_runs_many([f[k] for k in range(min(turns, 2)) for f in fps])
        nb = len(fps)
        raws = []
        for j, f in enumerate(fps):                 # one per chart and base angle
            own = [raw[k * nb + j] for k in range(min(turns, 2))]
            for k in range(2, turns):               # a half turn of candidate k - 2: its runs mirrored
                dy, a, L = own[k - 2]
                own.append((f[k].shape[0] - 1 - dy, f[k].shape[1] - a - L, L))
            raws.extend(own)
        runs = _runs_many(raws)
        cands: dict = {i: [] for i in range(len(self.uvs))}
        same: dict = {}                             # footprint -> its number: equal footprints share one
        for j, ((i, _, theta, t), f) in enumerate(zip(items, fps)):     # one per chart and base angle
            for k in range(turns):
                key = (f[k].shape, hashlib.blake2b(f[k].tobytes(), digest_size=16).digest())
                sid = same.setdefault(key, len(same))
                cands[i].append((f[k], theta + k * np.pi / 2, t, runs[j * turns + k], sid))
                # a quarter turn counter-clockwise: (x, y) -> (h - y, x) keeps texels on texels
                t = np.array([f[k].shape[0] - t[1], t[0]])
        return cands

    def _tried(self, i, cands):
        """Chart i's candidates in the order pack() tries them, the flattest first (ties by index), each
        footprint once, as its first candidate: an equal footprint finds the same position (or, bounded
        by a better top edge, none), and its larger index never wins the tie (a square card's four
        quarter turns are one footprint). Kept while the density stays the same."""
        if i not in self._order_tried:
            first: dict = {}
            for r, c in enumerate(cands):          # a chart's few rotations
                first.setdefault(c[4], r)
            self._order_tried[i] = sorted(first.values(), key=lambda r: (cands[r][0].shape[0], r))
        return self._order_tried[i]

    def _dilate_cached(self, sid, fp, g):
        """The dilation of footprint number ``sid`` (equal footprints share one) by the gutter ``g``."""
        key = (sid, g)
        if key not in self._dilated:
            self._dilated[key] = _dilate(fp, g)
        return self._dilated[key]

    def _base_footprints(self, density):
        """{chart: [(footprint, angle, offset) per base angle]} at ``density``, such that
        ``texels = density * R(angle) @ uv + offset`` on the footprint's grid."""
        items, qs, shifts = [], [], []
        for i in range(len(self.uvs)):            # one iteration per chart and base angle
            for theta in self.angles[i]:
                c, s = np.cos(theta), np.sin(theta)
                q = density * (self.uvs[i] @ np.array([[c, s], [-s, c]]))
                shift = 2 * _EPS - q.min(axis=0)
                items.append((i, theta))
                qs.append(q + shift)
                shifts.append(shift)
        fps = footprints(qs, [self.faces[i] for i, _ in items], [self.bedges[i] for i, _ in items],
                         [self.flipped[i] for i, _ in items])
        base = {}
        for (i, theta), fp, t in zip(items, fps, shifts):
            base.setdefault(i, []).append((fp, theta, t))
        return base

    def pack(self, density: float, width: int, height: int | None, gutter_px: int, *,
             give_up_above: int | None = None, order: np.ndarray | None = None) -> ShapePacking | None:
        """Bottom-left fill of a ``width``-texel strip (``height`` rows at most, None: unbounded).

        Returns a ShapePacking, or None when some chart does not fit. With ``give_up_above`` the packing
        stops once it needs more rows: it is returned with ``complete=False`` and ``height_used``
        extrapolated by the chart area still to place (at a fixed width, height grows with area).
        """
        g = int(gutter_px)
        m = (g + 1) // 2
        rows = height if height else (give_up_above + 2 * g + 2 if give_up_above else width)
        atlas = _Atlas(width, height, m, rows)
        n = len(self.uvs)
        rotation, offset = np.zeros(n), np.zeros((n, 2))
        placed = 0.0
        # per footprint number, the rows below which that footprint is known not to fit: blocked texels
        # are only ever added, so a row ruled out for one chart stays ruled out for an equal footprint
        # (a kit's many small charts share footprints: 48-75 % of the 1,000-part kit's candidates)
        low: dict = {}
        for done, i in enumerate(self.order if order is None else order):   # one per chart; the search is numpy
            if self.progress is not None and done % _PROGRESS == 0 and done:
                self.progress(done, n)          # a work count: the same calls on every run
            best = None
            cands = self._cached(i, density)
            # the flattest rotations first: their top edges bound the search of the others (the lowest
            # top edge wins, ties by y, x, rotation index, so the order tried does not change the result)
            for r in self._tried(i, cands):
                fp, theta, t, runs, sid = cands[r]
                pos = atlas.find(runs, fp.shape[0], fp.shape[1], top_bound=None if best is None else best[0][0],
                                 start=low.get(sid, 0))
                low[sid] = max(low.get(sid, 0), atlas.searched)
                if pos is None:
                    continue
                key = (pos[1] + fp.shape[0], pos[1], pos[0], r)
                if best is None or key < best[0]:
                    best = (key, fp, theta, t + pos, sid)
            if best is None:
                return None
            key, fp, theta, off, sid = best
            atlas.place(self._dilate_cached(sid, fp, g), key[2], key[1], g, key[1] + fp.shape[0] + g)
            rotation[i] = float(np.arctan2(np.sin(theta), np.cos(theta)))
            offset[i] = off
            placed += self.area[i]
            if give_up_above is not None and atlas.top - g + m > give_up_above:
                used = (atlas.top - g + m) * self.area.sum() / placed
                return ShapePacking(density=float(density), rotation=rotation, offset=offset,
                                    height_used=int(np.ceil(used)), complete=False)
        return ShapePacking(density=float(density), rotation=rotation, offset=offset,
                            height_used=atlas.top - g + m)


def mip_gutter_px(mip_levels: int) -> int:
    """Gutter (texels) that keeps charts from bleeding into each other at mip levels ``0..mip_levels-1``.

    The count follows ``uvbake.atlas.bake.dilate_px_for_mips``. uvbake's bake colours every texel whose
    centre is within ``BAKE_MARGIN_PX`` (2) of a chart, then dilates: every other texel takes the colour
    of the nearest covered texel, so the gutter between charts A and B is split where the two sides'
    covered texels are equally far. A bilinear sample at a point p of A at level k (each level a 2x box
    filter) reads level-0 texels whose centres are less than ``r = sqrt(2) * (1.5 * 2^k - 0.5)`` from p
    (as in the bake's derivation); such a centre x is within ``r + sqrt(0.5)`` of a texel covered by A and
    at least ``g - r - 2`` from any covered by B, so it holds A's colour when ``g > 2 r + 2 + sqrt(0.5)``:
    6, 10, 19, 36 texels for 1, 2, 3, 4 levels. Without the dilation half of that would do, but then
    the samples at a chart's edge read background; the rule ``g >= 2^k`` bleeds already at level 0
    (tests/test_shapepack.py simulates bake, dilation, box mips and bilinear reads for both).
    """
    from uvbake.atlas.bake import BAKE_MARGIN_PX

    L = int(mip_levels)
    if L < 1:
        return 0
    r = np.sqrt(2.0) * (1.5 * 2 ** (L - 1) - 0.5)
    return int(np.floor(2 * r + BAKE_MARGIN_PX + np.sqrt(0.5))) + 1
