"""Conservative chart footprints on a texel raster (uvbake.atlas.shapepack's rasteriser).

A chart's footprint is every texel whose closed square meets one of its triangles: a cell meets the
chart iff its centre is inside the chart or a boundary edge crosses it (a segment from an inside point
to an outside centre crosses the boundary), so the interior is filled by the non-zero winding rule on
the oriented boundary edges (holes stay free) and the boundary edges' supercover is added; triangles
folded against the chart's orientation are rasterised one by one. Many charts are rasterised in one
numpy pass, their canvases end to end (:func:`footprints`).
"""

from __future__ import annotations

import numpy as np

_EPS = 1e-7          # texels: every touch test is widened by this, so rounding never drops a touched texel


def _ranges(lo, hi):
    """For integer ranges ``[lo_i, hi_i]`` (inclusive): (owner index, value) of every member."""
    n = np.maximum(hi - lo + 1, 0)
    owner = np.repeat(np.arange(len(lo)), n)
    start = np.cumsum(n) - n
    return owner, lo[owner] + (np.arange(int(n.sum())) - start[owner])


def _supercover(P0, P1):
    """Rows and columns of every texel whose closed square a segment meets (widened by _EPS), and the
    segment each belongs to."""
    x0, x1 = P0[:, 0], P1[:, 0]
    e, col = _ranges(np.floor(np.minimum(x0, x1) - _EPS).astype(np.int64),
                     np.floor(np.maximum(x0, x1) + _EPS).astype(np.int64))
    a, b = P0[e], P1[e]
    dx = b[:, 0] - a[:, 0]
    flat = np.abs(dx) < 1e-12
    safe = np.where(flat, 1.0, dx)
    t0 = np.clip((col - _EPS - a[:, 0]) / safe, 0.0, 1.0)
    t1 = np.clip((col + 1 + _EPS - a[:, 0]) / safe, 0.0, 1.0)
    t0, t1 = np.where(flat, 0.0, t0), np.where(flat, 1.0, t1)
    ya = a[:, 1] + t0 * (b[:, 1] - a[:, 1])
    yb = a[:, 1] + t1 * (b[:, 1] - a[:, 1])
    k, row = _ranges(np.floor(np.minimum(ya, yb) - _EPS).astype(np.int64),
                     np.floor(np.maximum(ya, yb) + _EPS).astype(np.int64))
    return row, col[k], e[k]


def _centres_in_triangles(T, h, w):
    """Texels whose centre lies in (or on) one of the triangles ``T (t,3,2)``, either orientation, inside
    an ``h[i] x w[i]`` canvas for triangle i; (rows, columns, triangles)."""
    lo = np.ceil(T.min(axis=1) - 0.5 - _EPS).astype(np.int64)
    hi = np.floor(T.max(axis=1) - 0.5 + _EPS).astype(np.int64)
    tx, cx = _ranges(lo[:, 0], hi[:, 0])
    k, cy = _ranges(lo[tx, 1], hi[tx, 1])
    t, cx = tx[k], cx[k]
    p = np.column_stack([cx + 0.5, cy + 0.5])
    A, B, C = T[t, 0], T[t, 1], T[t, 2]

    def cross(o, q):
        return (q[:, 0] - o[:, 0]) * (p[:, 1] - o[:, 1]) - (q[:, 1] - o[:, 1]) * (p[:, 0] - o[:, 0])
    d1, d2, d3 = cross(A, B), cross(B, C), cross(C, A)
    tol = _EPS * np.maximum(1.0, np.abs(d1) + np.abs(d2) + np.abs(d3))
    inside = (((d1 >= -tol) & (d2 >= -tol) & (d3 >= -tol)) | ((d1 <= tol) & (d2 <= tol) & (d3 <= tol)))
    keep = inside & (cy >= 0) & (cy < h[t]) & (cx >= 0) & (cx < w[t])
    return cy[keep], cx[keep], t[keep]


def footprint(q: np.ndarray, F: np.ndarray, bedges: np.ndarray, flipped: np.ndarray) -> np.ndarray:
    """Conservative footprint of a chart whose texel coordinates ``q`` start at (2 _EPS, 2 _EPS).

    Parameters
    ----------
    q : (k,2) float array     chart vertices in texels, ``q.min(axis=0) == 2 * _EPS``
    F : (t,3) int array       triangles
    bedges : (b,2) int array  oriented boundary edges (``boundary_halfedges(F)``)
    flipped : (f,) int array  triangles whose orientation differs from the chart's majority; the winding
                              rule can miss the texels they cover, so they are rasterised one by one

    Returns
    -------
    (h,w) bool array: texel ``[r, c]`` is set iff its closed square meets a triangle (to _EPS).
    """
    return footprints([q], [F], [bedges], [flipped])[0]


#: canvas texels rasterised together by footprints() (its int32 winding counts: 16 MB)
_BATCH_CELLS = 1 << 22


def footprints(qs: list, Fs: list, bedges: list, flipped: list) -> list:
    """:func:`footprint` of several charts (lists of its arguments), rasterised together: the charts'
    canvases lie end to end in one flat array, so each step is one numpy pass over all of them (a
    chart of 40 triangles alone costs the per-call overhead of some 20 numpy calls). Bit for bit the
    same texels as one chart at a time; groups of about _BATCH_CELLS texels bound the memory."""
    w = np.array([int(np.floor(q[:, 0].max() + _EPS)) + 1 for q in qs], np.int64)   # one per chart
    h = np.array([int(np.floor(q[:, 1].max() + _EPS)) + 1 for q in qs], np.int64)
    cells = h * (w + 1)
    out, i0 = [], 0
    while i0 < len(qs):                       # one iteration per group of charts
        i1 = i0 + max(1, int(np.searchsorted(np.cumsum(cells[i0:]), _BATCH_CELLS, side="right")))
        out += _footprints_group(qs[i0:i1], Fs[i0:i1], bedges[i0:i1], flipped[i0:i1], h[i0:i1], w[i0:i1])
        i0 = i1
    return out


def _footprints_group(qs, Fs, bedges, flipped, h, w):
    """footprints() of one group: canvases ``h[i] x (w[i] + 1)`` end to end (the extra column takes
    crossings right of the last texel), rows summed by one cumulative sum less each row's start."""
    cells = h * (w + 1)
    off = np.cumsum(cells) - cells
    nv = np.array([len(q) for q in qs])
    Q = np.concatenate(qs)
    B = np.concatenate(bedges) + np.repeat(np.cumsum(nv) - nv, [len(b) for b in bedges])[:, None]
    chart = np.repeat(np.arange(len(qs)), [len(b) for b in bedges])
    P0, P1 = Q[B[:, 0]], Q[B[:, 1]]
    # winding number at texel centres: signed crossings of each row's centre line, summed from the left
    ya, yb = P0[:, 1], P1[:, 1]
    e, r = _ranges(np.ceil(np.minimum(ya, yb) - 0.5).astype(np.int64),
                   np.ceil(np.maximum(ya, yb) - 0.5).astype(np.int64) - 1)
    yc = r + 0.5
    xa, xb, y0, y1 = P0[e, 0], P1[e, 0], ya[e], yb[e]
    x = xa + (yc - y0) * (xb - xa) / (y1 - y0)
    ce = chart[e]
    c = np.clip(np.ceil(x - 0.5).astype(np.int64), 0, w[ce])
    diff = np.zeros(int(cells.sum()), np.int32)
    np.add.at(diff, off[ce] + r * (w[ce] + 1) + c, np.where(y1 > y0, 1, -1).astype(np.int32))
    run = np.cumsum(diff, dtype=np.int32)        # int32 sums: 2.3x faster than the default int64
    rc, start = _ranges(np.zeros(len(qs), np.int64), h - 1)          # every row: its chart, its start
    start = off[rc] + start * (w[rc] + 1)
    before = np.where(start > 0, run[np.maximum(start - 1, 0)], 0)
    run -= np.repeat(before, (w + 1)[rc]).astype(np.int32)
    fp = run != 0
    rr, cc, k = _supercover(P0, P1)
    fp[off[chart[k]] + rr * (w[chart[k]] + 1) + cc] = True
    flip = [i for i in range(len(qs)) if len(flipped[i])]               # one per chart with flipped triangles
    if flip:
        T = np.concatenate([qs[i][Fs[i][flipped[i]]] for i in flip])
        tc = np.repeat(flip, [len(flipped[i]) for i in flip])
        rr, cc, t = _centres_in_triangles(T, h[tc], w[tc])
        fp[off[tc[t]] + rr * (w[tc[t]] + 1) + cc] = True
        E = np.concatenate([T, T[:, [1, 2, 0]]], axis=1).reshape(-1, 2, 2)
        rr, cc, k = _supercover(E[:, 0], E[:, 1])
        ec = np.repeat(tc, 3)[k]
        fp[off[ec] + rr * (w[ec] + 1) + cc] = True
    return [fp[o:o + n].reshape(hi, wi + 1)[:, :wi] for o, n, hi, wi in zip(off, cells, h, w)]
