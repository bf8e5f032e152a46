"""Texture baking: a UV-space checker (distortion made visible) and vertex colours.

    img = bake_checker(V, F, corner_uv, texture_size_px=1024)            # (H,W,3) uint8
    img = bake_vertex_colors(V, F, corner_uv, colors, texture_size_px=1024)

Conventions (the one internal convention of uvbake, converted only at export):

- ``corner_uv (m,3,2)`` are atlas UVs in [0,1]^2 with **v pointing up** (OBJ convention, origin at the
  bottom-left of the image).
- The returned image is stored **row 0 = top** (as PNG and PIL store it), so texel ``(i, j)`` has its
  centre at ``u = (j + 0.5) / W``, ``v = 1 - (i + 0.5) / H``. This is exactly the layout Open3D's
  ``bake_*_attr_textures`` produce, and the layout an OBJ ``map_Kd`` expects. glTF puts the UV origin at
  the top-left, so the GLB writer stores ``(u, 1 - v)`` and the same image bytes.

How it is done: the semantics of Open3D's
``open3d.t.geometry.TriangleMesh.bake_vertex_attr_textures(size, {attr}, margin, fill)`` (for every
texel centre, the closest point of the UV triangles; within ``margin`` texels it gets the
barycentric interpolation of the attribute there, clamped to the triangle, else ``fill``), computed
by :func:`rasterize` in numpy: texel centres inside a triangle by row spans, the
:data:`BAKE_MARGIN_PX` band outside from the charts' outline edges. Every bake is a per-corner
attribute (a vertex on a seam has one UV per chart): the checker bakes the UV itself (each texel
receives its own UV, clamped to the chart in the margin) and computes the checker colour per texel;
vertex colours bake ``colors[F]``. Open3D's bake itself is kept as the reference in the tests (same
covered texels but for float32 rounding at the margin, same values to 1e-5); it is not called here
because ``import open3d`` alone costs about a second of CPU (docs/decisions/bake.md).
Dilation (:func:`dilate`) then pushes every covered texel's colour outward to background texels
within ``dilate_px`` (Euclidean, nearest covered texel, one ``scipy.ndimage.distance_transform_edt``).

Default dilation: :data:`DEFAULT_DILATE_PX` = 17 texels, enough that bilinear filtering at mip levels
0..3 (each level a 2x box filter of the one below) at any UV point inside a chart never reads
background. At level k a bilinear sample at p reads level-0 texels whose centres are less than
1.5 * 2^k - 0.5 texels from p along each axis (11.5 for k = 3, so under 16.3 Euclidean); p has a
covered texel within 0.71 texels (every texel centre within ``BAKE_MARGIN_PX`` of a triangle is
covered), so every texel read is within 17 texels of a covered one. Chart-to-chart bleeding at the
coarser levels is the packer's gutter's business; background never enters.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from uvbake.errors import InputError

#: Texels within this distance (in texels) of a UV triangle are baked (clamped to the closest point
#: of the triangle); must be at least sqrt(2) so that bilinear level-0 reads of any
#: point inside a triangle hit covered texels only.
BAKE_MARGIN_PX = 2.0

#: Mip levels 0..DEFAULT_MIP_LEVELS-1 are guaranteed free of background by the default dilation.
DEFAULT_MIP_LEVELS = 4


def dilate_px_for_mips(levels: int) -> int:
    """Dilation (texels) that keeps bilinear reads at mip levels ``0..levels-1`` off the background."""
    if levels < 1:
        return 0
    s = 2 ** (levels - 1)
    return int(math.ceil(math.sqrt(2.0) * (1.5 * s - 0.5) + math.sqrt(0.5)))


#: Default ``dilate_px`` (17 texels: mip levels 0..3).
DEFAULT_DILATE_PX = dilate_px_for_mips(DEFAULT_MIP_LEVELS)

#: Default checker: this many squares across the texture (``texture_size_px / 32`` texels a square).
DEFAULT_SQUARES_ACROSS = 32


# --------------------------------------------------------------------------------------------------
# public API


def bake_checker(V: ArrayLike, F: ArrayLike, corner_uv: ArrayLike, *, texture_size_px: int | tuple[int, int] = 1024,
                 square_size: float | None = None, texel_size_world: float | str | None = None,
                 colors: ArrayLike = ((235, 235, 235), (40, 40, 40)), dilate_px: int | None = None,
                 background: Sequence[int] = (0, 0, 0)) -> np.ndarray:
    """Bake a UV-space checkerboard: equal squares wherever the map is undistorted.

    uvbake packs every chart at one scale, so a checker of fixed size in UV space shows squares of one
    physical size on every undistorted part of the model, and stretched or sheared squares where the
    map distorts (the paper's Figures 5, 9 and 11).

    Parameters
    ----------
    V : (n,3) float array
    F : (m,3) int array
    corner_uv : (m,3,2) float array
        Atlas UVs per corner in [0,1]^2, v up.
    texture_size_px : int or (int, int)
        Side of a square texture, or its (width, height).
    square_size : float, optional
        Edge of a checker square: in atlas UV units, or in world units when ``texel_size_world`` is
        given. Default: ``texture_size_px / 32`` texels (32 squares across the texture).
    texel_size_world : float or "auto", optional
        World length of one texel edge (the packer's uniform scale). ``"auto"`` estimates it as
        ``sqrt(3D area / UV area) / texture_size_px``. When given, ``square_size`` is in world units
        and defaults to the round length (1, 2 or 5 times a power of ten) nearest to
        ``texture_size_px / 32`` texels, so squares have a readable physical size (say 1 cm).
    colors : two RGB triples (0..255)
        Colours of the even and odd squares.
    dilate_px : int, optional
        How far (texels) colours are pushed into the background; default :data:`DEFAULT_DILATE_PX`,
        ``-1`` fills the whole image, ``0`` none.
    background : RGB triple
        Colour of texels left uncovered after dilation.

    Returns
    -------
    (H,W,3) uint8 array, row 0 at the top (v = 1).
    """
    V, F, corner_uv, size = _check_inputs(V, F, corner_uv, texture_size_px)
    colors = np.asarray(colors, dtype=np.float64)
    if colors.shape != (2, 3) or not np.all(np.isfinite(colors)):
        raise InputError(f"colors must be two RGB triples, got shape {colors.shape}; "
                         "pass ((r,g,b), (r,g,b)) in 0..255")
    W, H = size
    sq = _square_size_uv(V, F, corner_uv, size, square_size, texel_size_world)

    # each covered texel's own UV: its centre inside a triangle, its closest point in the margin
    face, (band, tri, k, s) = rasterize(corner_uv, size)
    inside = np.flatnonzero(face.ravel() >= 0)
    row, col = np.divmod(inside, W)
    edge = _on_edges(corner_uv, tri, k, s)
    u = np.concatenate([(col + 0.5) / W, edge[:, 0]])
    v = np.concatenate([1.0 - (row + 0.5) / H, edge[:, 1]])
    texel = np.concatenate([inside, band])
    # squares of sq * W texels both ways (v runs H / W times faster than u in texels)
    v_sq = sq if W == H else sq * W / H
    parity = (np.floor(u / sq).astype(np.int64) + np.floor(v / v_sq).astype(np.int64)) & 1
    return _finish(texel, np.clip(np.rint(colors), 0, 255).astype(np.uint8)[parity], size, dilate_px, background)


def bake_vertex_colors(V: ArrayLike, F: ArrayLike, corner_uv: ArrayLike, vertex_colors: ArrayLike, *,
                       texture_size_px: int | tuple[int, int] = 1024, dilate_px: int | None = None,
                       background: Sequence[int] = (0, 0, 0)) -> np.ndarray:
    """Bake per-vertex colours into the atlas (barycentric interpolation inside each triangle).

    Parameters
    ----------
    V, F, corner_uv, texture_size_px, dilate_px, background
        As in :func:`bake_checker`.
    vertex_colors : (n,3) or (n,4) array
        Floats in [0,1] or uint8 in 0..255; alpha is dropped.

    Returns
    -------
    (H,W,3) uint8 array, row 0 at the top (v = 1).
    """
    V, F, corner_uv, size = _check_inputs(V, F, corner_uv, texture_size_px)
    colors = np.asarray(vertex_colors)
    if colors.ndim != 2 or colors.shape[0] != len(V) or colors.shape[1] not in (3, 4):
        raise InputError(f"vertex_colors must be (n,3) with n={len(V)}, got shape {colors.shape}; "
                         "pass one RGB colour per vertex")
    colors = colors[:, :3]
    colors = colors / 255.0 if colors.dtype == np.uint8 else colors.astype(np.float64)
    if not np.all(np.isfinite(colors)):
        raise InputError("vertex_colors hold NaN or infinite values; pass finite colours in [0,1]")
    texel, rgb = _sample(corner_uv, colors[F], size)
    return _finish(texel, np.rint(np.clip(rgb, 0.0, 1.0) * 255.0).astype(np.uint8), size, dilate_px, background)


def dilate(image: np.ndarray, mask: np.ndarray, *, iterations: int | None) -> np.ndarray:
    """Push colours outward from covered texels into the gutter.

    Parameters
    ----------
    image : (H,W) or (H,W,C) array
    mask : (H,W) bool array
        True where a texel is covered (its value is kept).
    iterations : int or None
        Texels not covered but within this Euclidean distance (in texels) of a covered texel take the
        value of the nearest covered texel; ``None`` or a negative value fills every texel.

    Returns
    -------
    A new array like ``image``. An all-False mask returns an unchanged copy.
    """
    image = np.asarray(image)
    mask = np.asarray(mask, dtype=bool)
    if mask.shape != image.shape[:2]:
        raise InputError(f"mask shape {mask.shape} does not match image shape {image.shape[:2]}; "
                         "pass one flag per texel")
    out = image.copy()
    if not mask.any() or mask.all() or iterations == 0:
        return out
    from scipy import ndimage

    dist, (ii, jj) = ndimage.distance_transform_edt(~mask, return_indices=True)
    fill = ~mask
    if iterations is not None and iterations >= 0:
        fill &= dist <= iterations
    out[fill] = image[ii[fill], jj[fill]]
    return out


# --------------------------------------------------------------------------------------------------
# internals


def _check_inputs(V: ArrayLike, F: ArrayLike, corner_uv: ArrayLike, texture_size_px: int | tuple[int, int]
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[int, int]]:
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F)
    corner_uv = np.asarray(corner_uv, dtype=np.float64)
    if V.ndim != 2 or V.shape[1] != 3:
        raise InputError(f"V must be (n,3), got shape {V.shape}; pass vertex positions")
    if F.ndim != 2 or F.shape[1] != 3 or len(F) == 0:
        raise InputError(f"F must be (m,3) with m > 0, got shape {F.shape}; pass triangles")
    if not np.issubdtype(F.dtype, np.integer) or F.min() < 0 or F.max() >= len(V):
        raise InputError(f"F must hold integer indices in 0..{len(V) - 1}; pass triangles indexing V")
    F = F.astype(np.int64)
    if corner_uv.shape != (len(F), 3, 2):
        raise InputError(f"corner_uv must be (m,3,2)=({len(F)},3,2), got {corner_uv.shape}; "
                         "pass the packed atlas UVs per face corner")
    if not np.all(np.isfinite(corner_uv)):
        raise InputError("corner_uv holds NaN or infinite values; pack the charts first")
    if corner_uv.min() < -1e-6 or corner_uv.max() > 1 + 1e-6:
        raise InputError(f"corner_uv spans [{corner_uv.min():.4g}, {corner_uv.max():.4g}], outside "
                         "[0,1]; pack the charts into the atlas first")
    return V, F, corner_uv, texture_dims(texture_size_px)


def texture_dims(texture_size_px: int | tuple[int, int]) -> tuple[int, int]:
    """(width, height) of a texture given as one side (square) or as (width, height), each 1..16384."""
    pair = texture_size_px if isinstance(texture_size_px, (tuple, list)) and len(texture_size_px) == 2 \
        else (texture_size_px, texture_size_px)
    for n in pair:
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 1 <= n <= 16384:
            raise InputError(f"texture_size_px must be an integer in 1..16384 or a (width, height) pair of them, "
                             f"got {texture_size_px!r}")
    return int(pair[0]), int(pair[1])


def _square_size_uv(V, F, corner_uv, size, square_size, texel_size_world):
    """Checker square edge in atlas UV units."""
    if texel_size_world is None:
        sq = 1.0 / DEFAULT_SQUARES_ACROSS if square_size is None else square_size
    else:
        if isinstance(texel_size_world, str):
            if texel_size_world != "auto":
                raise InputError(f"texel_size_world must be a positive number or 'auto', got "
                                 f"{texel_size_world!r}")
            texel_size_world = _texel_size_world(V, F, corner_uv, size)
        if not (np.isfinite(texel_size_world) and texel_size_world > 0):
            raise InputError(f"texel_size_world must be positive and finite, got {texel_size_world!r}")
        world_per_uv = texel_size_world * size[0]
        sq_world = _nice(world_per_uv / DEFAULT_SQUARES_ACROSS) if square_size is None else square_size
        sq = sq_world / world_per_uv
    try:
        sq = float(sq)
    except (TypeError, ValueError):
        raise InputError(f"square_size must be a positive number, got {square_size!r}") from None
    if not (np.isfinite(sq) and sq > 0):
        raise InputError(f"square_size must be positive and finite, got {square_size!r}")
    return sq


def _nice(x: float) -> float:
    """The number of the form 1, 2 or 5 times a power of ten closest to x (in ratio)."""
    e = math.floor(math.log10(x))
    candidates = [m * 10.0 ** k for k in (e, e + 1) for m in (1, 2, 5)]
    return min(candidates, key=lambda c: abs(math.log(c / x)))


def _texel_size_world(V, F, corner_uv, size):
    """World length of one texel edge, from the ratio of 3D area to UV area."""
    P = V[F]
    area3 = 0.5 * np.linalg.norm(np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), axis=1).sum()
    e1, e2 = corner_uv[:, 1] - corner_uv[:, 0], corner_uv[:, 2] - corner_uv[:, 0]
    area2 = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]).sum()
    if not (area2 > 0 and area3 > 0):
        raise InputError("cannot estimate texel_size_world: the mesh or its UVs have zero area; "
                         "pass texel_size_world as a number")
    return math.sqrt(area3 / (area2 * size[0] * size[1]))


def bake_corner_attribute(corner_uv: np.ndarray, values: np.ndarray, size: int | tuple[int, int]) -> np.ndarray:
    """Bake a per-corner attribute: ``(H, W, k)`` float64, NaN where uncovered.

    Parameters
    ----------
    corner_uv : (m,3,2) float array
        Atlas UVs, v up.
    values : (m,3,k) or (m,3) float array
        The attribute at each corner; interpolated barycentrically inside each triangle and clamped
        to the closest point of the closest triangle up to ``BAKE_MARGIN_PX`` texels outside.
    size : int or (W, H)
        Texture width and height.
    """
    values = np.asarray(values, dtype=np.float64)
    squeeze = values.ndim == 2
    W, H = texture_dims(size)
    texel, vals = _sample(corner_uv, values.reshape(len(values), 3, -1), (W, H))
    out = np.full((W * H, vals.shape[1]), np.nan)
    out[texel] = vals
    out = out.reshape(H, W, -1)
    return out[..., 0] if squeeze else out


def _sample(corner_uv, values, size):
    """The attribute ``values (m,3,k)`` at every covered texel: (flat texel indices (c,), values (c,k))."""
    corner_uv = np.asarray(corner_uv, dtype=np.float64)
    face, (band, tri, k, s) = rasterize(corner_uv, size)
    inside = np.flatnonzero(face.ravel() >= 0)
    f = face.ravel()[inside]
    gx, gy, h = _planes(corner_uv, values, size)
    W = texture_dims(size)[0]
    x = (inside % W + 0.5)[:, None]
    y = (inside // W + 0.5)[:, None]
    edge = _on_edges(values, tri, k, s)
    return np.concatenate([inside, band]), np.concatenate([gx[f] * x + gy[f] * y + h[f], edge])


def _on_edges(values, tri, k, s):
    """Per-corner ``values (m,3,...)`` at ``(1 - s) * corner k + s * corner k+1`` of triangles ``tri``."""
    return (1.0 - s)[:, None] * values[tri, k] + s[:, None] * values[tri, (k + 1) % 3]


def _texel_corners(corner_uv, size):
    """Corners in texel coordinates: x = u * W (columns), y = (1 - v) * H (rows)."""
    W, H = texture_dims(size)
    P = np.empty(corner_uv.shape)
    P[..., 0] = corner_uv[..., 0] * W
    P[..., 1] = (1.0 - corner_uv[..., 1]) * H
    return P


def _barycentric_planes(P):
    """Per triangle, lambda_k(x, y) = A_k x + B_k y + C_k: (A, B, C) each (m,3), and 2x signed areas."""
    a, e1, e2 = P[:, 0], P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    live = np.abs(det) > MIN_DOUBLE_AREA_PX2
    inv = np.divide(1.0, det, out=np.zeros_like(det), where=live)   # 0: degenerate, never scanned inside
    A1, B1 = e2[:, 1] * inv, -e2[:, 0] * inv
    A2, B2 = -e1[:, 1] * inv, e1[:, 0] * inv
    C1 = -(A1 * a[:, 0] + B1 * a[:, 1])
    C2 = -(A2 * a[:, 0] + B2 * a[:, 1])
    return (np.stack([-A1 - A2, A1, A2], axis=1), np.stack([-B1 - B2, B1, B2], axis=1),
            np.stack([1.0 - C1 - C2, C1, C2], axis=1), det)


def _planes(corner_uv, values, size):
    """Per triangle, the attribute as a plane over texel coordinates: value = gx x + gy y + h, (m,k) each."""
    A, B, C, _ = _barycentric_planes(_texel_corners(corner_uv, size))
    return (np.einsum("mc,mck->mk", A, values), np.einsum("mc,mck->mk", B, values),
            np.einsum("mc,mck->mk", C, values))


def rasterize(corner_uv: np.ndarray, size: int | tuple[int, int], *, margin_px: float = BAKE_MARGIN_PX
              ) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """Which triangle covers every texel centre, and where texels within ``margin_px`` outside clamp to.

    Parameters
    ----------
    corner_uv : (m,3,2) float array
        Atlas UVs, v up; texel ``(i, j)`` has its centre at ``u = (j + 0.5) / W``,
        ``v = 1 - (i + 0.5) / H``.
    size : int or (W, H)
        Texture width and height (one number: square).
    margin_px : float
        Texels whose centre is at most this far (Euclidean, in texels) from a triangle are covered.

    Returns
    -------
    face : (H, W) int32 (int64 past 2^31 triangles)
        The triangle whose inside holds the texel centre, -1 elsewhere.
    band : tuple (texel, tri, k, s) of (b,) arrays
        The other covered texels (flat index ``i * W + j``): their closest point on the triangles
        is at ``(1 - s) * corner k + s * corner (k + 1) % 3`` of triangle ``tri``.

    Inside: every triangle is scanned row by row (the span of texel centres between its edges, closed
    and widened by ``SPAN_EPS_PX`` so that a centre on an edge shared by two triangles is never
    missed by both); a centre inside several triangles takes the last in face order. Outside: the
    closest point of the union of the triangles lies on its outline, so only the outline's edges are
    measured (edges without a welded twin whose triangle turns the same way); the nearest wins
    (ties: first edge). This is what Open3D's ``bake_vertex_attr_textures`` computes with a
    closest-point query per texel (a test checks that the two agree), done here in numpy because
    importing Open3D alone costs about a second of CPU (docs/decisions/bake.md).
    """
    corner_uv = np.asarray(corner_uv, dtype=np.float64)
    size = texture_dims(size)
    P = _texel_corners(corner_uv, size)
    A, B, C, det = _barycentric_planes(P)
    face = np.full((size[1], size[0]), -1, dtype=np.int32 if len(corner_uv) < 2**31 else np.int64)
    _scan_inside(P, A, B, C, det, size, face)
    return face, _scan_outline(corner_uv, P, np.sign(det), size, margin_px, face)


#: Spans of texel centres inside a triangle are widened by this much (texels) on both sides.
SPAN_EPS_PX = 1e-7

#: Triangles with twice their area (texels^2) at most this are segments: only their edges bake.
MIN_DOUBLE_AREA_PX2 = 1e-9


def _scan_inside(P, A, B, C, det, size, face):
    """Write the triangle of every texel centre inside one (row spans, vectorised over all rows)."""
    W, H = size
    live = np.flatnonzero(np.abs(det) > MIN_DOUBLE_AREA_PX2)   # thinner ones: outline only
    Q = P[live]
    r0 = np.clip(np.ceil(Q[..., 1].min(axis=1) - 0.5), 0, H).astype(np.int64)
    r1 = np.clip(np.floor(Q[..., 1].max(axis=1) - 0.5), -1, H - 1).astype(np.int64)
    nrows = np.maximum(r1 - r0 + 1, 0)
    t = np.repeat(np.arange(len(live)), nrows)              # one entry per (triangle, row)
    row = r0[t] + np.arange(len(t)) - np.repeat(np.cumsum(nrows) - nrows, nrows)
    tl = live[t]
    rest = B[tl] * (row + 0.5)[:, None] + C[tl]             # lambda_k = A_k x + rest_k >= 0
    At = A[tl]
    with np.errstate(divide="ignore", invalid="ignore"):
        bound = -rest / At
    lo_x = np.max(np.where(At > 0, bound, -np.inf), axis=1)
    hi_x = np.min(np.where(At < 0, bound, np.inf), axis=1)
    empty = np.any((At == 0) & (rest < 0), axis=1)
    lo_x = np.maximum(lo_x, Q[t, :, 0].min(axis=1))
    hi_x = np.minimum(hi_x, Q[t, :, 0].max(axis=1))
    c0 = np.clip(np.ceil(lo_x - 0.5 - SPAN_EPS_PX), 0, W).astype(np.int64)
    c1 = np.clip(np.floor(hi_x - 0.5 + SPAN_EPS_PX), -1, W - 1).astype(np.int64)
    ncols = np.where(empty, 0, np.maximum(c1 - c0 + 1, 0))
    start = row * W + c0                                    # flat index of each span's first texel
    seg = np.repeat(np.arange(len(t)), ncols)
    flat = start[seg] + np.arange(len(seg)) - np.repeat(np.cumsum(ncols) - ncols, ncols)
    face.ravel()[flat] = tl[seg]


def _scan_outline(corner_uv, P, sign, size, margin_px, face):
    """Texels outside every triangle but within the margin: the closest point of the outline."""
    m = len(P)
    k = np.tile(np.arange(3), m)
    tri = np.repeat(np.arange(m), 3)
    start = corner_uv[tri, k]
    end = corner_uv[tri, (k + 1) % 3]
    # an edge is inside the union when a triangle turning the same way runs it the other way (a twin)
    fwd = np.ascontiguousarray(np.concatenate([start, end], axis=1)).view(np.dtype((np.void, 32))).ravel()
    rev = np.ascontiguousarray(np.concatenate([end, start], axis=1)).view(np.dtype((np.void, 32))).ravel()
    order = np.argsort(fwd, kind="stable")
    srt = fwd[order]
    left = np.searchsorted(srt, rev, side="left")
    right = np.searchsorted(srt, rev, side="right")
    twin = order[np.minimum(left, len(srt) - 1)] // 3
    interior = (right - left == 1) & (sign[tri] != 0) & (sign[twin] == sign[tri])
    tri, k = tri[~interior], k[~interior]
    A, B = P[tri, k], P[tri, (k + 1) % 3]
    dims = np.array(size)                                   # (W, H): x clipped to W, y to H
    lo = np.clip(np.ceil(np.minimum(A, B) - margin_px - 0.5), 0, dims).astype(np.int64)
    hi = np.clip(np.floor(np.maximum(A, B) + margin_px - 0.5), -1, dims - 1).astype(np.int64)
    ncol = np.maximum(hi[:, 0] - lo[:, 0] + 1, 0)
    n = ncol * np.maximum(hi[:, 1] - lo[:, 1] + 1, 0)
    e = np.repeat(np.arange(len(tri)), n)                   # one entry per (edge, texel of its box)
    local = np.arange(len(e)) - np.repeat(np.cumsum(n) - n, n)
    r = local // ncol[e]
    row = lo[e, 1] + r
    col = lo[e, 0] + local - r * ncol[e]
    free = face[row, col] < 0
    e, row, col = e[free], row[free], col[free]
    AB = (B - A)[e]
    L2 = np.einsum("ij,ij->i", AB, AB)
    p = np.stack([col + 0.5, row + 0.5], axis=1)
    s = np.clip(np.einsum("ij,ij->i", p - A[e], AB) / np.where(L2 > 0, L2, 1.0), 0.0, 1.0)
    d = np.hypot(*(A[e] + s[:, None] * AB - p).T)
    near = d <= margin_px
    e, s, d, key = e[near], s[near], d[near], row[near] * size[0] + col[near]
    pick = np.lexsort((e, d, key))                          # per texel: nearest, then first edge
    first = np.ones(len(pick), bool)
    first[1:] = key[pick][1:] != key[pick][:-1]
    pick = pick[first]
    return key[pick], tri[e[pick]], k[e[pick]], s[pick]


def _finish(texel, rgb, size, dilate_px, background):
    """The image: covered texels (flat indices) get ``rgb`` (uint8), dilated; the rest the background."""
    background = np.asarray(background, dtype=np.float64)
    if background.shape != (3,):
        raise InputError(f"background must be an RGB triple, got {background!r}")
    if dilate_px is None:
        dilate_px = DEFAULT_DILATE_PX
    if isinstance(dilate_px, bool) or not isinstance(dilate_px, (int, np.integer)):
        raise InputError(f"dilate_px must be an integer (-1 fills the image), got {dilate_px!r}")
    W, H = size
    image = np.empty((W * H, 3), np.uint8)
    image[:] = np.clip(np.rint(background), 0, 255).astype(np.uint8)
    image[texel] = rgb
    covered = np.zeros(W * H, bool)
    covered[texel] = True
    return dilate(image.reshape(H, W, 3), covered.reshape(H, W),
                  iterations=None if dilate_px < 0 else int(dilate_px))
