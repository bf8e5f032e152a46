"""The result of a check: per-chart verdicts, the report, the overlap image."""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from uvbake.errors import InputError
from uvbake.io.atomic import atomic_write_bytes
from uvbake.validate import budgets
from uvbake.validate.raster import _accumulate, _fixed_point, _spans

OVERLAP_RGB = (220, 20, 20)


FLIPPED_RGB = (20, 60, 230)


BACKGROUND_RGB = (255, 255, 255)


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
        Faces with exactly zero signed UV area, or in a chart collapsed to (nearly) a point: its UV
        extent at most ``uvbake.validate.core.COLLAPSED`` of the layout's (a subset of ``flipped``;
        they take no part in overlap pairs).
    overlap_pairs : (p,2) int64
        Pairs ``i < j`` of faces whose open interiors intersect, sorted, unique.
    overlap_subpixel : (p,) bool
        True where the pair's overlap claims no common pixel centre at ``resolution_px``.
    overlap_area_fraction : float
        Overlap pixels / pixels claimed at least once (0 when nothing is covered, NaN when the raster
        was skipped).
    overlap_px, covered_px : int
        The two counts above. An overlap pixel is claimed by both faces of a confirmed pair.
        ``covered_px`` is None when ``validate(count_covered=False)`` found no pair and skipped the
        raster.
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
    covered_px: int | None
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
    _corners: np.ndarray | None = field(default=None, repr=False, compare=False)
    _overlap_pix: np.ndarray | None = field(default=None, repr=False, compare=False)

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
        deg = f", {n_deg} degenerate (zero UV area or in a collapsed chart)" if n_deg else ""
        rows, cols = self.grid_shape
        if not self.complete:
            head += " (check stopped early: " + "; ".join(self.notes) + ")"
        return (
            f"{head}: {len(self.charts)} charts, {self.n_faces} triangles, "
            f"{self.n_flipped - n_deg} flipped{deg}, {self.n_overlaps} overlapping pairs "
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
            "covered_px": None if self.covered_px is None else int(self.covered_px),
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
        spans = _spans(Xi, Yi, rows, cols, max_rows=budgets.MAX_SPAN_ROWS)
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

    def save_image(self, path: str | os.PathLike[str]) -> None:
        """Write :meth:`overlap_image` as a PNG, atomically (temp file in the same folder, then rename)."""
        import io

        from PIL import Image

        buf = io.BytesIO()
        Image.fromarray(self.overlap_image()).save(buf, format="PNG")  # (rows, cols, 3) uint8: RGB
        atomic_write_bytes(path, buf.getvalue())


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
