"""Fixed-point rasterisation of UV triangles: spans, coverage accumulation, pixel-sharing candidate pairs."""

from __future__ import annotations

import numpy as np

from uvbake.validate import budgets
from uvbake.validate.candidates import _group_pairs, _raw_budget

_SUBPIXEL_BITS = 8


_S = 1 << _SUBPIXEL_BITS  # fixed-point units per pixel


_HALF = _S // 2  # pixel centre offset in fixed point




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
    out = ([], [], [], [])
    start = 0
    m = len(Xi)
    while start < m:
        base = csum[start - 1] if start else 0
        stop = int(np.searchsorted(csum, base + budgets.CHUNK, side="right"))
        stop = max(stop, start + 1)
        idx = np.arange(start, stop)
        cnt = nrows[idx]
        t = np.repeat(idx, cnt)
        first = np.cumsum(cnt) - cnt
        row = r0[t] + (np.arange(len(t)) - np.repeat(first, cnt))
        yc = row * _S + _HALF
        lo = np.zeros(len(t), np.int64)
        hi = np.full(len(t), cols, np.int64)
        for e in range(3):
            ax, ay = X[t, e], Y[t, e]
            dx = X[t, (e + 1) % 3] - ax
            dy = Y[t, (e + 1) % 3] - ay
            Bv = dx * (yc - ay) - dy * (_HALF - ax)  # E at column j is Bv - dy * S * j
            D = np.where(dy == 0, 1, dy * _S)
            q = -((-Bv) // D)  # ceil(Bv / D), for either sign of D
            lo = np.where(dy < 0, np.maximum(lo, q), lo)  # dy < 0: E >= 0  <=>  j >= ceil(Bv / D)
            hi = np.where(dy > 0, np.minimum(hi, q), hi)  # dy > 0: E > 0  <=>  j < ceil(Bv / D)
            flat_out = (dy == 0) & ~((Bv > 0) | ((Bv == 0) & (dx > 0)))
            hi = np.where(flat_out, 0, hi)
        keep = lo < hi
        for lst, arr in zip(out, (t, row, lo, hi)):
            lst.append(arr[keep])
        start = stop
    if not out[0]:
        z = np.zeros(0, np.int64)
        return z, z, z, z
    tri, row, x0, x1 = (np.concatenate(o) for o in out)
    return tri, row, x0, x1


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
