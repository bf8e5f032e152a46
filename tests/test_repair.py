"""Mesh repair: every defect reconstruction produces is fixed or split, reported, and mapped back."""

import json

import numpy as np
import pytest

from uvbake.errors import ChartError, InputError
from uvbake.mesh.charts import check_chart, split_charts
from uvbake.mesh.repair import repair
from uvbake.mesh.topology import nonmanifold_vertices, topology

from meshgen import bumpy_disk, grid


def _edge_counts(F):
    e = np.sort(F[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    return np.unique(e, axis=0, return_counts=True)[1]


def _assert_maps_back(res, V, F):
    """Every output vertex sits where its input vertex was; every output triangle is its input one."""
    assert np.array_equal(res.V, V[res.vertex_index])
    out = res.V[res.F]                         # (m',3,3)
    inp = V[F[res.face_index]]
    # same corners up to order (winding may be flipped)
    assert np.allclose(np.sort(out.sum(axis=1), axis=0), np.sort(inp.sum(axis=1), axis=0))
    assert np.allclose(np.sort((out ** 2).sum(axis=(1, 2))), np.sort((inp ** 2).sum(axis=(1, 2))))
    assert np.allclose(out.sum(axis=1), inp.sum(axis=1))


def _kinds(res):
    return {a["kind"]: a for a in res.actions}


def test_clean_mesh_is_unchanged():
    V, F = bumpy_disk(10)
    res = repair(V, F)
    assert res.actions == [] and res.warnings == []
    assert np.array_equal(res.V, V) and np.array_equal(res.F, F)
    assert np.array_equal(res.face_index, np.arange(len(F)))
    assert np.array_equal(res.vertex_index, np.arange(len(V)))


def test_bowtie_vertex_is_split_into_fans():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0]], float)
    F = np.array([[0, 1, 2], [0, 3, 4]])
    assert len(nonmanifold_vertices(F, 5)) == 1
    res = repair(V, F)
    assert len(res.V) == 6 and len(nonmanifold_vertices(res.F, len(res.V))) == 0
    assert sorted(res.vertex_index.tolist()) == [0, 0, 1, 2, 3, 4]
    assert _kinds(res)["split_nonmanifold_vertices"]["examples"] == [0]
    for c in split_charts(res.V, res.F):          # two valid single-triangle charts
        check_chart(c.V, c.F)
    _assert_maps_back(res, V, F)


def _c_shaped_label():
    """A flat 4 x 4-cell grid (two triangles a cell, every diagonal towards the cell's upper right corner)
    whose label 1 runs from cell (1,1) round through (0,1) ... (2,3) to cell (2,2): one edge-connected
    region that touches itself at vertex (2,2) only, where the label's two fans meet. The whole mesh is
    a manifold disk; around (2,2) the labels alternate cell by cell, so label 0's region (the rest, also
    one region) is pinched there too."""
    x, y = np.meshgrid(np.arange(5.0), np.arange(5.0), indexing="ij")
    V = np.column_stack([x.ravel(), y.ravel(), np.zeros(25)])
    vid = np.arange(25).reshape(5, 5)
    F, cells = [], []
    for i in range(4):                                  # one iteration per cell (16): the test's fixture
        for j in range(4):
            a, b, c, d = vid[i, j], vid[i + 1, j], vid[i + 1, j + 1], vid[i, j + 1]
            F += [[a, b, c], [a, c, d]]
            cells += [(i, j), (i, j)]
    ring = {(1, 1), (0, 1), (0, 2), (0, 3), (1, 3), (2, 3), (2, 2)}
    labels = np.array([1 if cell in ring else 0 for cell in cells])
    return V, np.array(F), labels, int(vid[2, 2])


def test_a_label_region_touching_itself_at_a_vertex_gets_a_copy_of_it_per_fan():
    V, F, labels, pinch = _c_shaped_label()
    assert len(nonmanifold_vertices(F, len(V))) == 0              # the mesh itself is clean
    assert repair(V, F).actions == []
    for k in (0, 1):
        assert nonmanifold_vertices(F[labels == k], len(V)).tolist() == [pinch]
    res = repair(V, F, face_labels=labels)
    # one copy for each label's second fan; the rest of the vertex's triangles keep it
    assert [(a["kind"], a["count"], a["examples"]) for a in res.actions] == [("split_label_pinches", 2, [pinch])]
    assert len(res.V) == len(V) + 2 and sorted(res.vertex_index.tolist()) == sorted([*range(len(V)), pinch, pinch])
    lab = labels[res.face_index]
    for k in (0, 1):                                              # each label's region is manifold on its own
        assert len(nonmanifold_vertices(res.F[lab == k], len(res.V))) == 0
    for c in split_charts(res.V, res.F, lab):
        check_chart(c.V, c.F)
    _assert_maps_back(res, V, F)
    again = repair(res.V, res.F, face_labels=lab)                 # idempotent with labels too
    assert again.actions == [] and np.array_equal(again.F, res.F)


def test_a_pinched_label_region_unwraps_into_charts_of_one_label():
    from uvbake.atlas.pipeline import unwrap

    V, F, labels, pinch = _c_shaped_label()
    r = unwrap((V, F), face_labels=labels, alpha=0.5, texture_size_px=128, gutter_px=1)
    assert r.report["valid"] and r.report["min_texel_share"] >= 1 / 16
    res = repair(V, F, face_labels=labels)
    lab = labels[res.face_index]
    assert {c.label for c in r.charts} == {0, 1}
    assert all(len(np.unique(lab[c.face_index])) == 1 for c in r.charts)
    with pytest.raises(ChartError, match="non-manifold vertices"):   # unrepaired, the region is refused
        unwrap((V, F), face_labels=labels, repair=False)


def test_nonmanifold_edge_keeps_the_best_pair_and_detaches_the_rest():
    # a flat quad (0,1,2),(1,0,3) with a fin (0,1,4) standing up on the shared edge
    V = np.array([[0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, -1, 0], [0.5, 0, 1]], float)
    F = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])
    assert _edge_counts(F).max() == 3
    res = repair(V, F)
    assert _edge_counts(res.F).max() <= 2
    assert len(nonmanifold_vertices(res.F, len(res.V))) == 0
    charts = split_charts(res.V, res.F)
    assert sorted(len(c.F) for c in charts) == [1, 2]
    big = max(charts, key=lambda c: len(c.F))
    assert sorted(big.face_index.tolist()) == [0, 1]   # the coplanar, consistent pair stays joined
    assert _kinds(res)["split_nonmanifold_edges"]["count"] == 1
    assert any(w.startswith("split 1 non-manifold edge (edges ") for w in res.warnings)
    _assert_maps_back(res, V, F)


def test_specks_are_dropped_with_a_warning():
    V, F = bumpy_disk(12)
    far = V[:3] + 10.0
    V2 = np.vstack([V, far])
    F2 = np.vstack([F, [[len(V), len(V) + 1, len(V) + 2]]])
    res = repair(V2, F2, min_component_faces=5)
    assert len(res.F) == len(F) and len(res.V) == len(V)
    assert not np.isin(len(F), res.face_index)
    assert _kinds(res)["drop_small_components"]["count"] == 1
    assert any(w.startswith("dropped 1 small piece (< 5 triangles each, 1 triangle: ") for w in res.warnings)
    # the default threshold keeps small meshes whole
    assert len(repair(V2, F2).F) == len(F2)


def test_duplicated_seam_vertices_are_welded_into_one_piece_when_asked_and_kept_as_a_cut_by_default():
    st, F = grid(9, 7)
    V = np.column_stack([st, 0.2 * np.sin(3 * st[:, 0])])
    # the left half keeps the middle column; the right half gets its own copies of it
    mid = np.isclose(st[:, 0], 0.5)
    right = (V[F][:, :, 0].mean(axis=1) > 0.5)
    copy = np.flatnonzero(mid)
    remap = np.arange(len(V))
    remap[copy] = len(V) + np.arange(len(copy))
    V2 = np.vstack([V, V[copy]])
    F2 = F.copy()
    F2[right] = remap[F2[right]]
    assert topology(F2, len(V2)).n_components == 2
    kept = repair(V2, F2)                      # the user's cut is their seam: nothing welded
    assert "weld_vertices" not in _kinds(kept) and topology(kept.F, len(kept.V)).n_components == 2
    res = repair(V2, F2, weld=True)
    assert _kinds(res)["weld_vertices"]["count"] == len(copy)
    topo = check_chart(res.V, res.F)
    assert topo.n_components == 1 and topo.n_boundary_loops == 1
    assert len(res.V) == len(V)
    _assert_maps_back(res, V2, F2)


def test_a_triangle_soup_is_welded_by_default():
    st, F = grid(5, 4)
    V = np.column_stack([st, 0.1 * st[:, 0] ** 2])
    Vs, Fs = V[F].reshape(-1, 3), np.arange(3 * len(F)).reshape(-1, 3)   # every triangle its own corners
    res = repair(Vs, Fs)
    assert _kinds(res)["weld_vertices"]["count"] > 0
    topo = check_chart(res.V, res.F)
    assert topo.n_components == 1 and len(res.V) == len(V)
    assert "weld_vertices" not in _kinds(repair(Vs, Fs, weld=False))


def test_touching_pieces_are_not_welded():
    # two triangles meeting at one coincident corner (separate vertices): welding would make a bowtie
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 0], [-1, 0, 0], [0, -1, 0]], float)
    F = np.array([[0, 1, 2], [3, 4, 5]])
    res = repair(V, F)
    assert res.actions == [] and len(res.V) == 6


def test_nan_and_degenerate_faces_are_dropped_and_reported():
    V, F = bumpy_disk(8)
    n = len(V)
    V2 = np.vstack([V, [[np.nan, 0, 0], [5, 5, 5], [6, 6, 6], [7, 7, 7]]])
    F2 = np.vstack([F, [[0, 1, n]],                      # NaN vertex
                    [[2, 2, 3]],                        # repeated vertex
                    [[n + 1, n + 2, n + 3]]])          # collinear: zero area
    res = repair(V2, F2)
    k = _kinds(res)
    assert k["drop_nonfinite_faces"]["examples"] == [len(F)]
    assert k["drop_degenerate_faces"]["count"] == 2
    assert sorted(k["drop_degenerate_faces"]["examples"]) == [len(F) + 1, len(F) + 2]
    assert k["drop_unreferenced_vertices"]["count"] == 4
    assert np.array_equal(res.face_index, np.arange(len(F)))
    assert np.array_equal(res.F, F) and np.array_equal(res.V, V)
    json.dumps(res.to_dict())                            # JSON-ready report


def test_inconsistent_winding_is_fixed_by_majority():
    V, F = bumpy_disk(8)
    F2 = F.copy()
    flip = np.arange(len(F)) % 7 == 0
    F2[flip] = F2[flip][:, ::-1]
    res = repair(V, F2)
    assert _kinds(res)["flip_faces"]["count"] == int(flip.sum())
    check_chart(res.V, res.F)
    assert np.array_equal(res.F, F[res.face_index]) or np.array_equal(np.sort(res.F, 1), np.sort(F, 1))
    # orientation of the majority (the original one) is kept: normals agree with the input's
    n_in = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    n_out = np.cross(res.V[res.F[:, 1]] - res.V[res.F[:, 0]], res.V[res.F[:, 2]] - res.V[res.F[:, 0]])
    assert np.all(np.einsum("ij,ij->i", n_in[res.face_index], n_out) > 0)


def moebius(nu=24, nv=3):
    u = np.linspace(0, 2 * np.pi, nu, endpoint=False)
    v = np.linspace(-0.3, 0.3, nv)
    U, W = np.meshgrid(u, v, indexing="ij")
    X = np.stack([(1 + W * np.cos(U / 2)) * np.cos(U), (1 + W * np.cos(U / 2)) * np.sin(U),
                  W * np.sin(U / 2)], -1).reshape(-1, 3)
    idx = np.arange(nu * nv).reshape(nu, nv)
    nxt = np.roll(idx, -1, 0)
    nxt[-1] = idx[0, ::-1]                       # the half twist: the last column joins reversed
    a, b, c, d = idx[:, :-1], nxt[:, :-1], nxt[:, 1:], idx[:, 1:]
    F = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    return X, F


def test_moebius_strip_is_cut_into_an_orientable_disk():
    V, F = moebius()
    topo0 = topology(F, len(V))
    assert topo0.n_boundary_loops == 1 and topo0.n_components == 1
    res = repair(V, F)
    assert "cut_nonorientable" in _kinds(res)
    assert any("non-orientable" in w for w in res.warnings)
    topo = check_chart(res.V, res.F)                # consistently oriented, manifold disk
    assert topo.genus == 0 and len(res.F) == len(F)
    _assert_maps_back(res, V, F)


def _messy():
    V, F = bumpy_disk(10, seed=3)
    n = len(V)
    extra_v = np.array([[np.nan, 0, 0], [9, 9, 9], [9.1, 9, 9], [9, 9.1, 9]])
    V2 = np.vstack([V, extra_v, V[:1]])                 # the last is a duplicate, unused
    F2 = np.vstack([F, [[0, 1, n]], [[n + 1, n + 2, n + 3]], F[:3], [[4, 4, 5]]])
    F2[5] = F2[5][::-1]
    return V2, F2


def test_repair_is_idempotent():
    V, F = _messy()
    res = repair(V, F, min_component_faces=2)
    assert res.actions
    again = repair(res.V, res.F, min_component_faces=2)
    assert again.actions == [] and again.warnings == []
    assert np.array_equal(again.V, res.V) and np.array_equal(again.F, res.F)
    check_chart(res.V, res.F)
    _assert_maps_back(res, V, F)


def test_malformed_input_names_the_elements():
    V, F = bumpy_disk(6)
    bad = F.copy()
    bad[3, 1] = len(V) + 4
    with pytest.raises(InputError, match=r"triangles 3 index vertices outside"):
        repair(V, bad)
    with pytest.raises(InputError, match=r"shape"):
        repair(V[:, :2], F)


def test_shared_meshes_are_clean(shared_meshes):
    from uvbake.io.load import load_mesh

    for name in ("halftunnel.off", "cow.off"):
        m = load_mesh(shared_meshes / name)
        res = repair(m.V, m.F)
        assert res.actions == [], (name, res.actions)
