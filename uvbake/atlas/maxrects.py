"""Rectangle packing: minimum-area bounding rectangles, the MaxRects packer and the search for the largest
common scale at which a set of boxes packs (with layouts lifted to the border)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from uvbake.mesh.arrays import pieces


def rotation_2d(theta: float) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


def _hull_points(P):
    """Convex hull vertices of 2D points (counter-clockwise), or the two extremes when degenerate."""
    P = np.asarray(P, dtype=np.float64)
    if len(P) < 3:
        return P
    return P[convex_hull_2d(P)]


def _cross(P, a, b, p):
    """z of (P[b] - P[a]) x (P[p] - P[a]), elementwise over index arrays."""
    return (P[b, 0] - P[a, 0]) * (P[p, 1] - P[a, 1]) - (P[b, 1] - P[a, 1]) * (P[p, 0] - P[a, 0])


def convex_hull_2d(P: np.ndarray) -> np.ndarray:
    """Indices of the convex hull's vertices of 2D points, counter-clockwise from the lowest-leftmost
    (quickhull, every hull edge of a round split at once; points within a few rounding errors of an edge's
    line are not vertices). Hand-written: scipy.spatial's import alone costs about 0.13 s of CPU, a
    third of a small mesh's unwrap, for one hull per chart."""
    return convex_hulls_2d([P])[0]


def convex_hulls_2d(Ps: list) -> list:
    """convex_hull_2d of every point set of ``Ps`` at once: the quickhull rounds run on all sets together
    (each set's hull is a block of one cyclic list), so a round costs the same numpy calls for 1 or 100
    charts (cow's 33 hulls: 15 -> 2 ms). Same indices, in the same order, as one set at a time."""
    Ps = [np.asarray(P, dtype=np.float64).reshape(-1, 2) for P in Ps]
    sizes = np.array([len(P) for P in Ps], np.int64)
    off = np.r_[0, np.cumsum(sizes)[:-1]].astype(np.int64)
    P = np.concatenate(Ps)
    k = len(Ps)
    cid = np.repeat(np.arange(k), sizes)
    o = np.lexsort((P[:, 1], P[:, 0], cid))
    i0, i1 = o[off], o[off + sizes - 1]
    ext = np.maximum.reduceat(P, off, axis=0) - np.minimum.reduceat(P, off, axis=0)
    tol = 8 * np.finfo(float).eps * ext.max(axis=1) ** 2
    hull, hc = np.column_stack([i0, i1]).ravel(), np.repeat(np.arange(k), 2)
    pts = np.arange(len(P))
    c, t = _cross(P, i0[cid], i1[cid], pts), tol[cid]
    seg = np.where(c < -t, 2 * cid, np.where(c > t, 2 * cid + 1, -1))  # outside edge j: right of hull[j] -> next
    pts, seg = pts[seg >= 0], seg[seg >= 0]
    while len(pts):                                              # rounds: each adds a vertex to every open edge
        h = len(hull)
        start = np.flatnonzero(np.r_[True, hc[1:] != hc[:-1]])  # each set's block of the cyclic hull list
        nxt = np.arange(1, h + 1)
        nxt[np.r_[start[1:], h] - 1] = start
        a, b = hull[seg], hull[nxt[seg]]
        d = -_cross(P, a, b, pts)
        order = np.lexsort((pts, -d, seg))                       # farthest first, ties by index
        first = order[np.r_[True, seg[order][1:] != seg[order][:-1]]]
        far = np.full(h, -1)
        far[seg[first]] = pts[first]
        pos = np.arange(h) + np.r_[0, np.cumsum(far >= 0)[:-1]]  # each old vertex's new index
        new = far >= 0
        hull = np.column_stack([hull, far]).ravel()
        hc = np.column_stack([hc, np.where(new, hc, -1)]).ravel()
        hc, hull = hc[hull >= 0], hull[hull >= 0]
        f = far[seg]
        t = tol[cid[pts]]
        left = _cross(P, a, f, pts) < -t
        right = ~left & (_cross(P, f, b, pts) < -t)
        seg = np.where(left, pos[seg], pos[seg] + 1)
        keep = left | right
        pts, seg = pts[keep], seg[keep]
    counts = np.bincount(hc, minlength=k)
    return [hs - off[j] for j, hs in enumerate(pieces(hull, np.cumsum(counts)[:-1]))]


def min_area_rect(P: np.ndarray) -> tuple[float, float, float]:
    """Minimum-area bounding rectangle of 2D points by rotating calipers on the convex hull.

    Returns ``(theta, w, h)``: rotating the points by ``theta`` (counter-clockwise, radians) makes the
    rectangle axis-aligned with width ``w >= h``. Vectorised over hull edges.
    """
    return _rect_of_hull(_hull_points(np.asarray(P, dtype=np.float64)))


def chart_hulls(Ps: list) -> list:
    """Each point set's convex hull vertices as indices (convex_hull_2d; sets of under 3 points: all
    their points), the hulls found together (convex_hulls_2d)."""
    Ps = [np.asarray(P, dtype=np.float64) for P in Ps]
    big = [i for i, P in enumerate(Ps) if len(P) >= 3]
    hulls = dict(zip(big, convex_hulls_2d([Ps[i] for i in big])))
    return [hulls[i] if i in hulls else np.arange(len(P)) for i, P in enumerate(Ps)]


def min_area_rects(Ps: list, hulls: list | None = None) -> np.ndarray:
    """min_area_rect of every point set of ``Ps`` as a (n,3) array (``hulls``: their chart_hulls, when
    known)."""
    Ps = [np.asarray(P, dtype=np.float64) for P in Ps]
    hulls = chart_hulls(Ps) if hulls is None else hulls
    Hs = [P[h] for P, h in zip(Ps, hulls)]
    out = np.zeros((len(Hs), 3))
    size = np.array([len(H) for H in Hs], np.int64)            # one per chart
    for n in np.unique(size):                                  # one per distinct hull size
        idx = np.flatnonzero(size == n)
        done = _rects_of_hulls(np.stack([Hs[i] for i in idx])) if 3 <= n <= _BATCH_HULL else None
        for j, i in enumerate(idx):                            # one per chart the batch could not take
            if done is None or not done[1][j]:
                out[i] = _rect_of_hull(Hs[i])
        if done is not None:
            out[idx[done[1]]] = done[0][done[1]]
    return out


#: Hulls of up to this many vertices are measured together, a batch per hull size (a kit's or a
#: foliage mesh's thousands of small charts paid some 30 numpy calls each); larger ones one at a time.
_BATCH_HULL = 64


def _rects_of_hulls(Hs):
    """_rect_of_hull of ``k`` hulls of ``n >= 3`` vertices each, stacked (k, n, 2), computed together with
    the same float operations per hull: ((k, 3) rectangles, (k,) bool: hull done). A hull is left to
    _rect_of_hull (False) when it is degenerate or its edge angles are not ascending (clockwise input,
    or rounding), where the binary search below is not a count."""
    k, n, _ = Hs.shape
    H = Hs - Hs.mean(axis=1)[:, None, :]
    E = np.roll(H, -1, axis=1) - H
    a = np.unwrap(np.arctan2(E[:, :, 1], E[:, :, 0]), axis=1)
    ok = (np.ptp(H, axis=1).max(axis=1) != 0.0) & np.all(np.diff(a, axis=1) >= 0, axis=1)

    def extreme(phi):                        # _caliper_extents's binary search: on ascending a, a count
        t = np.mod(phi + np.pi / 2 - a[:, :1], 2 * np.pi) + a[:, :1]
        return np.count_nonzero(a[:, None, :] < t[:, :, None], axis=2) % n

    u = np.stack([np.cos(a), np.sin(a)], axis=2)
    v = np.stack([-u[:, :, 1], u[:, :, 0]], axis=2)
    rows = np.arange(k)[:, None]

    def dot(P, d):                           # the per-hull einsum, on all hulls' rows
        return np.einsum("ij,ij->i", P.reshape(-1, 2), d.reshape(-1, 2)).reshape(k, n)

    w = dot(H[rows, extreme(a)], u) - dot(H[rows, extreme(a + np.pi)], u)
    h = dot(H[rows, extreme(a + np.pi / 2)], v) - dot(H, v)
    best = np.argmin(w * h, axis=1)
    theta, w, h = -a[np.arange(k), best], w[np.arange(k), best], h[np.arange(k), best]
    turn = h > w                             # lay the long side along x
    theta = np.where(turn, theta + np.pi / 2, theta)
    w, h = np.where(turn, h, w), np.where(turn, w, h)
    return np.column_stack([np.arctan2(np.sin(theta), np.cos(theta)), w, h]), ok


def _rect_of_hull(H):
    """min_area_rect from the hull vertices ``H`` (ccw; or up to two points)."""
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


def _scores(rule, free, idx, w, h, placed):
    """MaxRects's placement scores (primary, secondary; the least wins) of ``w x h`` boxes at the lower
    left corners of the free rectangles ``free[idx]``, boxes ``placed`` (k,4) already there."""
    fw, fh = free[idx, 2] - free[idx, 0], free[idx, 3] - free[idx, 1]
    lw, lh = fw - w, fh - h
    if rule == "bssf":
        return np.minimum(lw, lh), np.maximum(lw, lh)
    if rule == "blsf":
        return np.maximum(lw, lh), np.minimum(lw, lh)
    if rule == "baf":
        return fw * fh - w * h, np.minimum(lw, lh)
    if rule == "bl":
        return free[idx, 1] + h, free[idx, 0]
    # contact point: maximise the perimeter touching the border and placed boxes
    x0, y0 = free[idx, 0], free[idx, 1]
    x1, y1 = x0 + w, y0 + h
    contact = ((x0 == 0) + (x1 >= 1)) * h + ((y0 == 0) + (y1 >= 1)) * w
    if len(placed):
        px0, py0, px1, py1 = (placed[:, j][None, :] for j in range(4))
        ov_y = np.clip(np.minimum(y1[:, None], py1) - np.maximum(y0[:, None], py0), 0, None)
        ov_x = np.clip(np.minimum(x1[:, None], px1) - np.maximum(x0[:, None], px0), 0, None)
        touch_x = (px1 == x0[:, None]) | (px0 == x1[:, None])
        touch_y = (py1 == y0[:, None]) | (py0 == y1[:, None])
        # summed in the order the boxes were placed (an accumulation, unlike sum's pairwise order), as
        # _score_few does: both packers give the same scores to the bit
        contact = contact + np.cumsum(touch_x * ov_y, axis=1)[:, -1] + np.cumsum(touch_y * ov_x, axis=1)[:, -1]
    return -contact, free[idx, 1]


#: Up to this many boxes _maxrects runs on Python floats (_maxrects_few): numpy's per-call cost is most
#: of the work on a few boxes, and the split rounds' trial layouts pack 2-12 of them many times.
_FEW_BOXES = 8


def _maxrects(sizes, order, rule, allow_turn=True):
    """Pack rectangles ``sizes (n,2)`` in the unit square in ``order`` with placement ``rule``.

    Returns ``(pos (n,2), turned (n,) bool)`` or ``None`` when a rectangle does not fit. A rectangle
    may be turned by 90 degrees. Free space is kept as maximal rectangles (x0, y0, x1, y1). Both
    orientations of a box are scored together (ties: unturned first, then the lower free rectangle).
    """
    n = len(sizes)
    if n <= _FEW_BOXES:
        return _maxrects_few(sizes, order, rule, allow_turn)
    free = np.array([[0.0, 0.0, 1.0, 1.0]])
    placed = np.empty((n, 4))
    pos = np.zeros((n, 2))
    turned = np.zeros(n, dtype=bool)
    for k, i in enumerate(order):
        w0, h0 = float(sizes[i][0]), float(sizes[i][1])
        turns = 2 if allow_turn and w0 != h0 else 1
        # candidates: (free rectangle, orientation) pairs, unturned ones first
        fw = free[:, 2] - free[:, 0]
        fh = free[:, 3] - free[:, 1]
        W = np.array([w0, h0][:turns])
        H = np.array([h0, w0][:turns])
        ok = (fw[None, :] >= W[:, None]) & (fh[None, :] >= H[:, None])
        t_idx, idx = np.nonzero(ok)                 # row-major: orientation, then free rectangle
        if not len(idx):
            return None
        s1, s2 = _scores(rule, free, idx, W[t_idx], H[t_idx], placed[:k])
        j = np.lexsort((s2, s1))[0]                 # stable: the first of equal scores
        f, t = idx[j], bool(t_idx[j])
        x0, y0 = free[f, 0], free[f, 1]
        r = np.array([x0, y0, x0 + W[int(t)], y0 + H[int(t)]])
        pos[i] = (x0, y0)
        turned[i] = t
        placed[k] = r
        # split every free rectangle the new box intersects into up to four maximal pieces
        hit = (free[:, 0] < r[2]) & (free[:, 2] > r[0]) & (free[:, 1] < r[3]) & (free[:, 3] > r[1])
        F = free[hit]
        m = len(F)
        pieces = np.concatenate((F, F, F, F))       # left, right, below and above pieces, in that order
        pieces[:m, 2] = r[0]
        pieces[m:2 * m, 0] = r[2]
        pieces[2 * m:3 * m, 3] = r[1]
        pieces[3 * m:, 1] = r[3]
        P = pieces[np.concatenate((F[:, 0] < r[0], F[:, 2] > r[2], F[:, 1] < r[1], F[:, 3] > r[3]))]
        old = free[~hit]
        A = np.concatenate((old, P))
        # drop pieces inside another rectangle (of equal ones the first is kept; a piece is not tested
        # against itself). The untouched rectangles need no test: they were maximal, and a piece lies
        # inside the rectangle it was cut from
        cont = (P[:, None, :2] >= A[None, :, :2]).all(axis=2) & (P[:, None, 2:] <= A[None, :, 2:]).all(axis=2)
        first = (len(old) + np.arange(len(P)))[:, None] <= np.arange(len(A))[None, :]
        cont &= ~((P[:, None, :] == A[None, :, :]).all(axis=2) & first)
        free = np.concatenate((old, P[~cont.any(axis=1)]))
    return pos, turned


def _maxrects_few(sizes, order, rule, allow_turn=True):
    """:func:`_maxrects` on Python floats, for at most _FEW_BOXES boxes: the same operations in the same
    order (every score, the first of equal scores, the free rectangles' split and pruning), so the
    same layout to the bit (tests/test_pack_trials.py compares them)."""
    n = len(sizes)
    free = [(0.0, 0.0, 1.0, 1.0)]
    placed: list[tuple[float, float, float, float]] = []
    pos = np.zeros((n, 2))
    turned = np.zeros(n, dtype=bool)
    for i in order:
        best = _best_spot_few(free, float(sizes[i][0]), float(sizes[i][1]), rule, placed, allow_turn)
        if best is None:
            return None
        _, f, t, W, H = best
        r = (f[0], f[1], f[0] + W, f[1] + H)
        pos[i] = (f[0], f[1])
        turned[i] = bool(t)
        placed.append(r)
        free = _split_free_few(free, r)
    return pos, turned


def _best_spot_few(free, w0, h0, rule, placed, allow_turn):
    """(score, free rectangle, turned, w, h) of the best placement of a w0 x h0 box, or None: unturned
    first, then the free rectangles in order; the first of equal scores wins."""
    shapes = [(w0, h0), (h0, w0)] if allow_turn and w0 != h0 else [(w0, h0)]
    best = None
    for t, (W, H) in enumerate(shapes):
        for f in free:
            if f[2] - f[0] >= W and f[3] - f[1] >= H:
                key = _score_few(rule, f, W, H, placed)
                if best is None or key < best[0]:
                    best = (key, f, t, W, H)
    return best


def _split_free_few(free, r):
    """The free rectangles once box ``r`` is placed, as _maxrects keeps them: the untouched ones, then
    the left, right, below and above pieces of those it hits, without pieces inside another rectangle
    (of equal ones the first stays)."""
    old, hit = [], []
    for q in free:
        (hit if q[0] < r[2] and q[2] > r[0] and q[1] < r[3] and q[3] > r[1] else old).append(q)
    pieces = ([(q[0], q[1], r[0], q[3]) for q in hit if q[0] < r[0]]
              + [(r[2], q[1], q[2], q[3]) for q in hit if q[2] > r[2]]
              + [(q[0], q[1], q[2], r[1]) for q in hit if q[1] < r[1]]
              + [(q[0], r[3], q[2], q[3]) for q in hit if q[3] > r[3]])
    A = old + pieces

    def inside(ip, p):
        return any(p[0] >= a[0] and p[1] >= a[1] and p[2] <= a[2] and p[3] <= a[3] and not (p == a and ip <= ia)
                   for ia, a in enumerate(A))

    return old + [p for k, p in enumerate(pieces) if not inside(len(old) + k, p)]


def _score_few(rule, f, w, h, placed):
    """:func:`_scores` of one box at one free rectangle, on Python floats: (primary, secondary)."""
    fw, fh = f[2] - f[0], f[3] - f[1]
    lw, lh = fw - w, fh - h
    if rule == "bssf":
        return min(lw, lh), max(lw, lh)
    if rule == "blsf":
        return max(lw, lh), min(lw, lh)
    if rule == "baf":
        return fw * fh - w * h, min(lw, lh)
    if rule == "bl":
        return f[1] + h, f[0]
    x0, y0 = f[0], f[1]
    x1, y1 = x0 + w, y0 + h
    contact = (int(x0 == 0) + int(x1 >= 1)) * h + (int(y0 == 0) + int(y1 >= 1)) * w
    if placed:
        sx = sy = 0.0
        for px0, py0, px1, py1 in placed:                   # in the order placed, as _scores sums
            if px1 == x0 or px0 == x1:
                sx += max(min(y1, py1) - max(y0, py0), 0.0)
            if py1 == y0 or py0 == y1:
                sy += max(min(x1, px1) - max(x0, px0), 0.0)
        contact = contact + sx + sy
    return -contact, y0


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


# ------------------------------------------------------------- the common scale of a box packing

_REL_TOL = 1e-3          # relative precision of the scale bisection


def bisect_scale(feasible: Callable[[float], Any], s_hi: float, lo: float | None = None,
                 lo_payload: Any = None,
                 lift: Callable[[float, Any], tuple[float, Any]] | None = None) -> tuple[Any, Any]:
    """Largest s <= s_hi with feasible(s) (assumed roughly monotone), to _REL_TOL; returns (s, payload).

    ``lo`` (with its ``lo_payload``) is a scale already known to be feasible; without it one is found by
    halving from ``s_hi``. ``lift(s, payload)`` (optional) turns a feasible trial into a feasible
    ``(s', payload')`` with ``s' >= s`` (a layout scaled up until it touches the border), which raises
    the lower end of the bracket at no cost.
    """
    def up(s, payload):
        return (s, payload) if lift is None else lift(s, payload)

    if lo is None:
        payload = feasible(s_hi)
        if payload is not None:
            return s_hi, payload
        s, down = s_hi, 0.5 if lift is None else 0.9       # a lift takes back most of a small step's loss
        for _ in range(60 if lift is None else 300):      # find a feasible lower end by stepping down
            s *= down
            lo_payload = feasible(s)
            if lo_payload is not None:
                lo, lo_payload = up(s, lo_payload)
                break
        if lo is None:
            return None, None
        hi = min(s_hi, s / down)
    else:
        hi = s_hi
    if lift is not None:      # a lifted layout touches the border: probe geometrically above it
        step, fails = 2 * _REL_TOL, []
        while lo * (1 + step) < hi:
            s = lo * (1 + step)
            p = feasible(s)
            if p is None:
                fails.append(s)
            else:
                lo, lo_payload = up(s, p)
            step *= 4
        hi = min([f for f in fails if f > lo] + [hi])
    while hi - lo > _REL_TOL * hi:
        mid = 0.5 * (lo + hi)
        p = feasible(mid)
        if p is not None:
            lo, lo_payload = up(mid, p)
        else:
            hi = mid
    return lo, lo_payload


def _upper_scale(wh, pad):
    """Scale above which the padded boxes cannot fit the unit square (area and side bounds)."""
    w, h = wh[:, 0], wh[:, 1]
    A, B, C = (w * h).sum(), pad * (w + h).sum(), len(w) * pad * pad - 1.0
    if C >= 0:
        return 0.0
    s_area = (-B + np.sqrt(B * B - 4 * A * C)) / (2 * A) if A > 0 else np.inf
    side = np.maximum(w, h).max()
    s_side = (1.0 - pad) / side if side > 0 else np.inf
    return float(min(s_area, s_side))


def _pack_boxes(wh, pad, packers):
    """Largest common scale at which boxes ``s*wh + pad`` pack into the unit square, and where.

    ``packers`` are tried in turn: the first is bisected fully, each later one only has to beat the
    best scale so far (one trial packing, then a bisection upwards if it does). Every packing that
    fits is scaled up about the origin until a box meets the border (:func:`_lift_boxes`).
    """
    s_hi = _upper_scale(wh, pad)
    if not np.isfinite(s_hi):
        s_hi = 1.0
    if s_hi <= 0:
        return None, None
    best_s, best_p = None, None

    def lift(s, payload):
        return _lift_boxes(wh, pad, s, payload, s_hi)
    for packer in packers:
        def feasible(s, packer=packer):
            return packer(s * wh + pad)
        if best_s is None:
            best_s, best_p = bisect_scale(feasible, s_hi, lift=lift)
            continue
        s_try = best_s * (1 + _REL_TOL)
        if s_try > s_hi:
            break
        p = feasible(s_try)
        if p is not None:
            best_s, best_p = bisect_scale(feasible, s_hi, *lift(s_try, p), lift=lift)
    return best_s, best_p


def _lift_boxes(wh, pad, s, payload, s_hi):
    """A box layout that fits at scale ``s``, scaled by ``k >= 1`` about the origin until a box meets
    the unit square's border: boxes ``k (s wh + pad)`` contain ``(k s) wh + pad`` and stay apart, so
    ``(k s, k pos)`` is a valid layout too (a packing found at ``s`` proves the larger scale)."""
    pos, turned = payload
    size = s * wh + pad
    size = np.where(turned[:, None], size[:, ::-1], size)
    k = 1.0 / max(float((pos + size).max()), 1e-300)
    k = min(k * (1.0 - 1e-12), s_hi / s)
    if k <= 1.0:
        return s, payload
    return k * s, (k * pos, turned)


def _own_packers(wh, allow_turn=True, rules=_RULES):
    """One packer per (placement rule, order) pair."""
    return [lambda sizes, o=o, r=r: _maxrects(sizes, o, r, allow_turn) for r in rules for o in _orders(wh)]
