"""Tests of uvbake.validate: flips, overlaps (raster + exact), sub-pixel verdicts, the overlap image.

An independent oracle decides overlaps: the exact area (Fractions) of the intersection of two
triangles by Sutherland-Hodgman clipping, a different algorithm from the validator's separating axes.
"""

import json
from fractions import Fraction

import numpy as np
import pytest

from uvbake.validate.core import validate
from uvbake.validate.report import FLIPPED_RGB, OVERLAP_RGB

# --------------------------------------------------------------------------------------------------
# fixtures and the oracle


def grid(n, x0=0.0, y0=0.0, size=1.0):
    """A regular grid chart: V (n+1)^2 x 2, F 2 n^2 x 3, counter-clockwise, diagonals a->c."""
    g = np.linspace(0.0, 1.0, n + 1)
    x, y = np.meshgrid(g, g, indexing="xy")
    V = np.stack([x.ravel(), y.ravel()], axis=1) * size + np.array([x0, y0])
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    a = (i * (n + 1) + j).ravel()
    b, c, d = a + 1, a + n + 2, a + n + 1
    F = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return V, F


def clip_area(P, Q):
    """Exact area of the intersection of triangles P and Q (3,2), any orientation, as a Fraction."""

    def ccw(T):
        T = [(Fraction(float(x)), Fraction(float(y))) for x, y in T]
        a = (T[1][0] - T[0][0]) * (T[2][1] - T[0][1]) - (T[1][1] - T[0][1]) * (T[2][0] - T[0][0])
        return (T if a > 0 else [T[0], T[2], T[1]]), a

    P, ap = ccw(P)
    Q, aq = ccw(Q)
    if ap == 0 or aq == 0:
        return Fraction(0)
    poly = P
    for k in range(3):
        a, b = Q[k], Q[(k + 1) % 3]

        def side(p):
            return (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])

        out = []
        for i in range(len(poly)):
            p, q = poly[i], poly[(i + 1) % len(poly)]
            sp, sq = side(p), side(q)
            if sp >= 0:
                out.append(p)
            if sp * sq < 0:
                t = sp / (sp - sq)
                out.append((p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])))
        poly = out
        if len(poly) < 3:
            return Fraction(0)
    n = len(poly)
    return sum(poly[i][0] * poly[(i + 1) % n][1] - poly[(i + 1) % n][0] * poly[i][1] for i in range(n)) / 2


def oracle_pairs(corners):
    """(p,2) sorted pairs of faces whose intersection has positive exact area (brute force)."""
    bmin, bmax = corners.min(axis=1), corners.max(axis=1)
    out = []
    for i in range(len(corners)):
        for j in range(i + 1, len(corners)):
            if np.all(np.maximum(bmin[i], bmin[j]) < np.minimum(bmax[i], bmax[j])):
                if clip_area(corners[i], corners[j]) > 0:
                    out.append((i, j))
    return np.array(out, dtype=np.int64).reshape(-1, 2)


def assert_consistent(r):
    """Invariants every report must satisfy."""
    p = r.overlap_pairs
    assert p.dtype == np.int64 and p.ndim == 2 and p.shape[1] == 2
    assert np.all(p[:, 0] < p[:, 1])
    keys = p[:, 0] * r.n_faces + p[:, 1]
    assert np.all(np.diff(keys) > 0)  # sorted, unique
    assert r.overlap_subpixel.shape == (len(p),)
    assert set(r.degenerate.tolist()) <= set(r.flipped.tolist())
    assert not set(p.ravel().tolist()) & set(r.degenerate.tolist())
    assert sum(c.n_faces for c in r.charts) == r.n_faces
    assert sum(c.n_flipped for c in r.charts) == r.n_flipped
    assert r.valid == (r.n_flipped == 0 and r.n_overlaps == 0) or r.allow_subpixel


# --------------------------------------------------------------------------------------------------
# must not be flagged


def test_perfect_grid_claims_every_pixel_exactly_once():
    # vertices at pixel centres and corners, diagonals through pixel centres: the fill rule decides
    V, F = grid(32)
    r = validate(V[F], resolution_px=16)
    assert r.valid and r.n_overlaps == 0 and r.n_flipped == 0
    assert r.grid_shape == (16, 16) and r.pixel_size == 1 / 16
    assert r.covered_px == 16 * 16 and r.overlap_px == 0 and r.overlap_area_fraction == 0.0
    assert len(r.charts) == 1 and r.charts[0].valid and r.charts[0].orientation == 1
    assert r.charts[0].area == pytest.approx(1.0)
    assert_consistent(r)


def test_fill_rule_on_a_random_triangulation_through_pixel_centres():
    # a Delaunay triangulation of points on pixel centres and corners tiles [0,1]^2: each pixel centre
    # lies on edges and vertices shared by many triangles, and must be claimed exactly once
    from scipy.spatial import Delaunay

    rng = np.random.default_rng(3)
    R = 32
    pts = rng.integers(0, 2 * R + 1, size=(300, 2)) / (2 * R)
    corners4 = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    pts = np.unique(np.concatenate([pts, corners4]), axis=0)
    F = Delaunay(pts).simplices
    r = validate(pts, F, resolution_px=R)
    assert r.grid_shape == (R, R)
    assert r.covered_px == R * R and r.overlap_px == 0
    assert r.valid, r.summary()


def _claimed_by_brute_force(X, Y, rows, cols):
    """Set of (triangle, row, col) whose pixel centre the top-left rule gives the triangle, pixel by
    pixel from the edge functions (fixed point, 256 units per pixel), independent of _spans."""
    S, h = 256, 128
    out = set()
    for t in range(len(X)):
        x, y = [int(v) for v in X[t]], [int(v) for v in Y[t]]
        area = (x[1] - x[0]) * (y[2] - y[0]) - (y[1] - y[0]) * (x[2] - x[0])
        if area == 0:
            continue
        order = [0, 1, 2] if area > 0 else [0, 2, 1]
        x, y = [x[i] for i in order], [y[i] for i in order]
        for r in range(rows):
            for j in range(cols):
                px, py = S * j + h, S * r + h
                inside = True
                for e in range(3):
                    ax, ay, bx, by = x[e], y[e], x[(e + 1) % 3], y[(e + 1) % 3]
                    dx, dy = bx - ax, by - ay
                    E = dx * (py - ay) - dy * (px - ax)
                    if E < 0 or (E == 0 and not (dy < 0 or (dy == 0 and dx > 0))):
                        inside = False
                        break
                if inside:
                    out.add((t, r, j))
    return out


@pytest.mark.parametrize("division", ["float", "integer"])
def test_spans_claim_the_pixel_centres_the_top_left_rule_gives(division, monkeypatch):
    # corners on a quarter-pixel lattice put many pixel centres exactly on edges, horizontal edges
    # included; both ways of dividing (float64 for ordinary coordinates, integers past _FLOAT_EXACT)
    # must claim exactly the centres the edge functions give, each once per triangle
    import uvbake.validate.raster as module

    if division == "integer":
        monkeypatch.setattr(module, "_FLOAT_EXACT", 0)
    rng = np.random.default_rng(11)
    rows, cols = 7, 9
    X = rng.integers(-4, 4 * cols + 4, (60, 3)) * 64
    Y = rng.integers(-4, 4 * rows + 4, (60, 3)) * 64
    X[:20, 1], Y[:20, 1] = X[:20, 0] + 3 * 64, Y[:20, 0]        # a horizontal edge each
    X[20:30, 2], Y[20:30, 2] = X[20:30, 0] - 5 * 64, Y[20:30, 0]  # and the other way round
    tri, row, x0, x1 = module._spans(X, Y, rows, cols)
    got = [(int(t), int(r), int(j)) for t, r, a, b in zip(tri, row, x0, x1) for j in range(a, b)]
    assert len(got) == len(set(got))
    expected = _claimed_by_brute_force(X, Y, rows, cols)
    assert set(got) == expected and len(expected) > 100


def test_sorted_span_check_agrees_with_the_pixel_grid():
    # the check that skips the pixel grid on a valid atlas: a tiling claims each pixel once (covered
    # pixels = the grid's count), and one triangle added twice, or a span shifted onto its neighbour's
    # pixel, is seen as a pixel claimed twice
    from scipy.spatial import Delaunay

    import uvbake.validate.raster as module

    rng = np.random.default_rng(5)
    R = 256                                      # big triangles: fewer spans than pixels, the sorted check runs
    pts = np.unique(np.concatenate([rng.integers(0, 2 * R + 1, size=(400, 2)) / (2 * R),
                                    [[0, 0], [1, 0], [1, 1], [0, 1]]]), axis=0)
    T = pts[Delaunay(pts).simplices]
    Xi, Yi = module._fixed_point(T, np.zeros(2), 1.0 / R)
    tri, row, x0, x1 = module._spans(Xi, Yi, R, R)
    assert module._claimed_once(row, x0, x1, R)
    keys, _, covered, complete = module._raster_pairs(tri, row, x0, x1, R, R, len(T))
    grid = module._accumulate(row, x0, x1, R, R)
    assert len(keys) == 0 and complete and covered == np.count_nonzero(grid) == R * R and grid.max() == 1
    Xd, Yd = np.concatenate([Xi, Xi[7:8]]), np.concatenate([Yi, Yi[7:8]])
    assert not module._claimed_once(*module._spans(Xd, Yd, R, R)[1:], R)
    k = np.flatnonzero(x0 > 0)[0]                # the tiling claims the pixel left of it: another span's
    x0b = x0.copy()
    x0b[k] -= 1
    assert ((row == row[k]) & (x1 == x0[k])).any() and not module._claimed_once(row, x0b, x1, R)


def test_edge_and_vertex_neighbours_are_not_overlaps():
    V = np.array([[0.1, 0.1], [0.7, 0.13], [0.4, 0.8], [0.9, 0.9], [0.95, 0.2]])
    # faces 0 and 1 share the edge 1-2, faces 0 and 2 share only the vertex 1
    F = np.array([[0, 1, 2], [1, 3, 2], [1, 4, 3]])
    r = validate(V, F, resolution_px=64)
    assert r.valid and r.n_overlaps == 0
    # the same as an atlas of separate triangles (per-corner, UV-welded)
    r2 = validate(V[F], resolution_px=64)
    assert r2.valid and len(r2.charts) == 1


def test_charts_touching_at_a_point_are_separate_and_valid():
    # two square charts meeting at one corner; the second is mirrored as a whole. Per-corner UVs
    # weld the shared corner, but charts are edge-connected components, so the mirror is not a flip
    Va, Fa = grid(4, 0.1, 0.1, 0.4)
    Vb, Fb = grid(4, 0.5, 0.5, 0.4)
    Vb[:, 0] = 1.0 - Vb[:, 0]  # mirror x: now occupies [0.1,0.5] x [0.5,0.9] ... and meets at (0.5,0.5)
    Vb[:, 0] += 0.4
    atlas = np.concatenate([Va[Fa], Vb[Fb]])
    assert np.any(np.all(atlas.reshape(-1, 2) == [0.5, 0.5], axis=1))
    r = validate(atlas, resolution_px=128)
    assert r.valid, r.summary()
    assert len(r.charts) == 2
    assert sorted(c.orientation for c in r.charts) == [-1, 1]


def test_chart_mirrored_as_a_whole_is_not_flipped():
    V, F = grid(6)
    W = V * np.array([-1.0, 1.0])
    r = validate(W, F, resolution_px=64)
    assert r.valid and r.n_flipped == 0
    assert r.charts[0].orientation == -1 and r.charts[0].area == pytest.approx(1.0)


def test_touching_along_collinear_edges_with_unrepresentable_coordinates():
    # a, b, c, d = s * p for s = 1, 2, 4, 8 lie exactly on a line through the origin (scaling by 2 is
    # exact) but differences such as x - 4x round, so float determinants are not zero. Triangle T1 has
    # edge a->c, T2 has edge b->d on the same line, on the other side: they touch along [b, c] only.
    p = np.array([0.1, 0.7])
    a, b, c, d = p, 2 * p, 4 * p, 8 * p
    naive = (c[0] - a[0]) * (b[1] - a[1]) - (c[1] - a[1]) * (b[0] - a[0])
    assert naive != 0.0  # a plain float predicate would call b off the line
    n = np.array([-0.7, 0.1])  # normal to the line
    T1 = np.array([a, c, 3 * p + n])
    T2 = np.array([b, d, 5 * p - n])
    r = validate(np.stack([T1, T2]) / 8.0 + 0.0, resolution_px=64)  # /8 is exact
    assert r.valid and r.n_overlaps == 0, r.summary()
    assert r.n_exact > 0  # the float filter could not decide, exact arithmetic did
    # one ulp across the line is an overlap, and it is found
    T2b = T2.copy()
    T2b[0] = [np.nextafter(b[0], -1.0), b[1]]  # b moves left: into T1's side of the line
    assert clip_area(T1, T2b) > 0
    r2 = validate(np.stack([T1, T2b]) / 8.0, resolution_px=64)
    assert r2.overlap_pairs.tolist() == [[0, 1]] and r2.overlap_subpixel.tolist() == [True]
    assert not r2.valid
    assert validate(np.stack([T1, T2b]) / 8.0, resolution_px=64, allow_subpixel=True).valid


def test_touching_triangles_that_snapping_makes_both_claim_a_pixel_are_not_overlaps():
    # T1 and T2 touch along a line through the origin (points p * 2**k are exactly collinear) that
    # passes 1e-4 px from a pixel centre; snapping to 1/256 px moves T1's edge across that centre, so
    # the raster sees a pixel claimed twice. The exact pass must reject the pair and the pixel must
    # not count as overlap nor be drawn red.
    import uvbake.validate.raster as module

    R = 64
    spurious = 0
    for i, j in [(9, 8), (10, 8), (11, 8), (11, 10), (12, 8)]:
        c = np.array([i + 0.5, j + 0.5]) / R
        p = (c + np.array([0.0, 1e-4 / R])) / 512
        n = np.array([-p[1], p[0]]) * 512 * 0.3
        T1 = np.array([p, 1024 * p, 600 * p + n])
        T2 = np.array([2 * p, 1024 * p, 700 * p - n])
        atlas = np.stack([T1, T2])
        Xi, Yi = module._fixed_point(atlas, np.zeros(2), 1.0 / R)
        keys = module._raster_pairs(*module._spans(Xi, Yi, R, R), R, R, 2)[0]
        spurious += len(keys) > 0
        r = validate(atlas, resolution_px=R)
        assert r.valid and r.n_overlaps == 0 and r.overlap_px == 0, r.summary()
        assert not np.any(np.all(r.overlap_image() == OVERLAP_RGB, axis=2))
    assert spurious > 0  # the raster was fooled at least once; the verdict never was


def test_normal_fan_around_an_interior_vertex_is_valid():
    ang = np.arange(4) * np.pi / 2
    V = np.concatenate([[[0.0, 0.0]], np.stack([np.cos(ang), np.sin(ang)], 1)])
    F = np.array([[0, 1 + k, 1 + (k + 1) % 4] for k in range(4)])
    r = validate(V, F, resolution_px=64)
    assert r.valid and r.n_candidates == 0  # every pair is provably disjoint from the topology


# --------------------------------------------------------------------------------------------------
# must be found


def test_two_charts_stacked():
    V, F = grid(4, 0.1, 0.1, 0.5)
    W, G = grid(4, 0.3, 0.2, 0.5)
    atlas = np.concatenate([V[F], W[G]])
    r = validate(atlas, resolution_px=256)
    assert not r.valid and len(r.charts) == 2
    assert all(not c.valid for c in r.charts) and r.n_flipped == 0
    np.testing.assert_array_equal(r.overlap_pairs, oracle_pairs(atlas))
    # every overlapping pair mixes the two charts
    assert np.all(r.overlap_pairs[:, 0] < 32) and np.all(r.overlap_pairs[:, 1] >= 32)
    # overlap area: the squares' intersection 0.3 x 0.4 over their union 0.5 + 0.5 - 0.12 of area
    assert r.overlap_area_fraction == pytest.approx(0.12 / 0.38, rel=0.02)
    assert_consistent(r)


def test_count_covered_false_skips_the_raster_only_where_no_pair_overlaps():
    """count_covered=False: a layout without overlapping pairs reports covered_px None and the same
    verdict; one with pairs runs the raster as before and reports the same pixel figures."""
    V, F = grid(4, 0.1, 0.1, 0.5)
    W, G = grid(4, 0.3, 0.2, 0.5)
    apart = np.concatenate([V[F], W[G] + [0.5, 0.3]])             # side by side, 0.1 apart
    stacked = np.concatenate([V[F], W[G]])
    for atlas, ok in ((apart, True), (stacked, False)):
        full = validate(atlas, resolution_px=256)
        lean = validate(atlas, resolution_px=256, count_covered=False)
        assert full.valid is lean.valid is ok
        np.testing.assert_array_equal(lean.overlap_pairs, full.overlap_pairs)
        np.testing.assert_array_equal(lean.overlap_subpixel, full.overlap_subpixel)
        assert lean.overlap_px == full.overlap_px
        assert lean.overlap_area_fraction == full.overlap_area_fraction
        assert lean.summary() == full.summary()
        if ok:
            assert lean.covered_px is None and "raster" not in lean.timings_s
            assert full.covered_px > 0 and lean.to_dict()["covered_px"] is None
        else:
            assert lean.covered_px == full.covered_px > 0
            assert lean.overlap_px > 0


def test_identical_stacked_charts_overlap_everywhere():
    V, F = grid(3, 0.2, 0.2, 0.6)
    r = validate(np.concatenate([V[F], V[F]]), resolution_px=128)
    assert r.overlap_area_fraction == 1.0
    # each face overlaps at least its own copy
    assert {(i, i + len(F)) for i in range(len(F))} <= set(map(tuple, r.overlap_pairs.tolist()))


def test_chart_folded_over_itself():
    # a strip folded back along x = 0.6: the part beyond the fold is mirrored onto the part before it
    V, F = grid(10)
    W = V.copy()
    beyond = W[:, 0] > 0.6
    W[beyond, 0] = 1.2 - W[beyond, 0]
    r = validate(W, F, resolution_px=128)
    folded = np.flatnonzero(np.all(V[F][:, :, 0] >= 0.6, axis=1))
    np.testing.assert_array_equal(r.flipped, folded)
    assert len(r.degenerate) == 0
    np.testing.assert_array_equal(r.overlap_pairs, oracle_pairs(W[F]))
    # overlaps are between the folded part and the rest, never within one side
    is_folded = np.isin(r.overlap_pairs, folded)
    assert r.n_overlaps > 0 and np.all(is_folded.sum(axis=1) == 1)
    assert not r.valid and not r.charts[0].valid
    assert_consistent(r)


def test_one_flipped_triangle():
    V, F = grid(6)
    # vertex (1, 0) belongs to one face only: reflect it across that face's opposite edge
    v = 6
    (f,) = np.flatnonzero(np.any(F == v, axis=1))
    a, c = V[[u for u in F[f] if u != v]]
    d = (c - a) / np.linalg.norm(c - a)
    p = V[v] - a
    W = V.copy()
    W[v] = a + 2 * (p @ d) * d - p
    r = validate(W, F, resolution_px=64)
    assert r.flipped.tolist() == [f] and len(r.degenerate) == 0
    np.testing.assert_array_equal(r.overlap_pairs, oracle_pairs(W[F]))
    assert f in r.overlap_pairs  # it lies on top of its neighbour
    assert r.charts[0].n_flipped == 1 and not r.valid


def test_degenerate_triangle_is_flipped_not_overlapping():
    p = np.array([0.1, 0.7])
    tri = np.array([p, 2 * p, 4 * p]) / 8.0  # exactly collinear, not so in floats
    other = np.array([[0.5, 0.5], [0.9, 0.5], [0.7, 0.9]])
    r = validate(np.stack([other, tri]), resolution_px=64)
    assert r.flipped.tolist() == [1] and r.degenerate.tolist() == [1]
    assert r.n_overlaps == 0 and not r.valid


def test_sliver_overlap_smaller_than_a_pixel_is_found_and_marked_subpixel():
    R = 64
    A = np.array([[0.1, 0.1], [0.5, 0.1], [0.3, 0.5]])
    # B's apex pokes 1e-4 px below A's bottom edge, away from pixel centres (y = (i + 0.5) / 64)
    eps = 1e-4 / R
    B = np.array([[0.2, 0.0], [0.4, 0.0], [0.3, 0.1 + eps]])
    r = validate(np.stack([A, B]), resolution_px=R)
    assert r.overlap_pairs.tolist() == [[0, 1]] and r.overlap_subpixel.tolist() == [True]
    assert r.overlap_px == 0 and not r.valid
    assert validate(np.stack([A, B]), resolution_px=R, allow_subpixel=True).valid
    # a thin but long sliver that crosses pixel centres is not sub-pixel
    C = np.array([[0.12, 0.1 - 1.0 / R], [0.48, 0.1 - 1.0 / R], [0.3, 0.1 + 0.6 / R]])
    r2 = validate(np.stack([A, C]), resolution_px=R)
    assert r2.overlap_pairs.tolist() == [[0, 1]] and r2.overlap_subpixel.tolist() == [False]
    assert r2.overlap_px > 0


def test_fan_winding_twice_without_any_flip_is_found():
    # eight 90-degree triangles around one vertex: a closed fan winding 720 degrees, all positive
    ang = np.arange(8) * np.pi / 2
    V = np.concatenate([[[0.0, 0.0]], np.stack([np.cos(ang), np.sin(ang)], 1)])
    F = np.array([[0, 1 + k, 1 + (k + 1) % 8] for k in range(8)])
    r = validate(V, F, resolution_px=64)
    assert r.n_flipped == 0 and not r.valid
    assert {(k, k + 4) for k in range(4)} <= set(map(tuple, r.overlap_pairs.tolist()))
    np.testing.assert_array_equal(r.overlap_pairs, oracle_pairs(V[F]))
    # an open fan of five 90-degree triangles (450 degrees at a boundary vertex)
    r5 = validate(V[:7], F[:5], resolution_px=64)
    assert r5.overlap_pairs.tolist() == [[0, 4]] and r5.n_flipped == 0


# --------------------------------------------------------------------------------------------------
# atlases, seams, charts


def test_per_corner_atlas_with_seams():
    # one mesh (shared vertex indices) cut into two charts along x = 0.5; the right chart is moved
    # and mirrored in UV space, so the seam vertices have two UVs each
    V, F = grid(6)
    right = np.all(V[F][:, :, 0] >= 0.5, axis=1)
    uv = V[F] * 0.45 + 0.02
    uv[right] = (V[F][right] * np.array([-1.0, 1.0]) + np.array([1.5, 0.0])) * 0.45 + 0.02
    for faces in (F, None):
        r = validate(uv, faces, resolution_px=256)
        assert r.valid, r.summary()
        assert len(r.charts) == 2
        np.testing.assert_array_equal(r.chart_ids == r.chart_ids[0], ~right == ~right[0])
    # moved back onto the left chart: the two now overlap
    uv2 = uv.copy()
    uv2[right] -= np.array([0.3, 0.0])
    r = validate(uv2, F, resolution_px=256)
    np.testing.assert_array_equal(r.overlap_pairs, oracle_pairs(uv2))
    assert r.n_overlaps > 0 and r.n_flipped == 0


def test_chart_ids_override_connectivity():
    V, F = grid(2)
    # one connected chart whose halves are declared separate charts: with a half mirrored, the
    # components would call it flipped, the declared charts do not
    W = V.copy()
    left = np.all(V[F][:, :, 0] <= 0.5, axis=1)
    uv = W[F]
    uv[~left] = uv[~left] * np.array([-1.0, 1.0]) + np.array([2.0, 0.0])
    r_auto = validate(uv, resolution_px=64)
    assert r_auto.valid  # mirrored half is its own edge-connected component once moved away
    r = validate(uv, chart_ids=np.where(left, 7, 3), resolution_px=64)
    assert r.valid and len(r.charts) == 2
    assert sorted(c.orientation for c in r.charts) == [-1, 1]
    # the same faces declared one chart: the minority orientation is flipped
    r1 = validate(uv[[0, 1, 2, 3, 4]], chart_ids=np.zeros(5, int), resolution_px=64)
    n_left = int(left[:5].sum())
    assert r1.n_flipped == min(n_left, 5 - n_left)


def test_open3d_uvatlas_output_is_valid_and_a_moved_chart_is_caught():
    # a third-party atlas (Microsoft UVAtlas through Open3D), per-corner float32 UVs in [0,1]^2
    import open3d as o3d

    legacy = o3d.geometry.TriangleMesh.create_sphere(radius=1.0, resolution=12)
    mesh = o3d.t.geometry.TriangleMesh.from_legacy(legacy)
    mesh.compute_uvatlas(size=256)
    uv = mesh.triangle.texture_uvs.numpy()
    F = mesh.triangle.indices.numpy()
    r = validate(uv, F, resolution_px=256)
    assert r.valid, r.summary()
    assert r.grid_shape == (256, 256) and r.origin == (0.0, 0.0)
    assert validate(uv).valid  # without F, UV welding alone
    # move the smallest chart onto the middle of the largest one
    sizes = [c.n_faces for c in r.charts]
    small, big = int(np.argmin(sizes)), int(np.argmax(sizes))
    moved = uv.astype(np.float64)
    sel = r.chart_ids == small
    target = moved[r.chart_ids == big].reshape(-1, 2).mean(axis=0)
    moved[sel] += target - moved[sel].reshape(-1, 2).mean(axis=0)
    r2 = validate(moved, F, resolution_px=256)
    assert not r2.valid and r2.n_overlaps > 0
    assert np.all(np.any(sel[r2.overlap_pairs], axis=1))  # every pair involves the moved chart


def test_random_soup_matches_the_oracle_and_subpixel_is_about_pixel_centres():
    rng = np.random.default_rng(11)
    R = 64
    for _ in range(3):
        C = rng.random((80, 3, 2)) * 0.25 + rng.random((80, 1, 2)) * 0.75
        r = validate(C, resolution_px=R)
        np.testing.assert_array_equal(r.overlap_pairs, oracle_pairs(C))
        assert_consistent(r)
        # sub-pixel verdicts against brute-force pixel centres, leaving out centres within
        # 1/50 px of an edge (the raster snaps vertices to 1/256 px)
        centres = (np.stack(np.meshgrid(np.arange(R), np.arange(R), indexing="xy"), -1) + 0.5) / R
        centres = centres.reshape(-1, 2)

        def cross(p, q):
            return p[..., 0] * q[..., 1] - p[..., 1] * q[..., 0]

        def inside(T, margin):  # (n_centres,) bool: strictly inside by more than margin (uv units)
            T = T if cross(T[1] - T[0], T[2] - T[0]) > 0 else T[[0, 2, 1]]
            ok = np.ones(len(centres), bool)
            for k in range(3):
                e = T[(k + 1) % 3] - T[k]
                dist = cross(e, centres - T[k]) / np.linalg.norm(e)
                ok &= dist > margin
            return ok

        m = 1.0 / (50 * R)
        for (i, j), sub in zip(r.overlap_pairs, r.overlap_subpixel):
            surely_shared = np.any(inside(C[i], m) & inside(C[j], m))
            maybe_shared = np.any(inside(C[i], -m) & inside(C[j], -m))
            if surely_shared:
                assert not sub
            if not maybe_shared:
                assert sub


def test_noisy_meshes_match_the_oracle():
    # random vertex noise makes flips, folds and fans that wind more than once; every overlap the
    # oracle finds must be reported and nothing else, with and without faces (per-corner, welded)
    rng = np.random.default_rng(5)
    V, F = grid(8)
    for sigma, tangled in ((0.03, False), (0.08, True)):
        W = V + rng.normal(0.0, sigma, V.shape)  # grid spacing 0.125
        expected = oracle_pairs(W[F])
        for uv, faces in ((W, F), (W[F], None), (W[F], F)):
            r = validate(uv, faces, resolution_px=128)
            np.testing.assert_array_equal(r.overlap_pairs, expected)
            assert_consistent(r)
        assert (len(expected) > 0) == tangled


def test_box_pairs_of_sliver_strips_are_all_found_and_gridded_by_their_thin_side():
    # strips of slivers side by side (a CAD cylinder's side: 40:1 triangles, the strip wider than a
    # sliver is long), two crossing at a right angle and one at a free angle: the candidate grid finds
    # every pair of boxes overlapping with positive area (brute force), and its cells follow the
    # boxes' geometric mean side, not their long side (a cell that wide held 1,229 slivers of a real
    # atlas)
    from uvbake.validate import candidates

    rng = np.random.default_rng(8)
    quad = np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 1], [0, 1]]], float) * [0.02, 0.0005]
    tris = []
    for angle, x0, y0 in ((0.0, 0.1, 0.2), (np.pi / 2, 0.14, 0.19), (2.6, 0.9, 0.5)):
        rot = np.array([[np.cos(angle), np.sin(angle)], [-np.sin(angle), np.cos(angle)]])
        for a in range(3):                              # quads along the strip
            for b in range(80):                         # and across it: 0.04 wide, 0.06 long
                for t in quad + [0.02 * a, 0.0005 * b]:
                    tris.append(t @ rot + [x0, y0] + rng.normal(0, 1e-7, (3, 2)))
    C = np.array(tris)
    lo, hi = C.min(axis=1), C.max(axis=1)
    over = np.all((np.maximum(lo[:, None], lo[None]) < np.minimum(hi[:, None], hi[None])), axis=2)
    i, j = np.nonzero(np.triu(over, 1))
    seen = {}
    real = candidates._group_pairs

    def spy(group, item, m, **kw):
        seen["most"] = int(np.bincount(group).max())
        return real(group, item, m, **kw)

    try:
        candidates._group_pairs = spy
        pairs, complete, n = candidates._bbox_pairs(C, np.ones(len(C), bool))
    finally:
        candidates._group_pairs = real
    assert complete and n == len(i)
    got = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]
    np.testing.assert_array_equal(got, np.stack([i, j], axis=1))
    assert np.any((i // 480 == 0) & (j // 480 == 1))   # strips 0 and 1 cross
    assert seen["most"] <= 100, seen                    # measured 64; cells of the long side held 328


def test_raster_frame_for_charts_in_arbitrary_units_and_atlases_outside_the_unit_square():
    V, F = grid(4, 10.0, 5.0, 1.0)
    V = V * np.array([20.0, 10.0]) - np.array([190.0, 45.0])  # [10,30] x [5,15]
    r = validate(V, F, resolution_px=64)
    assert r.origin == (10.0, 5.0) and r.pixel_size == 20.0 / 64 and r.grid_shape == (32, 64)
    assert r.covered_px == 32 * 64 and r.valid
    # a per-corner atlas inside [0,1]^2 is judged in texels of a resolution_px texture
    W, G = grid(2, 0.25, 0.25, 0.5)
    r2 = validate(W[G], resolution_px=64)
    assert r2.origin == (0.0, 0.0) and r2.grid_shape == (64, 64) and r2.covered_px == 32 * 32
    # one outside it (tiling UVs) falls back to its bounding box
    r3 = validate(W[G] + 1.0, resolution_px=64)
    assert r3.origin == (1.25, 1.25) and r3.grid_shape == (64, 64)


# --------------------------------------------------------------------------------------------------
# report, image, API


def test_report_to_dict_is_plain_json():
    V, F = grid(3, 0.1, 0.1, 0.5)
    r = validate(np.concatenate([V[F], V[F] + 0.2]), resolution_px=64)
    d = json.loads(json.dumps(r.to_dict()))
    assert d["valid"] is False and d["n_faces"] == 36
    assert d["overlap_pairs"] == r.overlap_pairs.tolist()
    assert d["charts"][0]["n_overlapping"] == r.charts[0].n_overlapping > 0
    assert isinstance(d["time_s"], float) and d["time_s"] > 0


def test_overlap_image_has_strong_colours_where_expected(tmp_path):
    R = 64
    V, F = grid(4, 0.05, 0.05, 0.4)  # chart 1
    W, G = grid(4, 0.3, 0.3, 0.4)  # chart 2 overlaps chart 1 on [0.3,0.45]^2
    X, H = grid(2, 0.6, 0.05, 0.3)  # chart 3 with one flipped face
    X = X.copy()
    X[2] = [0.6 + 0.3 * 0.5, 0.05 + 0.3 * 0.5]  # vertex (1, 0) onto the quad's centre: flips a face
    atlas = np.concatenate([V[F], W[G], X[H]])
    path = tmp_path / "overlaps.png"
    r = validate(atlas, resolution_px=R, image_path=path)
    assert r.n_flipped == 1
    img = r.overlap_image()
    assert img.shape == (R, R, 3) and img.dtype == np.uint8

    def at(u, v):  # pixel containing (u, v); the image has v pointing up
        return tuple(img[R - 1 - int(v * R), int(u * R)])

    assert at(0.4, 0.4) == OVERLAP_RGB
    assert at(0.1, 0.1) not in (OVERLAP_RGB, FLIPPED_RGB) and min(at(0.1, 0.1)) > 150  # light
    assert at(0.99, 0.99) == (255, 255, 255)
    (f,) = r.flipped
    cu, cv = atlas[f].mean(axis=0)
    assert at(cu, cv) in (FLIPPED_RGB, OVERLAP_RGB)
    assert np.any(np.all(img == FLIPPED_RGB, axis=2))
    from PIL import Image

    np.testing.assert_array_equal(np.asarray(Image.open(path).convert("RGB")), img)
    assert [p.name for p in tmp_path.iterdir()] == ["overlaps.png"]  # no temp file left


def test_massive_overlap_stops_at_the_work_budget_and_is_never_valid(monkeypatch):
    # "reset" UVs: every quad mapped onto the whole texture; with small budgets the check stops
    from uvbake.validate import budgets

    sq = np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 1], [0, 1]]], float)
    uv = np.tile(sq, (20, 1, 1))
    full = validate(uv, resolution_px=32)
    # each lower triangle overlaps the 19 other lower ones, same for the upper; lower and upper
    # triangles only share the diagonal
    assert full.complete and full.n_overlaps == 2 * (20 * 19 // 2)
    monkeypatch.setattr(budgets, "MIN_RAW_PAIRS", 50)
    monkeypatch.setattr(budgets, "RAW_PAIRS_PER_FACE", 1)
    monkeypatch.setattr(budgets, "MAX_CLAIMS", 100)
    monkeypatch.setattr(budgets, "MAX_OVERLAP_PAIRS", 50)
    monkeypatch.setattr(budgets, "CHUNK", 16)            # the cap is checked between chunks
    r = validate(uv, resolution_px=32)
    assert not r.complete and not r.valid and r.notes
    # the list stops only once 50 pairs are confirmed: an invalid verdict is certain
    assert 50 <= r.n_overlaps < full.n_overlaps
    assert set(map(tuple, r.overlap_pairs.tolist())) <= set(map(tuple, full.overlap_pairs.tolist()))
    assert not r.overlap_subpixel.any()  # unknown is not "harmless"
    assert "stopped early" in r.summary()
    monkeypatch.setattr(budgets, "MAX_SPAN_ROWS", 10)
    r2 = validate(uv, resolution_px=32)
    assert np.isnan(r2.overlap_area_fraction) and not r2.valid
    d = json.loads(json.dumps(r2.to_dict()))
    assert d["complete"] is False and d["overlap_area_fraction"] is None


def test_uvbake_validate_is_the_function_even_after_importing_the_module():
    import uvbake.validate.core  # noqa: F401  (the package stays callable)

    V, F = grid(2)
    assert uvbake.validate(V, F, resolution_px=32).valid


# ---------------------------------------------------------------------------------------- issue 15


def _strips(n):
    """n disjoint parallel slivers along the diagonal whose bounding boxes all overlap each other:
    n (n-1) / 2 candidate pairs, none overlapping."""
    k = np.arange(n, dtype=float)[:, None] / n
    d = 1.0 / n
    A = np.column_stack([0 * k, k])
    B = np.column_stack([1 + 0 * k, 1 + k])
    C = np.column_stack([0 * k, k + d / 2])
    return np.stack([A, B, C], axis=1)


def test_candidate_pairs_are_never_truncated_into_a_verdict(monkeypatch):
    # with the old raw-pair budget at 1,000 this layout (19,900 candidates, no overlap) was
    # declared "overlaps are massive"; every candidate is now decided exactly, chunk by chunk
    from uvbake.validate import budgets

    monkeypatch.setattr(budgets, "MIN_RAW_PAIRS", 1000)
    monkeypatch.setattr(budgets, "RAW_PAIRS_PER_FACE", 1)
    monkeypatch.setattr(budgets, "CHUNK", 4096)
    uv = _strips(200)
    r = validate(uv, chart_ids=np.arange(200), resolution_px=64)
    assert r.valid and r.complete and r.n_overlaps == 0, r.summary()
    assert r.n_candidates >= 200 * 199 // 2 - 200          # all decided (a few share no home cell twice)
    assert "massive" not in r.summary()


def test_collapsed_charts_are_degenerate_not_massive_overlaps():
    # 3,000 charts collapsed to (nearly) one point, as a failed solve leaves them, beside a good one
    rng = np.random.default_rng(3)
    good = np.array([[[0.1, 0.1], [0.9, 0.1], [0.9, 0.9]], [[0.1, 0.1], [0.9, 0.9], [0.1, 0.9]]])
    tiny = 0.5 + 1e-13 * rng.uniform(-1, 1, size=(3000, 3, 2))
    uv = np.concatenate([good, tiny])
    chart_ids = np.concatenate([[0, 0], 1 + np.arange(3000)])
    r = validate(uv, chart_ids=chart_ids, resolution_px=256)
    assert r.complete and not r.valid
    assert r.n_overlaps == 0
    assert sorted(r.degenerate.tolist()) == list(range(2, 3002))
    assert "3000 degenerate" in r.summary() and "0 flipped" in r.summary()
    assert r.charts[0].valid and r.charts[0].n_degenerate == 0


def test_zero_area_triangles_are_reported_as_degenerate_up_front():
    uv = np.array([[[0, 0], [1, 0], [0, 1]], [[2, 2], [3, 3], [4, 4]]], float)
    r = validate(uv, resolution_px=32)
    assert r.degenerate.tolist() == [1] and not r.valid
    assert "1 degenerate" in r.summary() and "0 flipped" in r.summary()


def test_overlap_pairs_without_the_raster_are_validates_pairs():
    # the exact pass alone gives the same list the full check reports, on tangled noise and on charts
    from uvbake.validate.core import overlap_pairs

    rng = np.random.default_rng(7)
    V, F = grid(8)
    for sigma in (0.0, 0.03, 0.08):
        W = V + rng.normal(0.0, sigma, V.shape)
        ids = (np.arange(len(F)) >= len(F) // 2).astype(np.int64)
        for uv, faces, chart_ids in ((W, F, None), (W[F], None, None), (W[F], F, ids)):
            full = validate(uv, faces, chart_ids=chart_ids, resolution_px=128).overlap_pairs
            np.testing.assert_array_equal(overlap_pairs(uv, faces, chart_ids=chart_ids), full)
