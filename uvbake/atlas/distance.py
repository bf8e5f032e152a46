"""Distances between packed charts: boundary segments, exact minimum chart distance."""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import numpy as np


def boundary_halfedges(F: np.ndarray) -> np.ndarray:
    """Oriented boundary edges ``(b,2)`` of a triangle set: the half-edges without a twin."""
    E = F[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2).astype(np.int64)
    n = int(E.max()) + 1 if len(E) else 1
    key = np.minimum(E[:, 0], E[:, 1]) * n + np.maximum(E[:, 0], E[:, 1])   # one integer per undirected edge
    _, inv, cnt = np.unique(key, return_inverse=True, return_counts=True)
    return E[cnt[inv.ravel()] == 1]


def boundary_segments(uv: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Boundary edges of a chart as segments (b,2,2): edges used by exactly one triangle."""
    return uv[boundary_halfedges(F)]


def _seg_seg_dist(S, T):
    """Distance between every segment of S (a,2,2) and T (b,2,2), (a,b); 0 where they cross."""
    def pt_seg(P, A, B):
        d = B - A
        L = (d * d).sum(-1)
        t = np.where(L > 0, ((P - A) * d).sum(-1) / np.where(L > 0, L, 1), 0.0)
        t = np.clip(t, 0, 1)
        c = A + t[..., None] * d
        return np.sqrt(((P - c) ** 2).sum(-1))

    a0, a1 = S[:, None, 0], S[:, None, 1]
    b0, b1 = T[None, :, 0], T[None, :, 1]
    d = np.minimum.reduce([pt_seg(a0, b0, b1), pt_seg(a1, b0, b1), pt_seg(b0, a0, a1), pt_seg(b1, a0, a1)])

    def orient(p, q, r):
        return (q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1]) - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0])
    o1, o2 = orient(a0, a1, b0), orient(a0, a1, b1)
    o3, o4 = orient(b0, b1, a0), orient(b0, b1, a1)
    cross = (o1 * o2 < 0) & (o3 * o4 < 0)
    return np.where(cross, 0.0, d)


def _points_in_triangles(P, uv, F):
    """True where a point of P lies inside (or on) some triangle of (uv, F).

    Zero-area triangles are left out: the sign test would call every point on their line inside, and a
    point on one lies on its edges, which the segment distances already see.
    """
    a, b, c = uv[F[:, 0]], uv[F[:, 1]], uv[F[:, 2]]
    keep = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) != (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    a, b, c = a[keep], b[keep], c[keep]
    out = np.zeros(len(P), dtype=bool)
    for k in range(0, len(P), 256):
        p = P[k:k + 256, None, :]
        d1 = (b[:, 0] - a[:, 0]) * (p[..., 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (p[..., 0] - a[:, 0])
        d2 = (c[:, 0] - b[:, 0]) * (p[..., 1] - b[:, 1]) - (c[:, 1] - b[:, 1]) * (p[..., 0] - b[:, 0])
        d3 = (a[:, 0] - c[:, 0]) * (p[..., 1] - c[:, 1]) - (a[:, 1] - c[:, 1]) * (p[..., 0] - c[:, 0])
        inside = ((d1 >= 0) & (d2 >= 0) & (d3 >= 0)) | ((d1 <= 0) & (d2 <= 0) & (d3 <= 0))
        out[k:k + 256] = inside.any(axis=1)
    return out


def min_chart_distance(uvs: Sequence[np.ndarray], faces: Sequence[np.ndarray]) -> float:
    """Exact minimum distance between the triangles of different charts (0 when two charts overlap).

    Two disjoint planar triangle sets are at the distance of their closest boundary segments; they
    overlap when boundaries cross or a vertex of one lies in a triangle of the other.
    """
    segs = [boundary_segments(np.asarray(uv, float), np.asarray(F)) for uv, F in zip(uvs, faces)]
    boxes = np.array([[s[..., 0].min(), s[..., 1].min(), s[..., 0].max(), s[..., 1].max()] for s in segs])
    best = np.inf
    for i, j in itertools.combinations(range(len(uvs)), 2):
        # bbox distance is a lower bound: skip pairs that cannot beat the current best
        dx = max(boxes[i, 0] - boxes[j, 2], boxes[j, 0] - boxes[i, 2], 0.0)
        dy = max(boxes[i, 1] - boxes[j, 3], boxes[j, 1] - boxes[i, 3], 0.0)
        if np.hypot(dx, dy) >= best:
            continue
        if dx == 0 and dy == 0:   # bboxes overlap: a chart may sit in the other (hole or overlap)
            if (_points_in_triangles(np.asarray(uvs[i][:1], float), np.asarray(uvs[j], float), faces[j]).any()
                    or _points_in_triangles(np.asarray(uvs[j][:1], float), np.asarray(uvs[i], float),
                                            faces[i]).any()):
                return 0.0
        S, T = segs[i], segs[j]
        for k in range(0, len(S), 512):
            best = min(best, float(_seg_seg_dist(S[k:k + 512], T).min()))
        if best == 0.0:
            return 0.0
    return best
