"""Charts: splitting by labels and components, and every topology check naming its problem."""

import numpy as np
import pytest

import uvbake
from uvbake.mesh.charts import Chart, certified_disks, check_chart, split_charts
from uvbake.mesh.topology import nonmanifold_vertices, topology

from meshgen import bumpy_disk, grid, torus


def octahedron():
    V = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    F = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])
    return V, F


def test_disk_and_disk_with_holes_pass():
    V, F = bumpy_disk(8)
    topo = check_chart(V, F)
    assert (topo.n_boundary_loops, topo.genus, topo.n_components) == (1, 0, 1)
    keep = ~np.isin(F, [19, 44]).any(axis=1)
    c = split_charts(V, F[keep])[0]
    topo = check_chart(c.V, c.F)
    assert (topo.n_boundary_loops, topo.genus) == (3, 0)


def test_closed_chart_is_named_with_a_fix():
    V, F = octahedron()
    with pytest.raises(uvbake.ChartError, match=r"chart 0: is closed .*cut it open"):
        check_chart(V, F)


def test_handle_is_detected():
    V, F = torus()
    F = F[1:]                                     # one hole: a torus with a boundary, genus 1
    with pytest.raises(uvbake.ChartError, match=r"1 handle\(s\)"):
        check_chart(V, F)
    assert topology(F).genus == 1


def test_nonmanifold_edge():
    V, F = bumpy_disk(5)
    inner = F[10]                                 # a fin: a third triangle on an interior edge
    V2 = np.vstack([V, [[0, 0, 5.0]]])
    F2 = np.vstack([F, [[inner[0], inner[1], len(V)]]])
    with pytest.raises(uvbake.ChartError, match=rf"1 non-manifold edges .*\({min(inner[:2])},{max(inner[:2])}\)"):
        check_chart(V2, F2)


def test_bowtie_vertex_is_named():
    st, F = grid(3, 3)
    V = np.column_stack([st, np.zeros(len(st))])
    # two squares touching only at vertex 4 (the centre): keep the lower-left and upper-right cells
    tri = np.concatenate([F[[0, 4]], F[[3, 7]]])  # lower-left cell and upper-right cell
    np.testing.assert_array_equal(nonmanifold_vertices(tri, len(V)), [4])
    # charts are edge-connected, so splitting separates the two fans into two valid charts
    charts = split_charts(V, tri)
    assert len(charts) == 2 and all(4 in c.vertex_map for c in charts)
    with pytest.raises(uvbake.ChartError, match=r"non-manifold vertices .*vertices 3\b"):   # 4 compacted to 3
        check_chart(V[np.unique(tri)], np.searchsorted(np.unique(tri), tri))


def test_degenerate_nan_unreferenced_and_orientation():
    V, F = bumpy_disk(6)
    Vd = V.copy()
    Vd[F[5, 2]] = 0.5 * (Vd[F[5, 0]] + Vd[F[5, 1]])   # collinear corners: zero area
    with pytest.raises(uvbake.ChartError, match="degenerate triangles"):
        check_chart(Vd, F)
    with pytest.raises(uvbake.ChartError, match="degenerate"):
        check_chart(V, np.vstack([F, [[0, 0, 1]]]))
    Vn = V.copy()
    Vn[3, 1] = np.nan
    with pytest.raises(uvbake.InputError, match=r"NaN .*vertices 3"):
        check_chart(Vn, F)
    with pytest.raises(uvbake.ChartError, match="used by no triangle"):
        check_chart(np.vstack([V, [[9, 9, 9]]]), F)
    Fo = F.copy()
    Fo[7] = Fo[7, ::-1]
    with pytest.raises(uvbake.ChartError, match="opposite orientation"):
        check_chart(V, Fo)
    with pytest.raises(uvbake.InputError, match="outside"):
        check_chart(V, np.vstack([F, [[0, 1, len(V)]]]))
    with pytest.raises(uvbake.InputError, match=r"shape \(36, 2\)"):
        check_chart(V[:, :2], F)


def test_split_by_labels_and_components():
    V, F = bumpy_disk(9)
    centre_x = V[F].mean(axis=1)[:, 0]
    labels = np.where(centre_x < 0, 3, 7)
    charts = split_charts(V, F, labels)
    assert [c.label for c in charts] == [3, 7]
    assert sum(len(c.F) for c in charts) == len(F)
    # seam vertices are duplicated into both charts, and maps point back into V
    assert sum(len(c.V) for c in charts) > len(V)
    for c in charts:
        np.testing.assert_array_equal(c.V, V[c.vertex_map])
        np.testing.assert_array_equal(c.vertex_map[c.F], F[c.face_index])
    # one label in two separate pieces makes two charts
    labels2 = np.where(np.abs(centre_x) < 0.3, 1, 2)
    parts = split_charts(V, F, labels2)
    assert [c.label for c in parts] == [1, 2, 2]
    # components without labels
    V2 = np.vstack([V, V + [5, 0, 0]])
    F2 = np.vstack([F, F + len(V)])
    assert len(split_charts(V2, F2)) == 2
    with pytest.raises(uvbake.InputError, match="one integer per triangle"):
        split_charts(V, F, labels[:-1])


def test_parameterize_refuses_several_components():
    V, F = bumpy_disk(6)
    V2 = np.vstack([V, V + [5, 0, 0]])
    F2 = np.vstack([F, F + len(V)])
    with pytest.raises(uvbake.ChartError, match="2 connected components"):
        uvbake.parameterize(V2, F2)


def _chart_cases():
    """(V, F, check_chart accepts it) for good and bad charts of every kind check_chart names."""
    V, F = bumpy_disk(6)
    cases = [(V, F, True), (V * 1e-200, F, True), (V * 1e250, F, True)]
    keep = ~np.isin(F, [10, 20]).any(axis=1)
    holed = split_charts(V, F[keep])[0]
    cases.append((holed.V, holed.F, True))
    cases.append((*octahedron(), "cut"))                              # closed
    Vt, Ft = torus()
    cases.append((Vt, Ft[1:], "cut"))                                  # a handle
    Vd = V.copy()
    Vd[F[5, 2]] = 0.5 * (Vd[F[5, 0]] + Vd[F[5, 1]])
    cases.append((Vd, F, False))                                       # a zero-area triangle
    cases.append((np.vstack([V, [[9, 9, 9]]]), F, False))              # an unreferenced vertex
    Fo = F.copy()
    Fo[7] = Fo[7, ::-1]
    cases.append((V, Fo, False))                                       # a flipped neighbour
    inner = F[10]
    cases.append((np.vstack([V, [[0, 0, 5.0]]]), np.vstack([F, [[inner[0], inner[1], len(V)]]]), False))   # a fin
    st, Fg = grid(3, 3)
    Vg = np.column_stack([st, np.zeros(len(st))])
    tri = np.concatenate([Fg[[0, 4]], Fg[[3, 7]]])
    cases.append((Vg[np.unique(tri)], np.searchsorted(np.unique(tri), tri), False))   # a bowtie
    cases.append((np.vstack([V, V + [5, 0, 0]]), np.vstack([F, F + len(V)]), False))  # two components
    return cases


def test_charts_checked_together_are_certified_only_where_check_chart_accepts():
    """certified_disks decides all charts at once; it must never certify a chart check_chart rejects,
    and it must certify the good ones (the fast path is the point), whatever their neighbours in the
    batch or their scale; the pieces it calls closed are exactly those check_chart rejects only for
    being closed or having handles."""
    cases = _chart_cases()
    for V, F, good in cases:
        if good is True:
            check_chart(V, F)
        else:
            with pytest.raises((uvbake.ChartError, uvbake.InputError), match="closed|handle" if good == "cut" else None):
                check_chart(V, F)
    charts = [Chart(np.asarray(V, float), np.asarray(F, np.int64), np.arange(len(V)), np.arange(len(F)))
              for V, F, _ in cases]
    for order in (np.arange(len(cases)), np.arange(len(cases))[::-1]):
        sure, cut = certified_disks([charts[i] for i in order], closed=True)
        np.testing.assert_array_equal(sure, [cases[i][2] is True for i in order])
        # closed or with handles, and nothing else wrong: what the charting cuts without asking check_chart
        np.testing.assert_array_equal(cut, [cases[i][2] == "cut" for i in order])
        np.testing.assert_array_equal(certified_disks([charts[i] for i in order]), sure)


def test_boundary_loops_label_each_loop_and_measure_it():
    # a 5 x 5 grid of unit squares less its middle square: the border (20 long) and a hole (4 long)
    from uvbake.mesh.topology import boundary_edges, boundary_loops

    idx = np.arange(36).reshape(6, 6)
    x, y = np.meshgrid(np.arange(6.0), np.arange(6.0), indexing="ij")
    V = np.column_stack([x.ravel(), y.ravel(), np.zeros(36)])
    F = np.array([t for i in range(5) for j in range(5) if (i, j) != (2, 2) for t in
                  ([idx[i, j], idx[i + 1, j], idx[i + 1, j + 1]], [idx[i, j], idx[i + 1, j + 1], idx[i, j + 1]])])
    b = boundary_edges(F, 36)
    loop, length = boundary_loops(V, b)
    assert length.tolist() == pytest.approx([20.0, 4.0], abs=1e-12)       # numbered by lowest vertex
    hole = {int(idx[2, 2]), int(idx[3, 2]), int(idx[3, 3]), int(idx[2, 3])}
    assert set(b[loop == 1].ravel().tolist()) == hole
