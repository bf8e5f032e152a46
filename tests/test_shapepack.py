"""Shape packing (uvbake.atlas.shapepack via pack_charts(method="shape")): conservative footprints, exact
gutters on the raster and on the geometry, no mirroring, texel density across assets, non-square atlases,
mip-level gutters, determinism.

Distances are checked with the independent helpers of test_pack (vertex-to-triangle distances and edge
crossings), never with uvbake's own min_chart_distance alone.
"""

import numpy as np
import pytest

from uvbake.atlas import footprint as footprint_module
from uvbake.atlas import shapepack
from uvbake.atlas.distance import boundary_halfedges
from uvbake.atlas.footprint import footprint, footprints
from uvbake.atlas.pack import pack_charts
from uvbake.atlas.shapepack import gutter_element, mip_gutter_px
from uvbake.errors import InputError

from test_pack import edges_cross, grid_chart, min_gap, signed_areas, star_chart


def holed_chart(n=24, r0=0.4, r1=1.0):
    """An annulus (a chart with a hole), counter-clockwise triangles."""
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    P = np.vstack([np.column_stack([r0 * np.cos(t), r0 * np.sin(t)]), np.column_stack([r1 * np.cos(t), r1 * np.sin(t)])])
    i = np.arange(n)
    j = (i + 1) % n
    F = np.concatenate([np.column_stack([i, n + i, n + j]), np.column_stack([i, n + j, j])])
    return P, F


def mixed_charts(seed, n=9):
    rng = np.random.default_rng(seed)
    uvs, faces = [], []
    for k in range(n):
        if k % 3 == 0:
            uv, F = holed_chart(r0=rng.uniform(0.3, 0.7), r1=1.0)
            uv = uv * rng.uniform(0.5, 1.5)
        elif k % 3 == 1:
            uv, F = star_chart(rng, n=int(rng.integers(6, 16)), scale=rng.uniform(0.4, 1.5), aspect=rng.uniform(0.5, 2))
        else:
            uv, F = grid_chart(5, 2, rng.uniform(1, 3), rng.uniform(0.3, 1), theta=rng.uniform(0, 6))
        uvs.append(uv)
        faces.append(F)
    return uvs, faces


def texel_density(uv, F, world_area):
    """Measured texels per world unit: sqrt(texel area / world area)."""
    return np.sqrt(np.abs(signed_areas(uv, F)).sum() / world_area)


def ribbon(length=40.0, width=1.0, nu=200, nv=4):
    """A long strip (one chart), bent into a gentle arc as a flattened twisted ribbon is."""
    u, v = np.meshgrid(np.linspace(0, length, nu + 1), np.linspace(0, width, nv + 1), indexing="ij")
    R = 40 * length                                  # arc radius: sagitta length^2 / (8 R) = length / 320
    a = u / R
    P = np.column_stack([((R + v) * np.sin(a)).ravel(), (R - (R + v) * np.cos(a)).ravel()])
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    p = (i * (nv + 1) + j).ravel()
    F = np.concatenate([np.column_stack([p, p + nv + 1, p + nv + 2]), np.column_stack([p, p + nv + 2, p + 1])])
    if signed_areas(P, F).sum() < 0:
        F = F[:, ::-1]
    return P, F


# ------------------------------------------------------------------------------------------ raster


def _cells_touched_by_samples(q, F, k=24):
    """Texels containing dense samples of every triangle (barycentric grid incl. edges and corners)."""
    a, b = np.meshgrid(np.arange(k + 1), np.arange(k + 1))
    m = a + b <= k
    w = np.column_stack([a[m], b[m], k - a[m] - b[m]]) / k
    pts = np.einsum("sc,tcd->tsd", w, q[F]).reshape(-1, 2)
    return np.floor(pts).astype(int)


@pytest.mark.parametrize("seed", range(4))
def test_footprint_covers_every_texel_a_triangle_touches(seed):
    rng = np.random.default_rng(seed)
    uv, F = star_chart(rng, n=14, scale=30.0, aspect=1.7) if seed % 2 else holed_chart(n=30, r0=10, r1=25)
    q = uv - uv.min(axis=0) + 2e-7
    fp = footprint(q, F, boundary_halfedges(F), np.zeros(0, int))
    c = _cells_touched_by_samples(q, F)
    assert fp[c[:, 1], c[:, 0]].all()
    # and it is not a bounding box: the star's concavities / the annulus's hole stay free
    assert fp.mean() < 0.9
    # tight: no texel farther than one texel diagonal from the chart is set
    rows, cols = np.nonzero(fp)
    centres = np.column_stack([cols + 0.5, rows + 0.5])
    from test_pack import point_triangle_distance
    d = np.concatenate([point_triangle_distance(centres[k:k + 2000], q, F) for k in range(0, len(centres), 2000)])
    assert d.max() <= np.sqrt(0.5) + 1e-6


def test_quarter_turned_footprint_is_the_turned_charts_footprint():
    rng = np.random.default_rng(3)
    uv, F = star_chart(rng, n=11, scale=17.3, aspect=2.3)
    q = uv - uv.min(axis=0) + 2e-7
    B = boundary_halfedges(F)
    none = np.zeros(0, int)
    fp = footprint(q, F, B, none)
    h = fp.shape[0]
    turned = np.column_stack([h - q[:, 1], q[:, 0]])       # what ShapePacker does for a quarter turn
    direct = footprint(turned, F, B, none)
    np.testing.assert_array_equal(np.rot90(fp, -1), direct)


def _squares_meeting_triangles(q, F, h, w):
    """Brute force: texel (r, c) whose closed unit square meets a triangle (separating axes: the
    square's two, each triangle's three edge normals)."""
    T = q[F]
    r, c = np.mgrid[0:h, 0:w]
    lo = np.column_stack([c.ravel(), r.ravel()]).astype(float)
    meet = np.ones((len(lo), len(T)), bool)
    for ax in range(2):
        meet &= (lo[:, ax, None] <= T[:, :, ax].max(axis=1)[None]) & (lo[:, ax, None] + 1 >= T[:, :, ax].min(axis=1)[None])
    corners = lo[:, None, :] + np.array([[0, 0], [1, 0], [0, 1], [1, 1]])[None]
    for k in range(3):
        e = T[:, (k + 1) % 3] - T[:, k]
        nrm = np.column_stack([-e[:, 1], e[:, 0]])
        pt = np.einsum("tcd,td->tc", T, nrm)
        ps = np.einsum("scd,td->stc", corners, nrm)
        meet &= (ps.min(axis=2) <= pt.max(axis=1)[None]) & (ps.max(axis=2) >= pt.min(axis=1)[None])
    return meet.any(axis=1).reshape(h, w)


def test_charts_rasterised_together_get_exactly_the_texels_their_triangles_meet(monkeypatch):
    """footprints() lays the charts' canvases end to end; each chart must get exactly the texels whose
    square meets one of its triangles (brute force), in one group or several, folded charts included
    (coordinates are random reals: no square is within 1e-6 of touching a triangle by chance)."""
    rng = np.random.default_rng(7)
    uvs, faces = mixed_charts(11, n=12)
    qs, Bs, flips = [], [], []
    for k, (uv, F) in enumerate(zip(uvs, faces)):
        q = uv * rng.uniform(3, 20)
        if k % 4 == 1:                               # a fold: one vertex pulled across its fan
            q[F[0, 0]] += 0.8 * (q[F[0, 1]] - q[F[0, 0]]) + 0.8 * (q[F[0, 2]] - q[F[0, 0]])
        qs.append(q - q.min(axis=0) + 2e-7)
        Bs.append(boundary_halfedges(F))
        sa = signed_areas(qs[-1], F)
        flips.append(np.flatnonzero(sa * np.sign(sa.sum()) <= 0))
    assert sum(len(f) > 0 for f in flips) >= 2
    for cells in (1 << 22, 300):                      # one group; several (a chart alone when bigger)
        monkeypatch.setattr(footprint_module, "_BATCH_CELLS", cells)
        together = footprints(qs, faces, Bs, flips)
        assert len(together) == len(qs)
        for q, F, fp in zip(qs, faces, together):
            np.testing.assert_array_equal(fp, _squares_meeting_triangles(q, F, *fp.shape))


@pytest.mark.parametrize("g", [0, 1, 2, 3, 4, 7])
def test_gutter_element_is_texels_closer_than_the_gutter(g):
    el = gutter_element(g)
    r = np.arange(-g, g + 1)
    # distance between closed unit squares offset by (di, dj), brute force over their corners / edges
    di, dj = np.meshgrid(r, r, indexing="ij")
    d = np.hypot(np.maximum(np.abs(di) - 1, 0), np.maximum(np.abs(dj) - 1, 0))
    np.testing.assert_array_equal(el, (d < g) | ((di == 0) & (dj == 0)))


# --------------------------------------------------------------------------------------- packing


@pytest.mark.parametrize("seed,g,size", [(0, 4, 512), (1, 2, 256), (2, 8, 1024), (3, 0, 256), (4, 1, 512)])
def test_no_two_charts_closer_than_the_gutter(seed, g, size):
    uvs, faces = mixed_charts(seed)
    res = pack_charts(uvs, faces, texture_size_px=size, gutter_px=g, method="shape")
    assert res.method == "shape"
    Q = [q * size for q in res.uv]
    # exact geometry: the smallest vertex-triangle distance between charts, and no crossing edges
    gap = min_gap(Q, faces)
    assert gap >= g * (1 - 1e-9)
    for i in range(len(Q)):
        for j in range(i + 1, len(Q)):
            assert not edges_cross(Q[i], faces[i], Q[j], faces[j])
    # (layouts are scaled by non-integer factors to fill the atlas, so the guarantee is the exact one above,
    # as for boxes, not one on touched texels)
    # half a gutter from the border, inside [0, 1]
    lo, hi = min(q.min() for q in Q), max(q.max() for q in Q)
    assert lo >= g / 2 * (1 - 1e-9) and hi <= size - g / 2 * (1 - 1e-9)


def test_rotations_never_mirror():
    uvs, faces = mixed_charts(7, n=8)
    uvs[1] = uvs[1] * [1.0, -1.0]               # a clockwise chart must stay clockwise
    res = pack_charts(uvs, faces, texture_size_px=512, gutter_px=2, method="shape")
    assert np.any(np.abs(np.mod(res.rotation, np.pi / 2)) > 1e-6) or np.any(res.rotation != 0)
    for uv, F, q in zip(uvs, faces, res.uv):
        a0, a1 = signed_areas(uv, F), signed_areas(q, F)
        np.testing.assert_array_equal(np.sign(a1), np.sign(a0))
        np.testing.assert_allclose(a1, res.scale ** 2 * a0, rtol=1e-8, atol=1e-15)


def test_packing_is_deterministic():
    uvs, faces = mixed_charts(11)
    a = pack_charts(uvs, faces, texture_size_px=512, gutter_px=3, method="shape")
    b = pack_charts([u.copy() for u in uvs], [f.copy() for f in faces], texture_size_px=512, gutter_px=3,
                    method="shape")
    assert all(x.tobytes() == y.tobytes() for x, y in zip(a.uv, b.uv))
    assert a.rotation.tobytes() == b.rotation.tobytes() and a.scale == b.scale


def test_ribbon_packs_above_60_percent_in_a_matching_non_square_atlas():
    uv, F = ribbon()
    sq = pack_charts([uv], [F], texture_size_px=1024, gutter_px=4, method="shape")
    assert sq.efficiency < 0.1                   # a 40:1 strip in a square: mostly empty
    res = pack_charts([uv], [F], texture_size_px=(4096, 128), gutter_px=4, method="shape")
    assert (res.width_px, res.height_px) == (4096, 128)
    texels = np.abs(signed_areas(res.uv[0] * [4096, 128], F)).sum()
    assert texels / (4096 * 128) == pytest.approx(res.efficiency, rel=1e-9)
    assert res.efficiency > 0.60
    q = res.uv[0] * [4096, 128]
    assert q.min() >= 2 - 1e-9 and q[:, 0].max() <= 4094 + 1e-9 and q[:, 1].max() <= 126 + 1e-9


def test_same_texel_density_across_assets_within_one_percent():
    a_uvs, a_faces = mixed_charts(1, n=6)
    rng = np.random.default_rng(5)
    b_uvs, b_faces = [], []
    for _ in range(4):
        uv, F = star_chart(rng, n=9, scale=rng.uniform(0.5, 3.0))
        b_uvs.append(uv * 3.7)
        b_faces.append(F)
    d = 37.0
    ra = pack_charts(a_uvs, a_faces, texture_size_px=512, gutter_px=2, texel_density=d, method="shape")
    rb = pack_charts(b_uvs, b_faces, texture_size_px=None, gutter_px=2, texel_density=d)
    for r, uvs, faces in ((ra, a_uvs, a_faces), (rb, b_uvs, b_faces)):
        world = sum(np.abs(signed_areas(u, F)).sum() for u, F in zip(uvs, faces))
        texels = sum(np.abs(signed_areas(q * [r.width_px, r.height_px], F)).sum() for q, F in zip(r.uv, faces))
        assert np.sqrt(texels / world) == pytest.approx(d, rel=0.01)
        assert r.texel_density == d
    assert rb.width_px == rb.height_px and rb.width_px % 4 == 0       # grown square atlas
    assert min_gap([q * rb.width_px for q in rb.uv], b_faces) >= 2 * (1 - 1e-9)


def test_texel_density_that_cannot_fit_says_so():
    uvs, faces = mixed_charts(2, n=4)
    with pytest.raises(InputError, match="cannot fit texture_size_px=64 at texel_density") as e:
        pack_charts(uvs, faces, texture_size_px=64, texel_density=500.0)
    assert "\n" not in str(e.value)


@pytest.mark.parametrize("L,g", [(1, 6), (2, 10), (3, 19), (4, 36)])
def test_mip_levels_set_the_gutter(L, g):
    assert mip_gutter_px(L) == g
    uvs, faces = mixed_charts(3, n=4)
    res = pack_charts(uvs, faces, texture_size_px=1024, mip_levels=L, method="shape")
    assert res.gutter_px == g
    assert min_gap([q * 1024 for q in res.uv], faces) >= g * (1 - 1e-9)


def _bleeds(levels, gap, rng, trials=40, size=96):
    """Two 30-texel squares `gap` texels apart (side by side or corner to corner, random sub-texel
    offsets), baked as uvbake bakes (texels within BAKE_MARGIN_PX of a chart take the nearest chart's
    colour, then the rest is dilated from the nearest covered texel), box-filtered mips, bilinear
    reads at points of A on its sides facing B: does a read with non-zero weight see B's colour?"""
    from scipy import ndimage

    from uvbake.atlas.bake import BAKE_MARGIN_PX, dilate

    c = np.arange(size) + 0.5
    X, Y = np.meshgrid(c, c, indexing="xy")

    def dist(lo, hi):
        dx = np.maximum(np.maximum(lo[0] - X, X - hi[0]), 0)
        dy = np.maximum(np.maximum(lo[1] - Y, Y - hi[1]), 0)
        return np.hypot(dx, dy)

    s = np.linspace(0, 1, 97)
    for t in range(trials):
        a_lo = rng.uniform(0, 1, 2) + 8
        a_hi = a_lo + 30
        step = gap / np.sqrt(2)
        b_lo = a_hi + (np.array([step, step]) if t % 2 else np.array([gap, -15.0]))
        da, db = dist(a_lo, a_hi), dist(b_lo, b_lo + 30)
        covered = (da <= BAKE_MARGIN_PX) | (db <= BAKE_MARGIN_PX)
        level = dilate(np.where(covered & (da <= db), 1.0, 0.0), covered, iterations=None)   # nearest chart
        P = np.concatenate([np.column_stack([np.full_like(s, a_hi[0]), a_lo[1] + 30 * s]),
                            np.column_stack([a_lo[0] + 30 * s, np.full_like(s, a_hi[1])])])
        for k in range(levels):
            S = 2 ** k
            u = P / S - 0.5
            i0 = np.floor(u).astype(int)
            f = u - i0
            for di in (0, 1):
                for dj in (0, 1):
                    w = (f[:, 0] if di else 1 - f[:, 0]) * (f[:, 1] if dj else 1 - f[:, 1])
                    v = level[np.clip(i0[:, 1] + dj, 0, len(level) - 1), np.clip(i0[:, 0] + di, 0, len(level) - 1)]
                    if np.any((w > 0) & (v < 1.0)):
                        return True
            level = ndimage.uniform_filter(level, 2, origin=(-1, -1))[::2, ::2]      # the next 2x box level
    return False


@pytest.mark.parametrize("levels", [1, 2, 3])
def test_mip_gutter_keeps_bilinear_reads_on_the_charts_own_dilated_colour(levels):
    assert not _bleeds(levels, mip_gutter_px(levels), np.random.default_rng(levels))
    # the shorter rule (a gutter of 2^k texels for level k) lets the other chart's colour in
    assert _bleeds(levels, 2 ** (levels - 1), np.random.default_rng(levels))


@pytest.mark.parametrize("kwargs,match", [
    (dict(mip_levels=2, gutter_px=8), "mip_levels"),
    (dict(mip_levels=4, texture_size_px=1004), "multiple of"),
    (dict(mip_levels=9), "mip_levels"),
    (dict(mip_levels=0), "mip_levels"),
    (dict(texel_density=-1.0), "texel_density"),
    (dict(texel_density="big"), "texel_density"),
    (dict(texture_size_px=None), "texel_density"),
    (dict(texture_size_px=(512, 8)), "texture_size_px"),
    (dict(texture_size_px=(512, 256), method="maxrects"), "method"),
])
def test_bad_options_name_the_option(kwargs, match):
    uvs, faces = mixed_charts(4, n=3)
    with pytest.raises(InputError, match=match) as e:
        pack_charts(uvs, faces, **kwargs)
    assert "\n" not in str(e.value)


def test_ribbon_packs_above_60_percent_in_a_growing_free_aspect_atlas():
    uv, F = ribbon()
    world = np.abs(signed_areas(uv, F)).sum()
    d = np.sqrt(512 ** 2 / world)                 # about a quarter megatexel of chart
    sq = pack_charts([uv], [F], texture_size_px=None, texel_density=d, gutter_px=4)
    res = pack_charts([uv], [F], texture_size_px=None, texel_density=d, gutter_px=4, aspect="free")
    assert sq.efficiency < 0.1 and sq.width_px == sq.height_px
    assert res.width_px > 8 * res.height_px       # a long atlas for a long chart
    texels = np.abs(signed_areas(res.uv[0] * [res.width_px, res.height_px], F)).sum()
    assert texels / (res.width_px * res.height_px) == pytest.approx(res.efficiency, rel=1e-9)
    assert np.sqrt(texels / world) == pytest.approx(d, rel=0.01)
    assert res.efficiency > 0.60


def test_convex_hull_matches_qhull_up_to_rounding():
    """The hand-written hull: every point inside or on it (within rounding), ccw, and the same
    vertex set as Qhull's apart from points within rounding of an edge's line (dense circles)."""
    from scipy.spatial import ConvexHull

    from uvbake.atlas.maxrects import convex_hull_2d

    rng = np.random.default_rng(5)
    for k in range(120):
        n = int(rng.integers(3, 800))
        P = rng.normal(size=(n, 2)) * [1.0, rng.uniform(0.01, 3.0)]
        if k % 3 == 0:
            t = rng.uniform(0, 2 * np.pi, n)
            P = np.column_stack([np.cos(t), np.sin(t)])
        if k % 4 == 0:
            P = np.round(P * 4) / 4                     # duplicates and collinear runs
        h = convex_hull_2d(P)
        H = P[h]
        E = np.roll(H, -1, axis=0) - H
        assert 0.5 * np.sum(H[:, 0] * np.roll(H[:, 1], -1) - np.roll(H[:, 0], -1) * H[:, 1]) > 0   # ccw
        cross = E[:, None, 0] * (P[None, :, 1] - H[:, None, 1]) - E[:, None, 1] * (P[None, :, 0] - H[:, None, 0])
        scale = np.ptp(P, axis=0).max() ** 2
        assert cross.min() >= -1e-12 * scale           # nothing outside any edge
        q = ConvexHull(P)
        assert abs(q.volume - 0.5 * np.sum(H[:, 0] * np.roll(H[:, 1], -1) - np.roll(H[:, 0], -1) * H[:, 1])) \
            <= 1e-12 * scale
        if k % 3:                                       # no near-collinear points: the same vertices
            assert set(map(tuple, H)) == set(map(tuple, P[q.vertices]))


def test_hulls_of_many_sets_at_once_are_those_of_each_set_alone():
    """convex_hulls_2d runs the quickhull rounds of every set together (each hull a block of one list):
    the same indices in the same order as convex_hull_2d set by set, whatever the mix of sizes, scales
    (tolerances are per set) and degenerate sets; min_area_rects likewise equals min_area_rect."""
    from uvbake.atlas.maxrects import convex_hull_2d, convex_hulls_2d, min_area_rect, min_area_rects

    rng = np.random.default_rng(8)
    sets = []
    for k in range(40):
        n = int(rng.integers(3, 300))
        P = rng.normal(size=(n, 2)) * [1.0, rng.uniform(0.01, 3.0)] * 10.0 ** rng.integers(-6, 4)
        if k % 3 == 0:
            t = rng.uniform(0, 2 * np.pi, n)
            P = np.column_stack([np.cos(t), np.sin(t)])
        if k % 4 == 0:
            P = np.round(P * 4) / 4
        sets.append(P)
    sets += [np.zeros((4, 2)), np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0], [3.0, 3.0]]),
             np.array([[1.0, 2.0]] * 3)]
    rng.shuffle(sets)
    for h, P in zip(convex_hulls_2d(sets), sets):
        np.testing.assert_array_equal(h, convex_hull_2d(P))
    sets += [np.array([[0.0, 0.0], [2.0, 1.0]]), np.array([[5.0, 5.0]])]     # under 3 points: the points
    np.testing.assert_array_equal(min_area_rects(sets), np.array([min_area_rect(P) for P in sets]))


def test_rectangles_of_hulls_of_one_size_are_found_together_bit_for_bit(monkeypatch):
    """min_area_rects measures hulls of one size in one batch (a foliage mesh's thousands of cards):
    every rectangle is bit for bit min_area_rect's, for squares at any angle, regular and random
    polygons, tiny and huge scales, collinear and coincident points; only the hulls the batch leaves
    (degenerate ones, and larger than _BATCH_HULL) are measured one at a time."""
    from uvbake.atlas import maxrects
    from uvbake.atlas.maxrects import chart_hulls, min_area_rect, min_area_rects

    rng = np.random.default_rng(21)
    sets = []
    for k in range(600):
        t = rng.uniform(0, 2 * np.pi)
        R = np.array([[np.cos(t), np.sin(t)], [-np.sin(t), np.cos(t)]])
        scale = 10.0 ** rng.integers(-5, 5)
        if k % 3 == 0:                                  # a leaf card
            P = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]) * rng.uniform(0.1, 0.4)
        elif k % 3 == 1:                                # a regular polygon of 5-8 sides
            n = int(rng.integers(5, 9))
            a = 2 * np.pi * np.arange(n) / n
            P = np.column_stack([np.cos(a), np.sin(a)])
        else:                                           # random points: hulls of many sizes
            P = rng.normal(size=(int(rng.integers(3, 400)), 2)) * [1.0, rng.uniform(0.05, 1.0)]
        sets.append(P @ R * scale + rng.uniform(-5, 5, 2) * scale)
    sets += [np.zeros((4, 2)), np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0], [3.0, 3.0]]),
             np.array([[0.0, 0.0], [2.0, 1.0]]), np.array([[5.0, 5.0]])]
    alone = []
    real = maxrects._rect_of_hull
    monkeypatch.setattr(maxrects, "_rect_of_hull", lambda H: alone.append(len(H)) or real(H))
    got = min_area_rects(sets)
    monkeypatch.setattr(maxrects, "_rect_of_hull", real)
    want = np.array([min_area_rect(P) for P in sets])
    assert np.array_equal(got.view(np.int64), want.view(np.int64))   # bit for bit, signed zeros too
    sizes = [len(h) for h in chart_hulls(sets)]
    assert len(alone) <= sum(s < 3 or s > maxrects._BATCH_HULL for s in sizes) + 4
    assert sizes.count(4) >= 200 and len(alone) < 60

def test_calipers_find_the_minimum_area_rectangle_of_every_hull():
    from uvbake.atlas.maxrects import _hull_points, min_area_rect

    rng = np.random.default_rng(11)
    for k in range(60):
        n = int(rng.integers(3, 300))
        P = rng.normal(size=(n, 2)) * [1.0, rng.uniform(0.01, 3.0)]
        if k % 3 == 0:                             # near-circular hulls: many edges
            t = rng.uniform(0, 2 * np.pi, n)
            P = np.column_stack([np.cos(t), np.sin(t)]) * rng.uniform(0.5, 1.0, (n, 1))
        theta, w, h = min_area_rect(P)
        # brute force: every hull edge direction, every hull vertex projected
        H = _hull_points(P)
        E = np.roll(H, -1, axis=0) - H
        a = np.arctan2(E[:, 1], E[:, 0])
        x = H @ np.stack([np.cos(a), np.sin(a)])
        y = H @ np.stack([-np.sin(a), np.cos(a)])
        best = (np.ptp(x, axis=0) * np.ptp(y, axis=0)).min()
        assert w * h == pytest.approx(best, rel=1e-9)
        c, s = np.cos(theta), np.sin(theta)
        Q = P @ np.array([[c, s], [-s, c]])          # rotated by theta: the rectangle is axis-aligned
        assert np.ptp(Q[:, 0]) == pytest.approx(w, rel=1e-9) and np.ptp(Q[:, 1]) == pytest.approx(h, abs=1e-9 * w)
    assert min_area_rect(np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]]))[2] == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("size,ok", [(128, False), (512, True)])
def test_a_coarse_layout_scaled_to_the_atlas_keeps_the_exact_gutter_or_is_refused(size, ok):
    from uvbake.atlas.fit import scale_to_border
    from uvbake.atlas.shapepack import ShapePacker

    uvs, faces = mixed_charts(5, n=5)
    packer = ShapePacker(uvs, faces, [np.zeros(1)] * len(uvs))
    # a 64-texel strip with a 1-texel gutter, read as a raster 2x coarser than the atlas: gaps of >= 2
    # atlas texels, which a 4-texel gutter accepts only once the layout is scaled by >= 2
    p = packer.pack(64 / np.sqrt(packer.area.sum() / 0.4), 64, None, 1)
    q = scale_to_border(packer, p, size, size, 4, c=2, coarse_gutter=1)
    if not ok:
        assert q is None
        return
    Q = []
    for i, uv in enumerate(uvs):
        c, s = np.cos(q.rotation[i]), np.sin(q.rotation[i])
        Q.append(q.density * (uv @ np.array([[c, s], [-s, c]])) + q.offset[i])
    assert min_gap(Q, faces) >= 4 * (1 - 1e-9)
    lo, hi = min(x.min() for x in Q), max(x.max() for x in Q)
    assert lo >= 2 * (1 - 1e-9) and hi <= size - 2 * (1 - 1e-9)
    assert max(x.max(axis=0)[0] for x in Q) == pytest.approx(size - 2, rel=1e-6) or \
        max(x.max(axis=0)[1] for x in Q) == pytest.approx(size - 2, rel=1e-6)    # it fills one side


def test_row_widening_is_scipys_maximum_filter():
    """_widen_rows (numpy, running counts) against scipy.ndimage.maximum_filter1d, exactly."""
    from scipy.ndimage import maximum_filter1d

    from uvbake.atlas.shapepack import _widen_rows

    rng = np.random.default_rng(3)
    for _ in range(100):
        h, w = (int(x) for x in rng.integers(1, 40, 2))
        r = int(rng.integers(1, 12))
        a = rng.random((h, w)) < rng.uniform(0.0, 0.3)
        assert np.array_equal(_widen_rows(a, r), maximum_filter1d(a, size=2 * r + 1, axis=1, mode="constant"))


def test_run_tables_updated_in_place_are_the_tables_recomputed():
    """update_runs refreshes the free-run table and row maxima after texels of a box of rows and
    columns were blocked (placing) or freed (compaction lifts charts); the result must be a brute-force
    count of each texel's free run, exactly, after every change of a random sequence."""
    from uvbake.atlas.shapepack import update_runs

    def brute(blocked):
        h, w = blocked.shape
        out = np.zeros((h, w), np.int64)
        for y in range(h):                          # test oracle: a plain scan of each row from the right
            n = 0
            for x in range(w - 1, -1, -1):
                n = 0 if blocked[y, x] else n + 1
                out[y, x] = n
        return out

    rng = np.random.default_rng(5)
    for _ in range(60):
        h, w = int(rng.integers(1, 16)), int(rng.integers(1, 40))
        blocked = rng.random((h, w)) < rng.uniform(0.0, 0.6)
        run = shapepack._free_runs(blocked)
        rowmax = run.max(axis=1)
        for _ in range(6):
            r0 = int(rng.integers(0, h))
            r1 = int(rng.integers(r0, h + 1))
            c0 = int(rng.integers(0, w))
            c1 = int(rng.integers(c0, w + 1))
            blocked[r0:r1, c0:c1] = rng.random((r1 - r0, c1 - c0)) < rng.uniform(0.0, 1.0)
            update_runs(blocked, run, rowmax, r0, r1, c0, c1)
            ref = brute(blocked)
            assert np.array_equal(run, ref) and np.array_equal(rowmax, ref.max(axis=1))


def test_runs_of_footprints_found_together_are_each_footprints_own_runs(monkeypatch):
    """The packer finds the horizontal runs of every candidate footprint in one pass (footprints laid
    end to end, padded by a free column); each footprint's runs must be its own (a brute-force scan
    of every row), and their test order the documented one: the longest run first (the first of
    equal ones), then by the row's spread, then by start."""
    rng = np.random.default_rng(2)
    fps = [rng.random((int(rng.integers(1, 9)), int(rng.integers(1, 11)))) < rng.uniform(0.2, 0.9) for _ in range(30)]
    fps = [f for f in fps if f.any()] + [np.ones((3, 4), bool), np.eye(5, dtype=bool)[:, ::-1]]
    together = shapepack._raw_runs_many(fps)
    ordered = shapepack._runs_many(together)
    monkeypatch.setattr(shapepack, "_BATCH_CELLS", 40)             # several groups, a big one alone
    grouped = shapepack._raw_runs_many(fps)
    assert len(grouped) == len(fps)
    for g, t in zip(grouped, together):
        assert all(np.array_equal(x, y) for x, y in zip(g, t))
    for fp, (dy, a, L), (ody, oa, oL) in zip(fps, together, ordered):
        expect = []
        for r, row in enumerate(fp):
            c = 0
            while c < len(row):
                if row[c]:
                    e = c
                    while e < len(row) and row[e]:
                        e += 1
                    expect.append((r, c, e - c))
                    c = e
                else:
                    c += 1
        assert list(zip(dy.tolist(), a.tolist(), L.tolist())) == expect
        first = int(np.argmax(L))
        key = [(-1.0 if k == first else (r * 0.6180339887498949) % 1.0, s) for k, (r, s, _) in enumerate(expect)]
        want = sorted(range(len(expect)), key=lambda k: (key[k], k))
        assert list(zip(ody.tolist(), oa.tolist(), oL.tolist())) == [expect[k] for k in want]
