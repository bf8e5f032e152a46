"""Distortion, flip, chart and seam metrics shared by the benchmarks (vectorised numpy).

Every metric takes the input surface ``V (n,3)``, ``F (m,3)`` and the map as per-corner UVs
``(m,3,2)`` (the layout Open3D's ``texture_uvs`` uses), so that per-vertex maps (uvbake, libigl) and
per-corner atlases with split vertices (xatlas, UVAtlas) are measured the same way. Per-vertex UVs
``(n,2)`` are accepted too and turned into corners with :func:`corners`.

Definitions (used by ``bench/peers.py`` and its README table):

- **Jacobian**: for each triangle, J (2x2) maps the triangle's isometric 2D frame (first edge on the
  x axis, third corner above it) to its UV triangle. sigma1 >= sigma2 >= 0 are its singular values;
  ``sign(det J)`` is the triangle's UV orientation. A chart mirrored as a whole has det < 0 everywhere
  and the same singular values, so mirroring costs nothing.
- **Angle distortion** of a triangle: sigma1 / sigma2 (1 for a similarity; inf for a collapsed one).
  Reported as its area-weighted mean and its max over triangles (area = 3D area).
- **Area distortion**: ``min_s  sum_t a_t |log(s^2 sigma1 sigma2)| / sum_t a_t`` (a_t the 3D area),
  i.e. the area-weighted mean absolute log area ratio after the best *global* scale s (one scale for
  the whole atlas, so relative sizes of charts count). The exact minimiser of this L1 objective is
  ``log s^2 = -weighted median of log(sigma1 sigma2)``; that is what ``area_scale="median"`` (the
  default) uses. ``area_scale="mean"`` uses the L2 minimiser (weighted mean of the log), which can only
  give a larger value. Collapsed triangles (zero UV area, sigma2 = 0) are left out of all distortion
  numbers and counted separately (``n_collapsed``); they are also flipped in the sense below.
- **Charts**: the connected components of faces joined through *uncut* edges. An interior edge of
  (V, F) is uncut when its two faces give both of its endpoints bit-identical UVs.
- **Flipped**: triangles whose signed UV area is opposite in sign to their chart's total signed UV area,
  or zero (the convention of ``uvbake.validate``).
- **Seam length**: total 3D length of the *cut* interior edges of (V, F), i.e. interior edges whose two
  faces disagree on the UV of either endpoint. Boundary edges of the input are not counted (every
  method has them); for a labelled scene the edges between labelled charts are seams.
- **Packing efficiency**: total |UV area| of all triangles / area of the atlas rectangle ([0,1]^2 for
  normalised atlases); only meaningful for methods that pack, and only when nothing overlaps.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components


def corners(uv, F):
    """Per-corner UVs (m,3,2) from per-vertex ``uv (n,2)`` or pass-through of per-corner ones."""
    uv = np.asarray(uv, dtype=np.float64)
    if uv.ndim == 3:
        if uv.shape[1:] != (3, 2):
            raise ValueError(f"per-corner UVs must be (m,3,2), got {uv.shape}")
        return uv
    F = np.asarray(F, dtype=np.int64)
    return uv[F]


def singular_values(V, F, uv):
    """Per-triangle Jacobian singular values and UV orientation.

    Returns
    -------
    s1, s2 : (m,) float arrays, s1 >= s2 >= 0 (in UV units per 3D unit)
    det : (m,) float array, det J (negative: triangle mirrored in UV)
    area3d : (m,) float array, 3D triangle areas
    """
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    C = corners(uv, F)
    X = V[F]
    e1 = X[:, 1] - X[:, 0]
    e2 = X[:, 2] - X[:, 0]
    l1 = np.linalg.norm(e1, axis=1)
    nrm = np.cross(e1, e2)
    dbl = np.linalg.norm(nrm, axis=1)                     # 2 * area
    # isometric frame: p1 = (0,0), p2 = (l1,0), p3 = (x3,y3) with y3 = 2A / l1 > 0
    with np.errstate(invalid="ignore", divide="ignore"):
        x3 = np.einsum("ij,ij->i", e1, e2) / l1
        y3 = dbl / l1
    # P = [[l1, x3], [0, y3]];  J = D P^-1 with D = [u2-u1, u3-u1]
    d1 = C[:, 1] - C[:, 0]
    d2 = C[:, 2] - C[:, 0]
    with np.errstate(invalid="ignore", divide="ignore"):
        a = d1[:, 0] / l1
        c = d1[:, 1] / l1
        b = (d2[:, 0] - a * x3) / y3
        d = (d2[:, 1] - c * x3) / y3
    # closed-form singular values of [[a, b], [c, d]]
    p = np.hypot(a + d, c - b)
    q = np.hypot(a - d, c + b)
    s1 = 0.5 * (p + q)
    s2 = 0.5 * np.abs(p - q)
    det = a * d - b * c
    return s1, s2, det, 0.5 * dbl


def weighted_median(x, w):
    """Weighted median (lower one when the cumulative weight hits exactly one half)."""
    x = np.asarray(x, dtype=np.float64)
    w = np.asarray(w, dtype=np.float64)
    order = np.argsort(x)
    cw = np.cumsum(w[order])
    k = int(np.searchsorted(cw, 0.5 * cw[-1]))
    return float(x[order][min(k, len(x) - 1)])


def distortion(V, F, uv, *, area_scale="median"):
    """Angle and area distortion of a map (see the module docstring for the definitions).

    Returns
    -------
    dict with ``angle_mean``, ``angle_max``, ``area``, ``scale`` (the best global scale s applied to
    the UVs), ``n_collapsed`` (triangles with sigma2 == 0: zero UV area). Collapsed triangles are left
    out of the three distortion numbers and counted instead (their angle distortion is infinite).
    """
    if area_scale not in ("median", "mean"):
        raise ValueError(f"area_scale={area_scale!r}: use 'median' (L1-optimal) or 'mean' (L2-optimal)")
    s1, s2, _, w = singular_values(V, F, uv)
    ok = w > 0                                            # 3D-degenerate triangles carry no weight
    collapsed = ok & ~(s2 > 0)                            # zero (or NaN) UV area
    n_collapsed = int(collapsed.sum())
    ok &= ~collapsed
    s1, s2, w = s1[ok], s2[ok], w[ok]
    if not len(w):
        return dict(angle_mean=float("inf"), angle_max=float("inf"), area=float("inf"), scale=float("nan"),
                    n_collapsed=n_collapsed)
    W = w.sum()
    ratio = s1 / s2
    logdet = np.log(s1 * s2)
    shift = weighted_median(logdet, w) if area_scale == "median" else float(np.sum(w * logdet) / W)
    return dict(angle_mean=float(np.sum(w * ratio) / W), angle_max=float(np.max(ratio)),
                area=float(np.sum(w * np.abs(logdet - shift)) / W), scale=float(np.exp(-0.5 * shift)),
                n_collapsed=n_collapsed)


def _interior_edges(F):
    """Interior edges of (V, F): face/corner of both sides.

    Returns (f0, k0, f1, k1): edge from corner k0 to corner (k0+1)%3 of face f0 is shared with face f1,
    where it runs from corner k1 to (k1+1)%3 (opposite direction in a consistently oriented mesh,
    same direction in an inconsistent one; both are handled by matching vertex ids).
    """
    F = np.asarray(F, dtype=np.int64)
    m = len(F)
    a = F.ravel()
    b = F[:, [1, 2, 0]].ravel()
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    n = int(F.max()) + 1 if m else 0
    key = lo * n + hi
    order = np.argsort(key, kind="stable")
    ks = key[order]
    same = np.flatnonzero(ks[1:] == ks[:-1])
    h0, h1 = order[same], order[same + 1]                 # half-edge ids f*3 + k
    return h0 // 3, h0 % 3, h1 // 3, h1 % 3


def cut_edges(F, uv):
    """Interior edges whose two faces disagree on the UV of an endpoint.

    Returns
    -------
    cut : (e,) bool, uv-cut flag per interior edge
    f0, f1 : (e,) face pairs of the interior edges
    verts : (e,2) the edge's vertex ids
    """
    F = np.asarray(F, dtype=np.int64)
    C = corners(uv, F)
    f0, k0, f1, k1 = _interior_edges(F)
    a0, b0 = F[f0, k0], F[f0, (k0 + 1) % 3]
    a1 = F[f1, k1]
    # UV at each endpoint as seen from face f0 and face f1
    ua0, ub0 = C[f0, k0], C[f0, (k0 + 1) % 3]
    ua1, ub1 = C[f1, k1], C[f1, (k1 + 1) % 3]
    same_dir = a1 == a0                                   # f1 runs the edge the same way (inconsistent)
    ua1, ub1 = np.where(same_dir[:, None], ua1, ub1), np.where(same_dir[:, None], ub1, ua1)
    cut = np.any(ua0 != ua1, axis=1) | np.any(ub0 != ub1, axis=1)
    return cut, f0, f1, np.stack([a0, b0], axis=1)


def seam_length(V, F, uv):
    """Total 3D length of cut interior edges (see the module docstring)."""
    V = np.asarray(V, dtype=np.float64)
    cut, _, _, verts = cut_edges(F, uv)
    e = verts[cut]
    return float(np.linalg.norm(V[e[:, 0]] - V[e[:, 1]], axis=1).sum())


def chart_ids(F, uv):
    """Chart of every face: components of faces joined through uncut interior edges."""
    F = np.asarray(F, dtype=np.int64)
    m = len(F)
    cut, f0, f1, _ = cut_edges(F, uv)
    keep = ~cut
    g = sp.coo_matrix((np.ones(int(keep.sum())), (f0[keep], f1[keep])), shape=(m, m))
    _, labels = connected_components(g, directed=False)
    return labels.astype(np.int64)


def signed_areas(uv, F=None):
    """Signed UV area of every triangle (positive: counter-clockwise)."""
    C = corners(uv, F)
    d1 = C[:, 1] - C[:, 0]
    d2 = C[:, 2] - C[:, 0]
    return 0.5 * (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])


def flipped(F, uv, charts=None):
    """Faces flipped against their chart's orientation (sign of the chart's total signed area), or zero.

    ``charts`` defaults to :func:`chart_ids`. A chart mirrored as a whole has no flipped face.
    """
    A = signed_areas(uv, F)
    if charts is None:
        charts = chart_ids(F, uv)
    total = np.bincount(charts, weights=A)
    orient = np.where(total[charts] >= 0, 1.0, -1.0)
    return np.flatnonzero(A * orient <= 0)


def packing_efficiency(uv, F=None, *, width=1.0, height=1.0):
    """Total |UV area| / (width * height): atlas coverage (assumes no overlaps)."""
    return float(np.abs(signed_areas(uv, F)).sum() / (width * height))


@dataclass
class MapMetrics:
    angle_mean: float
    angle_max: float
    area: float
    n_collapsed: int
    n_charts: int
    n_flipped: int
    seam_length: float


def measure(V, F, uv, *, area_scale="median"):
    """All the per-map metrics above in one record (flips per chart orientation, charts from cuts)."""
    C = corners(uv, F)
    d = distortion(V, F, C, area_scale=area_scale)
    ch = chart_ids(F, C)
    return MapMetrics(angle_mean=d["angle_mean"], angle_max=d["angle_max"], area=d["area"],
                      n_collapsed=d["n_collapsed"], n_charts=int(ch.max()) + 1 if len(ch) else 0,
                      n_flipped=int(len(flipped(F, C, ch))), seam_length=seam_length(V, F, C))
