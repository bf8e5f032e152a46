"""Peer packers for comparison (never runtime code): xatlas and rectpack as uvbake placers.

    from packers import xatlas_placer, rectpack_placer
    uvbake.pack_charts(uvs, faces, method=xatlas_placer)

xatlas (``xatlas.Atlas.add_uv_mesh`` + ``PackOptions``, bisecting ``texels_per_unit`` until everything
fits one atlas) packs rasterised chart shapes, so charts may nest; uvbake measures the rigid transform
xatlas applied to each chart and re-applies it in float64 (xatlas returns float32), checks the charts
are ``gutter_px`` apart exactly and, if not, repacks with a larger padding. rectpack is MaxRects (best
short side fit, area order, 2^20 integer grid) on uvbake's padded boxes. Measurements:
docs/decisions/pack.md. Failures are RuntimeErrors (a peer failing is not bad input).
"""

from __future__ import annotations

import numpy as np

from uvbake.atlas.distance import min_chart_distance
from uvbake.atlas.maxrects import bisect_scale, min_area_rect, rotation_2d
from uvbake.atlas.pack import place_boxes
from uvbake.errors import InputError
from uvbake.mesh.arrays import rigid_align, signed_areas


class PeerPackerError(RuntimeError):
    """A peer packer failed (missing package, dropped or mirrored charts): not the user's input."""


def _rectpack_boxes(sizes, *, grid=1 << 20):
    import rectpack

    ints = np.ceil(sizes * grid).astype(np.int64)
    p = rectpack.newPacker(mode=rectpack.PackingMode.Offline, bin_algo=rectpack.PackingBin.BFF,
                           pack_algo=rectpack.MaxRectsBssf, sort_algo=rectpack.SORT_AREA, rotation=True)
    for i, (w, h) in enumerate(ints):
        p.add_rect(int(w), int(h), rid=i)
    p.add_bin(grid, grid, count=1)
    p.pack()
    rects = p.rect_list()
    if len(rects) != len(sizes):
        return None
    pos = np.zeros((len(sizes), 2))
    turned = np.zeros(len(sizes), dtype=bool)
    for _, x, y, w, h, rid in rects:
        pos[rid] = (x / grid, y / grid)
        turned[rid] = (int(w), int(h)) != (int(ints[rid, 0]), int(ints[rid, 1]))
    return pos, turned


def rectpack_placer(uvs, faces, N, g):
    """uvbake's boxes packed by rectpack's MaxRects (a placer for ``pack_charts(method=...)``)."""
    try:
        import rectpack  # noqa: F401
    except ImportError:
        raise PeerPackerError("rectpack is not installed; pip install rectpack") from None
    return place_boxes(uvs, faces, N, g, packers=[_rectpack_boxes])


def spread(uvs):
    """The charts moved apart on a grid (each its own cell), shapes kept: xatlas's add_uv_mesh joins charts
    that have a vertex at the same UV (each conformal map pins one at the origin) and packs them on top
    of each other (uvbake's 5 beetle charts became 2, a kit's 600 became 598)."""
    step = 1.25 * max(max(float(np.ptp(u, axis=0).max()) for u in uvs), 1e-12)
    k = int(np.ceil(np.sqrt(len(uvs))))
    return [u - u.min(axis=0) + step * np.array([i % k, i // k]) for i, u in enumerate(uvs)]


def _xatlas_try(pre, faces, N, padding, tpu, brute_force):
    """One xatlas packing of the pre-rotated charts as a single UV mesh; per-chart atlas UVs or None."""
    import xatlas

    offs = np.cumsum([0] + [len(u) for u in pre])
    U = np.ascontiguousarray(np.vstack(pre), dtype=np.float32)
    FF = np.ascontiguousarray(np.vstack([F + o for F, o in zip(faces, offs)]), dtype=np.uint32)
    atlas = xatlas.Atlas()
    atlas.add_uv_mesh(U, FF)      # one mesh: several add_uv_mesh calls scrambled faces in xatlas 0.0.11
    po = xatlas.PackOptions()
    po.resolution = N
    po.padding = int(padding)
    po.texels_per_unit = float(tpu)
    po.bilinear = False
    po.bruteForce = bool(brute_force)
    po.rotate_charts = False            # xatlas's 90-degree turn swaps u and v: a mirror
    po.rotate_charts_to_axis = False    # its axis basis can be left-handed (mirrors); uvbake pre-rotates
    atlas.generate(pack_options=po)
    if atlas.atlas_count != 1:
        return None
    vmap, _, auv = atlas.get_mesh(0)
    atlas_index, _ = atlas.get_mesh_vertex_assignment(0)
    if np.any(atlas_index == np.iinfo(np.uint32).max):
        raise PeerPackerError(f"xatlas left {int(np.sum(atlas_index == np.iinfo(np.uint32).max))} chart vertices "
                         f"unplaced (it drops charts with degenerate triangles)")
    if len(vmap) != len(U) or np.any(atlas_index != 0) or np.any(np.sort(vmap) != np.arange(len(U))):
        return None               # split or merged vertices: not the same charts any more
    Q = np.empty((len(U), 2))
    Q[vmap] = auv
    return [Q[offs[i]:offs[i + 1]] for i in range(len(pre))]


def xatlas_placer(uvs, faces, N, g, brute_force=False):
    """Charts packed by xatlas (a placer for ``pack_charts(method=...)``)."""
    try:
        import xatlas  # noqa: F401
    except ImportError:
        raise PeerPackerError("xatlas is not installed; pip install xatlas") from None
    total = sum(np.abs(signed_areas(uv, F)).sum() for uv, F in zip(uvs, faces))
    if total <= 0:
        raise InputError("all charts have zero area; nothing to pack (check the parameterization)")
    theta0 = np.array([min_area_rect(uv)[0] for uv in uvs])
    pre = spread([uv @ rotation_2d(t).T for uv, t in zip(uvs, theta0)])
    p0 = (g + 1) // 2        # xatlas leaves about 2 * padding + 1 texels between charts
    for padding in range(p0, g + 3):
        s, xuv = bisect_scale(lambda s: _xatlas_try(pre, faces, N, padding, s * N, brute_force),
                               1.0 / np.sqrt(total))
        if s is None:
            raise InputError(f"gutter_px={g} is too large for {len(uvs)} charts in a {N}-texel atlas; "
                             f"reduce gutter_px or increase texture_size_px")
        # re-apply xatlas's placement in float64 at exactly the common scale (xatlas returns float32 and
        # scales each chart by up to about 1 % differently): keep each chart's centroid where xatlas put it
        rotation = np.zeros(len(uvs))
        offset = np.zeros((len(uvs), 2))
        out = []
        for i, (uv, P, Q) in enumerate(zip(uvs, pre, xuv)):
            R, _, _ = rigid_align(P, Q)
            dtheta = float(np.arctan2(R[1, 0], R[0, 0]))
            if abs(dtheta) > 1e-3 or np.sign(signed_areas(Q, faces[i])).sum() * np.sign(
                    signed_areas(P, faces[i])).sum() < 0:
                raise PeerPackerError("xatlas turned or mirrored a chart")
            theta = float(np.arctan2(np.sin(theta0[i]), np.cos(theta0[i])))
            q = s * (uv @ rotation_2d(theta).T)
            off = Q.mean(axis=0) - q.mean(axis=0)
            rotation[i], offset[i] = theta, off
            out.append(q + off)
        lo = np.min([o.min(axis=0) for o in out], axis=0)
        hi = np.max([o.max(axis=0) for o in out], axis=0)
        if np.any(hi - lo > 1.0):
            continue
        shift = np.clip(-lo, 0, None) - np.clip(hi - 1.0, 0, None)   # float32 rounding at the border
        out = [o + shift for o in out]
        offset += shift
        gap = min_chart_distance(out, faces) if len(out) > 1 else np.inf
        if gap * N >= g * (1 + 1e-9):
            return s, rotation, offset, out, gap * N
    raise PeerPackerError(f"xatlas could not keep charts {g} texels apart")
