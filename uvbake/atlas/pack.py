"""Pack flattened charts into one texture atlas in [0,1]^2, with a gutter in texels.

Every chart keeps its shape and its true scale: one texel density (texels per world unit) is shared by
all charts; each chart is only rotated (never mirrored) and translated. The density is the largest at
which the packer fits all charts (a bisection), or the one the caller fixes (``texel_density``, the same
across assets; the atlas then grows, or the call says the charts cannot fit). The gutter is fixed in
texels while the charts scale; ``mip_levels`` derives it (``uvbake.atlas.shapepack.mip_gutter_px``).

Method ``"shape"`` (uvbake.atlas.shapepack) packs the charts' conservative texel footprints with quarter
turns of their minimum-area-rectangle angle (and 45 degrees from it for the six biggest charts), by
bottom-left fill on run-length tables, on square, non-square (``texture_size_px=(width, height)``) or
growing atlases (``texture_size_px=None``; ``aspect="free"`` grows the rectangle of fewest texels).

Method ``"maxrects"``: each chart is rotated to its minimum-area bounding rectangle (rotating calipers
on the convex hull, vectorised over hull edges), the rectangle is grown by the gutter (half a gutter on
every side), and the padded rectangles are packed into the unit square by MaxRects (Jylänki 2010) with
90-degree turns allowed, trying several placement rules and orders; the best scale wins. Boxes that do
not overlap keep any two charts at least ``gutter_px`` texels apart and every chart half a gutter from
the atlas border, by construction.

Method ``"auto"`` (the default) is "shape"; for a square atlas of at most 64 charts at a free scale it
also runs "maxrects" and keeps the denser packing (near-rectangular charts, like sample_scenes/scene.ply,
pack denser as boxes), or runs one alone when the charts fill their minimum-area boxes to >= 0.8 (boxes)
or < 0.7 (shapes).

Other placers plug in as ``method=placer`` (bench/packers.py wraps the peers xatlas and rectpack).

What was measured for these choices: docs/decisions/pack.md (``python bench/pack.py``).

Efficiency (``PackResult.efficiency``) is defined as::

    efficiency = sum over charts, over triangles, of |triangle area in texels|  /  (width * height)
               = texel_density**2 * (sum of |triangle areas| in world units**2) / (width * height)

i.e. the fraction of the atlas's texels covered by chart triangles (overlapping triangles inside a
chart would be counted twice; validated charts have none).
"""

from __future__ import annotations

import numbers
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from uvbake.atlas.maxrects import _RULES, _own_packers, _pack_boxes, chart_hulls, min_area_rects, rotation_2d
from uvbake.errors import InputError
from uvbake.mesh.arrays import signed_areas

#: what a placer returns: common scale, per-chart rotation and offset, placed UVs, measured gap (px) or None
Placement = tuple[float, np.ndarray, np.ndarray, list[np.ndarray], "float | None"]
METHODS = ("auto", "shape", "maxrects")
DEFAULT_METHOD = "shape"

_EPS_PAD = 1e-9          # extra padding in atlas units, so rounding never eats into the gutter


@dataclass
class PackResult:
    """Charts placed in the atlas.

    Attributes
    ----------
    uv : list of (k_i,2) float arrays     per-vertex atlas UVs of each chart, in [0,1]^2
    scale : float                         atlas u units per world unit, texel_density / width_px (every chart)
    texel_size_world : float              world length of one texel, 1 / texel_density
    rotation : (n,) float array           rotation of each chart, radians (counter-clockwise)
    offset : (n,2) float array            translation: ``uv[i] = scale * R(rotation[i]) @ chart_uv + offset[i]``
    efficiency : float                    sum of |triangle areas| in texels / (width_px * height_px)
    texture_size_px, gutter_px : int      the atlas resolution and gutter the packing was made for
    method : str                          the packer that was used ("shape", "maxrects", or a placer's name)
    time_s : float                        wall time of pack_charts (measured only: no decision reads it)
    min_gap_px : float or None            measured minimum distance between charts, texels (xatlas only)
    width_px, height_px : int             atlas size in texels (``texture_size_px`` is the width)
    texel_density : float                 texels per world unit, the same for every chart

    For a non-square atlas ``uv = (texel_density * R(rotation[i]) @ chart_uv + offset_px) / (width, height)``
    with ``offset_px = offset * (width, height)``: shapes are kept in texel units.
    """

    uv: list
    scale: float
    texel_size_world: float
    rotation: np.ndarray
    offset: np.ndarray
    efficiency: float
    texture_size_px: int
    gutter_px: int
    method: str
    time_s: float
    min_gap_px: float | None = None
    width_px: int = 0
    height_px: int = 0
    texel_density: float = 0.0

    @property
    def n_charts(self) -> int:
        return len(self.uv)

    def to_dict(self) -> dict:
        """JSON-ready summary (no per-vertex arrays)."""
        return {
            "n_charts": self.n_charts,
            "scale": float(self.scale),
            "texel_size_world": float(self.texel_size_world),
            "rotation": [float(r) for r in self.rotation],
            "offset": [[float(a), float(b)] for a, b in self.offset],
            "efficiency": float(self.efficiency),
            "texture_size_px": int(self.texture_size_px),
            "gutter_px": int(self.gutter_px),
            "method": self.method,
            "time_s": float(self.time_s),
            "min_gap_px": None if self.min_gap_px is None else float(self.min_gap_px),
            "width_px": int(self.width_px),
            "height_px": int(self.height_px),
            "texel_density": float(self.texel_density),
        }


# ----------------------------------------------------------------------------------------- checks

def _check_int_option(value, name, lo, hi, fix):
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise InputError(f"{name}={value!r} is not an integer; {fix}")
    value = int(value)
    if not lo <= value <= hi:
        raise InputError(f"{name}={value} is out of range [{lo}, {hi}]; {fix}")
    return value


def _check_size(texture_size_px, texel_density):
    """(width, height) in texels, or (None, None) when the atlas grows to fit ``texel_density``."""
    fix = "pass an integer number of texels between 16 and 16384, e.g. 1024, or a (width, height) pair"
    if texture_size_px is None:
        if texel_density is None:
            raise InputError("texture_size_px=None needs texel_density (the atlas then grows to fit); "
                             "pass texture_size_px, e.g. 1024, or texel_density")
        return None, None
    if isinstance(texture_size_px, (tuple, list)) and len(texture_size_px) == 2:
        W, H = (_check_int_option(v, "texture_size_px", 16, 16384, fix) for v in texture_size_px)
        return W, H
    N = _check_int_option(texture_size_px, "texture_size_px", 16, 16384, fix)
    return N, N


def _check_gutter(gutter_px, mip_levels, W, H):
    """The gutter in texels: ``gutter_px``, or derived from ``mip_levels`` (see mip_gutter_px)."""
    from uvbake.atlas.shapepack import mip_gutter_px

    need = None
    if mip_levels is not None:
        K = _check_int_option(mip_levels, "mip_levels", 1, 8, "pass how many mip levels must not bleed, 1 to 8")
        need, q = mip_gutter_px(K), 2 ** (K - 1)
        if W is not None and (W % q or H % q):
            raise InputError(f"texture_size_px={W if W == H else (W, H)} is not a multiple of {q} (mip_levels={K} "
                             f"halves it {K - 1} times); pass a texture size divisible by {q} or fewer mip_levels")
    if gutter_px is None:
        return 4 if need is None else need
    if isinstance(gutter_px, bool) or not isinstance(gutter_px, numbers.Integral):
        raise InputError(f"gutter_px={gutter_px!r} is not an integer; pass a whole number of texels >= 0, e.g. 4")
    g = int(gutter_px)
    if g < 0:
        raise InputError(f"gutter_px={g} is negative; pass a whole number of texels >= 0, e.g. 4")
    if need is not None and g < need:
        raise InputError(f"gutter_px={g} is less than the {need} texels mip_levels={mip_levels} needs; "
                         f"leave gutter_px out (it is derived from mip_levels) or raise it")
    if W is not None and g >= min(W, H):
        raise InputError(f"gutter_px={g} leaves no room in a {min(W, H)}-texel atlas; "
                         f"reduce gutter_px or increase texture_size_px")
    return g


def check_texel_density(texel_density: Any) -> float | None:
    """``texel_density`` as a float (None stays None: the scale is fitted), or InputError naming it."""
    if texel_density is None:
        return None
    try:
        d = float(texel_density)
    except (TypeError, ValueError):
        d = float("nan")
    if isinstance(texel_density, bool) or not np.isfinite(d) or d <= 0:
        raise InputError(f"texel_density={texel_density!r} is not a positive number; pass texels per world "
                         f"unit, e.g. 512")
    return d


def _check_inputs(chart_uvs, chart_faces, method):
    if not callable(method) and (not isinstance(method, str) or method not in METHODS):
        raise InputError(f"method={method!r} is not one of {', '.join(METHODS)} or a placer function; "
                         "pick one of those")
    if chart_uvs is None or len(chart_uvs) == 0:
        raise InputError("the chart list is empty; pass at least one chart's UVs and faces to pack")
    if chart_faces is None or len(chart_faces) != len(chart_uvs):
        n_f = None if chart_faces is None else len(chart_faces)
        raise InputError(f"got {len(chart_uvs)} chart UV arrays but {n_f} face arrays; pass one (t,3) face "
                         f"array per chart")
    checked = [_check_chart(i, uv, F) for i, (uv, F) in enumerate(zip(chart_uvs, chart_faces))]
    uvs, faces = [c[0] for c in checked], [c[1] for c in checked]
    return uvs, faces


def _check_chart(i: int, uv: Any, F: Any) -> tuple[np.ndarray, np.ndarray]:
    try:
        uv = np.asarray(uv, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"chart {i}: UVs are not numeric; pass a (k,2) float array") from None
    if uv.ndim != 2 or uv.shape[1] != 2 or len(uv) == 0:
        raise InputError(f"chart {i}: UVs have shape {uv.shape}; pass a (k,2) float array with k >= 1")
    if not np.all(np.isfinite(uv)):
        bad = int(np.flatnonzero(~np.isfinite(uv).all(axis=1))[0])
        raise InputError(f"chart {i}: UVs contain NaN or infinite values (vertex {bad}); "
                         f"re-run the parameterization of that chart")
    F = np.asarray(F)
    if F.ndim != 2 or F.shape[1] != 3 or len(F) == 0 or not np.issubdtype(F.dtype, np.integer):
        raise InputError(f"chart {i}: faces have shape {F.shape} and type {F.dtype}; "
                         f"pass a non-empty (t,3) integer array")
    if F.min() < 0 or F.max() >= len(uv):
        raise InputError(f"chart {i}: face indices must lie in [0, {len(uv) - 1}]; "
                         f"pass faces that index that chart's UVs")
    return uv, F.astype(np.int64)


# the rules the box packer runs when it only competes with shapes ("auto"): on the 14 multi-chart sets
# of bench/pack.py with 2-64 charts they reach the density of all five rules within 1 % at 30-75 % of
# the time (docs/decisions/pack.md)
_AUTO_RULES = ("baf", "cp")


def place_boxes(uvs: list[np.ndarray], faces: list[np.ndarray], N: int, g: int,
                packers: list[Callable[[np.ndarray], Any]] | None = None, rects: Any = None,
                rules: tuple[str, ...] = _RULES) -> Placement:
    """Rotate each chart to its minimum-area rectangle, pad by the gutter and pack the boxes.

    ``packers`` map padded box sizes (k,2) to (positions (k,2), turned (k,) bool) or None when they do
    not fit; default: uvbake's MaxRects with the placement ``rules`` and every order. ``rects``: the
    charts' min_area_rect when already known. A *placer* as :func:`pack_charts` takes one: (s,
    rotation, offset, placed UVs, measured gap in texels or None).
    """
    pad = g / N + _EPS_PAD
    rects = min_area_rects(uvs) if rects is None else rects
    wh = np.array([[w, h] for _, w, h in rects])
    if packers is None:
        packers = _own_packers(wh, rules=rules)
    s, payload = _pack_boxes(wh, pad, packers)
    if s is None:
        raise InputError(f"gutter_px={g} is too large for {len(uvs)} charts in a {N}-texel atlas: the gutters "
                         f"alone do not fit; reduce gutter_px or increase texture_size_px")
    pos, turned = payload
    rotation = np.zeros(len(uvs))
    offset = np.zeros((len(uvs), 2))
    out = []
    for i, uv in enumerate(uvs):                # one iteration per chart
        theta = rects[i][0] + (np.pi / 2 if turned[i] else 0.0)
        theta = float(np.arctan2(np.sin(theta), np.cos(theta)))
        q = s * (uv @ rotation_2d(theta).T)
        lo = q.min(axis=0)
        off = pos[i] + pad / 2 - lo
        rotation[i], offset[i] = theta, off
        out.append(q + off)
    return s, rotation, offset, out, None


# ------------------------------------------------------------------------------------------- API

def pack_charts(chart_uvs: Sequence[ArrayLike], chart_faces: Sequence[ArrayLike], *,
                texture_size_px: int | tuple[int, int] | None = 1024, gutter_px: int | None = None,
                rotate: bool = True, method: str = "auto", texel_density: float | None = None,
                mip_levels: int | None = None, aspect: str = "square",
                progress: Callable[[int, int], Any] | None = None) -> PackResult:
    """Pack charts into one atlas in [0,1]^2 at a common scale, ``gutter_px`` texels apart.

    Parameters
    ----------
    chart_uvs : list of (k_i,2) float arrays
        Per-vertex UVs of each chart in the surface's own length units (from ``uvbake.parameterize``).
    chart_faces : list of (t_i,3) int arrays
        Each chart's triangles, indexing its UVs.
    texture_size_px : int, (width, height) or None
        Atlas resolution in texels (16 .. 16384 a side); a pair asks for a non-square atlas ("shape"
        only); None (with ``texel_density``) lets a square atlas grow until the charts fit.
    gutter_px : int, optional
        Minimum distance between the triangles of any two charts, in texels (>= 0); default 4, or the
        gutter ``mip_levels`` needs. Charts also keep half a gutter from the atlas border.
    rotate : bool
        Rotate charts (never mirror). With ``rotate=False`` charts are only translated.
    method : "auto" | "shape" | "maxrects" | callable
        "shape" packs rasterised chart shapes (uvbake.atlas.shapepack); "maxrects" their minimum-area
        rectangles; "auto" is "shape", and for a square atlas of at most 64 charts at a free scale also
        tries "maxrects" and keeps the denser packing. A callable is a placer
        ``placer(uvs, faces, texture_size_px, gutter_px) -> (s, rotation, offset, uvs, gap_px)`` (see
        :func:`place_boxes`; bench/packers.py wraps xatlas and rectpack), reported by its ``__name__``.
    texel_density : float, optional
        Texels per world unit, fixed (one density across assets): the charts are packed at that scale,
        the atlas grows when ``texture_size_px`` is None, else an InputError says they cannot fit.
    mip_levels : int, optional
        How many mip levels (1..8: levels 0..mip_levels-1) must not bleed between charts under bilinear
        filtering of uvbake's dilated bakes; sets the gutter (6, 10, 19, 36 texels for 1..4 levels; see
        ``uvbake.atlas.shapepack.mip_gutter_px``).
    aspect : "square" | "free"
        Shape of an atlas that grows (``texture_size_px=None``): square, or the rectangle of fewest
        texels (a long ribbon gets a long atlas).
    progress : callable, optional
        ``progress(placed, total)``: charts placed by the running shape packing, every 64 of them.

    Returns
    -------
    :class:`PackResult`; ``efficiency`` = sum of |triangle areas| in texels / (width * height).
    """
    t0 = time.perf_counter()
    uvs, faces = _check_inputs(chart_uvs, chart_faces, method)
    density = check_texel_density(texel_density)
    W, H = _check_size(texture_size_px, density)
    g = _check_gutter(gutter_px, mip_levels, W, H)
    if not isinstance(rotate, (bool, np.bool_)):
        raise InputError(f"rotate={rotate!r} is not a bool; pass rotate=True or rotate=False")
    used = DEFAULT_METHOD if method == "auto" else method
    extents = [np.ptp(uv, axis=0).max() for uv in uvs]
    if max(extents) == 0.0:
        raise InputError("every chart's UVs collapse to a point; nothing to pack (check the parameterization)")
    if used != "shape" and (density is not None or W != H):
        raise InputError(f"method={method!r} packs square atlases at a free scale; use method='shape' for "
                         f"texel_density or a non-square texture_size_px")
    K = 0 if mip_levels is None else max(int(mip_levels) - 1, 0)        # the coarsest level kept clean
    if aspect not in ("square", "free"):
        raise InputError(f"aspect={aspect!r} is not 'square' or 'free'; pick one of those")
    if aspect == "free" and W is not None:
        raise InputError("aspect='free' sizes a growing atlas; pass texture_size_px=None with texel_density")
    if used == "shape":
        s, rotation, offset, out, gap, W, H, density, used = _place_shapes_or_boxes(
            uvs, faces, W, H, g, density, rotate, K, aspect, try_boxes=method == "auto", progress=progress)
    else:
        s, rotation, offset, out, gap, used = _place_free_scale(uvs, faces, W, g, rotate, used)
        density = s * W
    # a chart that cannot fit: the whole atlas would give the largest chart less than one texel
    if density * max(extents) < 1.0:
        raise InputError(f"the charts cannot fit a {W}x{H}-texel atlas with gutter_px={g}: the largest chart "
                         f"would be under one texel; reduce gutter_px or increase texture_size_px")
    area = sum(np.abs(signed_areas(uv, F)).sum() for uv, F in zip(uvs, faces))
    return packed_result(out, rotation, offset, gap, density, area, W, H, g, used, t0)


def packed_result(out: list[np.ndarray], rotation: np.ndarray, offset: np.ndarray, gap: float | None, density: float,
                  area: float, W: int, H: int, g: int, method: str, t0: float) -> PackResult:
    """The PackResult of a layout at ``density`` texels per unit holding charts of UV ``area``
    (efficiency: their texels over the W x H atlas's), timed from ``t0`` (time.perf_counter)."""
    return PackResult(uv=out, scale=float(density / W), texel_size_world=float(1.0 / density), rotation=rotation,
                      offset=offset, efficiency=float(density * density * area / (W * H)), texture_size_px=W,
                      gutter_px=g, method=method, time_s=time.perf_counter() - t0, min_gap_px=gap, width_px=W,
                      height_px=H, texel_density=float(density))


# "auto" on a square atlas at a free scale picks by how full the charts' minimum-area boxes are (chart
# area / box area, summed): boxes leave only their empty corners to shapes. On the 15 sets of 2-64 charts
# of bench/pack.py boxes won every set filled >= 0.84 (by 0.8-26 points) and lost every set filled < 0.74
# (by 5-14 points); in between both run (docs/decisions/pack.md, release 2c).
_BOXES_ONLY_FILL = 0.8
_SHAPES_ONLY_FILL = 0.7


def _place_shapes_or_boxes(uvs, faces, W, H, g, density, rotate, K, aspect, try_boxes, progress=None):
    """Shape packing; for "auto" on a square atlas of at most 64 charts at a free scale, boxes too (the
    denser wins), unless the boxes' fill decides alone (_BOXES_ONLY_FILL, _SHAPES_ONLY_FILL).

    One chart: its box in the square is what shapes reach too (they try the same angles), so the shape
    search is skipped; the shape search gives up once it cannot beat the boxes.
    """
    boxes = None
    hulls = chart_hulls(uvs) if rotate else None               # the rectangles' and the shape search's
    rects = min_area_rects(uvs, hulls) if rotate else None
    if try_boxes and W == H and density is None and len(uvs) <= 64:
        fill = _box_fill(uvs, faces, rects)
        if len(uvs) == 1 or fill >= _SHAPES_ONLY_FILL:
            boxes = place_boxes(uvs, faces, W, g, rects=rects, rules=_AUTO_RULES) if rotate else \
                _place_unrotated(uvs, faces, W, g)
        if boxes is not None and (len(uvs) == 1 or fill >= _BOXES_ONLY_FILL):
            return (*boxes, W, H, boxes[0] * W, "maxrects")
    shapes = _place_shapes(uvs, faces, W, H, g, density, rotate, K, aspect, rects,
                           guess=None if boxes is None else boxes[0] * W, hulls=hulls, progress=progress)
    if boxes is not None and (shapes is None or boxes[0] > shapes[0] * (1 + 1e-12)):
        return (*boxes, W, H, boxes[0] * W, "maxrects")
    s, rotation, offset, out, gap, W, H, density = shapes
    return s, rotation, offset, out, gap, W, H, density, "shape"


def _box_fill(uvs, faces, rects):
    """Total chart area over the total area of the charts' boxes (minimum-area ones when ``rects``,
    else axis-aligned)."""
    area = sum(float(np.abs(signed_areas(uv, F)).sum()) for uv, F in zip(uvs, faces))
    if rects is not None:
        box = float((rects[:, 1] * rects[:, 2]).sum())
    else:
        box = float(sum(np.prod(np.ptp(uv, axis=0)) for uv in uvs))
    return area / box if box > 0 else 1.0


def _place_free_scale(uvs, faces, N, g, rotate, used):
    """MaxRects boxes (rotated or not) or a placer, in a square N-texel atlas at the best common scale."""
    if callable(used):
        if not rotate:
            raise InputError(f"method={_name(used)} always rotates charts; use rotate=True or method='maxrects'")
        s, rotation, offset, out, gap = used(uvs, faces, N, g)
        return s, rotation, offset, out, gap, _name(used)
    if rotate:
        return (*place_boxes(uvs, faces, N, g), used)
    return (*_place_unrotated(uvs, faces, N, g), used)


def _shape_angles(n, rects, rotate, few):
    """Base rotations of every chart: its minimum-area-rectangle angle (+ quarter turns); the six biggest
    also at 45 degrees from it, where free angles pay most (bench/pack.py: +6.7 points on halftunnel, +4
    on sphere_cap), unless they are longer than 3:1 (a diagonal long chart rasterises a mostly empty
    square), and at 22.5 and 67.5 degrees (cow's 30 charts: 65.0 -> 66.2 %); with ``few`` charts (<= 4)
    every chart at those (bumpy +1.0 point, paid by one width round instead of two)."""
    if not rotate:
        return [np.zeros(1) for _ in range(n)]
    big = set(np.lexsort((np.arange(n), -rects[:, 1] * rects[:, 2]))[:6].tolist())
    big = {i for i in big if rects[i, 1] <= 3 * rects[i, 2]}
    angles = [np.array([t, t + np.pi / 4] if i in big else [t]) for i, t in enumerate(rects[:, 0])]
    return [np.concatenate([a, a[0] + np.array([np.pi / 8, 3 * np.pi / 8])]) if few or i in big else a
            for i, a in enumerate(angles)]


# The free-scale shape search: from _FIT_SCALE_FROM charts fit_scale (a coarse search on a _MANY_COARSE_PX
# raster, twice that when the charts holding most area are under _SMALL_CHART_TEXELS coarse texels a side,
# to a _MANY_COARSE_TOL bracket, then one finer trial); below, fit_width (one 256-texel raster in strips of
# several widths, other chart orders for 5-8 charts and on big meshes); layouts of >= _COMPACT_CHARTS charts
# on big meshes compacted (full resolution from _COMPACT_FULL_FACES faces, half from _BIG_MESH_FACES). The
# measurements behind each constant: docs/decisions/pack.md ("The free-scale search's constants", and the
# ninth session for the finer raster).
_FIT_SCALE_FROM = 64
_MANY_COARSE_TOL = 0.04
_MANY_COARSE_PX = 256
_SMALL_CHART_TEXELS = 16
_TINY_CHART_TEXELS = 32         # atlas texels: the last trial on a raster twice as fine (fit_scale's finer_last)
_BIG_MESH_FACES = 8192          # orders for any chart count, compaction at half resolution
_COMPACT_FULL_FACES = 16384     # compaction at full resolution
_COMPACT_CHARTS = 8
# work done "at full resolution" (fit_scale's last trial, the compaction) runs on at most this many texels a
# side, coarser than a larger atlas: its cost grows with the raster's area (docs/decisions/pack.md)
_FINE_SIDE = 2048
# a growing atlas (a fixed texel density) larger than this is grown on a coarser raster (see _grow)
_GROW_SIDE = 4096
_ORDERS_FROM = 4
_ORDERS_UP_TO = 8


def _fit_free_scale(packer, W, H, g, guess):
    """The densest shape packing of a W x H atlas; None when it cannot beat ``guess`` (boxes' density)."""
    from uvbake.atlas.fit import filling_side, fit_scale, fit_width, scale_to_border, swap_budget

    n, faces = len(packer.uvs), sum(len(F) for F in packer.faces)
    big = faces >= _BIG_MESH_FACES
    if n >= _FIT_SCALE_FROM:
        p = fit_scale(packer, W, H, g, coarse_px=_many_coarse_px(packer, W, H), coarse_tol=_MANY_COARSE_TOL,
                      fine_packs=1, guess=guess, beat_guess=guess is not None, fine_side=_FINE_SIDE,
                      finer_last=2 * max(W, H) <= _FINE_SIDE and filling_side(packer, W, H) < _TINY_CHART_TEXELS)
    else:       # one raster, strips of several widths, each layout scaled to the atlas
        area = float(packer.area.sum())
        p = fit_width(packer, W, H, g, guess if guess is not None else np.sqrt(0.5 * W * H / area),
                      floor=guess, rounds=1,
                      order_packs=2 if _ORDERS_FROM < n and (n <= _ORDERS_UP_TO or big) else 0,
                      swaps=swap_budget(n, faces) if _ORDERS_FROM < n else 0)
    if p is None and guess is not None:
        return None
    if p is None:
        raise InputError(f"the charts cannot fit a {W}x{H}-texel atlas with gutter_px={g}: the gutters alone "
                         f"take the room; reduce gutter_px or increase texture_size_px")
    q = scale_to_border(packer, p, W, H, g)
    if q is None:         # a full-resolution layout of fit_scale past the border margin (rare: 1022 of 1020
        # texels on a spiky sphere's 64+ charts): the coarse strips, whose layouts scaled to the border fit
        q = fit_width(packer, W, H, g, p.density, rounds=1, order_packs=0)
        if q is None:
            raise InputError(f"the charts cannot fit a {W}x{H}-texel atlas with gutter_px={g}; reduce gutter_px "
                             f"or increase texture_size_px")
    p = q
    if big and _COMPACT_CHARTS <= n < _FIT_SCALE_FROM:
        p = _compacted(packer, p, W, H, g, (1 if faces >= _COMPACT_FULL_FACES else 2) * _per_compact_texel(W, H))
    return p


def _many_coarse_px(packer, W, H):
    """fit_scale's coarse raster for many charts (uvbake.atlas.fit.resolving_coarse_px)."""
    from uvbake.atlas.fit import resolving_coarse_px

    return resolving_coarse_px(packer, W, H, _MANY_COARSE_PX, _SMALL_CHART_TEXELS)


def _per_compact_texel(W, H):
    """Atlas texels per compaction texel beyond the rule's own: a power of two keeping the compaction's
    raster within _FINE_SIDE a side (its run tables cost as the atlas's area)."""
    from uvbake.atlas.fit import _fine_factor

    return _fine_factor(W, H, _FINE_SIDE)


def _compacted(packer, p, W, H, g, c=1):
    """``p`` compacted (uvbake.atlas.compact) on a raster ``c`` times coarser than the atlas (moves of ``c``
    texels, gutter ``ceil(g / c)`` coarse texels: every distance scales by ``c``) and scaled back to the
    border, when denser."""
    from uvbake.atlas.compact import compact
    from uvbake.atlas.fit import scale_to_border

    cg = -(-g // c)
    q = compact(packer, replace(p, density=p.density / c, offset=p.offset / c), W // c, H // c, cg)
    q = scale_to_border(packer, q, W, H, g, c, cg)
    return q if q is not None and q.density > p.density else p


def _grow(packer, g, density, mip_levels, aspect):
    """A growing atlas at a fixed ``density``: (W, H, ShapePacking) (uvbake.atlas.fit.grow_atlas)."""
    from uvbake.atlas.fit import grow_atlas

    return grow_atlas(packer, g, density, max(4, 2 ** mip_levels), aspect, _GROW_SIDE)


def _place_shapes(uvs, faces, W, H, g, density, rotate, mip_levels, aspect, rects, guess=None, hulls=None,
                  progress=None):
    """Shape packing (uvbake.atlas.shapepack) at the best common scale, at ``density`` or growing.

    With ``guess`` (a box packing's density) the free-scale search gives up, returning None, as soon as
    it is clear shapes will not beat it. ``hulls``: the charts' chart_hulls, when known.
    """
    from uvbake.atlas.shapepack import ShapePacker

    few = rotate and density is None and len(uvs) <= 4
    packer = ShapePacker(uvs, faces, _shape_angles(len(uvs), rects, rotate, few), quarter_turns=bool(rotate),
                         hulls=hulls, progress=progress)
    if density is None:
        p = _fit_free_scale(packer, W, H, g, guess)
        if p is None:
            return None
    elif W is None:
        W, H, p = _grow(packer, g, density, mip_levels, aspect)
    else:
        p = packer.pack(density, W, None, g)
        if p is None or p.height_used > H:
            need = "a wider atlas" if p is None else f"about {W}x{p.height_used} texels"
            raise InputError(f"the charts cannot fit texture_size_px={W if W == H else (W, H)} at "
                             f"texel_density={density:g} (they need {need}); raise texture_size_px, lower "
                             f"texel_density, or leave texture_size_px out to let the atlas grow")
    size = np.array([W, H], dtype=np.float64)
    out = []
    for i, uv in enumerate(uvs):              # one iteration per chart
        out.append((p.density * (uv @ rotation_2d(p.rotation[i]).T) + p.offset[i]) / size)
    return p.density / W, p.rotation, p.offset / size, out, None, W, H, p.density


def _name(placer: Any) -> str:
    return str(getattr(placer, "__name__", "custom"))


def _place_unrotated(uvs, faces, N, g):
    """Box packing without any rotation (no calipers, no 90-degree turns): charts are only translated."""
    pad = g / N + _EPS_PAD
    lo = np.array([uv.min(axis=0) for uv in uvs])
    wh = np.array([np.ptp(uv, axis=0) for uv in uvs])
    s, payload = _pack_boxes(wh, pad, _own_packers(wh, allow_turn=False))
    if s is None:
        raise InputError(f"gutter_px={g} is too large for {len(uvs)} charts in a {N}-texel atlas: the gutters "
                         f"alone do not fit; reduce gutter_px or increase texture_size_px")
    pos, _ = payload
    offset = pos + pad / 2 - s * lo
    out = [s * uv + offset[i] for i, uv in enumerate(uvs)]
    return s, np.zeros(len(uvs)), offset, out, None


def corner_uvs(pack_result: PackResult, chart_faces: Sequence[np.ndarray], face_index: Sequence[np.ndarray],
               n_faces: int) -> np.ndarray:
    """Per-corner atlas UVs (n_faces,3,2) of the whole mesh, the layout of Open3D's ``texture_uvs``.

    ``face_index[i]`` gives, for each face of chart i (in ``chart_faces[i]`` order), its index in the
    whole mesh. Every mesh face must belong to exactly one chart.
    """
    n_faces = _check_int_option(n_faces, "n_faces", 1, np.iinfo(np.int64).max, "pass the mesh's face count")
    if len(chart_faces) != pack_result.n_charts or len(face_index) != pack_result.n_charts:
        raise InputError(f"pack result has {pack_result.n_charts} charts but got {len(chart_faces)} face arrays and "
                         f"{len(face_index)} face_index arrays; pass one of each per packed chart")
    out = np.full((n_faces, 3, 2), np.nan)
    seen = np.zeros(n_faces, dtype=np.int64)
    for i, (F, idx) in enumerate(zip(chart_faces, face_index)):
        F = np.asarray(F, dtype=np.int64)
        idx = np.asarray(idx, dtype=np.int64).ravel()
        if len(idx) != len(F):
            raise InputError(f"chart {i}: face_index has {len(idx)} entries for {len(F)} faces; pass one mesh "
                             f"face index per chart face")
        if len(idx) and (idx.min() < 0 or idx.max() >= n_faces):
            raise InputError(f"chart {i}: face_index must lie in [0, {n_faces - 1}]; pass indices into the mesh's faces")
        out[idx] = pack_result.uv[i][F]
        np.add.at(seen, idx, 1)
    if np.any(seen != 1):
        bad = np.flatnonzero(seen != 1)
        what = "no chart" if seen[bad[0]] == 0 else "several charts"
        raise InputError(f"mesh face {int(bad[0])} belongs to {what} ({len(bad)} faces affected); every face must "
                         f"be in exactly one chart")
    return out
