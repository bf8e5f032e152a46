"""The one definition of every map metric: distortion, flips, charts, seams, packing (vectorised numpy).

Used by the pipeline's report (:mod:`uvbake.atlas.pipeline`), the benchmarks (bench/metrics.py
re-exports this module) and the tests.

Every metric takes the input surface ``V (n,3)``, ``F (m,3)`` and the map as per-corner UVs
``(m,3,2)`` (the layout Open3D's ``texture_uvs`` uses), so that per-vertex maps (uvbake, libigl) and
per-corner atlases with split vertices (xatlas, UVAtlas) are measured the same way. Per-vertex UVs
``(n,2)`` are accepted too and turned into corners with :func:`corners`.

Definitions (the pipeline's JSON report and the README's tables):

- **Jacobian**: for each triangle, J (2x2) maps the triangle's isometric 2D frame
  (:func:`uvbake.flatten.energy.triangle_frames`) to its UV triangle. sigma1 >= sigma2 >= 0 are its singular values;
  ``sign(det J)`` is the triangle's UV orientation. A chart mirrored as a whole has det < 0 everywhere
  and the same singular values, so mirroring costs nothing.
- **Angle distortion** of a triangle: sigma1 / sigma2 (1 for a similarity; inf for a collapsed one).
  Reported as its area-weighted mean and its max over triangles (area = 3D area).
- **Area distortion**: ``sum_t a_t |log(s^2 sigma1 sigma2)| / sum_t a_t`` (a_t the 3D area). uvbake's own
  maps are at the surface's scale, so its report uses s = 1 (``area_scale="none"``); for peers'
  normalised atlases s is the best global scale, ``min_s`` of the same sum
  i.e. the area-weighted mean absolute log area ratio after the best *global* scale s (one scale for
  the whole atlas, so relative sizes of charts count). The exact minimiser of this L1 objective is
  ``log s^2 = -weighted median of log(sigma1 sigma2)``; that is what ``area_scale="median"`` (the
  default) uses. ``area_scale="mean"`` uses the L2 minimiser (weighted mean of the log), which can only
  give a larger value. Collapsed triangles (zero UV area, sigma2 = 0) and degenerate 3D triangles are
  left out of all distortion numbers (the means are over the others, weighted by their 3D area) and
  counted separately (``n_collapsed``); collapsed ones are also flipped in the sense below.
- **Charts**: the connected components of faces joined through *uncut* edges. An interior edge of
  (V, F) is uncut when its two faces give both of its endpoints bit-identical UVs.
- **Flipped**: triangles whose signed UV area is opposite in sign to their chart's total signed UV area,
  or zero (the convention of ``uvbake.validate``).
- **Seam length**: total 3D length of the *cut* interior edges of (V, F), i.e. interior edges whose two
  faces disagree on the UV of either endpoint. Boundary edges of the input are not counted (every
  method has them); for a labelled scene the edges between labelled charts are seams.
- **Texel share** of a triangle (:func:`texel_share`): s_t = (UV area_t / UV area total) /
  (3D area_t / 3D area total), on the packed atlas; 1 is fair, 0 is a triangle with no texels. The
  report's ``min_texel_share``, ``area_below_quarter`` and ``area_below_sixteenth`` (the share of the
  3D area with s_t below 1/4 and 1/16) come from :func:`texel_summary`.
- **Packing efficiency**: total |UV area| of all triangles / area of the atlas rectangle ([0,1]^2 for
  normalised atlases); only meaningful for methods that pack, and only when nothing overlaps.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from uvbake.flatten.energy import corner_jacobians, triangle_frames
from uvbake.mesh.arrays import signed_areas
from uvbake.mesh.graph import components


def corners(uv: ArrayLike, F: np.ndarray | None) -> np.ndarray:
    """Per-corner UVs (m,3,2) from per-vertex ``uv (n,2)`` or pass-through of per-corner ones."""
    uv = np.asarray(uv, dtype=np.float64)
    if uv.ndim == 3:
        if uv.shape[1:] != (3, 2):
            raise ValueError(f"per-corner UVs must be (m,3,2), got {uv.shape}")
        return uv
    F = np.asarray(F, dtype=np.int64)
    return uv[F]


def singular_values(V: np.ndarray, F: np.ndarray | None, uv: np.ndarray) -> tuple[np.ndarray, ...]:
    """Per-triangle Jacobian singular values and UV orientation.

    Returns
    -------
    s1, s2 : (m,) float arrays, s1 >= s2 >= 0 (in UV units per 3D unit; NaN for degenerate 3D triangles)
    det : (m,) float array, det J (negative: triangle mirrored in UV)
    area3d : (m,) float array, 3D triangle areas
    """
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    _, Q, area = triangle_frames(V, F)
    J = corner_jacobians(corners(uv, F), Q)
    a, b, c, d = J[:, 0, 0], J[:, 0, 1], J[:, 1, 0], J[:, 1, 1]
    det = a * d - b * c
    # a 2 x 2 matrix's singular values in closed form, not a LAPACK call per triangle
    # (docs/decisions/atlas-speed.md): s1 = |J's conformal part| + |its anti-conformal part|, s2 = |det| / s1
    s1 = np.hypot(0.5 * (a + d), 0.5 * (c - b)) + np.hypot(0.5 * (a - d), 0.5 * (c + b))
    with np.errstate(invalid="ignore", divide="ignore"):
        s2 = np.where(s1 > 0, np.abs(det) / s1, np.where(np.isnan(s1), np.nan, 0.0))
    return s1, s2, det, area


def weighted_median(x: ArrayLike, w: ArrayLike) -> float:
    """Weighted median (lower one when the cumulative weight hits exactly one half)."""
    x = np.asarray(x, dtype=np.float64)
    w = np.asarray(w, dtype=np.float64)
    order = np.argsort(x)
    cw = np.cumsum(w[order])
    k = int(np.searchsorted(cw, 0.5 * cw[-1]))
    return float(x[order][min(k, len(x) - 1)])


def _mean(w, x, ok):
    """Area-weighted mean of x over the triangles ``ok`` (w: weights normalised over all triangles)."""
    if ok.all():
        return float(np.sum(w * x))
    return float(np.sum(w[ok] * x[ok]) / np.sum(w[ok]))


def distortion(V: np.ndarray, F: np.ndarray | None, uv: np.ndarray, *,
               area_scale: str = "median") -> dict[str, Any]:
    """Angle and area distortion of a map (see the module docstring for the definitions).

    Parameters
    ----------
    area_scale : {"median", "mean", "none"}
        The global scale s of the area distortion: L1-optimal, L2-optimal, or 1 (maps at true scale).

    Returns
    -------
    dict with ``angle_mean``, ``angle_max``, ``area``, ``scale`` (the global scale s applied to the
    UVs), ``n_collapsed`` (triangles with sigma2 == 0: zero UV area) and ``area_3d``. Collapsed and
    degenerate triangles are left out of the three distortion numbers.
    """
    if area_scale not in ("median", "mean", "none"):
        raise ValueError(f"area_scale={area_scale!r}: use 'median' (L1-optimal), 'mean' (L2-optimal) or "
                         "'none' (s = 1)")
    s1, s2, _, area = singular_values(V, F, uv)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = s1 / s2
        logdet = np.log(s1 * s2)
    ok = np.isfinite(ratio) & np.isfinite(logdet)
    n_collapsed = int(np.count_nonzero((area > 0) & ~(s2 > 0)))
    if not ok.any():
        return dict(angle_mean=float("inf"), angle_max=float("inf"), area=float("inf"), scale=float("nan"),
                    n_collapsed=n_collapsed, area_3d=float(area.sum()))
    w = area / area.sum()
    if area_scale == "none":
        shift = 0.0
    elif area_scale == "median":
        shift = weighted_median(logdet[ok], w[ok])
    else:
        shift = float(np.sum(w[ok] * logdet[ok]) / np.sum(w[ok]))
    return dict(angle_mean=_mean(w, ratio, ok), angle_max=float(np.max(ratio[ok])),
                area=_mean(w, np.abs(logdet - shift), ok), scale=float(np.exp(-0.5 * shift)),
                n_collapsed=n_collapsed, area_3d=float(area.sum()))


def chart_distortion(V: np.ndarray, F: np.ndarray | None, uv: np.ndarray) -> dict[str, Any]:
    """The pipeline report's distortion of one chart at true scale (``area_scale="none"``)."""
    d = distortion(V, F, uv, area_scale="none")
    return dict(angle_distortion_mean=d["angle_mean"], angle_distortion_max=d["angle_max"],
                area_distortion_mean=d["area"], area_3d=d["area_3d"])


def chart_distortions(Vs: list, Fs: list, uvs: list) -> list[dict[str, Any]]:
    """:func:`chart_distortion` of many charts, computed on all of them at once (the charts laid end to
    end; each chart's sums are accumulated per chart, so they may differ from chart_distortion's in the
    last bits): a kit of hundreds of small parts paid some thirty numpy calls per chart."""
    k = len(Fs)
    if k == 0:
        return []
    nv = np.array([len(V) for V in Vs])                      # one per chart
    nf = np.array([len(F) for F in Fs])
    voff, foff = np.cumsum(nv) - nv, np.cumsum(nf) - nf
    cf = np.repeat(np.arange(k), nf)
    F = np.concatenate([np.asarray(F, dtype=np.int64) for F in Fs]) + voff[cf][:, None]
    s1, s2, _, area = singular_values(np.concatenate(Vs), F, np.concatenate(uvs))
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = s1 / s2
        logdet = np.log(s1 * s2)
    ok = np.isfinite(ratio) & np.isfinite(logdet)
    area_3d = np.bincount(cf, weights=area, minlength=k)
    with np.errstate(divide="ignore", invalid="ignore"):
        w = area / area_3d[cf]
        n_ok = np.bincount(cf, weights=ok, minlength=k)
        every = n_ok == nf
        den = np.bincount(cf, weights=np.where(ok, w, 0.0), minlength=k)

        def mean(x):                                  # _mean per chart: over ok triangles, renormalised if some are not
            num = np.bincount(cf, weights=np.where(ok, w * np.where(ok, x, 0.0), 0.0), minlength=k)
            return np.where(every, num, num / den)
        angle_mean, area_mean = mean(ratio), mean(np.abs(logdet))
    nonempty = nf > 0
    angle_max = np.full(k, -np.inf)
    angle_max[nonempty] = np.maximum.reduceat(np.where(ok, ratio, -np.inf), foff[nonempty])
    none = n_ok == 0
    out = []
    for i in range(k):                                # one per chart: the dicts
        if none[i]:
            out.append(dict(angle_distortion_mean=float("inf"), angle_distortion_max=float("inf"),
                            area_distortion_mean=float("inf"), area_3d=float(area_3d[i])))
        else:
            out.append(dict(angle_distortion_mean=float(angle_mean[i]), angle_distortion_max=float(angle_max[i]),
                            area_distortion_mean=float(area_mean[i]), area_3d=float(area_3d[i])))
    return out


def distortion_summary(per_chart: list[dict[str, Any]], flipped: int, energy: float) -> dict[str, Any]:
    """The report's whole-mesh summary: chart distortions combined, weighted by their 3D area."""
    total = sum(x["area_3d"] for x in per_chart) or 1.0
    return dict(
        charts=len(per_chart),
        flipped=int(flipped),
        energy=float(energy),
        angle_distortion_mean=float(sum(x["angle_distortion_mean"] * x["area_3d"] for x in per_chart) / total),
        angle_distortion_max=float(max(x["angle_distortion_max"] for x in per_chart)),
        area_distortion_mean=float(sum(x["area_distortion_mean"] * x["area_3d"] for x in per_chart) / total),
    )


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


def cut_edges(F: np.ndarray, uv: ArrayLike) -> tuple[np.ndarray, ...]:
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


def uv_seam_length(V: ArrayLike, F: np.ndarray, uv: ArrayLike) -> float:
    """Total 3D length of cut interior edges (see the module docstring)."""
    V = np.asarray(V, dtype=np.float64)
    cut, _, _, verts = cut_edges(F, uv)
    e = verts[cut]
    return float(np.linalg.norm(V[e[:, 0]] - V[e[:, 1]], axis=1).sum())


def seam_placement(V: ArrayLike, F: np.ndarray, uv: ArrayLike, *, crease_deg: float = 30.0) -> dict[str, float]:
    """Where the seams lie: their 3D length, the share of it on creases (triangle normals at least
    ``crease_deg`` apart) and on valleys (concave edges), and their cost
    (:func:`uvbake.mesh.cut.seam_costs`: length discounted on creases, most on valleys) over length.
    ``F`` consistently oriented, as uvbake's repair leaves it."""
    from uvbake.mesh.cut import dihedrals, seam_costs

    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    cut, f0, f1, verts = cut_edges(F, uv)
    f0, f1, e = f0[cut], f1[cut], verts[cut]
    length = np.linalg.norm(V[e[:, 0]] - V[e[:, 1]], axis=1)
    total = float(length.sum())
    if total <= 0:
        return dict(seam_length=0.0, on_creases=0.0, on_valleys=0.0, cost_per_length=0.0)
    cos, valley = dihedrals(V, F, f0, f1, e[:, 0], e[:, 1])
    crease = cos <= np.cos(np.radians(crease_deg))
    cost = seam_costs(V, F, f0, f1, e[:, 0], e[:, 1])
    return dict(seam_length=total, on_creases=float(length[crease].sum() / total),
                on_valleys=float(length[crease & valley].sum() / total), cost_per_length=float(cost.sum() / total))


def chart_ids(F: np.ndarray, uv: ArrayLike) -> np.ndarray:
    """Chart of every face: components of faces joined through uncut interior edges."""
    F = np.asarray(F, dtype=np.int64)
    m = len(F)
    cut, f0, f1, _ = cut_edges(F, uv)
    keep = ~cut
    _, labels = components(m, f0[keep], f1[keep])
    return labels.astype(np.int64)


def flipped(F: np.ndarray, uv: ArrayLike, charts: np.ndarray | None = None) -> np.ndarray:
    """Faces flipped against their chart's orientation (sign of the chart's total signed area), or zero.

    ``charts`` defaults to :func:`chart_ids`. A chart mirrored as a whole has no flipped face.
    """
    A = signed_areas(corners(uv, F))
    if charts is None:
        charts = chart_ids(F, uv)
    total = np.bincount(charts, weights=A)
    orient = np.where(total[charts] >= 0, 1.0, -1.0)
    return np.flatnonzero(A * orient <= 0)


def packing_efficiency(uv: ArrayLike, F: np.ndarray | None = None, *, width: float = 1.0,
                       height: float = 1.0) -> float:
    """Total |UV area| / (width * height): atlas coverage (assumes no overlaps)."""
    return float(np.abs(signed_areas(corners(uv, F))).sum() / (width * height))


@dataclass
class MapMetrics:
    angle_mean: float
    angle_max: float
    area: float
    n_collapsed: int
    n_charts: int
    n_flipped: int
    seam_length: float


def measure(V: np.ndarray, F: np.ndarray, uv: np.ndarray, *, area_scale: str = "median") -> MapMetrics:
    """All the per-map metrics above in one record (flips per chart orientation, charts from cuts)."""
    C = corners(uv, F)
    d = distortion(V, F, C, area_scale=area_scale)
    ch = chart_ids(F, C)
    return MapMetrics(angle_mean=d["angle_mean"], angle_max=d["angle_max"], area=d["area"],
                      n_collapsed=d["n_collapsed"], n_charts=int(ch.max()) + 1 if len(ch) else 0,
                      n_flipped=int(len(flipped(F, C, ch))), seam_length=uv_seam_length(V, F, C))


# ----------------------------------------------------------------------------- texel share
def _uv_areas(corner_uv):
    c = np.asarray(corner_uv, dtype=np.float64)
    e1, e2 = c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]
    return 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])


def _areas_3d(V, F):
    X = np.asarray(V, dtype=np.float64)[np.asarray(F)]
    return 0.5 * np.linalg.norm(np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0]), axis=1)


def texel_share(V: np.ndarray, F: np.ndarray, corner_uv: ArrayLike) -> np.ndarray:
    """(m,) texel share of every triangle: its share of the UV area over its share of the 3D area.

    ``corner_uv`` is (m,3,2) (per-vertex (n,2) UVs are accepted too). Triangles with zero 3D area get
    share 1 (they need no texels)."""
    uv = np.asarray(corner_uv, dtype=np.float64)
    if uv.ndim == 2:
        uv = uv[np.asarray(F)]
    a_uv, a_3d = _uv_areas(uv), _areas_3d(V, F)
    tot_uv, tot_3d = a_uv.sum(), a_3d.sum()
    if tot_uv <= 0 or tot_3d <= 0:
        return np.zeros(len(a_3d))
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (a_uv / tot_uv) / (a_3d / tot_3d)
    return np.where(a_3d > 0, s, 1.0)


def area_below(V: np.ndarray, F: np.ndarray, share: ArrayLike, threshold: float) -> float:
    """Share of the 3D surface area whose texel share is below ``threshold``."""
    a = _areas_3d(V, F)
    return float(a[np.asarray(share) < threshold].sum() / a.sum()) if a.sum() > 0 else 0.0


def texel_summary(V: np.ndarray, F: np.ndarray, corner_uv: ArrayLike) -> dict[str, float]:
    """The report's texel fields: least share and the area shares below 1/4 and 1/16 of fair."""
    s = texel_share(V, F, corner_uv)
    return dict(min_texel_share=float(s.min()) if len(s) else 1.0,
                area_below_quarter=area_below(V, F, s, 0.25),
                area_below_sixteenth=area_below(V, F, s, 1.0 / 16.0))
