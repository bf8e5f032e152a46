"""Baking: UV-space checker, vertex colours, gutter dilation safe for bilinear + mip filtering."""

import numpy as np
import pytest

pytest.importorskip("open3d")

from uvbake.atlas.bake import DEFAULT_DILATE_PX, bake_checker, bake_vertex_colors, dilate, dilate_px_for_mips  # noqa: E402
from uvbake.errors import InputError  # noqa: E402

SENTINEL = (255, 0, 255)  # magenta: any mix of it into the grey checker makes R != G


def plane_grid(nx, ny, x0=0.0, y0=0.0, w=1.0, h=1.0):
    """A flat (nx x ny)-cell grid in the z=0 plane: V (k,3), F (m,3)."""
    xs, ys = np.linspace(x0, x0 + w, nx + 1), np.linspace(y0, y0 + h, ny + 1)
    X, Y = np.meshgrid(xs, ys)
    V = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
    idx = np.arange(X.size).reshape(ny + 1, nx + 1)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    return V, np.vstack([np.column_stack([a, b, c]), np.column_stack([a, c, d])]).astype(np.int64)


def two_chart_grid(n=8, scale=0.4):
    """A 2x1 plane cut at x = 1 into two charts, packed at one scale (uv units per world unit).

    Chart 0 (x < 1) goes to u in [0.05, 0.45], v in [0.05, 0.45]; chart 1 (x > 1) to u in
    [0.55, 0.95], v in [0.50, 0.90]. Vertices on x = 1 are shared in 3D and get one UV per chart.
    """
    V, F = plane_grid(2 * n, n, w=2.0, h=1.0)
    P = V[F]
    chart = (P[:, :, 0].mean(axis=1) > 1.0).astype(int)
    offset = np.array([[0.05, 0.05], [0.55 - scale, 0.50]])
    corner_uv = offset[chart][:, None, :] + scale * P[:, :, :2]
    return V, F, corner_uv, chart


def texel_centres(size):
    j = np.arange(size)
    u = (j + 0.5) / size
    v = 1.0 - (j + 0.5) / size
    return u, v


def inside_rect(size, u0, u1, v0, v1, pad_px=0.0):
    u, v = texel_centres(size)
    pad = pad_px / size
    cols = (u > u0 + pad) & (u < u1 - pad)
    rows = (v > v0 + pad) & (v < v1 - pad)
    return rows[:, None] & cols[None, :]


# --------------------------------------------------------------------------------------------------
# checker


def test_checker_period_and_equal_squares_in_both_charts():
    V, F, uv, _ = two_chart_grid()
    size, sq = 256, 1.0 / 16  # 16 texels a square
    img = bake_checker(V, F, uv, texture_size_px=size, square_size=sq)
    assert img.shape == (size, size, 3) and img.dtype == np.uint8
    dark = img[..., 0] == 40
    light = img[..., 0] == 235
    i, j = np.mgrid[0:size, 0:size]
    row_cell = (size - 1 - i) // 16  # v = 1 - (i+0.5)/size  ->  floor(v*16) = (size-1-i)//16
    expected_dark = ((j // 16 + row_cell) % 2) == 1
    for rect in [(0.05, 0.45, 0.05, 0.45), (0.55, 0.95, 0.50, 0.90)]:
        inside = inside_rect(size, *rect)
        assert np.array_equal(dark[inside], expected_dark[inside])
        assert np.all(dark[inside] | light[inside])
    # measure square sizes: runs of one colour along a row, away from the chart borders
    runs = []
    for rect in [(0.05, 0.45, 0.05, 0.45), (0.55, 0.95, 0.50, 0.90)]:
        r = int(round((1 - (rect[2] + rect[3]) / 2) * size))
        c0, c1 = int(np.ceil(rect[0] * size)), int(rect[1] * size)
        row = dark[r, c0:c1].astype(int)
        edges = np.flatnonzero(np.diff(row)) + 1
        runs.append(np.diff(edges))  # interior runs only
    assert len(runs[0]) >= 3 and len(runs[1]) >= 3
    assert set(runs[0].tolist()) == {16} and set(runs[1].tolist()) == {16}


def test_checker_square_size_in_world_units():
    V, F, uv, _ = two_chart_grid(scale=0.4)  # 0.4 uv per world unit
    size = 256
    texel_world = 1.0 / (0.4 * size)
    a = bake_checker(V, F, uv, texture_size_px=size, square_size=0.25, texel_size_world=texel_world)
    b = bake_checker(V, F, uv, texture_size_px=size, square_size=0.25, texel_size_world="auto")
    c = bake_checker(V, F, uv, texture_size_px=size, square_size=0.25 * 0.4)  # the same, in uv units
    assert np.array_equal(a, b) and np.array_equal(a, c)
    # with a texel size, the default square is a round world length near 8 texels (256/32):
    # 8 texels = 8 / (0.4 * 256) = 0.078 world units -> 0.1 (= 10.24 texels)
    rounded = bake_checker(V, F, uv, texture_size_px=size, texel_size_world=texel_world)
    assert np.array_equal(rounded, bake_checker(V, F, uv, texture_size_px=size, square_size=0.1 * 0.4))
    default = bake_checker(V, F, uv, texture_size_px=size)
    assert np.array_equal(default, bake_checker(V, F, uv, texture_size_px=size, square_size=1 / 32))


def test_checker_shows_distortion_as_non_square_cells():
    # the same 3D square mapped with u stretched 2x: squares in 3D become 1:2 rectangles on the model,
    # i.e. the UV-space checker covers half as much surface along x
    V, F = plane_grid(4, 4)
    uv_even = 0.1 + 0.4 * V[F][:, :, :2]
    uv_stretched = uv_even * np.array([2.0, 1.0]) - np.array([0.1, 0.0])
    size = 128
    a = bake_checker(V, F, uv_even, texture_size_px=size, square_size=1 / 16)
    b = bake_checker(V, F, uv_stretched, texture_size_px=size, square_size=1 / 16)
    # count colour changes per unit of surface length along x and y
    def changes(img, rect):
        inside = inside_rect(size, *rect, pad_px=1)
        rows, cols = np.flatnonzero(inside.any(1)), np.flatnonzero(inside.any(0))
        sub = img[rows[0]:rows[-1] + 1, cols[0]:cols[-1] + 1, 0]
        return (np.diff(sub[len(sub) // 2].astype(int)) != 0).sum(), \
            (np.diff(sub[:, sub.shape[1] // 2].astype(int)) != 0).sum()
    ax, ay = changes(a, (0.1, 0.5, 0.1, 0.5))
    bx, by = changes(b, (0.1, 0.9, 0.1, 0.5))
    assert abs(bx - 2 * ax) <= 1 and by == ay


def test_checker_rejects_bad_input():
    V, F, uv, _ = two_chart_grid()
    with pytest.raises(InputError, match="corner_uv"):
        bake_checker(V, F, uv[:, :2], texture_size_px=32)
    with pytest.raises(InputError, match="outside"):
        bake_checker(V, F, uv + 1.0, texture_size_px=32)
    with pytest.raises(InputError, match="square_size"):
        bake_checker(V, F, uv, texture_size_px=32, square_size=0)
    with pytest.raises(InputError, match="texture_size_px"):
        bake_checker(V, F, uv, texture_size_px=0)


# --------------------------------------------------------------------------------------------------
# dilation


def test_dilate_nearest_and_limited_distance():
    img = np.zeros((9, 9, 3), np.uint8)
    mask = np.zeros((9, 9), bool)
    mask[4, 1], img[4, 1] = True, (10, 0, 0)
    mask[4, 7], img[4, 7] = True, (20, 0, 0)
    out = dilate(img, mask, iterations=2)
    assert out[4, 0, 0] == 10 and out[4, 3, 0] == 10 and out[4, 5, 0] == 20 and out[2, 7, 0] == 20
    assert out[4, 4, 0] == 0  # 3 texels from both: beyond 2
    assert out[0, 0, 0] == 0
    full = dilate(img, mask, iterations=None)
    assert np.all(full[..., 0] > 0) and np.all(full[:, :4, 0] == 10) and np.all(full[:, 5:, 0] == 20)
    assert np.array_equal(img, dilate(img, mask, iterations=0))
    assert np.array_equal(img[mask], out[mask])  # covered texels never change


def test_background_after_dilation_is_nearest_chart_colour():
    V, F, uv, _ = two_chart_grid()
    size = 128
    raw = bake_checker(V, F, uv, texture_size_px=size, background=SENTINEL, dilate_px=0)
    covered = ~np.all(raw == SENTINEL, axis=-1)
    assert 0.2 < covered.mean() < 0.5
    full = bake_checker(V, F, uv, texture_size_px=size, background=SENTINEL, dilate_px=-1)
    assert not np.any(np.all(full == SENTINEL, axis=-1))
    assert np.array_equal(full[covered], raw[covered])
    ci, cj = np.nonzero(covered)
    rng = np.random.default_rng(0)
    bi, bj = np.nonzero(~covered)
    for k in rng.choice(len(bi), 300, replace=False):
        d2 = (ci - bi[k]) ** 2 + (cj - bj[k]) ** 2
        nearest = d2 == d2.min()  # brute force; any of the tied nearest texels
        colours = raw[ci[nearest], cj[nearest]]
        assert np.any(np.all(colours == full[bi[k], bj[k]], axis=-1))
    limited = bake_checker(V, F, uv, texture_size_px=size, background=SENTINEL, dilate_px=5)
    from scipy import ndimage
    dist = ndimage.distance_transform_edt(~covered)
    assert np.array_equal(limited[dist <= 5], full[dist <= 5])
    assert np.all(limited[dist > 5] == SENTINEL)


def mip_pyramid(img, levels):
    out = [img.astype(np.float64)]
    for _ in range(levels - 1):
        a = out[-1]
        out.append(0.25 * (a[0::2, 0::2] + a[1::2, 0::2] + a[0::2, 1::2] + a[1::2, 1::2]))
    return out


def bilinear_texels(level_img, uv):
    """The 2x2 texels bilinear filtering reads at each uv (clamp to edge): (k,4,3)."""
    h, w = level_img.shape[:2]
    x = uv[:, 0] * w - 0.5
    y = (1.0 - uv[:, 1]) * h - 0.5
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    texels = []
    for dy in (0, 1):
        for dx in (0, 1):
            xi, yi = np.clip(x0 + dx, 0, w - 1), np.clip(y0 + dy, 0, h - 1)
            texels.append(level_img[yi, xi])
    return np.stack(texels, axis=1)


def uv_samples_inside(corner_uv, per_triangle=40, seed=1):
    rng = np.random.default_rng(seed)
    w = rng.dirichlet(np.ones(3), size=(len(corner_uv), per_triangle))
    pts = np.einsum("mkc,mcd->mkd", w, corner_uv).reshape(-1, 2)
    edges = (0.5 * (corner_uv + np.roll(corner_uv, 1, axis=1))).reshape(-1, 2)
    return np.vstack([pts, corner_uv.reshape(-1, 2), edges])


def sees_background(img, samples, levels=4):
    """Per level: does any bilinear read (with weight or not) touch a texel contaminated by magenta?"""
    hits = []
    for lvl in mip_pyramid(img, levels):
        t = bilinear_texels(lvl, samples)
        hits.append(bool(np.any(np.abs(t[..., 0] - t[..., 1]) > 1e-9)))
    return hits


def test_bilinear_and_mips_never_read_background():
    V, F, uv, chart = two_chart_grid()
    uv = uv.copy()
    uv[chart == 1] += (0.03, 0.08)  # chart 1 up to 0.98: 2.5 texels from the image edge (clamp)
    size = 128
    samples = uv_samples_inside(uv)
    img = bake_checker(V, F, uv, texture_size_px=size, background=SENTINEL)
    assert DEFAULT_DILATE_PX == dilate_px_for_mips(4) == 17
    assert sees_background(img, samples) == [False] * 4
    # the test can see the failure: no dilation leaks at level 1+, a short one at level 3
    none = bake_checker(V, F, uv, texture_size_px=size, background=SENTINEL, dilate_px=0)
    assert any(sees_background(none, samples))
    short = bake_checker(V, F, uv, texture_size_px=size, background=SENTINEL, dilate_px=6)
    assert sees_background(short, samples)[3]


def test_thin_charts_are_covered():
    # slivers thinner than a texel still get texels (Open3D margin), so mips never read background
    V = np.array([[0, 0, 0], [1, 0, 0], [1, 0.01, 0], [0, 0.01, 0]], float)
    F = np.array([[0, 1, 2], [0, 2, 3]])
    uv = np.array([[[0.2, 0.5], [0.8, 0.5], [0.8, 0.502]], [[0.2, 0.5], [0.8, 0.502], [0.2, 0.502]]])
    img = bake_checker(V, F, uv, texture_size_px=64, background=SENTINEL)
    assert sees_background(img, uv_samples_inside(uv)) == [False] * 4


# --------------------------------------------------------------------------------------------------
# vertex colours


def test_vertex_colors_red_and_green_charts():
    Va, Fa = plane_grid(4, 4)
    Vb, Fb = plane_grid(4, 4, x0=1.5)
    V, F = np.vstack([Va, Vb]), np.vstack([Fa, Fb + len(Va)])
    uv = np.concatenate([0.05 + 0.4 * Va[Fa][:, :, :2],
                         np.array([0.55, 0.5]) + 0.4 * (Vb[Fb][:, :, :2] - [1.5, 0])])
    colors = np.vstack([np.tile([1.0, 0, 0], (len(Va), 1)), np.tile([0, 1.0, 0], (len(Vb), 1))])
    size = 64
    img = bake_vertex_colors(V, F, uv, colors, texture_size_px=size, background=(0, 0, 255))
    red = inside_rect(size, 0.05, 0.45, 0.05, 0.45, pad_px=-1.5)  # chart + 1.5 px of its gutter
    green = inside_rect(size, 0.55, 0.95, 0.50, 0.90, pad_px=-1.5)
    assert np.all(img[red] == (255, 0, 0))
    assert np.all(img[green] == (0, 255, 0))
    assert not np.any(np.all(img == (0, 0, 255), axis=-1)[inside_rect(size, 0, 0.6, 0, 0.5)])
    # uint8 colours are accepted as 0..255
    img8 = bake_vertex_colors(V, F, uv, (colors * 255).astype(np.uint8), texture_size_px=size,
                              background=(0, 0, 255))
    assert np.array_equal(img, img8)


def test_vertex_colors_linear_ramp_is_interpolated():
    V, F = plane_grid(3, 3)
    uv = 0.1 + 0.8 * V[F][:, :, :2]
    colors = np.column_stack([V[:, 0], V[:, 1], 1.0 - 0.5 * V[:, 0]])  # linear in position
    size = 128
    img = bake_vertex_colors(V, F, uv, colors, texture_size_px=size).astype(float) / 255.0
    centroid_uv = uv.mean(axis=1)
    j = np.floor(centroid_uv[:, 0] * size).astype(int)
    i = np.floor((1.0 - centroid_uv[:, 1]) * size).astype(int)
    mean_colour = colors[F].mean(axis=1)
    # the texel centre is within half a texel of the centroid; the ramp changes 1/(0.8*128) a texel
    assert np.abs(img[i, j] - mean_colour).max() < 1.0 / (0.8 * size) + 1.0 / 255
    # and every covered texel holds the ramp at its centre (Open3D's barycentric interpolation)
    u, v = texel_centres(size)
    inside = inside_rect(size, 0.1, 0.9, 0.1, 0.9)
    x = ((u - 0.1) / 0.8)[None, :].repeat(size, 0)
    y = ((v - 0.1) / 0.8)[:, None].repeat(size, 1)
    ramp = np.stack([x, y, 1.0 - 0.5 * x], axis=-1)
    assert np.abs(img[inside] - ramp[inside]).max() <= 0.5 / 255 + 1e-6


def test_vertex_colors_rejects_wrong_shape():
    V, F, uv, _ = two_chart_grid()
    with pytest.raises(InputError, match="vertex_colors"):
        bake_vertex_colors(V, F, uv, np.zeros((3, 3)), texture_size_px=16)


def open3d_bake(corner_uv, values, size, margin=2.0):
    """Open3D's own bake (vertices split per corner, NaN outside the margin): the reference."""
    import open3d as o3d

    m, k = len(corner_uv), values.shape[2]
    mesh = o3d.t.geometry.TriangleMesh()
    mesh.vertex.positions = o3d.core.Tensor(np.zeros((3 * m, 3), dtype=np.float32))
    mesh.triangle.indices = o3d.core.Tensor(np.arange(3 * m, dtype=np.int64).reshape(m, 3))
    mesh.triangle.texture_uvs = o3d.core.Tensor(np.ascontiguousarray(corner_uv, dtype=np.float32))
    mesh.vertex["attr"] = o3d.core.Tensor(np.ascontiguousarray(values.reshape(3 * m, k), dtype=np.float32))
    tex = mesh.bake_vertex_attr_textures(size, {"attr"}, margin=margin, fill=float("nan"), update_material=False)
    return tex["attr"].numpy().astype(np.float64).reshape(size, size, k)


def sample_scene_atlas():
    """uvbake's own atlas of a sample scene at 256 px: seams, gutters, chart outlines at any angle."""
    from pathlib import Path

    import uvbake

    res = uvbake.unwrap(Path(__file__).resolve().parent.parent / "sample_scenes" / "multi_component.ply",
                        texture_size_px=256, gutter_px=2)
    return res.V, res.F, res.corner_uv


@pytest.mark.parametrize("case", ["two_charts", "sliver", "scene"])
def test_numpy_bake_matches_open3d_closest_point_bake(case):
    from uvbake.atlas.bake import bake_corner_attribute
    if case == "two_charts":
        V, F, uv, _ = two_chart_grid(n=6)
        size = 96
    elif case == "sliver":
        V = np.array([[0, 0, 0], [1, 0, 0], [1, 0.01, 0], [0, 0.01, 0]], float)
        F = np.array([[0, 1, 2], [0, 2, 3]])
        uv = np.array([[[0.2, 0.5], [0.8, 0.5], [0.8, 0.502]], [[0.2, 0.5], [0.8, 0.502], [0.2, 0.502]]])
        size = 64
    else:
        V, F, uv = sample_scene_atlas()
        size = 256
    values = np.concatenate([uv, V[F][:, :, :1]], axis=-1)  # (m,3,3): u, v, x
    ours = bake_corner_attribute(uv, values, size)
    ref = open3d_bake(uv, values, size)
    a, b = np.isnan(ours[..., 0]), np.isnan(ref[..., 0])
    # coverage may differ only where a texel sits exactly at the margin (Open3D: float32 distances)
    assert (a != b).mean() < 0.002
    both = ~a & ~b
    assert both.sum() > 0.9 * (~b).sum()
    # values: Open3D interpolates in float32 (relative error ~1e-7 of coordinates up to ~size)
    scale = np.nanmax(np.abs(values), axis=(0, 1))
    assert np.all(np.abs(ours[both] - ref[both]) <= 1e-5 * np.maximum(scale, 1.0))
    # inside the triangles the baked UV is the texel centre itself
    if case == "two_charts":
        u, v = texel_centres(size)
        inside = inside_rect(size, 0.05, 0.45, 0.05, 0.45) | inside_rect(size, 0.55, 0.95, 0.50, 0.90)
        assert np.abs(ours[..., 0][inside] - np.broadcast_to(u[None, :], (size, size))[inside]).max() < 1e-12
        assert np.abs(ours[..., 1][inside] - np.broadcast_to(v[:, None], (size, size))[inside]).max() < 1e-12


def test_shared_edges_leave_no_cracks_and_every_covered_texel_is_within_the_margin():
    from uvbake.atlas.bake import BAKE_MARGIN_PX, rasterize
    # a fan of thin triangles around a centre whose edges pass exactly through texel centres
    size = 64
    ang = np.linspace(0, 2 * np.pi, 37)
    ring = 0.5 + 0.4 * np.stack([np.cos(ang), np.sin(ang)], axis=1)
    c = np.full((36, 2), 0.5)
    C = np.stack([c, ring[:-1], ring[1:]], axis=1)          # CCW in uv
    face, (band, tri, k, s) = rasterize(C, size)
    u, v = texel_centres(size)
    U, Vv = np.meshgrid(u, v)
    r = np.hypot(U - 0.5, Vv - 0.5)
    # every texel centre well inside the polygon is inside some triangle, none in the margin list
    inner = r < 0.4 * np.cos(np.pi / 36) - 1e-9
    assert np.all(face[inner] >= 0)
    assert not np.isin(band, np.flatnonzero(inner.ravel())).any()
    # covered outside texels lie within the margin of the polygon, and the closest point is on it
    i, j = np.divmod(band, size)
    p = np.stack([j + 0.5, i + 0.5], axis=1)
    P = np.stack([C[..., 0] * size, (1 - C[..., 1]) * size], axis=-1)
    q = (1 - s)[:, None] * P[tri, k] + s[:, None] * P[tri, (k + 1) % 3]
    assert np.all(np.hypot(*(q - p).T) <= BAKE_MARGIN_PX)
    assert np.all(r.ravel()[band] > 0.4 * np.cos(np.pi / 36) - 1.0 / size)


def test_zero_area_triangles_bake_their_margin_only():
    """A UV triangle collapsed to a segment or a point covers the texels within the margin of it."""
    from uvbake.atlas.bake import BAKE_MARGIN_PX, bake_corner_attribute
    size = 64
    C = np.array([[[0.6, 0.6], [0.8, 0.8], [0.7, 0.7]],      # a segment (the third corner on it)
                  [[0.3, 0.8], [0.3, 0.8], [0.3, 0.8]]])    # a point
    values = np.array([[[0.0], [1.0], [0.5]], [[7.0], [7.0], [7.0]]])
    out = bake_corner_attribute(C, values, size)[..., 0]
    u, v = texel_centres(size)
    U, Vv = np.meshgrid(u, v)
    # brute force, in texels: distance to the segment and to the point
    p = np.stack([U, Vv], axis=-1) * size
    a, b = C[0, 0] * size, C[0, 1] * size
    t = np.clip(((p - a) @ (b - a)) / ((b - a) @ (b - a)), 0, 1)
    d_seg = np.linalg.norm(a + t[..., None] * (b - a) - p, axis=-1)
    d_pt = np.linalg.norm(p - C[1, 0] * size, axis=-1)
    near_seg, near_pt = d_seg <= BAKE_MARGIN_PX - 1e-9, d_pt <= BAKE_MARGIN_PX - 1e-9
    far = (d_seg > BAKE_MARGIN_PX + 1e-9) & (d_pt > BAKE_MARGIN_PX + 1e-9)
    assert near_seg.sum() > 20 and near_pt.sum() >= 12
    assert np.all(np.isnan(out[far])) and not np.any(np.isnan(out[near_seg | near_pt]))
    # the value is the attribute at the closest point: linear along the segment, 7 at the point
    assert np.allclose(out[near_seg], t[near_seg], atol=1e-12)
    assert np.all(out[near_pt] == 7.0)


def test_a_rectangular_texture_keeps_texels_square_and_interpolates_by_texel_centre():
    # a 2:1 plane filling a 256 x 128 texture: u runs over 256 texels, v over 128, so the checker's
    # squares (1/32 of the width: 8 texels) must be 8 texels both ways, and a ramp baked into the same
    # texture must hold its value at every texel centre (u = (j + 0.5) / W, v = 1 - (i + 0.5) / H)
    V, F = plane_grid(8, 4, w=2.0, h=1.0)
    uv = np.column_stack([V[:, 0] / 2.0, V[:, 1]])[F]
    W, H = 256, 128
    img = bake_checker(V, F, uv, texture_size_px=(W, H))
    assert img.shape == (H, W, 3)
    dark = img[..., 0] == 40
    runs_across = np.diff(np.flatnonzero(np.diff(dark[H // 2].astype(int))))
    runs_down = np.diff(np.flatnonzero(np.diff(dark[:, W // 2].astype(int))))
    assert set(runs_across.tolist()) == {8} and set(runs_down.tolist()) == {8}
    colors = np.column_stack([V[:, 0] / 2.0, V[:, 1], np.zeros(len(V))])        # (u, v, 0) at each vertex
    ramp = bake_vertex_colors(V, F, uv, colors, texture_size_px=(W, H)).astype(float) / 255.0
    j, i = np.meshgrid(np.arange(W), np.arange(H))
    assert np.abs(ramp[..., 0] - (j + 0.5) / W).max() <= 0.5 / 255 + 1e-6
    assert np.abs(ramp[..., 1] - (1.0 - (i + 0.5) / H)).max() <= 0.5 / 255 + 1e-6
    with pytest.raises(InputError, match="width, height"):
        bake_checker(V, F, uv, texture_size_px=(256, 0))
