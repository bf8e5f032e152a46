"""2D pictures of an atlas: the charts in colour with their seams, and a legend strip under any image.

    img = uvbake.pictures.atlas_image(result)                    # (H,W,3) uint8, also uvbake.render.atlas_image
    img = uvbake.pictures.with_legend(img, ["8 charts", "packing 81 %"])

The chart fill is the validator's own picture (:meth:`uvbake.validate.report.ValidationReport.overlap_image`:
every chart in its colour, overlapping pixels red, flipped triangles blue), so the atlas image shows what
was checked. Seams (every chart-boundary edge in UV: the cuts and the mesh's own boundary) are drawn as
1-pixel dark lines. Text is Pillow's bundled default font (FreeType), so the same Pillow gives the same
bytes on every machine.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from uvbake.errors import InputError

SEAM_RGB = (40, 40, 40)
LEGEND_BG = (255, 255, 255)
LEGEND_FG = (20, 20, 20)
FONT_PX = 13
LINE_PX = 17


def atlas_image(source: Any, F: ArrayLike | None = None, chart_ids: ArrayLike | None = None, *, size_px: int = 512,
                legend: bool = True, report: dict[str, Any] | None = None) -> np.ndarray:
    """The atlas coloured by chart, seams drawn, with a legend (chart count, packing, worst distortion).

    Parameters
    ----------
    source : UnwrapResult or (m,3,2) float array
        An :class:`uvbake.atlas.pipeline.UnwrapResult`, or per-corner atlas UVs in [0,1]^2 (v up).
    F : (m,3) int array
        Needed with arrays.
    chart_ids : (m,) int array, optional
        Chart of each face (arrays only; default: one chart).
    size_px : int
        Side of the atlas square in pixels (16 to 4096); the legend adds rows below it.
    legend : bool
        Add the legend strip.
    report : dict, optional
        An unwrap report (arrays only) for the legend's packing and distortion.

    Returns
    -------
    (size_px + legend rows, size_px, 3) uint8 array, row 0 at the top (v = 1).
    """
    from uvbake.validate.core import validate

    if hasattr(source, "corner_uv"):
        corner_uv, F, chart_ids, report = source.corner_uv, source.F, source.chart_ids, source.report
    else:
        corner_uv = source
    if F is None:
        raise InputError("atlas_image needs F with corner UVs (or an UnwrapResult)")
    corner_uv = np.asarray(corner_uv, np.float64)
    F = np.asarray(F)
    if corner_uv.ndim != 3 or corner_uv.shape[1:] != (3, 2) or len(corner_uv) != len(F):
        raise InputError(f"corner_uv must be ({len(F)},3,2), got shape {corner_uv.shape}")
    if isinstance(size_px, bool) or not isinstance(size_px, (int, np.integer)) or not 16 <= size_px <= 4096:
        raise InputError(f"size_px={size_px!r} must be a whole number of pixels from 16 to 4096")
    if chart_ids is None:
        chart_ids = np.zeros(len(F), np.int64)
    verdict = validate(corner_uv, F, chart_ids=chart_ids, resolution_px=int(size_px))
    img = verdict.overlap_image()
    _draw_seams(img, corner_uv)
    if not legend:
        return img
    return with_legend(img, legend_lines(verdict.to_dict(), report))


def legend_lines(verdict: dict[str, Any], report: dict[str, Any] | None = None) -> list[str]:
    """The legend's lines from a validation report dict (and an unwrap report, when there is one)."""
    n_charts = verdict.get("n_charts")
    state = "valid" if verdict.get("valid") else (f"NOT valid: {verdict.get('n_flipped', 0)} flipped (blue), "
                                                  f"{verdict.get('n_overlaps', 0)} overlapping pairs (red)")
    lines = [f"{n_charts} chart{'s' if n_charts != 1 else ''}, {verdict.get('n_faces')} triangles: {state}"]
    if report:
        atlas, final = report.get("atlas", {}), report.get("distortion", {}).get("final", {})
        parts = []
        if atlas.get("efficiency") is not None:
            parts.append(f"packing {100 * atlas['efficiency']:.1f} %")
        if atlas.get("texture_size_px"):
            from uvbake.atlas.pipeline import atlas_size, size_text

            parts.append(f"{size_text(atlas_size(report))} px, gutter {atlas.get('gutter_px')} px")
        if parts:
            lines.append(", ".join(parts))
        if final.get("angle_distortion_max") is not None:
            lines.append(f"worst angle distortion {final['angle_distortion_max']:.3f} (s1/s2), "
                         f"mean area distortion {final.get('area_distortion_mean', float('nan')):.3f} (|ln s1 s2|)")
    return lines


def with_legend(img: np.ndarray, lines: list[str]) -> np.ndarray:
    """``img`` with the text ``lines`` in a white strip below it (same width)."""
    from PIL import Image, ImageDraw, ImageFont

    img = np.asarray(img, np.uint8)
    if img.ndim != 3 or img.shape[2] != 3:
        raise InputError(f"with_legend takes an (H,W,3) uint8 image, got shape {img.shape}")
    width = img.shape[1]
    font = ImageFont.load_default(size=FONT_PX)
    wrapped = []
    for line in lines:
        wrapped.extend(_wrap(line, font, width - 8))
    strip = Image.new("RGB", (width, LINE_PX * len(wrapped) + 6), LEGEND_BG)
    draw = ImageDraw.Draw(strip)
    for i, line in enumerate(wrapped):
        draw.text((4, 3 + LINE_PX * i), line, fill=LEGEND_FG, font=font)
    return np.vstack([img, np.asarray(strip)])


def _wrap(line, font, width):
    """Greedy word wrap to ``width`` pixels."""
    out, cur = [], ""
    for word in line.split(" "):
        trial = f"{cur} {word}".strip()
        if cur and font.getlength(trial) > width:
            out.append(cur)
            cur = word
        else:
            cur = trial
    return out + [cur]


def seam_edges(corner_uv: np.ndarray) -> np.ndarray:
    """(k,2,2) UV segments of chart boundaries: face edges whose UV endpoints no other face shares.

    An interior edge of a chart is used by two faces with the same two UVs; a seam edge has different
    UVs on its two sides (or one side only, on the mesh's boundary).
    """
    seg = np.stack([corner_uv, np.roll(corner_uv, -1, axis=1)], axis=2).reshape(-1, 2, 2)
    q = np.round(seg * 2.0 ** 24).astype(np.int64)                      # exact for UVs written twice
    a, b = q[:, 0], q[:, 1]
    swap = (a[:, 0] > b[:, 0]) | ((a[:, 0] == b[:, 0]) & (a[:, 1] > b[:, 1]))
    key = np.where(swap[:, None], np.hstack([b, a]), np.hstack([a, b]))
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return seg[counts[inverse.reshape(-1)] == 1]


def _draw_seams(img, corner_uv):
    """Draw the seam segments into ``img`` (row 0 = v 1) as 1-pixel lines, vectorised."""
    rows, cols = img.shape[:2]
    seg = seam_edges(corner_uv)
    if len(seg) == 0:
        return
    p0 = seg[:, 0] * (cols, rows)
    p1 = seg[:, 1] * (cols, rows)
    n = np.maximum(2, np.ceil(np.abs(p1 - p0).max(axis=1) * 2).astype(np.int64) + 1)   # 2 samples per pixel
    idx = np.repeat(np.arange(len(seg)), n)
    t = (np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)) / np.repeat(n - 1, n)
    pts = p0[idx] + t[:, None] * (p1 - p0)[idx]
    c = np.clip(np.floor(pts[:, 0]).astype(np.int64), 0, cols - 1)
    r = np.clip(rows - 1 - np.floor(pts[:, 1]).astype(np.int64), 0, rows - 1)
    img[r, c] = SEAM_RGB
