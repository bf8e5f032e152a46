"""Rectangle packing: minimum-area bounding rectangles and the MaxRects packer."""

from __future__ import annotations

import numpy as np


def rotation_2d(theta: float) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


def _hull_points(P):
    """Convex hull vertices of 2D points (counter-clockwise), or the points when degenerate."""
    if len(P) < 3:
        return P
    from scipy.spatial import ConvexHull, QhullError

    try:
        return P[ConvexHull(P).vertices]
    except QhullError:          # collinear or coincident points: their two extremes along the spread
        c = P - P.mean(axis=0)
        d = np.linalg.svd(c, full_matrices=False)[2][0]
        return P[[int(np.argmin(c @ d)), int(np.argmax(c @ d))]]


def min_area_rect(P: np.ndarray) -> tuple[float, float, float]:
    """Minimum-area bounding rectangle of 2D points by rotating calipers on the convex hull.

    Returns ``(theta, w, h)``: rotating the points by ``theta`` (counter-clockwise, radians) makes the
    rectangle axis-aligned with width ``w >= h``. Vectorised over hull edges.
    """
    P = np.asarray(P, dtype=np.float64)
    H = _hull_points(P)
    H = H - H.mean(axis=0)
    if len(H) < 2 or np.ptp(H, axis=0).max() == 0.0:
        return 0.0, 0.0, 0.0
    if len(H) < 3:   # degenerate: align the direction of largest spread
        _, _, vt = np.linalg.svd(H, full_matrices=False)
        angles = np.array([np.arctan2(vt[0, 1], vt[0, 0])])
        c, s = np.cos(angles), np.sin(angles)
        x = H @ np.stack([c, s])
        y = H @ np.stack([-s, c])
        w = x.max(axis=0) - x.min(axis=0)
        h = y.max(axis=0) - y.min(axis=0)
    else:
        w, h, angles = _caliper_extents(H)
    k = int(np.argmin(w * h))
    theta, w, h = -angles[k], w[k], h[k]
    if h > w:                                # lay it long side along x
        theta += np.pi / 2
        w, h = h, w
    theta = float(np.arctan2(np.sin(theta), np.cos(theta)))
    return theta, float(w), float(h)


def _caliper_extents(H):
    """Width and height of the bounding rectangle along every edge of a convex polygon ``H`` (ccw).

    Rotating calipers without the O(h^2) projection: the edge directions of a convex polygon increase
    monotonically, so the vertex extreme in a direction is found by binary search on them.
    """
    E = np.roll(H, -1, axis=0) - H
    a = np.unwrap(np.arctan2(E[:, 1], E[:, 0]))
    if a[-1] < a[0]:                         # clockwise input: reverse it
        return _caliper_extents(H[::-1].copy())
    n = len(H)

    def extreme(phi):                        # vertex maximising p . (cos phi, sin phi)
        t = np.mod(phi + np.pi / 2 - a[0], 2 * np.pi) + a[0]
        return np.searchsorted(a, t, side="left") % n

    u = np.column_stack([np.cos(a), np.sin(a)])
    v = np.column_stack([-u[:, 1], u[:, 0]])
    xmax = np.einsum("ij,ij->i", H[extreme(a)], u)
    xmin = np.einsum("ij,ij->i", H[extreme(a + np.pi)], u)
    ymax = np.einsum("ij,ij->i", H[extreme(a + np.pi / 2)], v)
    ymin = np.einsum("ij,ij->i", H, v)        # the edge itself is the low side (ccw: inward normal v)
    return xmax - xmin, ymax - ymin, a


_RULES = ("bssf", "blsf", "baf", "bl", "cp")


def _maxrects(sizes, order, rule, allow_turn=True):
    """Pack rectangles ``sizes (n,2)`` in the unit square in ``order`` with placement ``rule``.

    Returns ``(pos (n,2), turned (n,) bool)`` or ``None`` when a rectangle does not fit. A rectangle
    may be turned by 90 degrees. Free space is kept as maximal rectangles (x0, y0, x1, y1).
    """
    n = len(sizes)
    free = np.array([[0.0, 0.0, 1.0, 1.0]])
    placed = np.empty((0, 4))
    pos = np.zeros((n, 2))
    turned = np.zeros(n, dtype=bool)
    for i in order:
        best = None
        fw = free[:, 2] - free[:, 0]
        fh = free[:, 3] - free[:, 1]
        for t, (w, h) in enumerate((sizes[i], sizes[i][::-1])):
            if t == 1 and (not allow_turn or sizes[i][0] == sizes[i][1]):
                break
            ok = (fw >= w) & (fh >= h)
            if not ok.any():
                continue
            idx = np.flatnonzero(ok)
            lw, lh = fw[idx] - w, fh[idx] - h
            if rule == "bssf":
                s1, s2 = np.minimum(lw, lh), np.maximum(lw, lh)
            elif rule == "blsf":
                s1, s2 = np.maximum(lw, lh), np.minimum(lw, lh)
            elif rule == "baf":
                s1, s2 = fw[idx] * fh[idx] - w * h, np.minimum(lw, lh)
            elif rule == "bl":
                s1, s2 = free[idx, 1] + h, free[idx, 0]
            else:  # contact point: maximise the perimeter touching the border and placed boxes
                x0, y0 = free[idx, 0], free[idx, 1]
                x1, y1 = x0 + w, y0 + h
                contact = ((x0 == 0) + (x1 >= 1)) * h + ((y0 == 0) + (y1 >= 1)) * w
                if len(placed):
                    px0, py0, px1, py1 = (placed[:, j][None, :] for j in range(4))
                    ov_y = np.clip(np.minimum(y1[:, None], py1) - np.maximum(y0[:, None], py0), 0, None)
                    ov_x = np.clip(np.minimum(x1[:, None], px1) - np.maximum(x0[:, None], px0), 0, None)
                    touch_x = (px1 == x0[:, None]) | (px0 == x1[:, None])
                    touch_y = (py1 == y0[:, None]) | (py0 == y1[:, None])
                    contact = contact + (touch_x * ov_y).sum(1) + (touch_y * ov_x).sum(1)
                s1, s2 = -contact, free[idx, 1]
            j = np.lexsort((s2, s1))[0]
            cand = (s1[j], s2[j], idx[j], t, w, h)
            if best is None or (cand[0], cand[1]) < (best[0], best[1]):
                best = cand
        if best is None:
            return None
        _, _, f, t, w, h = best
        x0, y0 = free[f, 0], free[f, 1]
        r = np.array([x0, y0, x0 + w, y0 + h])
        pos[i] = (x0, y0)
        turned[i] = bool(t)
        placed = np.vstack([placed, r])
        # split every free rectangle the new box intersects into up to four maximal pieces
        hit = (free[:, 0] < r[2]) & (free[:, 2] > r[0]) & (free[:, 1] < r[3]) & (free[:, 3] > r[1])
        if hit.any():
            F = free[hit]
            pieces = []
            m = F[:, 0] < r[0]
            pieces.append(np.column_stack([F[m, 0], F[m, 1], np.full(m.sum(), r[0]), F[m, 3]]))
            m = F[:, 2] > r[2]
            pieces.append(np.column_stack([np.full(m.sum(), r[2]), F[m, 1], F[m, 2], F[m, 3]]))
            m = F[:, 1] < r[1]
            pieces.append(np.column_stack([F[m, 0], F[m, 1], F[m, 2], np.full(m.sum(), r[1])]))
            m = F[:, 3] > r[3]
            pieces.append(np.column_stack([F[m, 0], np.full(m.sum(), r[3]), F[m, 2], F[m, 3]]))
            free = np.vstack([free[~hit], *pieces])
            # drop rectangles contained in another one (keep one of equal duplicates)
            A = free
            cont = ((A[:, None, 0] >= A[None, :, 0]) & (A[:, None, 1] >= A[None, :, 1])
                    & (A[:, None, 2] <= A[None, :, 2]) & (A[:, None, 3] <= A[None, :, 3]))
            np.fill_diagonal(cont, False)
            eq = cont & cont.T
            cont &= ~(eq & (np.arange(len(A))[:, None] < np.arange(len(A))[None, :]))
            free = A[~cont.any(axis=1)]
    return pos, turned


def _orders(wh):
    """Candidate insertion orders of the (unpadded) rectangles, biggest first by several keys."""
    w, h = wh[:, 0], wh[:, 1]
    keys = [w * h, np.maximum(w, h), w + h, h, np.minimum(w, h)]
    out = []
    for k in keys:
        o = tuple(np.lexsort((np.arange(len(k)), -k)))
        if o not in out:
            out.append(o)
    return [np.array(o) for o in out]
