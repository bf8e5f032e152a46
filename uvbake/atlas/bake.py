"""Texture baking through Open3D: a UV-space checker (distortion made visible) and vertex colours.

    img = bake_checker(V, F, corner_uv, texture_size_px=1024)            # (H,W,3) uint8
    img = bake_vertex_colors(V, F, corner_uv, colors, texture_size_px=1024)

Conventions (the one internal convention of uvbake, converted only at export):

- ``corner_uv (m,3,2)`` are atlas UVs in [0,1]^2 with **v pointing up** (OBJ convention, origin at the
  bottom-left of the image).
- The returned image is stored **row 0 = top** (as PNG and PIL store it), so texel ``(i, j)`` has its
  centre at ``u = (j + 0.5) / W``, ``v = 1 - (i + 0.5) / H``. This is exactly the layout Open3D's
  ``bake_*_attr_textures`` produce, and the layout an OBJ ``map_Kd`` expects. glTF puts the UV origin at
  the top-left, so the GLB writer stores ``(u, 1 - v)`` and the same image bytes.

How it is done:

- Open3D's ``open3d.t.geometry.TriangleMesh.bake_vertex_attr_textures(size, {attr}, margin, fill)``
  needs a float32 ``triangle.texture_uvs (m,3,2)`` and float vertex attributes indexed by
  ``triangle.indices``. For every texel centre it finds the closest point of the UV triangles
  (Embree's closest-point query on the triangles laid flat at z = 0) and, when that point is within
  ``margin`` texels, writes the barycentric interpolation of the attribute there (so texels just
  outside a chart get the chart's value at its boundary, clamped); all others get ``fill``. It only
  does square textures, and a ``margin`` of 0 marks almost nothing (it compares a float32 squared
  distance with 0), so uvbake always bakes with ``margin=BAKE_MARGIN_PX`` and ``fill=NaN``: the NaN
  texels are the background, the rest are "covered".
- Every bake goes through :func:`bake_corner_attribute`: vertices split per corner (a vertex on a seam
  has one UV per chart, and Open3D indexes vertex attributes with ``triangle.indices``), the
  attribute given per corner. The checker bakes the UV itself (each texel receives its own UV, clamped
  to the chart in the margin) and computes the checker colour per texel in numpy; vertex colours
  bake ``colors[F]``.
- Open3D makes a closest-point query for every texel, and those far from all triangles are slow, so
  the texture is baked in tiles of :data:`TILE_PX` texels, each with only the triangles near it, and
  tiles far from every triangle are skipped (about 3x faster on a half-empty 2048^2 atlas; same
  texels, up to float32 rounding exactly at the margin).
- Dilation (:func:`dilate`) then pushes every covered texel's colour outward to background texels
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

import numpy as np

from uvbake.errors import InputError

#: Texels within this distance (in texels) of a UV triangle are baked by Open3D itself (clamped to
#: the closest point of the triangle); must be at least sqrt(2) so that bilinear level-0 reads of any
#: point inside a triangle hit covered texels only.
BAKE_MARGIN_PX = 2.0

#: Bake in tiles of this many texels (see :func:`bake_corner_attribute`).
TILE_PX = 128

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


def bake_checker(V, F, corner_uv, *, texture_size_px=1024, square_size=None, texel_size_world=None,
                 colors=((235, 235, 235), (40, 40, 40)), dilate_px=None, background=(0, 0, 0)):
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
    texture_size_px : int
        Width and height of the (square) texture.
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
    sq = _square_size_uv(V, F, corner_uv, size, square_size, texel_size_world)

    uv = bake_corner_attribute(corner_uv, corner_uv, size)  # each texel's own (clamped) UV
    covered = ~np.isnan(uv[..., 0])
    cell = np.floor(np.nan_to_num(uv) / sq).astype(np.int64)
    parity = (cell[..., 0] + cell[..., 1]) & 1
    image = np.clip(np.rint(colors), 0, 255).astype(np.uint8)[parity]
    return _finish(image, covered, dilate_px, background)


def bake_vertex_colors(V, F, corner_uv, vertex_colors, *, texture_size_px=1024, dilate_px=None,
                       background=(0, 0, 0)):
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
    rgb = bake_corner_attribute(corner_uv, colors[F], size)
    covered = ~np.isnan(rgb[..., 0])
    image = np.clip(np.nan_to_num(rgb), 0.0, 1.0) * 255.0
    return _finish(image, covered, dilate_px, background)


def dilate(image, mask, *, iterations):
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


def _check_inputs(V, F, corner_uv, texture_size_px):
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
    if isinstance(texture_size_px, bool) or not isinstance(texture_size_px, (int, np.integer)) \
            or not 1 <= texture_size_px <= 16384:
        raise InputError(f"texture_size_px must be an integer in 1..16384, got {texture_size_px!r}")
    return V, F, corner_uv, int(texture_size_px)


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
        world_per_uv = texel_size_world * size
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
    return math.sqrt(area3 / area2) / size


def bake_corner_attribute(corner_uv, values, size, *, tile_px=None):
    """Bake a per-corner attribute with Open3D: ``(size, size, k)`` float64, NaN where uncovered.

    Parameters
    ----------
    corner_uv : (m,3,2) float array
        Atlas UVs, v up.
    values : (m,3,k) or (m,3) float array
        The attribute at each corner; interpolated barycentrically inside each triangle and clamped
        to the closest point of the closest triangle up to ``BAKE_MARGIN_PX`` texels outside.
    size : int
        Texture width and height.
    tile_px : int, optional
        Bake in tiles of this many texels (default :data:`TILE_PX`), each with only the triangles
        near it; tiles with no triangle near them are skipped.

    Open3D answers a closest-point query for every texel of the texture, and the queries far from
    every triangle are the slow ones (they search the whole scene). Baking only the tiles that the
    UV triangles touch, each with the triangles whose box is within the margin of the tile, gives
    the same texels: a texel within the margin of its closest triangle lies within the margin of that
    triangle's box, so the triangle is in its tile's scene.
    """
    corner_uv = np.asarray(corner_uv, dtype=np.float64)
    values = np.asarray(values, dtype=np.float64)
    squeeze = values.ndim == 2
    values = values.reshape(len(corner_uv), 3, -1)
    k = values.shape[2]
    tile = int(TILE_PX if tile_px is None else tile_px)
    tile = max(1, min(tile, size))
    out = np.full((size, size, k), np.nan)
    # triangle boxes in texel coordinates: x = u * size (columns), y = (1 - v) * size (rows)
    x = corner_uv[..., 0] * size
    y = (1.0 - corner_uv[..., 1]) * size
    pad = BAKE_MARGIN_PX + 1.0
    x0, x1 = x.min(axis=1) - pad, x.max(axis=1) + pad
    y0, y1 = y.min(axis=1) - pad, y.max(axis=1) + pad
    for i0 in range(0, size, tile):
        rows_sel = (y1 >= i0) & (y0 <= i0 + tile)
        if not rows_sel.any():
            continue
        for j0 in range(0, size, tile):
            sel = np.flatnonzero(rows_sel & (x1 >= j0) & (x0 <= j0 + tile))
            if len(sel) == 0:
                continue
            # tile-local UVs: texel (i0 + a, j0 + b) has its centre at ((b+.5)/tile, 1-(a+.5)/tile)
            local = np.empty((len(sel), 3, 2))
            local[..., 0] = (x[sel] - j0) / tile
            local[..., 1] = 1.0 - (y[sel] - i0) / tile
            baked = _bake_open3d(local, values[sel], tile)
            h, w = min(tile, size - i0), min(tile, size - j0)
            out[i0:i0 + h, j0:j0 + w] = baked[:h, :w]
    return out[..., 0] if squeeze else out


def _bake_open3d(corner_uv, values, size):
    """One ``bake_vertex_attr_textures`` call on a mesh with vertices split per corner."""
    import open3d as o3d

    o3c = o3d.core
    m, k = len(corner_uv), values.shape[2]
    mesh = o3d.t.geometry.TriangleMesh()
    mesh.vertex.positions = o3c.Tensor(np.zeros((3 * m, 3), dtype=np.float32))
    mesh.triangle.indices = o3c.Tensor(np.arange(3 * m, dtype=np.int64).reshape(m, 3))
    mesh.triangle.texture_uvs = o3c.Tensor(np.ascontiguousarray(corner_uv, dtype=np.float32))
    mesh.vertex["uvbake_attr"] = o3c.Tensor(np.ascontiguousarray(values.reshape(3 * m, k),
                                                                 dtype=np.float32))
    textures = mesh.bake_vertex_attr_textures(size, {"uvbake_attr"}, margin=BAKE_MARGIN_PX,
                                              fill=float("nan"), update_material=False)
    return textures["uvbake_attr"].numpy().astype(np.float64).reshape(size, size, k)


def _finish(image, covered, dilate_px, background):
    """Dilate covered colours, paint the rest with the background colour, round to uint8."""
    background = np.asarray(background, dtype=np.float64)
    if background.shape != (3,):
        raise InputError(f"background must be an RGB triple, got {background!r}")
    if dilate_px is None:
        dilate_px = DEFAULT_DILATE_PX
    if isinstance(dilate_px, bool) or not isinstance(dilate_px, (int, np.integer)):
        raise InputError(f"dilate_px must be an integer (-1 fills the image), got {dilate_px!r}")
    image = np.clip(np.rint(image), 0, 255).astype(np.uint8)
    image[~covered] = np.clip(np.rint(background), 0, 255).astype(np.uint8)
    return dilate(image, covered, iterations=None if dilate_px < 0 else int(dilate_px))
