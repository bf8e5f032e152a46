"""Bijectivity validation of UV layouts: flipped triangles and overlapping triangle pairs.

Two passes, both vectorised:

1. **Raster pass.** Every triangle is scan-converted into a coverage grid of pixel centres in
   integer fixed-point coordinates (8 sub-pixel bits) with a top-left fill rule, so that two
   triangles sharing an edge or a vertex never both claim a pixel centre. The fill rule is a
   symbolic perturbation of each sample point, hence a partition of the plane: a pixel claimed by two
   triangles is covered twice for real (up to the 1/256-pixel snapping): an overlap pixel once the
   exact pass confirms the pair, and a pair sharing none is a sub-pixel overlap.
2. **Exact pass.** Candidate pairs (from a spatial hash of bounding boxes, which catches overlaps
   smaller than a pixel too) are confirmed with orientation predicates: float
   determinants with Shewchuk's forward error bound, and exact dyadic-rational arithmetic (Python
   integers in numpy object arrays) for the rare determinants the bound cannot decide. Two triangles
   overlap when their open interiors intersect; by the separating-axis theorem for the Minkowski
   difference of two triangles this is false exactly when one of the six edge lines has the other
   triangle wholly on its outer side or on it. Pairs that only share an edge or a vertex, or touch
   along collinear edges, are therefore never reported. Most neighbour pairs never reach the
   predicates: faces sharing an edge with consistent orientation, or sharing a vertex whose fan
   winds once, are disjoint by topology alone (see ``_topology_filter``).

The verdict comes from the exact pass alone; the raster pass tells sub-pixel overlaps from others and
counts pixels. ``validate(count_covered=False)`` (the pipeline's own check) runs the raster only when the
exact pass confirms a pair: a valid layout skips it.

Massive overlaps (every face mapped onto the whole texture, as "reset" UVs do) would need quadratic
work; past fixed work budgets the check stops with ``complete=False`` and ``valid=False``, having
found every flip and a partial list of overlapping pairs.

Coordinates of the raster. A per-corner atlas ``(m,3,2)`` whose UVs lie in [0,1]^2 is rasterised on
[0,1]^2 at ``resolution_px`` x ``resolution_px``: one pixel is one texel of a texture of that size.
Anything else (per-vertex charts in arbitrary units, atlases with UVs outside [0,1]) is rasterised on
the bounding box of its UVs with square pixels of side ``max(extent) / resolution_px``. An overlap is
*sub-pixel* when no pixel centre is claimed by both triangles: a bake at that resolution writes no
texel twice for that pair (it can still bleed through bilinear filtering or mip-mapping).
"""

from __future__ import annotations

import os
import time

import numpy as np
from numpy.typing import ArrayLike

from uvbake.errors import InputError
from uvbake.mesh.arrays import unique_sorted
from uvbake.validate import budgets
from uvbake.validate.boundary import pair_faces
from uvbake.validate.candidates import (
    _bbox_pairs,
    _edge_components,
    _half_edges,
    _row_ids,
    _topology_filter,
    corner_boxes,
)
from uvbake.validate.predicates import _interiors_overlap, _orient
from uvbake.validate.raster import (
    _fixed_point,
    _raster_frame,
    _raster_pairs,
    _spans,
)
from uvbake.validate.report import ChartVerdict, ValidationReport

__all__ = ["validate", "ValidationReport", "ChartVerdict"]

_MAX_ABS_UV = 1e100
#: A chart whose UV extent is at most this share of the layout's is collapsed (no texel at 16384 px).
COLLAPSED = 1e-9
_RES_RANGE = (16, 16384)


# --------------------------------------------------------------------------------------------------
# report


# --------------------------------------------------------------------------------------------------
# public entry point


def validate(
    uv: ArrayLike,
    F: ArrayLike | None = None,
    *,
    chart_ids: ArrayLike | None = None,
    resolution_px: int = 2048,
    image_path: str | os.PathLike[str] | None = None,
    allow_subpixel: bool = False,
    count_covered: bool = True,
) -> ValidationReport:
    """Check that a UV layout is bijective: no flipped triangle, no two triangles overlapping.

    Parameters
    ----------
    uv : (n,2) float array with F, or (m,3,2) float array
        Per-vertex UVs of one or several charts sharing the index space of ``F``, or per-corner UVs
        of an atlas (the layout of Open3D's ``texture_uvs``).
    F : (m,3) int array, optional
        Faces. Required with per-vertex ``uv``. With per-corner ``uv`` it is optional and only used to
        decide connectivity: corners are welded when they have bit-identical UVs *and* the same vertex
        of ``F``; without ``F``, bit-identical UVs alone weld.
    chart_ids : (m,) int array, optional
        Chart of every face. When absent, charts are the connected components of the UV mesh through
        shared edges (two welded corners) traversed in opposite directions, so that charts touching
        at a point, or glued along an edge with one of them mirrored, stay apart.
    resolution_px : int, default 2048
        Side of the coverage grid in pixels, between 16 and 16384. For an atlas in [0,1]^2 this is the
        texture size at which "sub-pixel" is judged.
    image_path : str or path, optional
        When given, the overlap image (see :meth:`ValidationReport.overlap_image`) is written there.
    allow_subpixel : bool, default False
        When True, overlaps that claim no common pixel centre do not make the layout invalid (they
        are still reported).
    count_covered : bool, default True
        Count the pixels the layout covers even when no pair overlaps. The raster pass that counts them
        only otherwise tells sub-pixel overlaps from others; with False it runs only when the exact pass
        confirms an overlapping pair (or ``image_path`` is given), and a layout without one reports
        ``covered_px`` None. The verdict is the same either way.

    Returns
    -------
    ValidationReport

    Notes
    -----
    A chart's orientation is the sign of its total signed UV area, so a chart mirrored as a whole is
    not flipped; a face is flipped when its exact orientation is opposite to its chart's or zero.
    Overlaps are pairs of faces whose open interiors intersect (decided exactly); faces that share an
    edge or a vertex, or touch along an edge, never count. Zero-area faces are reported as flipped and
    take no part in overlap pairs.
    """
    t_start = time.perf_counter()
    timings = {}

    def lap(name, t0):
        t1 = time.perf_counter()
        timings[name] = t1 - t0
        return t1

    corners, vid, atlas = _prepare(uv, F)
    m = len(corners)
    res = _check_resolution(resolution_px)
    t = lap("prepare", t_start)

    # ---- charts and orientation -----------------------------------------------------------------
    twin, dup = _half_edges(vid)
    chart, n_charts, sign, n_exact, chart_area2, chart_sign, degenerate_mask = _orientation(corners, vid, twin,
                                                                                           chart_ids)
    flipped_mask = (sign != chart_sign[chart]) | degenerate_mask
    t = lap("orientation", t)

    # ---- exact pass -----------------------------------------------------------------------------
    notes: list[str] = []
    pairs, bbox_complete, n_cand, n_exact_pairs = _exact_pairs(
        corners, vid, sign, twin, dup, pair_faces(corners, vid, chart, n_charts, twin, dup, sign, ~degenerate_mask))
    n_exact += n_exact_pairs
    if not bbox_complete:
        notes.append(f"listing stopped after {len(pairs)} overlapping pairs (the layout is invalid; "
                     "the list is partial)")
    t = lap("candidates", t)

    # ---- raster pass (the pixels of confirmed pairs, the covered count) -------------------------
    origin, pixel_size, rows, cols = _raster_frame(corners, atlas, res)
    covered_px: int | None
    if count_covered or len(pairs) or image_path is not None:
        Xi, Yi = _fixed_point(corners, origin, pixel_size)
        spans, pix_keys, pix_of_key, covered_px, raster_complete = _raster_pass(Xi, Yi, rows, cols, m, notes)
        t = lap("raster", t)
    else:       # no pair to classify: no pixel of a confirmed pair, whatever the raster would show
        z = np.zeros(0, np.int64)
        spans, pix_keys, pix_of_key, covered_px, raster_complete = (), z, z, None, True
    raster_keys = unique_sorted(pix_keys)
    keys = pairs[:, 0] * m + pairs[:, 1]
    at = np.minimum(np.searchsorted(raster_keys, keys), max(len(raster_keys) - 1, 0))
    subpixel = raster_keys[at] != keys if len(raster_keys) else np.ones(len(keys), bool)
    if not raster_complete:
        subpixel[:] = False  # unknown: not shown to be harmless
    # overlap pixels: claimed by a confirmed pair (snapping to 1/256 px can make triangles that only
    # touch both claim a pixel; the exact pass rejects those pairs, and their pixels do not count)
    if len(keys):
        at = np.minimum(np.searchsorted(keys, pix_keys), len(keys) - 1)
        overlap_pix = unique_sorted(pix_of_key[keys[at] == pix_keys])
    else:
        overlap_pix = np.zeros(0, np.int64)
    overlap_px = len(overlap_pix)
    t = lap("exact", t)

    # ---- verdicts -------------------------------------------------------------------------------
    flipped = np.flatnonzero(flipped_mask).astype(np.int64)
    degenerate = np.flatnonzero(degenerate_mask).astype(np.int64)
    counted = pairs[~subpixel] if allow_subpixel else pairs
    overlapping = np.zeros(m, bool)
    overlapping[counted.ravel()] = True
    n_faces_c = np.bincount(chart, minlength=n_charts)
    n_flip_c = np.bincount(chart[flipped_mask], minlength=n_charts)
    n_deg_c = np.bincount(chart[degenerate_mask], minlength=n_charts)
    n_over_c = np.bincount(chart[overlapping], minlength=n_charts)
    charts = [
        ChartVerdict(
            chart=i,
            n_faces=int(n_faces_c[i]),
            n_flipped=int(n_flip_c[i]),
            n_degenerate=int(n_deg_c[i]),
            n_overlapping=int(n_over_c[i]),
            orientation=int(chart_sign[i]),
            area=float(abs(chart_area2[i]) / 2.0),
            valid=bool(n_flip_c[i] == 0 and n_over_c[i] == 0),
        )
        for i in range(n_charts)
    ]
    complete = bool(bbox_complete and raster_complete)
    report = ValidationReport(
        # exact whatever the budgets: flips are all found and candidate pairs are all decided; a
        # budget only shortens the list of confirmed pairs (then the layout is invalid for certain)
        valid=bool(len(flipped) == 0 and len(counted) == 0 and bbox_complete),
        complete=complete,
        notes=notes,
        n_faces=int(m),
        flipped=flipped,
        degenerate=degenerate,
        overlap_pairs=pairs,
        overlap_subpixel=subpixel,
        overlap_area_fraction=(
            float(overlap_px / covered_px) if covered_px else (0.0 if spans is not None else float("nan"))
        ),
        overlap_px=int(overlap_px),
        covered_px=None if covered_px is None else int(covered_px),
        charts=charts,
        chart_ids=chart,
        resolution_px=res,
        grid_shape=(rows, cols),
        origin=(float(origin[0]), float(origin[1])),
        pixel_size=float(pixel_size),
        n_candidates=int(n_cand),
        n_exact=int(n_exact),
        allow_subpixel=bool(allow_subpixel),
        time_s=0.0,
        timings_s=timings,
        _corners=corners,
        _overlap_pix=overlap_pix,
    )
    lap("verdicts", t)
    report.time_s = time.perf_counter() - t_start
    if image_path is not None:
        report.save_image(image_path)
    return report


def overlap_pairs(uv: ArrayLike, F: ArrayLike | None, *, chart_ids: ArrayLike | None = None,
                  prove: bool = True) -> np.ndarray:
    """The overlapping pairs :func:`validate` reports, (p,2) int64 sorted, without its raster pass.

    The raster pass only tells sub-pixel overlaps from others and draws the overlap image; the pairs
    themselves come from the exact pass alone, so this is the same list at about two thirds of the
    cost (for callers that split charts at their overlaps, before packing). ``prove=False`` skips the
    charts' boundary proofs (:func:`~uvbake.validate.boundary.pair_faces`): for charts that failed them."""
    corners, vid, _ = _prepare(uv, F)
    twin, dup = _half_edges(vid)
    chart, n_charts, sign, _, _, _, degenerate_mask = _orientation(corners, vid, twin, chart_ids)
    live = pair_faces(corners, vid, chart, n_charts, twin, dup, sign, ~degenerate_mask) if prove else ~degenerate_mask
    return _exact_pairs(corners, vid, sign, twin, dup, live)[0]


def _orientation(corners, vid, twin, chart_ids):
    """Charts, exact orientation per face and per chart, and degenerate faces (zero area, or in a
    chart collapsed to a point: no texel at any resolution, and no part in overlap pairs, which
    would be a quadratic, meaningless enumeration)."""
    m = len(corners)
    chart = _edge_components(vid, twin) if chart_ids is None else _prepare_chart_ids(chart_ids, m)
    n_charts = int(chart.max()) + 1
    A, B, C = corners[:, 0], corners[:, 1], corners[:, 2]
    sign, n_exact = _orient(A[:, 0], A[:, 1], B[:, 0], B[:, 1], C[:, 0], C[:, 1])
    area2 = (B[:, 0] - A[:, 0]) * (C[:, 1] - A[:, 1]) - (B[:, 1] - A[:, 1]) * (C[:, 0] - A[:, 0])
    chart_area2 = np.bincount(chart, weights=area2, minlength=n_charts)
    chart_sign = np.where(chart_area2 >= 0, 1, -1).astype(np.int8)
    by_chart = np.argsort(chart, kind="stable")
    starts = np.searchsorted(chart[by_chart], np.arange(n_charts))
    bmin, bmax = corner_boxes(corners)
    cmin = np.minimum.reduceat(bmin[by_chart], starts)
    cmax = np.maximum.reduceat(bmax[by_chart], starts)
    span = float((cmax.max(axis=0) - cmin.min(axis=0)).max())
    collapsed = (cmax - cmin).max(axis=1) <= COLLAPSED * span
    degenerate_mask = (sign == 0) | collapsed[chart]
    return chart, n_charts, sign, n_exact, chart_area2, chart_sign, degenerate_mask


def _exact_pairs(corners, vid, sign, twin, dup, live):
    """Overlapping pairs (p,2) sorted by (i, j), whether the list is complete, candidates, exact tests."""
    m = len(corners)
    ccw = corners.copy()
    neg = sign < 0
    ccw[neg, 1], ccw[neg, 2] = corners[neg, 2], corners[neg, 1]
    n_exact_pairs = [0]

    def confirm(i, j):          # the exact test, applied chunk by chunk as candidates are found
        over, k = _interiors_overlap(ccw[i], ccw[j])
        n_exact_pairs[0] += k
        return over

    pairs, complete, n_cand = _bbox_pairs(
        corners, live, _topology_filter(corners, vid, sign, twin, dup), confirm=confirm,
        max_pairs=budgets.MAX_OVERLAP_PAIRS)
    pairs = pairs.astype(np.int64).reshape(-1, 2)
    pairs = pairs[np.argsort(pairs[:, 0] * m + pairs[:, 1])]
    return pairs, complete, n_cand, n_exact_pairs[0]


# --------------------------------------------------------------------------------------------------
# input


def _raster_pass(Xi, Yi, rows, cols, m, notes):
    """Spans (None past the budget), pixel-sharing pair keys and their pixels, covered pixels, completeness."""
    spans = _spans(Xi, Yi, rows, cols, max_rows=budgets.MAX_SPAN_ROWS)
    if spans is None:
        notes.append(f"raster skipped: the triangles span more than {budgets.MAX_SPAN_ROWS} pixel rows")
        return None, np.zeros(0, np.int64), np.zeros(0, np.int64), 0, False
    tri, row, x0, x1 = spans
    pix_keys, pix_of_key, covered_px, raster_complete = _raster_pairs(tri, row, x0, x1, rows, cols, m)
    if not raster_complete:
        notes.append("raster pairs truncated: too many pixels claimed more than once")
    return spans, pix_keys, pix_of_key, covered_px, raster_complete


def _prepare(uv, F):
    """Per-corner UVs (m,3,2) float64, welded corner ids (m,3) int64, and whether it is an atlas."""
    uv = np.asarray(uv)
    if uv.dtype.kind not in "fiu":
        raise InputError(f"uv has dtype {uv.dtype}; pass a float array of shape (n,2) or (m,3,2)")
    uv = uv.astype(np.float64)
    if uv.ndim == 2 and uv.shape[1] == 2:
        if F is None:
            raise InputError(
                "per-vertex uv of shape (n,2) needs faces; pass F (m,3), or per-corner uv (m,3,2)"
            )
        Fa = _check_faces(F, len(uv))
        corners = uv[Fa]
        vid = Fa
        atlas = False
    elif uv.ndim == 3 and uv.shape[1:] == (3, 2):
        corners = np.ascontiguousarray(uv)
        bits = (corners.reshape(-1, 2) + 0.0).view(np.int64)  # +0.0 folds -0.0 into 0.0
        if F is not None:
            Fa = _check_faces(F, None)
            if len(Fa) != len(corners):
                raise InputError(
                    f"F has {len(Fa)} faces but uv has {len(corners)}; pass one row of F per uv triangle"
                )
            keys = np.column_stack([Fa.reshape(-1), bits])
        else:
            keys = bits
        vid = _row_ids(keys).reshape(-1, 3)
        atlas = True
    else:
        raise InputError(
            f"uv has shape {uv.shape}; pass per-vertex uv (n,2) with F (m,3), or per-corner uv (m,3,2)"
        )
    if len(corners) == 0:
        raise InputError("there are no triangles to validate; pass at least one face")
    if not np.all(np.isfinite(corners)):
        raise InputError("uv has NaN or infinite coordinates on some faces; fix or drop those faces")
    if np.abs(corners).max() > _MAX_ABS_UV:
        raise InputError(f"uv has coordinates beyond {_MAX_ABS_UV:g}; rescale the UVs")
    return corners, vid, atlas


def _check_faces(F, n):
    Fa = np.asarray(F)
    if Fa.dtype.kind not in "iu" or Fa.ndim != 2 or Fa.shape[1] != 3:
        raise InputError(f"F must be an integer array of shape (m,3); got {Fa.dtype} {Fa.shape}")
    Fa = Fa.astype(np.int64)
    if len(Fa) and (Fa.min() < 0 or (n is not None and Fa.max() >= n)):
        raise InputError(f"F indexes vertices outside 0..{n - 1}; fix the face indices")
    return Fa


def _check_resolution(resolution_px):
    lo, hi = _RES_RANGE
    if isinstance(resolution_px, bool) or not isinstance(resolution_px, (int, np.integer)):
        raise InputError(f"resolution_px must be an integer in {lo}..{hi}; got {resolution_px!r}")
    if not lo <= int(resolution_px) <= hi:
        raise InputError(f"resolution_px must be in {lo}..{hi}; got {resolution_px}")
    return int(resolution_px)


def _prepare_chart_ids(chart_ids, m):
    c = np.asarray(chart_ids)
    if c.dtype.kind not in "iu" or c.shape != (m,):
        raise InputError(f"chart_ids must be an integer array of shape ({m},); got {c.dtype} {c.shape}")
    return np.unique(c, return_inverse=True)[1].astype(np.int64).reshape(m)


# --------------------------------------------------------------------------------------------------
# exact orientation


# --------------------------------------------------------------------------------------------------
# raster pass


# --------------------------------------------------------------------------------------------------
# candidate pairs from bounding boxes


# --------------------------------------------------------------------------------------------------
# helpers


