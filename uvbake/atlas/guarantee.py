"""The guarantee: every chart's map is flip-free, overlap-free and gives every triangle its texels.

    step_limit = determinant_step_limit(energy, uv_fixed)     # for the LM: no det A crosses zero
    charts, results, splits = solve_valid(charts, starts, ...)  # solve, check locally, split bad regions

Injective solve. The LM starts from the charting stage's conformal map, which has every det A > 0
(the charting stage cuts wherever it does not). Along a step delta the Jacobian of each triangle is
A(t) = A + t D (the map is linear in the UVs), so det A(t) = det A + t (A11 D22 + D11 A22 - A12 D21
- D12 A21) + t^2 det D: a quadratic in t. The step is shortened to STEP_SHRINK times the smallest
positive root over all triangles (vectorised), so no triangle flips or collapses during the solve
(Smith and Schaefer, "Bijective parameterization with free boundaries", SIGGRAPH 2015, use the same
bound with a line search).

What the bound cannot prevent is handled like a flip, once per bad region, never by re-solving whole
charts in a loop: a triangle whose area factor falls below 1/max_stretch of its chart's mean
(texel starvation), one sheared past max_stretch^2 (sigma1/sigma2: near alpha 1 the energy barely
weighs angles), and boundary overlaps (two parts of a chart's boundary that cross in the plane).
The chart is split once so that the bad region goes to one side (a short cut,
:func:`uvbake.mesh.cut.split_where`); each side starts from the parent's map restricted to it (still
flip-free; after a shear, from its own conformal map), and only the sides are solved again. The number of such splits is bounded by a work
count (``max_splits``), never by time.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike

from uvbake.mesh.arrays import unique_sorted

if TYPE_CHECKING:
    from uvbake.flatten.energy import DistortionEnergy
    from uvbake.flatten.solvers.result import ParamResult
    from uvbake.mesh.charts import Chart

#: Fraction of the largest determinant-keeping step that is taken.
STEP_SHRINK = 0.9


def determinant_step_limit(energy: DistortionEnergy, uv_fixed: np.ndarray) -> Callable[[np.ndarray, np.ndarray], float]:
    """``limit(x, delta) -> t`` in (0, 1]: the step fraction keeping every det A > 0 (see module notes)."""
    zero = np.zeros_like(np.asarray(uv_fixed, dtype=np.float64))

    def limit(x, delta):
        A11, A12, A21, A22 = energy._terms(energy.to_uv(x, uv_fixed))
        D11, D12, D21, D22 = energy._terms(energy.to_uv(delta, zero))
        c0 = A11 * A22 - A12 * A21
        c1 = A11 * D22 + D11 * A22 - A12 * D21 - D12 * A21
        c2 = D11 * D22 - D12 * D21
        t = smallest_positive_root(c0, c1, c2)
        tmin = float(t.min()) if len(t) else np.inf
        return 1.0 if tmin > 1.0 / STEP_SHRINK else STEP_SHRINK * tmin

    return limit


def smallest_positive_root(c0: ArrayLike, c1: ArrayLike, c2: ArrayLike) -> np.ndarray:
    """Per entry, the smallest t > 0 with c0 + c1 t + c2 t^2 = 0 (inf where there is none).

    Roots from the cancellation-free pair q / c2 and c0 / q, q = -(c1 + sign(c1) sqrt(disc)) / 2."""
    c0, c1, c2 = (np.asarray(c, dtype=np.float64) for c in (c0, c1, c2))
    disc = c1 * c1 - 4.0 * c0 * c2
    real = disc >= 0
    sq = np.sqrt(np.where(real, disc, 0.0))
    q = -0.5 * (c1 + np.where(c1 >= 0, sq, -sq))
    with np.errstate(divide="ignore", invalid="ignore"):
        r1 = np.where(c2 != 0, q / c2, np.inf)
        r2 = np.where(q != 0, c0 / q, np.inf)
    r1 = np.where(real & np.isfinite(r1) & (r1 > 0), r1, np.inf)
    r2 = np.where(real & np.isfinite(r2) & (r2 > 0), r2, np.inf)
    return np.minimum(r1, r2)


def area_factors(chart: Chart, uv: ArrayLike) -> np.ndarray:
    """(m,) each triangle's UV area over its 3D area, relative to the chart's mean (signed: <= 0 is
    flipped or collapsed)."""
    X = chart.V[chart.F]
    a3 = 0.5 * np.linalg.norm(np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0]), axis=1)
    U = np.asarray(uv)[chart.F]
    e1, e2 = U[:, 1] - U[:, 0], U[:, 2] - U[:, 0]
    a2 = 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    total = a2.sum()
    if total < 0:                                     # a chart mirrored as a whole keeps its orientation
        a2, total = -a2, -total
    if total <= 0:
        return np.zeros(len(a3))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(a3 > 0, (a2 / a3) / (total / a3.sum()), 1.0)


def shear_ratios(V: np.ndarray, F: np.ndarray, uv: ArrayLike) -> np.ndarray:
    """(m,) each triangle's angle distortion sigma1/sigma2 (the singular values of its Jacobian):
    1 for a similarity, inf where the map flips or collapses it; 1 for a triangle without 3D area.
    From ``|J|_F^2 / |det J| = r + 1/r`` with ``r = sigma1/sigma2``, no SVD."""
    X = np.asarray(V, dtype=np.float64)[F]
    U = np.asarray(uv, dtype=np.float64)[F]
    return _shears(X, U)


def _shears(X, U):
    """shear_ratios of the triangles with 3D corners X (m,3,3) and UV corners U (m,3,2)."""
    e1, e2 = X[:, 1] - X[:, 0], X[:, 2] - X[:, 0]
    n1 = np.linalg.norm(e1, axis=1)
    two_a = np.linalg.norm(np.cross(e1, e2), axis=1)               # twice the 3D area
    with np.errstate(divide="ignore", invalid="ignore"):
        # the triangle in its own plane: (0,0), (n1,0), (x2,y2); J maps it onto its UV corners
        x2 = np.einsum("ij,ij->i", e1, e2) / n1
        y2 = two_a / n1
        d1, d2 = U[:, 1] - U[:, 0], U[:, 2] - U[:, 0]
        c1 = d1 / n1[:, None]                                      # J's first column
        c2 = (d2 - x2[:, None] * c1) / y2[:, None]                 # its second
        det = c1[:, 0] * c2[:, 1] - c1[:, 1] * c2[:, 0]
        k = (np.einsum("ij,ij->i", c1, c1) + np.einsum("ij,ij->i", c2, c2)) / np.abs(det)
        r = 0.5 * (k + np.sqrt(np.maximum(k * k - 4.0, 0.0)))
    r = np.where(det > 0, r, np.inf)
    return np.where(two_a > 0, np.where(np.isnan(r), np.inf, r), 1.0)


def _end_to_end(charts, uvs):
    """Every chart's triangles laid end to end: (chart of each triangle, 3D corners, UV corners)."""
    k = len(charts)
    nv = np.array([len(c.V) for c in charts])                  # one per chart
    nf = np.array([len(c.F) for c in charts])
    cf = np.repeat(np.arange(k), nf)
    F = np.concatenate([c.F for c in charts]) + np.repeat(np.cumsum(nv) - nv, nf)[:, None]
    X = np.concatenate([c.V for c in charts])[F]
    U = np.concatenate([np.asarray(u, dtype=np.float64) for u in uvs])[F]
    return cf, X, U


def worst_shears(charts: list[Chart], uvs: list) -> np.ndarray:
    """(k,) each chart's largest :func:`shear_ratios`, computed on all charts at once."""
    k = len(charts)
    if k == 0:
        return np.zeros(0)
    cf, X, U = _end_to_end(charts, uvs)
    worst = np.full(k, 1.0)
    np.maximum.at(worst, cf, _shears(X, U))
    return worst


def least_factors(charts: list[Chart], uvs: list) -> np.ndarray:
    """(k,) each chart's least :func:`area_factors`, computed on all charts at once (laid end to end;
    each chart's totals summed per chart, so within about 1e-12 relative of area_factors'); -inf for a
    chart whose UV area is (nearly) zero, where area_factors is all zeros or decided by rounding."""
    k = len(charts)
    if k == 0:
        return np.zeros(0)
    cf, X, U = _end_to_end(charts, uvs)
    a3 = 0.5 * np.linalg.norm(np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0]), axis=1)
    e1, e2 = U[:, 1] - U[:, 0], U[:, 2] - U[:, 0]
    a2 = 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    t2, t3 = np.bincount(cf, weights=a2, minlength=k), np.bincount(cf, weights=a3, minlength=k)
    clear = np.abs(t2) > 1e-9 * np.bincount(cf, weights=np.abs(a2), minlength=k)
    sign = np.where(t2 < 0, -1.0, 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        f = np.where(a3 > 0, (sign[cf] * a2 / a3) / (np.abs(t2) / t3)[cf], 1.0)
    least = np.full(k, np.inf)
    np.minimum.at(least, cf, np.where(np.isnan(f), -np.inf, f))
    return np.where(clear, least, -np.inf)


#: Area factor at or below which a triangle counts as collapsed, a validity matter like a flip (rounding
#: can flip such a speck once its chart is placed in the atlas): split off even past the distortion
#: splits' cap.
COLLAPSED = 1e-6

#: Largest share of a chart's area allowed below 1/max_stretch of its texel density after the solve.
LOW_AREA_SHARE = 0.004


def starved_or_flipped(chart: Chart, uv: ArrayLike, max_stretch: float) -> np.ndarray:
    """Triangles that are flipped, collapsed, sheared or starved: below 1/max_stretch^2 of the chart's
    mean texel density, and also those below 1/max_stretch when they cover more than LOW_AREA_SHARE of
    the chart; sheared: sigma1/sigma2 above max_stretch^2 (:func:`shear_ratios`). Charting keeps the
    conformal start at 1/max_stretch or more (and sigma1/sigma2 at 1); the solve may move a few
    triangles by up to the budget again (default 4: the floor is 1/16, the least share the atlas
    promises, and at most 0.4% of the area below 1/4). Measured: the paper's unweighted conformal map
    at alpha 0 left 2% of camelhead's area below 1/4 where the area-weighted prediction left none."""
    f = area_factors(chart, uv)
    bad = (f < 1.0 / max_stretch ** 2) | (shear_ratios(chart.V, chart.F, uv) > max_stretch ** 2)
    low = f < 1.0 / max_stretch
    X = chart.V[chart.F]
    a3 = np.linalg.norm(np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0]), axis=1)
    if a3[low].sum() > LOW_AREA_SHARE * a3.sum():
        bad |= low
    return np.flatnonzero(bad)


def map_energy(A: np.ndarray, alpha: float) -> float:
    """The report's energy of a map from its per-triangle Jacobians A (m,2,2): the sum over triangles
    of alpha (det A - 1)^2 + (1 - alpha) ((A11 - A22)^2 + (A12 + A21)^2), unweighted (so the pieces
    of a chart add up to the chart)."""
    det = A[:, 0, 0] * A[:, 1, 1] - A[:, 0, 1] * A[:, 1, 0]
    return float(np.sum(alpha * (det - 1.0) ** 2 + (1.0 - alpha) * ((A[:, 0, 0] - A[:, 1, 1]) ** 2
                                                                   + (A[:, 0, 1] + A[:, 1, 0]) ** 2)))


def equalise_density(chart: Chart, result: ParamResult) -> ParamResult:
    """Scale the result's map uniformly so its UV area equals the chart's 3D area, in place (one texel
    density for all charts: a triangle's texel share in the packed atlas is then its area factor in
    its chart). The energy is re-evaluated at the scaled map (F is not scale-invariant); the scale is
    recorded in ``result.extra["density_scale"]``."""
    return equalise_densities([chart], [result])[0]


def equalise_densities(charts: list[Chart], results: list[ParamResult]) -> list[ParamResult]:
    """:func:`equalise_density` of every chart, in place: the per-triangle frames and Jacobians on all
    charts at once (laid end to end), each chart's sums on its own triangles as before."""
    from uvbake.flatten.energy import jacobians, triangle_frames

    if not charts:
        return []
    nv = np.array([len(c.V) for c in charts])                  # one per chart
    nf = np.array([len(c.F) for c in charts])
    voff, foff = np.cumsum(nv) - nv, np.cumsum(nf) - nf
    F = np.concatenate([c.F for c in charts]) + np.repeat(voff, nf)[:, None]
    _, Q, area = triangle_frames(np.concatenate([c.V for c in charts]), F)
    A = jacobians(Q, F, np.concatenate([np.asarray(r.uv, dtype=np.float64) for r in results]))
    det = A[:, 0, 0] * A[:, 1, 1] - A[:, 0, 1] * A[:, 1, 0]
    for result, f0, m in zip(results, foff, nf):               # one per chart: its sums
        a3 = area[f0:f0 + m]
        uv_area = abs(float(np.dot(a3, det[f0:f0 + m])))
        k = float(np.sqrt(a3.sum() / uv_area)) if uv_area > 0 and a3.sum() > 0 else 1.0
        result.uv = result.uv * k
        result.energy = map_energy(A[f0:f0 + m] * k, result.alpha)
        result.extra = dict(result.extra or {}) | {"density_scale": k}
    return results


#: Copies of one mesh vertex in a chart (the two sides of a cut) whose UVs agree to this share of the
#: chart's extent are given one UV (see snap_copies).
SNAP_SHARE = 1e-12


def snap_copies(chart: Chart, result: ParamResult) -> ParamResult:
    """Give the copies of a mesh vertex in ``chart`` (the two sides of a cut or slit) one UV, the
    lowest copy's, where their solved UVs agree to SNAP_SHARE of the chart's extent, in place. An
    isometric solve closes a cut through a flat region: its sides meet to rounding, and the packing's
    rotation can round them across each other, a sliver overlap the exact validation counts. Given one UV, the copies stay equal through every transform, and the
    validation welds them (same mesh vertex, same UV)."""
    vm = np.asarray(chart.vertex_map)
    order = np.argsort(vm, kind="stable")
    same = vm[order][1:] == vm[order][:-1]
    if not same.any():
        return result
    uv = np.array(result.uv, dtype=np.float64)
    # each copy and the first (lowest-index) copy of its mesh vertex
    group_start = np.concatenate([[True], ~same])
    first = order[np.maximum.accumulate(np.where(group_start, np.arange(len(order)), 0))]
    tol = SNAP_SHARE * float(np.ptp(uv, axis=0).max())
    near = np.abs(uv[order] - uv[first]).max(axis=1) <= tol
    move = order[near & ~group_start]
    if len(move):
        uv[move] = uv[first[near & ~group_start]]
        result.uv = uv
    return result


def split_bad(chart: Chart, uv: ArrayLike, bad: np.ndarray) -> tuple[list[Chart], list[np.ndarray], dict]:
    """Split ``chart`` once so ``bad`` triangles go to one side; each side with the parent's map.

    Returns (parts, starts, record)."""
    from uvbake.atlas.charting import sub_charts
    from uvbake.mesh.cut import seam_length, split_where

    sub = split_where(chart.V, chart.F, bad)
    parts = sub_charts(chart, sub)
    starts = []
    for p in parts:
        # the part's vertices are corner fans of the parent's: map each back through a corner
        loc = _local_vertices(chart, p)
        starts.append(np.asarray(uv)[loc])
    rec = dict(chart=chart.name, faces=int(len(chart.F)), bad=int(len(bad)), parts=len(parts),
               seam_length=seam_length(chart.V, chart.F, sub), reason="starved")
    return parts, starts, rec


def separating_split(chart: Chart, uv: ArrayLike, pairs: ArrayLike) -> tuple[list[Chart], list[np.ndarray], dict]:
    """Split ``chart`` once so that the two triangles of each overlapping pair (local (p,2) indices)
    go to different parts: the two sheets that overlap in the plane (the sides of a slit, two fans
    meeting at a vertex, a boundary that curls over itself) become two charts.

    Sheets: each pair's member nearer (along the dual graph) to the first pair's first triangle is
    on side A, the other on side B; a harmonic field, 0 on A and 1 on B, is cut at its sweep level
    of least conductance (as :func:`uvbake.mesh.cut.bisect`). Returns (parts, starts, record)."""
    from scipy.sparse.csgraph import dijkstra

    from uvbake.atlas.charting import sub_charts
    from uvbake.mesh.cut import (
        _dual_edges,
        _factor,
        _laplacian,
        _make_valid,
        _sweep,
        seam_costs,
        seam_length,
        split_where,
    )

    V, F = chart.V, chart.F
    m, n = len(F), len(V)
    fi, fj, ea, eb, hi, hj = _dual_edges(F, n)
    w = np.maximum(seam_costs(V, F, fi, fj, ea, eb), 1e-12)
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    G = sp.coo_matrix((w, (fi, fj)), shape=(m, m)).tocsr()
    d = dijkstra(G, directed=False, indices=int(pairs[0, 0]))
    near_first = d[pairs[:, 0]] <= d[pairs[:, 1]]
    A = np.where(near_first, pairs[:, 0], pairs[:, 1])
    B = np.where(near_first, pairs[:, 1], pairs[:, 0])
    A, B = np.setdiff1d(A, B), np.setdiff1d(B, A)
    sub = None
    if len(A) and len(B) and np.all(np.isfinite(d)):
        fixed = np.zeros(m, bool)
        fixed[A] = fixed[B] = True
        u = np.zeros(m)
        u[B] = 1.0
        free = np.flatnonzero(~fixed)
        if len(free):
            L = _laplacian(m, fi, fj, w / w.mean()).tocsr()
            u[free] = _factor(L[free][:, free].tocsc())(-(L[free][:, np.flatnonzero(fixed)] @ u[fixed]))
        X = V[F]
        mass = np.maximum(0.5 * np.linalg.norm(np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0]), axis=1), 1e-300)
        lab = _sweep(u + 1e-9 * d / max(d.max(), 1e-300), fi, fj, w, mass, 0.0)
        lab, ok = _make_valid(F, n, lab, fi, fj, hi, hj)
        if ok:
            sub = lab
    if sub is None:
        sub = split_where(V, F, unique_sorted(pairs))
    parts = sub_charts(chart, sub)
    starts = [np.asarray(uv)[_local_vertices(chart, p)] for p in parts]
    rec = dict(chart=chart.name, faces=int(len(F)), bad=int(len(unique_sorted(pairs))), parts=len(parts),
               seam_length=seam_length(V, F, sub), reason="overlap")
    return parts, starts, rec


def _local_vertices(parent, part):
    """Index in ``parent``'s vertices of each vertex of ``part`` (a sub-chart of the same faces)."""
    pos = np.searchsorted(parent.face_index, part.face_index) if np.all(np.diff(parent.face_index) > 0) else \
        _positions(parent.face_index, part.face_index)
    loc = np.empty(len(part.V), np.int64)
    loc[part.F.ravel()] = parent.F[pos].ravel()
    return loc


def _positions(haystack, needles):
    order = np.argsort(haystack, kind="stable")
    return order[np.searchsorted(haystack[order], needles)]


def overlapping_pairs(charts: list[Chart], uvs: list[np.ndarray]) -> list[np.ndarray]:
    """Overlapping triangle pairs inside each chart, as a list of local (p,2) arrays, from one exact
    check (the exact pass of :func:`uvbake.validate.validate`) of all the charts laid side by side on
    shelves, for the charts their boundary does not already prove overlap-free."""
    from uvbake.validate.boundary import proven_injective

    if not charts:
        return []
    # a chart whose triangles are all positive and whose boundary is simple has no overlap (degree
    # argument, uvbake/validate/boundary.py); only the others go through the exact all-triangle check
    proven = proven_injective(uvs, [c.F for c in charts])
    todo = [k for k in range(len(charts)) if not proven[k]]
    out = [np.zeros((0, 2), np.int64) for _ in charts]
    if todo:
        for k, pairs in zip(todo, _exact_overlaps([charts[k] for k in todo], [uvs[k] for k in todo])):
            out[k] = pairs
    return out


def _exact_overlaps(charts, uvs):
    """The exact check of :func:`overlapping_pairs` on the charts laid side by side on shelves."""
    from uvbake.validate.core import overlap_pairs

    # each chart at about unit size first, by a power of two (exact): a chart the solve shrank to a speck
    # laid beside charts of unit size would keep none of its shape's digits (overlap is scale-free)
    lo = [np.asarray(uv).min(axis=0) for uv in uvs]
    ext = [float((np.asarray(uv).max(axis=0) - low).max()) for uv, low in zip(uvs, lo)]
    unit = [np.ldexp(1.0, -int(np.clip(np.frexp(e)[1], -1000, 1000))) if e > 0 else 1.0 for e in ext]
    uvs = [(np.asarray(uv) - low) * u for uv, low, u in zip(uvs, lo, unit)]
    lo = [np.zeros(2) for _ in uvs]
    size = np.array([np.asarray(uv).max(axis=0) - low for uv, low in zip(uvs, lo)])
    gap = 0.05 * float(size.max()) + 1e-12
    width = max(float(np.sqrt((size + gap).prod(axis=1).sum())) * 1.5, float(size[:, 0].max()) + gap)
    offset, x, y, row_h = [], 0.0, 0.0, 0.0
    for w, h in size:                                   # one shelf position per chart
        if x > 0 and x + w > width:
            x, y, row_h = 0.0, y + row_h + gap, 0.0
        offset.append((x, y))
        x += w + gap
        row_h = max(row_h, h)
    corner = np.concatenate([(np.asarray(uv) - low + o)[c.F] for c, uv, low, o in zip(charts, uvs, lo, offset)])
    F = np.concatenate([c.F + k for c, k in zip(charts, np.cumsum([0] + [len(c.V) for c in charts[:-1]]))])
    ids = np.repeat(np.arange(len(charts)), [len(c.F) for c in charts])
    first = np.cumsum([0] + [len(c.F) for c in charts[:-1]])
    pairs = overlap_pairs(corner, F, chart_ids=ids, prove=False)      # their boundaries proved nothing
    owner = ids[pairs[:, 0]] if len(pairs) else np.zeros(0, np.int64)
    return [pairs[owner == i] - first[i] for i in range(len(charts))]


def _solve_flip_free(charts, starts, options, workers, progress, pinch_keys=None):
    """The paper's LM from each (valid) start; where that ends with flips, the injective LM from the
    same start instead. Measured (docs/decisions/atlas.md): the step bound alone stalls where the
    path to the minimum passes near a fold (fandisk's largest chart at alpha 0.5: stuck at F 18.37,
    while the plain LM reaches 4.68 with nothing flipped), so it is the fallback, not the rule."""
    from uvbake.flatten.solve import parameterize_charts

    # checked: charting verified every chart a disk with holes (disk_charts), and cuts, joins and
    # splits keep that by construction, so the solver's own topology check is not repeated
    def keys(some):                                   # each chart's pinch keys (uvbake.flatten.pinches)
        return None if pinch_keys is None else [pinch_keys[c.vertex_map] for c in some]

    results = parameterize_charts(charts, starts=starts, workers=workers, progress=progress, checked=True,
                                  pinch_keys=keys(charts), **options)
    again = [i for i, r in enumerate(results) if r.n_flipped > 0 and starts[i] is not None]
    if again:
        # from the plain run's last flip-free iterate when it has one (nearer the minimum than the
        # start: beetle's redo 17 -> N iterations), else from the start
        resume = [starts[i] if results[i].flip_free_uv is None else results[i].flip_free_uv for i in again]
        redo = parameterize_charts([charts[i] for i in again], starts=resume, workers=workers,
                                   injective=True, checked=True, pinch_keys=keys([charts[i] for i in again]), **options)
        for i, r in zip(again, redo):
            results[i] = r
    # a start flipped or collapsed itself (a part of a parent's map across its fold) leaves the LM no
    # valid path: such charts start again from their own conformal map when that has no flip (a single
    # triangle's always: a spiky sphere kept one-triangle charts flipped or collapsed to a point at alpha 0.1)
    fresh = _own_conformal_starts(charts, [i for i, r in enumerate(results) if _broken_map(charts[i], r)], pinch_keys)
    if fresh:
        redo = parameterize_charts([charts[i] for i in fresh], starts=list(fresh.values()), workers=workers,
                                   injective=True, checked=True, pinch_keys=keys([charts[i] for i in fresh]), **options)
        for i, r in zip(fresh, redo):
            if not _broken_map(charts[i], r):
                results[i] = r
    return results


def _broken_map(chart, result):
    """Whether a solved map has a non-finite coordinate, a flipped or a collapsed (zero-area) triangle."""
    from uvbake.mesh.arrays import signed_areas

    uv = np.asarray(result.uv)
    return bool(result.n_flipped > 0 or not np.all(np.isfinite(uv)) or np.any(signed_areas(uv, chart.F) <= 0))


def _own_conformal_starts(charts, indices, pinch_keys=None):
    """{i: chart i's own conformal map} for the charts in ``indices`` whose conformal map has no flipped
    or collapsed triangle (each pinch one vertex, with ``pinch_keys`` per mesh vertex)."""
    from uvbake.atlas.conformal import conformal_factor
    from uvbake.cancel import check_cancelled

    out = {}
    for i in indices:                                 # one iteration per chart left flipped
        check_cancelled()                             # Ctrl-C / SIGTERM: stop between charts
        uv, logf = conformal_factor(charts[i].V, charts[i].F,
                                    keys=None if pinch_keys is None else pinch_keys[charts[i].vertex_map])
        if np.all(np.isfinite(logf)):
            out[i] = uv
    return out


#: The least cap on the guarantee's splits when none is given (solve_valid's max_splits).
MIN_SPLITS = 256
#: Without a given cap, each kind may split this many times per chart entering the solve (at least
#: MIN_SPLITS): a noisy fandisk at --max-charts 1 needed 558 overlap splits and about 600 distortion ones
#: for 558 charts, past the one per chart allowed before.
SPLITS_PER_CHART = 4
#: ... and at least one per this many triangles: with a chart budget few, large charts enter the solve
#: (a noisy cow at --max-stretch 1.5 --max-charts 2, alpha 0: 39 charts, 5,804 triangles) and needed
#: 283 distortion splits, over the 256 four per chart allowed, which left triangles at 0.12 of their
#: share against the budget's 0.44 (docs/decisions/atlas.md, tenth session).
TRIANGLES_PER_SPLIT = 8


def solve_valid(charts: list[Chart], starts: list[np.ndarray], options: dict, *, max_stretch: float,
                workers: int | None = None, max_splits: int | None = None, max_rounds: int | None = None,
                note: Callable[[str, int, int], None] | None = None,
                pinch_keys: np.ndarray | None = None) -> tuple[list[Chart], list[ParamResult], list[dict]]:
    """Solve every chart with the injective LM from its start, then check each chart once: what
    starves (or flipped because the start was not valid) is split once per bad region, overlapping
    sheets are split apart, and only the parts are solved again, from the parent's map. Rounds and
    splits are bounded by counts, never by time: every round splits at least one chart, so the
    splits' caps bound the rounds too (``max_splits`` for each kind; None: SPLITS_PER_CHART per chart
    entering the solve or one per TRIANGLES_PER_SPLIT triangles, at least MIN_SPLITS; ``max_rounds``,
    None: no other bound; docs/decisions/atlas.md, eighth and tenth sessions). Only the charts that
    changed in a round are checked in the next.

    Returns (charts, results, splits). ``note(stage, done, total)`` is called per solved chart.
    ``pinch_keys``: per mesh vertex (:func:`uvbake.flatten.pinches.repair_copies`), or None: every
    solve and conformal map takes each pinch of a chart as one vertex."""
    note = note or (lambda stage, done, total: None)
    charts, starts = list(charts), list(starts)
    # four splits per chart, one per eight triangles, at least MIN_SPLITS: a fixed cap left rough scans
    # of many charts invalid
    if max_splits is None:
        triangles = sum(len(c.F) for c in charts)
        max_splits = max(MIN_SPLITS, SPLITS_PER_CHART * len(charts), triangles // TRIANGLES_PER_SPLIT)
    results = _solve_flip_free(charts, starts, options, workers, lambda d, n, r: note("solve", d, n), pinch_keys)
    splits: list[dict] = []
    todo = list(range(len(charts)))
    rounds = 0
    # each kind of split has its own cap: distortion (starved, sheared) never uses up validity (flips,
    # collapsed triangles, overlaps)
    spent = {"distortion": 0, "validity": 0}
    while max_rounds is None or rounds < max_rounds:   # rounds: each splits every bad chart once
        rounds += 1
        if not todo or min(spent.values()) >= max_splits:
            break
        new = _split_bad_charts(charts, results, todo, splits, max_stretch, max_splits, spent, pinch_keys)
        if not new:
            break
        flat = [p for _, parts, _ in new for p in parts]
        flat_starts = [s for _, _, st in new for s in st]
        solved = _solve_flip_free(flat, flat_starts, options, workers, lambda d, n, r: note("split", d, n), pinch_keys)
        charts, results, todo = _replace_split(charts, results, new, solved)
    return charts, results, splits


def _split_bad_charts(charts, results, todo, splits, max_stretch, max_splits, spent, pinch_keys=None):
    """Split each chart in ``todo`` that starves, shears, flipped or overlaps itself, once (records
    appended to ``splits``; ``spent`` counts each kind's splits against ``max_splits``: past the
    distortion cap only flipped or collapsed triangles are split off). Returns [(chart index, parts,
    their starts)]."""
    some = [charts[i] for i in todo], [results[i].uv for i in todo]
    overlaps = overlapping_pairs(*some)
    # a chart whose least area factor is clearly above 1/max_stretch and no triangle sheared past
    # max_stretch^2 neither starves, shears nor flipped
    sheared = worst_shears(*some) > max_stretch ** 2
    fine = (least_factors(*some) >= (1 + 1e-9) / max_stretch) & ~sheared
    new = []
    for i, pairs, sure, shear in zip(todo, overlaps, fine, sheared):
        c = charts[i]
        if len(c.F) < 2:
            continue
        bad = np.zeros(0, np.int64) if sure else starved_or_flipped(c, results[i].uv, max_stretch)
        kind = "distortion"
        if len(bad) and spent["distortion"] >= max_splits:
            bad, kind, shear = bad[area_factors(c, results[i].uv)[bad] <= COLLAPSED], "validity", False
        if len(bad) and spent[kind] < max_splits:
            parts, pstarts, rec = split_bad(c, results[i].uv, bad)
            if shear:       # the parent's map would keep its shear (alpha near 1 barely weighs angles):
                rec["reason"] = "sheared"                 # the parts start from their own conformal maps
                fresh = _own_conformal_starts(parts, range(len(parts)), pinch_keys)
                pstarts = [fresh.get(k, st) for k, st in enumerate(pstarts)]
        elif len(pairs) and spent["validity"] < max_splits:
            parts, pstarts, rec = separating_split(c, results[i].uv, pairs)
            kind = "validity"
        else:
            continue
        spent[kind] += 1
        splits.append(rec)
        new.append((i, parts, pstarts))
    return new


def _replace_split(charts, results, new, solved):
    """Charts and results with each split chart replaced by its solved parts in place, and the
    indices of those parts (the next round's charts to check)."""
    replace, it = {}, iter(solved)
    for i, parts, _ in new:
        replace[i] = [(p, next(it)) for p in parts]
    out_c, out_r, todo = [], [], []
    for i, (c, r) in enumerate(zip(charts, results)):
        for p, pr in replace.get(i, [(c, r)]):
            if i in replace:
                todo.append(len(out_c))
            out_c.append(p)
            out_r.append(pr)
    return out_c, out_r, todo
