"""Fixed-point rasterisation of UV triangles: spans, coverage accumulation, pixel-sharing candidate pairs."""

from __future__ import annotations

import numpy as np

from uvbake.validate import budgets
from uvbake.validate.candidates import _group_pairs, _raw_budget

_SUBPIXEL_BITS = 8


_S = 1 << _SUBPIXEL_BITS  # fixed-point units per pixel


_HALF = _S // 2  # pixel centre offset in fixed point




#: Fixed-point coordinates below this (with at most 2^14 rows and columns) let _spans divide in float64:
#: Bv (< 2^49) and dy S (< 2^32) are exact there, a non-integer quotient lies at least 2^-32 from the
#: integers, more than float64's rounding error (2^-33) for quotients under 2^20, and larger quotients
#: are clamped to [0, cols] either way, so the ceiling is the integer one wherever it matters.
_FLOAT_EXACT = 1 << 23

_BAND_PX = 1 << 22  # pixels per band of the coverage grid accumulation


def _raster_frame(corners, atlas, res):
    """Origin (2,), pixel size, rows and cols of the coverage grid (see the module docstring)."""
    lo = corners.min(axis=(0, 1))
    hi = corners.max(axis=(0, 1))
    if atlas and lo.min() >= 0.0 and hi.max() <= 1.0:
        return np.zeros(2), 1.0 / res, res, res
    extent = float((hi - lo).max())
    if extent == 0.0:
        extent = 1.0
    pixel = extent / res
    cols = int(min(res, max(1, np.ceil((hi[0] - lo[0]) / pixel))))
    rows = int(min(res, max(1, np.ceil((hi[1] - lo[1]) / pixel))))
    return lo.astype(np.float64), pixel, rows, cols


def _fixed_point(corners, origin, pixel_size):
    """Integer fixed-point coordinates (m,3) of the corners, ``_S`` units per pixel."""
    scale = _S / pixel_size
    Xi = np.rint((corners[..., 0] - origin[0]) * scale).astype(np.int64)
    Yi = np.rint((corners[..., 1] - origin[1]) * scale).astype(np.int64)
    return Xi, Yi


def _spans(Xi, Yi, rows, cols, max_rows=None):
    """Scan-convert triangles into row spans of covered pixel centres (top-left fill rule).

    A pixel centre p on an edge a->b (E(p) = cross(b - a, p - a) = 0) is claimed as if it were moved
    by (eps, eps**2): only when dy < 0, or dy == 0 and dx > 0. This is a symbolic perturbation, so
    triangles with disjoint interiors never claim the same centre, whatever they share.

    Parameters
    ----------
    Xi, Yi : (m,3) int64 fixed-point coordinates
    rows, cols : int
    max_rows : int, optional
        Return None when the triangles span more rows than this in total.

    Returns
    -------
    tri, row, x0, x1 : (s,) int64 arrays; triangle ``tri`` claims pixels ``x0 <= col < x1`` of ``row``
    """
    X0, X1, X2 = Xi[:, 0], Xi[:, 1], Xi[:, 2]
    Y0, Y1, Y2 = Yi[:, 0], Yi[:, 1], Yi[:, 2]
    area = (X1 - X0) * (Y2 - Y0) - (Y1 - Y0) * (X2 - X0)
    neg = area < 0
    X = np.stack([X0, np.where(neg, X2, X1), np.where(neg, X1, X2)], axis=1)
    Y = np.stack([Y0, np.where(neg, Y2, Y1), np.where(neg, Y1, Y2)], axis=1)
    ymin, ymax = Y.min(axis=1), Y.max(axis=1)
    r0 = np.maximum(-((_HALF - ymin) // _S), 0)  # ceil((ymin - h) / S)
    r1 = np.minimum((ymax - _HALF) // _S, rows - 1)  # floor((ymax - h) / S)
    nrows = np.where(area != 0, np.maximum(r1 - r0 + 1, 0), 0)
    csum = np.cumsum(nrows)
    if max_rows is not None and len(csum) and csum[-1] > max_rows:
        return None
    r0, r1, bounds = _edge_bounds(X, Y, r0, r1)
    big = max(int(np.abs(Xi).max(initial=0)), int(np.abs(Yi).max(initial=0)))
    exact_in_float = big < _FLOAT_EXACT and rows <= 1 << 14 and cols <= 1 << 14
    bounds = [np.ascontiguousarray(bounds[:, :, k], np.float64 if exact_in_float else np.int64) for k in range(3)]
    nrows = np.where(area != 0, np.maximum(r1 - r0 + 1, 0), 0)
    csum = np.cumsum(nrows)
    out = ([], [], [], [])
    start = 0
    m = len(Xi)
    while start < m:
        base = csum[start - 1] if start else 0
        stop = int(np.searchsorted(csum, base + budgets.CHUNK // 8, side="right"))   # 8 x (s,) arrays below
        stop = max(stop, start + 1)
        idx = np.arange(start, stop)
        cnt = nrows[idx]
        t = np.repeat(idx, cnt)
        first = np.cumsum(cnt) - cnt
        row = r0[t] + (np.arange(len(t)) - np.repeat(first, cnt))
        # (s, 4) each: two lower-bound edges, then two upper-bound ones
        A, C, D = (np.repeat(c[idx], cnt, axis=0) for c in bounds)
        q = A * row.astype(A.dtype)[:, None]
        q += C
        if exact_in_float:
            q /= D
            np.ceil(q, out=q)
        else:
            np.negative(q, out=q)
            q //= D
            np.negative(q, out=q)
        lo = np.maximum(np.maximum(q[:, 0], q[:, 1]), 0).astype(np.int64)
        hi = np.minimum(np.minimum(q[:, 2], q[:, 3]), cols).astype(np.int64)
        keep = lo < hi
        for lst, arr in zip(out, (t, row, lo, hi)):
            lst.append(arr[keep])
        start = stop
    if not out[0]:
        z = np.zeros(0, np.int64)
        return z, z, z, z
    tri, row, x0, x1 = (np.concatenate(o) for o in out)
    return tri, row, x0, x1


def _edge_bounds(X, Y, r0, r1):
    """Each counter-clockwise triangle's edges as column bounds linear in the row, for :func:`_spans`.

    Along edge a->b the edge function at pixel centre (j, r) is ``E = Bv(r) - dy S j`` with
    ``Bv(r) = dx S r + dx (h - ay) - dy (h - ax)``: an edge with dy < 0 admits ``j >= ceil(Bv / (dy S))``
    and one with dy > 0 admits ``j < ceil(Bv / (dy S))``. A triangle has one or two of each; a single one
    fills both of its slots. A horizontal edge (dy = 0) bounds no column: on every row strictly inside
    the triangle E > 0, and the row through it (its first or last) is claimed only when dx > 0, so
    with dx < 0 that row is dropped from ``r0`` or ``r1``.

    Returns r0, r1 (adjusted) and bounds (m, 4, 3) int64: (dx S, dx (h - ay) - dy (h - ax), dy S) of
    the lower-bound edges, then of the upper-bound ones. :func:`_spans` divides in float64 where that
    gives the exact integer ceiling wherever it matters (see _FLOAT_EXACT).
    """
    Xb, Yb = np.roll(X, -1, axis=1), np.roll(Y, -1, axis=1)
    dx, dy = Xb - X, Yb - Y
    coef = np.stack([dx * _S, dx * (_HALF - Y) - dy * (_HALF - X), dy * _S], axis=2)   # (m, 3, 3)
    lower, upper = dy < 0, dy > 0
    # the edge filling a slot: the first and the last edge of each kind (the same one when there is one)
    e = np.arange(3)[None, :]
    first_lo = np.where(lower, e, 3).min(axis=1)
    last_lo = np.where(lower, e, -1).max(axis=1)
    first_up = np.where(upper, e, 3).min(axis=1)
    last_up = np.where(upper, e, -1).max(axis=1)
    slots = np.clip(np.stack([first_lo, last_lo, first_up, last_up], axis=1), 0, 2)
    bounds = np.take_along_axis(coef, slots[:, :, None], axis=1)
    # a horizontal edge with dx < 0 drops the row through it (when that row's centre lies on it)
    flat = (dy == 0) & (dx < 0)
    on_row = flat & ((Y - _HALF) % _S == 0)
    row_of = (Y - _HALF) // _S
    drop_first = (on_row & (row_of == r0[:, None])).any(axis=1)
    drop_last = (on_row & (row_of == r1[:, None])).any(axis=1)
    return r0 + drop_first, r1 - drop_last, bounds


def _accumulate(row, x0, x1, rows, cols, weight=None):
    """Per-pixel sum of ``weight`` (or count) over the spans, (rows, cols), banded to bound memory."""
    band = max(1, _BAND_PX // (cols + 1))
    dtype = np.int64 if weight is None else np.float64
    out = np.zeros((rows, cols), np.int32 if weight is None else np.float64)
    for b0 in range(0, rows, band):
        b1 = min(rows, b0 + band)
        sel = (row >= b0) & (row < b1)
        if not sel.any():
            continue
        base = (row[sel] - b0) * (cols + 1)
        n = (b1 - b0) * (cols + 1)
        w = None if weight is None else weight[sel]
        diff = np.bincount(base + x0[sel], weights=w, minlength=n) - np.bincount(
            base + x1[sel], weights=w, minlength=n
        )
        acc = np.cumsum(diff.astype(dtype).reshape(b1 - b0, cols + 1), axis=1)[:, :cols]
        out[b0:b1] = acc
    return out


def _claimed_once(row, x0, x1, cols):
    """Whether no pixel lies in two spans: with the spans sorted by (row, first column), each must end
    before the next begins. Sorting s spans is cheaper than a pass over the pixel grid when spans are
    fewer than pixels; on a large count (s log s past the grid) the caller's grid pass decides."""
    s = len(row)
    if s < 2:
        return True
    if s * max(1, int(np.log2(s))) > 4 * (int(row.max()) + 1) * (cols + 1) or (int(row.max()) + 1) * (cols + 1) >= 1 << 31:
        return False
    base = row * (cols + 1)
    start = (base + x0).astype(np.int32)
    order = np.argsort(start)
    return bool(np.all(start[order[1:]] >= (base + x1)[order[:-1]]))


def _raster_pairs(tri, row, x0, x1, rows, cols, m):
    """Pairs of triangles claiming a common pixel, banded over rows so memory stays bounded.

    Parameters
    ----------
    tri, row, x0, x1 : (s,) int64 spans from :func:`_spans`
    rows, cols, m : int

    Returns
    -------
    keys, pix : (q,) int64
        Every pair ``i * m + j`` (i < j) claiming a common pixel, and that pixel ``row * cols + col``
        (a pair appears once per pixel it shares).
    covered_px : int
        Pixels claimed at least once.
    complete : bool
        False when the work budget left some multiply-claimed pixels unexpanded.
    """
    if _claimed_once(row, x0, x1, cols):   # the usual case (a valid atlas): no pixel grid needed
        z = np.zeros(0, np.int64)
        return z, z, int((x1 - x0).sum()), True
    band = max(1, _BAND_PX // (cols + 1))
    covered_px = 0
    keys = [np.zeros(0, np.int64)]
    pixels = [np.zeros(0, np.int64)]
    claims = raw = 0
    complete = True
    for b0 in range(0, rows, band):
        b1 = min(rows, b0 + band)
        sel = np.flatnonzero((row >= b0) & (row < b1))
        if len(sel) == 0:
            continue
        r, a, b = row[sel] - b0, x0[sel], x1[sel]
        n = (b1 - b0) * (cols + 1)
        diff = np.bincount(r * (cols + 1) + a, minlength=n) - np.bincount(r * (cols + 1) + b, minlength=n)
        count = np.cumsum(diff.reshape(b1 - b0, cols + 1), axis=1)  # column ``cols`` is always 0
        covered_px += int(np.count_nonzero(count))
        multi = count >= 2
        if not multi.any():
            continue
        # spans touching a multiply-claimed pixel, from inclusive per-row prefix sums
        csum = np.cumsum(multi, axis=1, dtype=np.int32)
        before = np.where(a > 0, csum[r, np.maximum(a - 1, 0)], 0)
        hot = np.flatnonzero(csum[r, b - 1] - before > 0)
        if not complete:
            continue  # keep counting pixels, expand no more
        lens = b[hot] - a[hot]
        if claims + lens.sum() > budgets.MAX_CLAIMS:
            keep = np.cumsum(lens) <= budgets.MAX_CLAIMS - claims
            hot, lens, complete = hot[keep], lens[keep], False
        claims += int(lens.sum())
        first = np.cumsum(lens) - lens
        rr = np.repeat(r[hot], lens)
        col = np.repeat(a[hot], lens) + (np.arange(len(rr)) - np.repeat(first, lens))
        on = multi[rr, col]
        pix = (rr[on] + b0) * cols + col[on]
        k, g, done = _group_pairs(
            pix, np.repeat(tri[sel][hot], lens)[on], m, budget=_raw_budget(m) - raw, with_groups=True
        )
        raw += len(k)
        complete &= done and raw < _raw_budget(m)
        keys.append(k)
        pixels.append(g)
    return np.concatenate(keys), np.concatenate(pixels), covered_px, complete
