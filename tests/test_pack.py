"""Chart packing: shapes, scale, orientation, gutters, rotation, efficiency, corner UVs, errors.

Geometric checks here are independent of uvbake.atlas.pack: the distance between two charts is computed as
the minimum over the vertices of each of the distance to the other's triangles (0 inside), with a
separate test for crossing edges, which is exact for planar triangle sets.
"""

import numpy as np
import pytest

from uvbake.atlas.distance import min_chart_distance
from uvbake.atlas.pack import corner_uvs, pack_charts
from uvbake.errors import InputError

# ------------------------------------------------------------------------------------------ helpers


def star_chart(rng, n=12, scale=1.0, aspect=1.0):
    """A non-convex star-shaped polygon fanned from its centre: (uv (n+1,2), F (n,3)), counter-clockwise."""
    ang = np.sort(rng.uniform(0, 2 * np.pi, n))
    ang += np.linspace(0, 0.2, n)  # keep them distinct
    r = rng.uniform(0.3, 1.0, n) * scale
    P = np.column_stack([r * np.cos(ang) * aspect, r * np.sin(ang)])
    uv = np.vstack([[0.0, 0.0], P]) + rng.uniform(-5, 5, 2)
    i = np.arange(n)
    F = np.column_stack([np.zeros(n, int), 1 + i, 1 + (i + 1) % n])
    return uv, F


def grid_chart(nx, ny, w, h, theta=0.0, shift=(0.0, 0.0)):
    x, y = np.meshgrid(np.linspace(0, w, nx + 1), np.linspace(0, h, ny + 1), indexing="xy")
    P = np.column_stack([x.ravel(), y.ravel()])
    c, s = np.cos(theta), np.sin(theta)
    P = P @ np.array([[c, -s], [s, c]]).T + np.asarray(shift)
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="xy")
    a = (j * (nx + 1) + i).ravel()
    b, cc, d = a + 1, a + nx + 2, a + nx + 1
    F = np.concatenate([np.column_stack([a, b, cc]), np.column_stack([a, cc, d])])
    return P, F


def chart_set(seed, n=8):
    rng = np.random.default_rng(seed)
    uvs, faces = [], []
    for k in range(n):
        if k % 3 == 2:
            uv, F = grid_chart(4, 2, rng.uniform(0.5, 3), rng.uniform(0.3, 1), theta=rng.uniform(0, 6.3),
                               shift=rng.uniform(-3, 3, 2))
        else:
            uv, F = star_chart(rng, n=int(rng.integers(5, 20)), scale=rng.uniform(0.2, 2),
                               aspect=rng.uniform(0.3, 3))
        uvs.append(uv)
        faces.append(F)
    return uvs, faces


def signed_areas(uv, F):
    a, b, c = uv[F[:, 0]], uv[F[:, 1]], uv[F[:, 2]]
    return 0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))


def point_triangle_distance(P, uv, F):
    """(p,) distance of each point to the union of triangles (0 when inside or on one)."""
    A, B, C = uv[F[:, 0]][None], uv[F[:, 1]][None], uv[F[:, 2]][None]
    p = P[:, None, :]

    def cross(o, a, q):
        return (a[..., 0] - o[..., 0]) * (q[..., 1] - o[..., 1]) - (a[..., 1] - o[..., 1]) * (q[..., 0] - o[..., 0])

    def seg(a, b):
        d = b - a
        t = np.clip(((p - a) * d).sum(-1) / (d * d).sum(-1), 0, 1)
        return np.linalg.norm(p - (a + t[..., None] * d), axis=-1)

    d1, d2, d3 = cross(A, B, p), cross(B, C, p), cross(C, A, p)
    inside = ((d1 >= 0) & (d2 >= 0) & (d3 >= 0)) | ((d1 <= 0) & (d2 <= 0) & (d3 <= 0))
    dist = np.minimum.reduce([seg(A, B), seg(B, C), seg(C, A)])
    return np.where(inside, 0.0, dist).min(axis=1)


def edges_cross(uv1, F1, uv2, F2):
    def edges(uv, F):
        E = np.unique(np.sort(F[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1), axis=0)
        return uv[E[:, 0]], uv[E[:, 1]]
    a0, a1 = (x[:, None] for x in edges(uv1, F1))
    b0, b1 = (x[None] for x in edges(uv2, F2))

    def orient(p, q, r):
        return (q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1]) - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0])
    return bool(np.any((orient(a0, a1, b0) * orient(a0, a1, b1) < 0) & (orient(b0, b1, a0) * orient(b0, b1, a1) < 0)))


def min_gap(uvs, faces):
    """Exact minimum distance between triangles of different charts, independent of uvbake.atlas.pack."""
    best = np.inf
    for i in range(len(uvs)):
        for j in range(i + 1, len(uvs)):
            if edges_cross(uvs[i], faces[i], uvs[j], faces[j]):
                return 0.0
            best = min(best, point_triangle_distance(uvs[i], uvs[j], faces[j]).min(),
                       point_triangle_distance(uvs[j], uvs[i], faces[i]).min())
    return best


def rot(t):
    return np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])

# -------------------------------------------------------------------------------------------- tests


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_shapes_scale_orientation_and_bounds(seed):
    uvs, faces = chart_set(seed)
    res = pack_charts(uvs, faces, texture_size_px=512, gutter_px=3)
    s = res.scale
    assert res.texel_size_world == pytest.approx(1.0 / (s * 512), rel=1e-12)
    assert res.n_charts == len(uvs) and res.method in ("shape", "maxrects")
    for i, (uv, F, q) in enumerate(zip(uvs, faces, res.uv)):
        assert q.shape == uv.shape
        assert q.min() >= 0.0 and q.max() <= 1.0
        # same shape at the common scale: all pairwise distances scaled by `scale`
        d0 = np.linalg.norm(uv[:, None] - uv[None], axis=-1)
        d1 = np.linalg.norm(q[:, None] - q[None], axis=-1)
        np.testing.assert_allclose(d1, s * d0, rtol=1e-10, atol=1e-12)
        # never mirrored: every triangle keeps its orientation, area scaled by s^2
        np.testing.assert_allclose(signed_areas(q, F), s * s * signed_areas(uv, F), rtol=1e-8, atol=1e-15)
        # the stored transform reproduces the UVs
        np.testing.assert_allclose(q, s * uv @ rot(res.rotation[i]).T + res.offset[i], atol=1e-12)
    d = res.to_dict()
    assert d["method"] == res.method and d["n_charts"] == len(uvs) and "uv" not in d


@pytest.mark.parametrize("seed,gutter,size", [(0, 0, 256), (1, 2, 1024), (2, 4, 1024), (3, 8, 512), (4, 16, 2048)])
def test_gutter_is_kept(seed, gutter, size):
    uvs, faces = chart_set(seed, n=10)
    res = pack_charts(uvs, faces, texture_size_px=size, gutter_px=gutter)
    gap = min_gap(res.uv, faces)
    assert gap >= gutter / size * (1 - 1e-9)
    if gutter:                                    # and the packing is tight: some pair is close to the gutter
        assert gap <= 3 * gutter / size
    assert min_chart_distance(res.uv, faces) == pytest.approx(gap, rel=1e-9, abs=1e-15)
    lo = min(q.min() for q in res.uv)
    hi = max(q.max() for q in res.uv)
    assert lo >= gutter / size / 2 * (1 - 1e-9) and hi <= 1 - gutter / size / 2 * (1 - 1e-9)


def test_gutter_detects_overlap_and_nesting():
    sq, F = grid_chart(2, 2, 1.0, 1.0)
    assert min_chart_distance([sq, sq + [0.5, 0.5]], [F, F]) == 0.0          # overlapping
    big, Fb = grid_chart(4, 4, 4.0, 4.0)
    assert min_chart_distance([big, sq * 0.5 + 1.2], [Fb, F]) == 0.0          # inside another chart
    assert min_chart_distance([sq, sq + [1.5, 0.0]], [F, F]) == pytest.approx(0.5)


def test_elongated_chart_rotated_37_degrees_comes_out_axis_aligned():
    uv, F = grid_chart(10, 2, 5.0, 1.0, theta=np.radians(37.0), shift=(2.0, -1.0))
    res = pack_charts([uv], [F], texture_size_px=1024, gutter_px=4, method="maxrects")   # boxes: the MAR
    q = res.uv[0]
    bbox = np.ptp(q, axis=0).prod()
    assert bbox == pytest.approx(res.scale ** 2 * 5.0 * 1.0, rel=1e-9)   # the minimum-area rectangle
    assert np.ptp(q, axis=0)[0] > np.ptp(q, axis=0)[1]                    # long side along u, fits the square


def test_rotation_gives_minimum_area_rectangle_of_irregular_chart():
    rng = np.random.default_rng(7)
    uv, F = star_chart(rng, n=15, aspect=4.0)
    uv = uv @ rot(0.4).T
    res = pack_charts([uv], [F], texture_size_px=1024, gutter_px=0, method="maxrects")
    box = np.ptp(res.uv[0], axis=0).prod() / res.scale ** 2
    angles = np.linspace(0, np.pi / 2, 20001)       # brute force over rotations
    areas = [np.ptp(uv @ rot(a).T, axis=0).prod() for a in angles[::20]]
    k = int(np.argmin(areas)) * 20
    fine = angles[max(k - 20, 0):k + 21]
    best = min(np.ptp(uv @ rot(a).T, axis=0).prod() for a in fine)
    assert box <= best * (1 + 1e-9)


def test_rotate_false_only_translates():
    uvs, faces = chart_set(8, n=5)
    res = pack_charts(uvs, faces, texture_size_px=512, gutter_px=2, rotate=False)
    assert np.all(res.rotation == 0)
    for uv, q in zip(uvs, res.uv):
        d = q - res.scale * uv
        np.testing.assert_allclose(d, d[:1].repeat(len(d), 0), atol=1e-12)
    assert min_gap(res.uv, faces) >= 2 / 512 * (1 - 1e-9)


def test_efficiency_matches_definition():
    uvs, faces = chart_set(9)
    N = 1024
    res = pack_charts(uvs, faces, texture_size_px=N, gutter_px=4)
    texels = sum(np.abs(signed_areas(q * N, F)).sum() for q, F in zip(res.uv, faces))
    assert res.efficiency == pytest.approx(texels / N ** 2, rel=1e-9)
    assert res.efficiency == pytest.approx(res.scale ** 2 * sum(np.abs(signed_areas(u, F)).sum()
                                                               for u, F in zip(uvs, faces)), rel=1e-12)


@pytest.mark.parametrize("N,g", [(1024, 4), (256, 2), (2048, 0)])
def test_single_square_chart_fills_the_atlas_but_the_gutter(N, g):
    uv, F = grid_chart(3, 3, 2.0, 2.0, theta=0.3)
    res = pack_charts([uv], [F], texture_size_px=N, gutter_px=g)
    ideal = ((N - g) / N) ** 2                         # half a gutter on each side
    assert ideal * (1 - 2.5e-3) <= res.efficiency <= ideal * (1 + 1e-9)


def test_corner_uvs_puts_chart_uvs_at_their_faces():
    uvs, faces = chart_set(10, n=4)
    n_faces = sum(len(F) for F in faces)
    perm = np.random.default_rng(0).permutation(n_faces)
    face_index = np.split(perm, np.cumsum([len(F) for F in faces])[:-1])
    res = pack_charts(uvs, faces, texture_size_px=512, gutter_px=2)
    C = corner_uvs(res, faces, face_index, n_faces)
    assert C.shape == (n_faces, 3, 2) and np.isfinite(C).all()
    for q, F, idx in zip(res.uv, faces, face_index):
        np.testing.assert_array_equal(C[idx], q[F])
    with pytest.raises(InputError, match="face"):
        corner_uvs(res, faces, face_index, n_faces + 1)      # a face that no chart covers


def _square():
    return grid_chart(1, 1, 1.0, 1.0)


@pytest.mark.parametrize("kwargs,name", [
    (dict(texture_size_px=8), "texture_size_px"),
    (dict(texture_size_px=20000), "texture_size_px"),
    (dict(texture_size_px=512.0), "texture_size_px"),
    (dict(texture_size_px=True), "texture_size_px"),
    (dict(gutter_px=-1), "gutter_px"),
    (dict(gutter_px=2.5), "gutter_px"),
    (dict(gutter_px=1024, texture_size_px=1024), "gutter_px"),
    (dict(gutter_px=400, texture_size_px=1024), "gutter_px"),     # 9 charts: the gutters alone do not fit
    (dict(method="skyline"), "method"),
    (dict(rotate="yes"), "rotate"),
])
def test_bad_options_raise_input_error_naming_the_option(kwargs, name):
    uv, F = _square()
    uvs = [uv + [2 * k, 0] for k in range(9)]
    with pytest.raises(InputError, match=name) as e:
        pack_charts(uvs, [F] * 9, **kwargs)
    assert "\n" not in str(e.value)


def test_bad_charts_raise_input_error():
    uv, F = _square()
    with pytest.raises(InputError, match="empty"):
        pack_charts([], [])
    bad = uv.copy()
    bad[1, 0] = np.nan
    with pytest.raises(InputError, match="NaN"):
        pack_charts([uv, bad], [F, F])
    with pytest.raises(InputError, match="face"):
        pack_charts([uv], [F, F])
    with pytest.raises(InputError, match="face indices"):
        pack_charts([uv], [F + 10])
    with pytest.raises(InputError, match="cannot fit"):     # gutters leave the charts under a texel
        pack_charts([uv, uv, uv], [F, F, F], texture_size_px=64, gutter_px=31)


def test_a_full_resolution_layout_past_the_border_margin_falls_back_to_one_that_keeps_the_gutter(monkeypatch):
    import dataclasses

    import uvbake.atlas.fit as fit

    uvs, faces = chart_set(5, n=70)                      # 64 charts and more: fit_scale's full-resolution trials
    real = fit.fit_scale
    overran = []

    def past_the_border(packer, W, H, g, **kw):           # the search's layout, 2 % past the atlas's side
        p = real(packer, W, H, g, **kw)
        lo, hi = fit._layout_box(packer, p)
        k = 1.02 * W / (hi - lo).max()
        q = dataclasses.replace(p, density=p.density * k, offset=(p.offset - lo) * k)
        overran.append(fit.scale_to_border(packer, q, W, H, g) is None)
        return q

    monkeypatch.setattr(fit, "fit_scale", past_the_border)
    size, gutter = 1024, 4
    res = pack_charts(uvs, faces, texture_size_px=size, gutter_px=gutter, method="shape")
    assert overran == [True]
    assert min_gap(res.uv, faces) >= gutter / size * (1 - 1e-9)
    lo = min(q.min() for q in res.uv)
    hi = max(q.max() for q in res.uv)
    assert lo >= gutter / size / 2 * (1 - 1e-9) and hi <= 1 - gutter / size / 2 * (1 - 1e-9)
    assert res.efficiency > 0.3
