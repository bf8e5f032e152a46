"""Bijectivity validation of UV layouts: flipped triangles and overlapping triangle pairs.

Two passes, both vectorised:

1. **Raster pass.** Every triangle is scan-converted into a coverage grid of pixel centres in
   integer fixed-point coordinates (8 sub-pixel bits) with a top-left fill rule, so that two
   triangles sharing an edge or a vertex never both claim a pixel centre. The fill rule is a
   symbolic perturbation of each sample point, hence a partition of the plane: a pixel claimed by two
   triangles is covered twice for real (up to the 1/256-pixel snapping), and it is an overlap candidate.
2. **Exact pass.** Candidate pairs (from the raster and from a spatial hash of bounding boxes, which
   catches overlaps smaller than a pixel) are confirmed with orientation predicates: float
   determinants with Shewchuk's forward error bound, and exact dyadic-rational arithmetic (Python
   integers in numpy object arrays) for the rare determinants the bound cannot decide. Two triangles
   overlap when their open interiors intersect; by the separating-axis theorem for the Minkowski
   difference of two triangles this is false exactly when one of the six edge lines has the other
   triangle wholly on its outer side or on it. Pairs that only share an edge or a vertex, or touch
   along collinear edges, are therefore never reported. Most neighbour pairs never reach the
   predicates: faces sharing an edge with consistent orientation, or sharing a vertex whose fan
   winds once, are disjoint by topology alone (see ``_topology_filter``).

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

import time
from dataclasses import dataclass, field

import numpy as np

from uvbake.errors import InputError

__all__ = ["validate", "ValidationReport", "ChartVerdict"]

_SUBPIXEL_BITS = 8
_S = 1 << _SUBPIXEL_BITS  # fixed-point units per pixel
_HALF = _S // 2  # pixel centre offset in fixed point
_CHUNK = 1 << 20  # elements per vectorised chunk (bounds temporary memory)
_BAND_PX = 1 << 22  # pixels per band of the coverage grid accumulation
_EPS = 2.0**-53
_CCW_ERR = (3.0 + 16.0 * _EPS) * _EPS  # Shewchuk's ccwerrboundA
_TINY = 1e-280  # below this the products may have underflowed: decide exactly
_MAX_ABS_UV = 1e100
_RES_RANGE = (16, 16384)
# work budgets: past them the layout is overlapping massively (e.g. every face mapped onto the whole
# texture) and the check stops, reporting what it found and `complete=False` (never `valid=True`)
_MAX_SPAN_ROWS = 1 << 25  # triangle rows scanned by the raster
_RAW_PAIRS_PER_FACE = 48  # pairs sharing a hash cell or a pixel, per pass: a valid atlas needs ~15
_MIN_RAW_PAIRS = 1 << 22
_MAX_CLAIMS = 1 << 22  # (pixel, triangle) claims expanded on multiply-claimed rows

OVERLAP_RGB = (220, 20, 20)
FLIPPED_RGB = (20, 60, 230)
BACKGROUND_RGB = (255, 255, 255)


# --------------------------------------------------------------------------------------------------
# report


@dataclass
class ChartVerdict:
    """Verdict on one chart.

    Attributes
    ----------
    chart : int
        Chart number (index into ``ValidationReport.charts``).
    n_faces, n_flipped, n_degenerate, n_overlapping : int
        Faces in the chart; of them, flipped (opposite orientation or zero area), degenerate (zero
        area), and in at least one overlapping pair that counts against validity (within or across
        charts; sub-pixel pairs are left out when ``allow_subpixel=True``).
    orientation : int
        +1 when the chart's total signed UV area is >= 0 (counter-clockwise), -1 when mirrored.
    area : float
        Absolute total signed UV area of the chart, in UV units squared.
    valid : bool
        No flipped face and no overlapping face.
    """

    chart: int
    n_faces: int
    n_flipped: int
    n_degenerate: int
    n_overlapping: int
    orientation: int
    area: float
    valid: bool

    def to_dict(self) -> dict:
        return {
            "chart": int(self.chart),
            "n_faces": int(self.n_faces),
            "n_flipped": int(self.n_flipped),
            "n_degenerate": int(self.n_degenerate),
            "n_overlapping": int(self.n_overlapping),
            "orientation": int(self.orientation),
            "area": float(self.area),
            "valid": bool(self.valid),
        }


@dataclass
class ValidationReport:
    """Result of :func:`validate`.

    Attributes
    ----------
    valid : bool
        True when no face is flipped and no pair of faces overlaps (sub-pixel overlaps count unless
        ``allow_subpixel=True`` was passed), and the check is complete.
    complete : bool
        False when a work budget stopped the check (massive overlaps, such as every face mapped onto
        the whole texture): flips are still all found, overlap lists are partial.
    notes : list of str
        Why the check is incomplete, if it is.
    n_faces : int
    flipped : (k,) int64
        Faces whose orientation is opposite to their chart's or zero (degenerate ones included).
    degenerate : (d,) int64
        Faces with exactly zero signed UV area (a subset of ``flipped``).
    overlap_pairs : (p,2) int64
        Pairs ``i < j`` of faces whose open interiors intersect, sorted, unique.
    overlap_subpixel : (p,) bool
        True where the pair's overlap claims no common pixel centre at ``resolution_px``.
    overlap_area_fraction : float
        Overlap pixels / pixels claimed at least once (0 when nothing is covered, NaN when the raster
        was skipped).
    overlap_px, covered_px : int
        The two counts above. An overlap pixel is claimed by both faces of a confirmed pair.
    charts : list of ChartVerdict
    chart_ids : (m,) int64
        Chart number of every face.
    resolution_px : int
    grid_shape : (int, int)
        ``(rows, cols)`` of the coverage grid (rows along v).
    origin : (float, float)
        UV coordinates of the grid's lower-left corner.
    pixel_size : float
        Side of one pixel in UV units.
    n_candidates : int
        Candidate pairs tested exactly.
    n_exact : int
        Orientation determinants the float filter could not decide (computed exactly).
    time_s : float
    timings_s : dict
        Seconds per stage.
    """

    valid: bool
    complete: bool
    notes: list
    n_faces: int
    flipped: np.ndarray
    degenerate: np.ndarray
    overlap_pairs: np.ndarray
    overlap_subpixel: np.ndarray
    overlap_area_fraction: float
    overlap_px: int
    covered_px: int
    charts: list
    chart_ids: np.ndarray
    resolution_px: int
    grid_shape: tuple
    origin: tuple
    pixel_size: float
    n_candidates: int
    n_exact: int
    allow_subpixel: bool
    time_s: float
    timings_s: dict
    _corners: np.ndarray = field(default=None, repr=False, compare=False)
    _overlap_pix: np.ndarray = field(default=None, repr=False, compare=False)

    @property
    def n_flipped(self) -> int:
        return int(len(self.flipped))

    @property
    def n_overlaps(self) -> int:
        return int(len(self.overlap_pairs))

    @property
    def n_subpixel(self) -> int:
        return int(np.count_nonzero(self.overlap_subpixel))

    def summary(self) -> str:
        """One line: the verdict and its counts."""
        head = "valid" if self.valid else "INVALID"
        n_deg = len(self.degenerate)
        deg = f" ({n_deg} degenerate)" if n_deg else ""
        rows, cols = self.grid_shape
        if not self.complete:
            head += " (check stopped early: " + "; ".join(self.notes) + ")"
        return (
            f"{head}: {len(self.charts)} charts, {self.n_faces} triangles, "
            f"{self.n_flipped} flipped{deg}, {self.n_overlaps} overlapping pairs "
            f"({self.n_subpixel} sub-pixel at {cols}x{rows} px), "
            f"{100.0 * self.overlap_area_fraction:.4g}% of covered pixels overlap"
        )

    def to_dict(self) -> dict:
        """JSON-serialisable form (plain lists, ints, floats, bools)."""
        frac = float(self.overlap_area_fraction)
        return {
            "valid": bool(self.valid),
            "complete": bool(self.complete),
            "notes": [str(n) for n in self.notes],
            "summary": self.summary(),
            "n_faces": int(self.n_faces),
            "n_charts": len(self.charts),
            "n_flipped": self.n_flipped,
            "flipped": self.flipped.tolist(),
            "degenerate": self.degenerate.tolist(),
            "n_overlaps": self.n_overlaps,
            "n_subpixel": self.n_subpixel,
            "overlap_pairs": self.overlap_pairs.tolist(),
            "overlap_subpixel": self.overlap_subpixel.tolist(),
            "overlap_area_fraction": frac if np.isfinite(frac) else None,
            "overlap_px": int(self.overlap_px),
            "covered_px": int(self.covered_px),
            "charts": [c.to_dict() for c in self.charts],
            "resolution_px": int(self.resolution_px),
            "grid_shape": [int(s) for s in self.grid_shape],
            "origin": [float(o) for o in self.origin],
            "pixel_size": float(self.pixel_size),
            "n_candidates": int(self.n_candidates),
            "n_exact": int(self.n_exact),
            "allow_subpixel": bool(self.allow_subpixel),
            "time_s": float(self.time_s),
            "timings_s": {k: float(v) for k, v in self.timings_s.items()},
        }

    def overlap_image(self) -> np.ndarray:
        """The overlap picture, v pointing up (row 0 is the top of the UV square, as in a texture).

        Charts are painted in light colours, overlap pixels in red ``OVERLAP_RGB`` and flipped
        triangles in blue ``FLIPPED_RGB`` (on top); sub-pixel overlaps and flipped triangles that
        claim no pixel get a 3x3 dot of their colour so they stay visible (sub-pixel overlaps of a flipped
        triangle are left to its blue).

        Returns
        -------
        (rows, cols, 3) uint8 array
        """
        if self._corners is None:
            raise InputError("this report holds no UVs to draw; produce it with uvbake.validate()")
        rows, cols = self.grid_shape
        Xi, Yi = _fixed_point(self._corners, self.origin, self.pixel_size)
        spans = _spans(Xi, Yi, rows, cols, max_rows=_MAX_SPAN_ROWS)
        if spans is None:
            raise InputError(
                "too many triangle rows to draw at this resolution; validate at a lower resolution_px"
            )
        tri, row, x0, x1 = spans
        count = _accumulate(row, x0, x1, rows, cols)
        chart_sum = _accumulate(row, x0, x1, rows, cols, weight=self.chart_ids[tri] + 1.0)
        is_flipped = np.zeros(self.n_faces, bool)
        is_flipped[self.flipped] = True
        flip_cnt = _accumulate(row, x0, x1, rows, cols, weight=is_flipped[tri].astype(np.float64))

        palette = _pastel(len(self.charts))
        img = np.empty((rows, cols, 3), np.uint8)
        img[:] = BACKGROUND_RGB
        hit = count >= 1
        chart_of_px = np.rint(chart_sum[hit] / count[hit]).astype(np.int64) - 1
        img[hit] = palette[np.clip(chart_of_px, 0, len(palette) - 1)]
        img.reshape(-1, 3)[self._overlap_pix] = OVERLAP_RGB
        img[flip_cnt > 0] = FLIPPED_RGB  # on top: a flipped face usually lies over its neighbour

        def dots(points, rgb):
            if len(points) == 0:
                return
            c = np.floor((points[:, 0] - self.origin[0]) / self.pixel_size).astype(np.int64)
            r = np.floor((points[:, 1] - self.origin[1]) / self.pixel_size).astype(np.int64)
            for dr in (-1, 0, 1):
                for dc in (-1, 0, 1):
                    rr = np.clip(r + dr, 0, rows - 1)
                    cc = np.clip(c + dc, 0, cols - 1)
                    img[rr, cc] = rgb

        drawn = np.zeros(self.n_faces, bool)
        drawn[tri] = True
        unseen = self.flipped[~drawn[self.flipped]]  # zero-area or smaller than a pixel
        dots(self._corners[unseen].mean(axis=1), FLIPPED_RGB)
        sub = self.overlap_pairs[self.overlap_subpixel & ~np.any(is_flipped[self.overlap_pairs], axis=1)]
        if len(sub):
            a, b = self._corners[sub[:, 0]], self._corners[sub[:, 1]]
            lo = np.maximum(a.min(axis=1), b.min(axis=1))
            hi = np.minimum(a.max(axis=1), b.max(axis=1))
            dots(0.5 * (lo + hi), OVERLAP_RGB)
        return img[::-1].copy()

    def save_image(self, path) -> None:
        """Write :meth:`overlap_image` as a PNG, atomically (temp file in the same folder, then rename)."""
        import io

        from PIL import Image

        buf = io.BytesIO()
        Image.fromarray(self.overlap_image()).save(buf, format="PNG")  # (rows, cols, 3) uint8: RGB
        atomic_write_bytes(path, buf.getvalue())


# --------------------------------------------------------------------------------------------------
# public entry point


def validate(
    uv,
    F=None,
    *,
    chart_ids=None,
    resolution_px=2048,
    image_path=None,
    allow_subpixel=False,
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
    if chart_ids is None:
        chart = _edge_components(vid, twin)
    else:
        chart = _prepare_chart_ids(chart_ids, m)
    n_charts = int(chart.max()) + 1
    A, B, C = corners[:, 0], corners[:, 1], corners[:, 2]
    sign, n_exact = _orient(A[:, 0], A[:, 1], B[:, 0], B[:, 1], C[:, 0], C[:, 1])
    area2 = (B[:, 0] - A[:, 0]) * (C[:, 1] - A[:, 1]) - (B[:, 1] - A[:, 1]) * (C[:, 0] - A[:, 0])
    chart_area2 = np.bincount(chart, weights=area2, minlength=n_charts)
    chart_sign = np.where(chart_area2 >= 0, 1, -1).astype(np.int8)
    flipped_mask = sign != chart_sign[chart]
    degenerate_mask = sign == 0
    t = lap("orientation", t)

    # ---- raster pass ----------------------------------------------------------------------------
    origin, pixel_size, rows, cols = _raster_frame(corners, atlas, res)
    Xi, Yi = _fixed_point(corners, origin, pixel_size)
    notes = []
    spans = _spans(Xi, Yi, rows, cols, max_rows=_MAX_SPAN_ROWS)
    if spans is None:
        pix_keys = pix_of_key = np.zeros(0, np.int64)
        covered_px, raster_complete = 0, False
        notes.append(f"raster skipped: the triangles span more than {_MAX_SPAN_ROWS} pixel rows")
    else:
        pix_keys, pix_of_key, covered_px, raster_complete = _raster_pairs(*spans, rows, cols, m)
        if not raster_complete:
            notes.append("raster pairs truncated: too many pixels claimed more than once")
    raster_keys = _sorted_unique(pix_keys)
    t = lap("raster", t)

    # ---- exact pass -----------------------------------------------------------------------------
    live = ~degenerate_mask
    cand, bbox_complete = _bbox_pairs(corners, live, _topology_filter(corners, vid, sign, twin, dup))
    if not bbox_complete:
        notes.append(f"candidate pairs truncated after {_raw_budget(m)} overlapping bounding boxes")
    if len(raster_keys):
        ra, rb = raster_keys // m, raster_keys % m
        rk = raster_keys[live[ra] & live[rb]]
        cand_keys = _sorted_unique(np.concatenate([cand[:, 0] * m + cand[:, 1], rk]))
        cand = np.stack([cand_keys // m, cand_keys % m], axis=1)
    t = lap("candidates", t)
    ccw = corners.copy()
    neg = sign < 0
    ccw[neg, 1], ccw[neg, 2] = corners[neg, 2], corners[neg, 1]
    hits = []
    for s in range(0, len(cand), _CHUNK // 4):
        c = cand[s : s + _CHUNK // 4]
        over, k = _interiors_overlap(ccw[c[:, 0]], ccw[c[:, 1]])
        n_exact += k
        hits.append(c[over])
    pairs = np.concatenate(hits) if hits else np.zeros((0, 2), np.int64)
    pairs = pairs.astype(np.int64).reshape(-1, 2)
    keys = pairs[:, 0] * m + pairs[:, 1]
    order = np.argsort(keys)
    pairs, keys = pairs[order], keys[order]
    at = np.minimum(np.searchsorted(raster_keys, keys), max(len(raster_keys) - 1, 0))
    subpixel = raster_keys[at] != keys if len(raster_keys) else np.ones(len(keys), bool)
    if not raster_complete:
        subpixel[:] = False  # unknown: not shown to be harmless
    # overlap pixels: claimed by a confirmed pair (snapping to 1/256 px can make triangles that only
    # touch both claim a pixel; the exact pass rejects those pairs, and their pixels do not count)
    if len(keys):
        at = np.minimum(np.searchsorted(keys, pix_keys), len(keys) - 1)
        overlap_pix = _sorted_unique(pix_of_key[keys[at] == pix_keys])
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
    if not complete:
        notes.append("overlaps are massive; the lists of pairs are partial and the layout is not valid")
    report = ValidationReport(
        valid=bool(complete and len(flipped) == 0 and len(counted) == 0),
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
        covered_px=int(covered_px),
        charts=charts,
        chart_ids=chart,
        resolution_px=res,
        grid_shape=(rows, cols),
        origin=(float(origin[0]), float(origin[1])),
        pixel_size=float(pixel_size),
        n_candidates=int(len(cand)),
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


# --------------------------------------------------------------------------------------------------
# input


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


def _row_ids(keys):
    """Ids 0..k-1 of the distinct rows of an (N,c) int64 array (equal rows get equal ids)."""
    order = np.lexsort(keys.T[::-1])
    sk = keys[order]
    new = np.ones(len(sk), bool)
    new[1:] = np.any(sk[1:] != sk[:-1], axis=1)
    ids = np.empty(len(sk), np.int64)
    ids[order] = np.cumsum(new) - 1
    return ids


def _half_edges(vid):
    """Twin matching of the half-edges of the welded mesh (half-edge ``3 f + k`` goes from corner k
    of face f to corner k + 1).

    Returns
    -------
    twin : (3m,) int64
        Index of a half-edge going the opposite way along the same edge, or -1.
    dup : (3m,) bool
        The same directed edge occurs more than once (a fold or a non-manifold edge).
    """
    nv = int(vid.max()) + 1
    src, dst = vid.reshape(-1), vid[:, [1, 2, 0]].reshape(-1)
    key = (np.minimum(src, dst) * nv + np.maximum(src, dst)) * 2 + (src > dst)
    order = np.argsort(key)
    k = key[order]
    same_dir = k[1:] == k[:-1]
    dup = np.zeros(len(k), bool)
    dup[order[1:][same_dir]] = True
    dup[order[:-1][same_dir]] = True
    pair = ((k[1:] >> 1) == (k[:-1] >> 1)) & ~same_dir  # consecutive in sort: p->q then q->p
    pair &= src[order[1:]] != dst[order[1:]]
    twin = np.full(len(k), -1, np.int64)
    twin[order[:-1][pair]] = order[1:][pair]
    twin[order[1:][pair]] = order[:-1][pair]
    return twin, dup


def _edge_components(vid, twin):
    """Chart of every face: connected components of faces joined through twin half-edges.

    Two faces are joined when one has the welded edge p->q and the other q->p, as in an oriented
    mesh. Faces meeting at a point only, or along an edge traversed the same way by both (two charts
    glued by welding, one mirrored), stay apart; a fold keeps its twin edges and stays one chart.

    Parameters
    ----------
    vid : (m,3) int64 welded corner ids
    twin : (3m,) int64 from :func:`_half_edges`

    Returns
    -------
    chart : (m,) int64, charts numbered 0..k-1
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    m = len(vid)
    h = np.flatnonzero(twin >= 0)
    u, v = h // 3, twin[h] // 3
    g = coo_matrix((np.ones(len(u), np.int8), (u, v)), shape=(m, m))
    _, labels = connected_components(g, directed=False)
    return np.unique(labels, return_inverse=True)[1].astype(np.int64).reshape(m)


# --------------------------------------------------------------------------------------------------
# exact orientation


def _orient(ax, ay, bx, by, cx, cy):
    """Exact sign of cross(b - a, c - a) for arrays of points.

    Parameters
    ----------
    ax, ay, bx, by, cx, cy : (k,) float64 arrays

    Returns
    -------
    sign : (k,) int8 array in {-1, 0, 1}
    n_exact : int
        How many signs the float filter could not decide and were computed in exact arithmetic.
    """
    left = (bx - ax) * (cy - ay)
    right = (by - ay) * (cx - ax)
    det = left - right
    sign = np.sign(det).astype(np.int8)
    idx = np.flatnonzero(np.abs(det) <= _error_bound(left, right))
    a = np.stack([ax[idx], ay[idx]], axis=1)
    b = np.stack([bx[idx], by[idx]], axis=1)
    c = np.stack([cx[idx], cy[idx]], axis=1)
    sign[idx], n = _orient_undecided(a, b, c)
    return sign, n


def _error_bound(left, right):
    """Shewchuk's forward error bound on left - right (ccwerrboundA), floored at _TINY so that
    results near underflow are decided exactly."""
    err = np.abs(left)
    err += np.abs(right)
    err *= _CCW_ERR
    return np.maximum(err, _TINY, out=err)


def _orient_undecided(a, b, c):
    """Exact signs of cross(b - a, c - a) for the few determinants the float filter left undecided.

    Parameters
    ----------
    a, b, c : (k,2) float64 arrays

    Returns
    -------
    sign : (k,) int8
    n_exact : int
        Determinants that needed exact arithmetic (zeros recognisable from the floats do not).
    """
    sign = np.zeros(len(a), np.int8)
    if len(a) == 0:
        return sign, 0
    bax, bay = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
    cax, cay = c[:, 0] - a[:, 0], c[:, 1] - a[:, 1]
    # exactly zero: a zero difference (x - y == 0 iff x == y) in each product, or c == b
    zero = ((bax == 0) | (cay == 0)) & ((bay == 0) | (cax == 0))
    zero |= np.all(b == c, axis=1)
    hard = np.flatnonzero(~zero)
    if len(hard):
        sign[hard] = _orient_exact(a[hard], b[hard], c[hard])
    return sign, int(len(hard))


def _orient_exact(a, b, c):
    """Sign of cross(b - a, c - a) in exact dyadic-rational arithmetic (Python ints, no Python loop).

    Every coordinate is m * 2**e with an integer m, |m| < 2**53; scaling the six coordinates of a
    determinant by 2**-min(e) makes them integers, whose determinant numpy evaluates exactly in an
    object array.
    """
    pts = np.concatenate([a, b, c], axis=1)  # (k,6)
    mant, expo = np.frexp(pts)
    mi = np.ldexp(mant, 53).astype(np.int64)  # exact
    big = np.iinfo(np.int64).max
    e = np.where(mi == 0, big, expo.astype(np.int64) - 53)
    emin = e.min(axis=1, keepdims=True)
    emin = np.where(emin == big, 0, emin)
    shift = np.where(mi == 0, 0, e - emin)
    X = mi.astype(object) << shift.astype(object)
    ax, ay, bx, by, cx, cy = (X[:, i] for i in range(6))
    det = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
    return (det > 0).astype(np.int8) - (det < 0).astype(np.int8)


def _interiors_overlap(P, Q):
    """Whether the open interiors of counter-clockwise triangles P and Q intersect, exactly.

    They are disjoint exactly when one of the six edge lines has the other triangle wholly on its
    outer side or on it (the edges of the Minkowski difference P - Q are edges of P and of Q).

    Parameters
    ----------
    P, Q : (k,3,2) float64 arrays, each triangle counter-clockwise and of non-zero area

    Returns
    -------
    overlap : (k,) bool
    n_exact : int
    """
    overlap = np.ones(len(P), bool)
    n_exact = 0
    for T, U in ((P, Q), (Q, P)):
        live = np.flatnonzero(overlap)
        sep, n = _separated_by_edges(T[live], U[live])
        overlap[live[sep]] = False
        n_exact += n
    return overlap, n_exact


def _separated_by_edges(T, U):
    """(k,) bool: some edge line of counter-clockwise T has all three points of U on or right of it.

    Parameters
    ----------
    T, U : (k,3,2) float64 arrays
    """
    k = len(T)
    nxt = np.array([1, 2, 0])
    e = T[:, nxt] - T  # (k,3,2) edge vectors
    d = U[:, None, :, :] - T[:, :, None, :]  # (k,3 edges,3 points,2)
    left = e[:, :, None, 0] * d[..., 1]
    right = e[:, :, None, 1] * d[..., 0]
    det = left - right
    sign = np.sign(det).astype(np.int8)
    unsure = np.flatnonzero(np.abs(det) <= _error_bound(left, right))
    n = 0
    if len(unsure):
        kk, ee, pp = np.unravel_index(unsure, (k, 3, 3))
        s, n = _orient_undecided(T[kk, ee], T[kk, nxt[ee]], U[kk, pp])
        sign.reshape(-1)[unsure] = s
    return np.any(np.all(sign <= 0, axis=2), axis=1), n


# --------------------------------------------------------------------------------------------------
# raster pass


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
        stop = int(np.searchsorted(csum, base + _CHUNK, side="right"))
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
    return tuple(np.concatenate(o) for o in out)


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
        if claims + lens.sum() > _MAX_CLAIMS:
            keep = np.cumsum(lens) <= _MAX_CLAIMS - claims
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


def _group_pairs(group, item, m, group_filter=None, unique=True, budget=None, with_groups=False):
    """Keys ``i * m + j`` (i < j) of the pairs of items that share a group, chunked to bound memory.

    Parameters
    ----------
    group, item : (n,) int64 arrays (group >= 0, 0 <= item < m)
    m : int
    group_filter : callable, optional
        ``group_filter(i, j, g) -> (k,) bool``: which of the pairs (i, j) found in group g to keep.
    unique : bool
        Sort and de-duplicate the keys (a pair may share several groups).
    budget : int, optional
        Stop after about this many raw pairs (before filtering).
    with_groups : bool
        Also return the group of every key (then keys are neither sorted nor de-duplicated).

    Returns
    -------
    keys : (p,) int64
    groups : (p,) int64, only ``with_groups``
    complete : bool
        False when the budget stopped the enumeration.
    """
    if len(group) < 2:
        z = np.zeros(0, np.int64)
        return (z, z, True) if with_groups else (z, True)
    if int(group.max()) < (1 << 62) // max(m, 1):
        order = np.argsort(group * m + item)
    else:
        order = np.lexsort((item, group))
    g, it = group[order], item[order]
    n = len(g)
    new = np.ones(n, bool)
    new[1:] = g[1:] != g[:-1]
    starts = np.flatnonzero(new)
    ends = np.append(starts[1:], n)
    pos = np.arange(n)
    cnt = ends[np.cumsum(new) - 1] - pos - 1  # partners after each element in its group
    csum = np.cumsum(cnt)
    keys = [np.zeros(0, np.int64)]
    groups = [np.zeros(0, np.int64)]
    complete = budget is None or csum[-1] <= budget
    limit = csum[-1] if complete else max(int(budget), 0)
    s = 0
    while s < n:
        base = csum[s - 1] if s else 0
        if base >= limit and not complete:
            break
        e = max(int(np.searchsorted(csum, min(base + _CHUNK, limit), side="right")), s + 1)
        c = cnt[s:e]
        a = np.repeat(pos[s:e], c)
        first = np.cumsum(c) - c
        b = a + 1 + (np.arange(len(a)) - np.repeat(first, c))
        i, j = it[a], it[b]  # i <= j: items are sorted within a group
        ok = i != j
        if group_filter is not None:
            ok &= group_filter(i, j, g[a])
        k = i[ok] * m + j[ok]
        if with_groups:
            groups.append(g[a][ok])
        keys.append(_sorted_unique(k) if unique and not with_groups else k)
        s = e
    out = np.concatenate(keys)
    if with_groups:
        return out, np.concatenate(groups), bool(complete)
    return (_sorted_unique(out) if unique else np.sort(out)), bool(complete)


def _raw_budget(m):
    """Raw pairs a pass may enumerate for m faces."""
    return max(_MIN_RAW_PAIRS, _RAW_PAIRS_PER_FACE * m)


def _sorted_unique(a):
    """Sorted distinct values of a 1-D array (sort-based; faster here than np.unique's hashing)."""
    a = np.sort(a)
    if len(a) < 2:
        return a
    keep = np.empty(len(a), bool)
    keep[0] = True
    np.not_equal(a[1:], a[:-1], out=keep[1:])
    return a[keep]


# --------------------------------------------------------------------------------------------------
# candidate pairs from bounding boxes


def _bbox_pairs(corners, live, disjoint=None):
    """Pairs (i<j) of live faces whose bounding boxes overlap with positive area.

    A uniform grid hashes every box into the cells it touches; a pair is kept only in the cell that
    holds the lower-left corner of the boxes' intersection, so no pair is produced twice.

    Parameters
    ----------
    corners : (m,3,2) float64
    live : (m,) bool
        Faces that take part.
    disjoint : callable, optional
        ``disjoint(i, j) -> (k,) bool``: pairs known to be disjoint, dropped.

    Returns
    -------
    pairs : (p,2) int64
    complete : bool
        False when the work budget stopped the enumeration.
    """
    m = len(corners)
    faces = np.flatnonzero(live)
    if len(faces) < 2:
        return np.zeros((0, 2), np.int64), True
    bmin = corners.min(axis=1)
    bmax = corners.max(axis=1)
    ext = (bmax - bmin)[faces].max(axis=1)
    lo = bmin[faces].min(axis=0)
    span = float((bmax[faces].max(axis=0) - lo).max())
    if span == 0.0:
        return np.zeros((0, 2), np.int64), True
    cell = max(float(np.median(ext)), span / 65536.0)
    while True:
        c0 = np.floor((bmin[faces] - lo) / cell).astype(np.int64)
        c1 = np.floor((bmax[faces] - lo) / cell).astype(np.int64)
        ny_cells = c1[:, 1] - c0[:, 1] + 1
        ncell = (c1[:, 0] - c0[:, 0] + 1) * ny_cells
        if ncell.sum() <= 16 * len(faces) + 1024:
            break
        cell *= 2.0
    ny = int(c1[:, 1].max()) + 1
    f = np.repeat(faces, ncell)
    k = np.arange(len(f)) - np.repeat(np.cumsum(ncell) - ncell, ncell)
    nyc = np.repeat(ny_cells, ncell)
    key = (np.repeat(c0[:, 0], ncell) + k // nyc) * ny + np.repeat(c0[:, 1], ncell) + k % nyc
    cx = np.zeros(m, np.int64)
    cy = np.zeros(m, np.int64)
    cx[faces], cy[faces] = c0[:, 0], c0[:, 1]
    x0, y0 = np.ascontiguousarray(bmin.T)
    x1, y1 = np.ascontiguousarray(bmax.T)

    def keep(i, j, g):
        # home cell = cell of the intersection's lower-left corner (floor is monotone)
        ok = np.maximum(cx[i], cx[j]) * ny + np.maximum(cy[i], cy[j]) == g
        idx = np.flatnonzero(ok)
        a, b = i[idx], j[idx]
        strict = (np.maximum(x0[a], x0[b]) < np.minimum(x1[a], x1[b])) & (
            np.maximum(y0[a], y0[b]) < np.minimum(y1[a], y1[b])
        )
        if disjoint is not None:
            s_idx = np.flatnonzero(strict)
            strict[s_idx[disjoint(a[s_idx], b[s_idx])]] = False
        ok[idx] = strict
        return ok

    keys, complete = _group_pairs(key, f, m, group_filter=keep, unique=False, budget=_raw_budget(m))
    return np.stack([keys // m, keys % m], axis=1), complete


def _topology_filter(corners, vid, sign, twin, dup):
    """A test of pairs of faces whose disjointness follows from the mesh around what they share.

    - Two faces sharing a welded edge traversed in opposite directions, with the same non-zero
      orientation, have their third vertices strictly on opposite sides of it.
    - A *safe* vertex has all its faces of the same non-zero orientation, forming one fan (no
      directed edge twice; 0 unmatched incident half-edges, a cycle, or 2, a chain) whose corner
      angles sum to less than 3 pi for a cycle (so winding once, exactly 2 pi) or less than
      2 pi - 1e-6 for a chain. The faces' wedges at that vertex are then disjoint, and each face lies
      inside its wedge, so two faces sharing a safe vertex cannot overlap.

    Parameters
    ----------
    corners : (m,3,2) float64
    vid : (m,3) int64
    sign : (m,) int8 exact orientations
    twin, dup : from :func:`_half_edges`

    Returns
    -------
    disjoint : callable ``(i, j) -> (k,) bool``
    """
    nv = int(vid.max()) + 1
    v = vid.reshape(-1)
    fsign = np.repeat(sign, 3)
    n_inc = np.bincount(v, minlength=nv)
    same = (np.bincount(v[fsign > 0], minlength=nv) == n_inc) | (
        np.bincount(v[fsign < 0], minlength=nv) == n_inc
    )
    src, dst = v, vid[:, [1, 2, 0]].reshape(-1)
    unmatched = twin < 0
    n_unmatched = np.bincount(src[unmatched], minlength=nv) + np.bincount(dst[unmatched], minlength=nv)
    bad = np.zeros(nv, bool)
    bad[src[dup]] = True
    bad[dst[dup]] = True
    u = corners[:, [1, 2, 0]] - corners  # to the next corner
    w = corners[:, [2, 0, 1]] - corners  # to the previous corner
    cross = u[..., 0] * w[..., 1] - u[..., 1] * w[..., 0]
    dot = u[..., 0] * w[..., 0] + u[..., 1] * w[..., 1]
    angle_sum = np.bincount(v, weights=np.arctan2(np.abs(cross), dot).reshape(-1), minlength=nv)
    safe = same & ~bad & (
        ((n_unmatched == 0) & (angle_sum < 3.0 * np.pi))
        | ((n_unmatched == 2) & (angle_sum < 2.0 * np.pi - 1e-6))
    )
    nxt = [1, 2, 0]

    def disjoint(i, j):
        va, vb = vid[i], vid[j]
        consistent = (sign[i] == sign[j]) & (sign[i] != 0)
        out = np.zeros(len(i), bool)
        for k in range(3):
            safe_k = safe[va[:, k]]
            for l in range(3):
                # shared corner a_k == b_l: safe vertex, or edge a_k -> a_k+1 == b_l -> b_l-1
                twin_edge = consistent & (va[:, nxt[k]] == vb[:, (l + 2) % 3])
                out |= (va[:, k] == vb[:, l]) & (safe_k | twin_edge)
        return out

    return disjoint


# --------------------------------------------------------------------------------------------------
# helpers


def _pastel(n):
    """(n,3) uint8 light colours, well spread in hue (golden-ratio steps)."""
    h = (np.arange(n) * 0.6180339887498949) % 1.0
    s, v = 0.28, 0.97
    i = np.floor(h * 6).astype(int) % 6
    f = h * 6 - np.floor(h * 6)
    p, q, t = v * (1 - s), v * (1 - s * f), v * (1 - s * (1 - f))
    table = np.stack(
        [
            np.choose(i, [v, q, p, p, t, v]),
            np.choose(i, [t, v, v, q, p, p]),
            np.choose(i, [p, p, t, v, v, q]),
        ],
        axis=1,
    )
    return np.rint(255 * table).astype(np.uint8)


def atomic_write_bytes(path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (see :func:`uvbake.io.atomic_write`)."""
    from uvbake.io import atomic_write

    with atomic_write(path, "wb") as fh:
        fh.write(data)

