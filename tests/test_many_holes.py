"""Charts with more holes than the charting links: a sphere closed but for small holes is bisected like
a closed one, a holey tube has only its two ends linked (uvbake.atlas.opening)."""

import numpy as np
import pytest

from uvbake.atlas.charting import make_charts, sub_charts
from uvbake.atlas.opening import MAX_OPENED_LOOPS, _loop_spans, nearly_closed, open_holes
from uvbake.mesh.charts import Chart, check_chart
from uvbake.mesh.topology import topology

from meshgen import open_tube


def _without(V, F, k, seed):
    """(V, F) less ``k`` triangles chosen at random, no two sharing a vertex and none on the border:
    ``k`` one-triangle holes, the mesh still manifold."""
    from uvbake.mesh.topology import boundary_edges

    keep, used = np.ones(len(F), bool), np.zeros(len(V), bool)
    used[boundary_edges(F, len(V)).ravel()] = True
    for f in np.random.default_rng(seed).permutation(len(F)):      # a test's few hundred draws
        if (~keep).sum() == k:
            break
        if not used[F[f]].any():
            keep[f], used[F[f]] = False, True
    return V, F[keep]


def _holey_sphere(k=30, seed=1):
    from trimesh import creation

    s = creation.icosphere(subdivisions=3)
    return _without(np.asarray(s.vertices, float), np.asarray(s.faces, np.int64), k, seed)


def _chart(V, F, name="c"):
    return Chart(V, F, np.arange(len(V)), np.arange(len(F)), -1, name)


def test_a_loops_span_is_the_disk_of_its_perimeter():
    r, k = 0.7, 64
    t = 2 * np.pi * np.arange(k) / k
    V = np.column_stack([r * np.cos(t), r * np.sin(t), np.zeros(k)])
    b = np.column_stack([np.arange(k), (np.arange(k) + 1) % k])
    perimeter = k * 2 * r * np.sin(np.pi / k)
    span = _loop_spans(V, b, np.zeros(k, np.int64), 1)
    assert span[0] == pytest.approx(perimeter ** 2 / (4 * np.pi), rel=1e-12)
    assert span[0] == pytest.approx(np.pi * r ** 2, rel=2e-3)           # a circle: its own disk


def test_only_a_chart_with_many_small_holes_is_nearly_closed():
    V, F = _holey_sphere()
    assert topology(F, len(V)).n_boundary_loops > MAX_OPENED_LOOPS
    assert nearly_closed(_chart(V, F))
    # the same sphere with few holes: open_holes links them instead
    assert not nearly_closed(_chart(*_without(*_holey_sphere(0), 5, 1)))
    # a hemisphere (one long loop) with the same kind of holes: its rim is no small hole
    V, F = _holey_sphere(60)
    south = sub_charts(_chart(V, F), (V[F].mean(axis=1)[:, 2] < 0).astype(np.int64))[0]
    assert topology(south.F, len(south.V)).n_boundary_loops > MAX_OPENED_LOOPS
    assert not nearly_closed(south)


def test_a_sphere_with_many_small_holes_is_charted_like_a_closed_one():
    V, F = _holey_sphere()
    charts, starts, log = make_charts(V, F, max_stretch=4.0)
    # bisected once, like the closed sphere: two charts (before: seven, cut by the area factor of a
    # map that blows one hole up into the outer border, then separated where it overlapped)
    assert log["budget_cuts"][0].get("nearly_closed") is True and log["budget_cuts"][0]["parts"] == 2
    assert len(charts) == 2
    for c in charts:
        check_chart(c.V, c.F)
    assert sorted(np.concatenate([c.face_index for c in charts]).tolist()) == list(range(len(F)))


def test_a_tube_with_many_small_holes_has_only_its_ends_linked():
    V, F = _without(*open_tube(nu=32, nv=60, radius=0.3, length=3.0), 40, 2)
    loops = topology(F, len(V)).n_boundary_loops
    assert loops > MAX_OPENED_LOOPS + 2
    opened, seam, linked = open_holes(_chart(V, F))
    t = topology(opened.F, len(opened.V))
    # one seam from end to end (the tube's length), the small holes left as they were
    assert linked == 1 and seam == pytest.approx(3.0, rel=0.05)
    assert (t.genus, t.n_components) == (0, 1) and loops - 3 <= t.n_boundary_loops <= loops - 1
    # the charting: one chart (before only the ends were linked: nine, from slits, cuts and overlaps)
    charts, _, log = make_charts(V, F, max_stretch=4.0)
    assert len(charts) == 1 and [c.get("holes_linked") for c in log["budget_cuts"]] == [1]


def test_of_many_comparable_loops_the_largest_are_linked():
    """A tube with 20 holes of 3 x 3 cells, each over 1/16 of the ends' span: the ends and the largest
    holes, MAX_OPENED_LOOPS loops in all, are linked and the rest stay holes (before: nothing was linked,
    22 loops being more than open_holes links)."""
    nu, nv = 32, 60
    V, F = open_tube(nu=nu, nv=nv, radius=0.3, length=3.0)
    cells = [(r, c) for r in (3, 11, 19, 27, 35, 43, 51) for c in (2, 10, 18)][:20]
    drop = [h * (nv - 1) * nu + (r + i) * nu + c + j for r, c in cells for i in range(3) for j in range(3)
            for h in (0, 1)]
    F = np.delete(F, drop, axis=0)
    loops = topology(F, len(V)).n_boundary_loops
    assert loops == 22
    opened, seam, linked = open_holes(_chart(V, F))
    t = topology(opened.F, len(opened.V))
    assert linked == MAX_OPENED_LOOPS - 1
    assert (t.genus, t.n_components) == (0, 1) and t.n_boundary_loops <= loops - linked


def test_a_slit_in_a_chart_with_a_hole_runs_to_the_outer_border_around_the_hole():
    # a tip one diagonal from a hole's corner and four edges from the border: the slit goes to the
    # border (a slit into the hole would have to open the hole; the conformal map keeps it small)
    from uvbake.atlas.opening import slit
    from uvbake.mesh.topology import boundary_edges

    n = 8
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    x, y = np.meshgrid(np.arange(n + 1.0), np.arange(n + 1.0), indexing="ij")
    V = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    F = np.array([t for i in range(n) for j in range(n) if (i, j) != (2, 2) for t in
                  ([idx[i, j], idx[i + 1, j], idx[i + 1, j + 1]], [idx[i, j], idx[i + 1, j + 1], idx[i, j + 1]])])
    chart = _chart(V, F)
    hole = {int(idx[2, 2]), int(idx[3, 2]), int(idx[3, 3]), int(idx[2, 3])}
    border = set(boundary_edges(F, len(V)).ravel().tolist()) - hole
    opened, seam = slit(chart, np.array([idx[4, 4]]))
    vm = opened.vertex_map
    cut = set(np.unique(vm)[np.bincount(vm)[np.unique(vm)] > 1].tolist())     # mesh vertices with two copies
    assert cut and not cut & hole and cut & border
    assert seam == pytest.approx(4.0, abs=1e-12)                                 # the straight way out: 4 edges
    assert topology(opened.F).n_boundary_loops == 2 and check_chart(opened.V, opened.F)


@pytest.mark.parametrize("hole, linked", [({(3, 3)}, False), ({(i, j) for i in range(2, 6) for j in range(2, 6)}, True)])
def test_open_holes_links_a_large_hole_and_leaves_a_small_one(hole, linked):
    # an 8 x 8 grid less one square (a loop 4 long against the border's 32: it stays a hole) or less
    # a 4 x 4 block (16 against 32: an annulus, linked to the border by one seam)
    n = 8
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    x, y = np.meshgrid(np.arange(n + 1.0), np.arange(n + 1.0), indexing="ij")
    V = np.column_stack([x.ravel(), y.ravel(), 0.2 * np.sin(x.ravel())])
    F = np.array([t for i in range(n) for j in range(n) if (i, j) not in hole for t in
                  ([idx[i, j], idx[i + 1, j], idx[i + 1, j + 1]], [idx[i, j], idx[i + 1, j + 1], idx[i, j + 1]])])
    out = open_holes(_chart(V, F))
    if not linked:
        assert out is None
    else:
        opened, seam, k = out
        assert k == 1 and seam > 0 and topology(opened.F).n_boundary_loops == 1
