"""Pinches (uvbake.flatten.pinches): copies repair made of one input vertex, welded for the solves."""

from pathlib import Path

import numpy as np
import pytest

import uvbake
from uvbake.atlas.conformal import conformal_factor
from uvbake.flatten.pinches import pinch_representatives, repair_copies
from uvbake.mesh.repair import repair

ROOT = Path(__file__).resolve().parents[1]


def _grid(n=7):
    """An n x n grid of unit squares in the plane, two triangles each: (V, F, index of point (i, j))."""
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    x, y = np.meshgrid(np.arange(n + 1.0), np.arange(n + 1.0), indexing="ij")
    V = np.column_stack([x.ravel(), y.ravel(), 0.1 * np.sin(x.ravel()) * np.cos(y.ravel())])
    F = []
    for i in range(n):
        for j in range(n):
            a, b, c, d = idx[i, j], idx[i + 1, j], idx[i + 1, j + 1], idx[i, j + 1]
            F.append(((i, j), [[a, b, c], [a, c, d]]))
    return V, F, idx


def _figure_eight():
    """A grid with two diagonal squares removed: a hole whose border touches itself at point (3, 3),
    a non-manifold vertex (two fans meet there) that repair splits into two copies."""
    V, cells, idx = _grid()
    F = np.array([t for (ij, tris) in cells if ij not in ((2, 2), (3, 3)) for t in tris])
    return V, F, int(idx[3, 3])


def test_repair_copies_keys_only_split_vertices():
    keys = repair_copies(np.array([0, 1, 1, 2, 3, 3, 3]))
    assert keys.tolist() == [-1, 1, 1, -1, 3, 3, 3]
    assert repair_copies(np.arange(5)) is None


def test_pinch_on_a_hole_is_welded_once():
    V, F, pinch = _figure_eight()
    rep = repair(V, F)
    copies = np.flatnonzero(rep.vertex_index == pinch)
    assert len(copies) == 2                             # repair split the bowtie vertex
    keys = repair_copies(rep.vertex_index)
    r = pinch_representatives(keys, rep.F)
    assert r is not None
    moved = np.flatnonzero(r != np.arange(len(r)))
    assert moved.tolist() == [copies.max()] and r[copies.max()] == copies.min()


def test_the_sides_of_a_cut_are_not_welded():
    # two boundary edges whose ends carry the same keys are the two sides of a cut: left apart;
    # the same copies without the twin edge are a pinch
    V, cells, idx = _grid(4)
    F = np.array([t for _, tris in cells for t in tris])
    keys = np.full(len(V), -1)
    keys[[idx[0, 0], idx[0, 4]]] = 7
    keys[[idx[1, 0], idx[1, 4]]] = 8
    assert pinch_representatives(keys, F) is None
    keys[[idx[1, 0], idx[1, 4]]] = -1
    r = pinch_representatives(keys, F)
    assert r is not None and r[idx[0, 4]] == idx[0, 0] and np.sum(r != np.arange(len(r))) == 1


def _slit_octahedron():
    """An octahedron slit open at its top vertex: the top's faces on the -y side take a copy of it, so
    the surface is a disk whose boundary runs +x, top, -x, copy; the two tops share a pinch key."""
    V = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1], [0, 0, 1]], float)
    F = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 6], [3, 0, 6],           # the top fan, -y side on the copy 6
                  [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])
    keys = np.full(len(V), -1)
    keys[[4, 6]] = 4
    return V, F, keys


def test_copies_whose_weld_would_close_the_chart_stay_apart():
    # welding the two tops would close the slit and leave the chart no boundary to flatten (a non-manifold
    # fin detached by repair made such a slit on a scan: the conformal solve then had nothing to pin)
    V, F, keys = _slit_octahedron()
    assert pinch_representatives(keys, F) is None
    uv, logf = conformal_factor(V, F, keys=keys)
    assert np.all(np.isfinite(uv)) and np.ptp(uv[[4, 6]], axis=0).max() > 1e-6
    # laid end to end with a chart whose pinch may be welded, only that one is
    V8, F8, pinch = _figure_eight()
    rep = repair(V8, F8)
    k8 = repair_copies(rep.vertex_index)
    both = pinch_representatives(np.concatenate([keys, k8]), np.vstack([F, rep.F + len(V)]),
                                 np.repeat([0, 1], [len(V), len(rep.V)]))
    moved = np.flatnonzero(both != np.arange(len(both)))
    assert len(moved) == 1 and moved[0] >= len(V)


def test_a_welded_soups_coincident_vertices_left_apart_are_copies():
    # a subdivided box with holes, as a triangle soup (bench/sweep.py seed 9, draw 70): repair welds it but
    # leaves apart coincident vertices whose weld would make a bowtie; two of them, on one chart's
    # boundary 3e-14 apart in its map, met as a crossing once packed (one overlapping pair, a valid
    # atlas's check said INVALID). Keyed as copies they are welded for the solve like repair's own.
    d = np.load(Path(__file__).parent / "data" / "box_soup_holes.npz")
    V, F = d["V"], d["F"].astype(np.int64)
    rep = repair(V, F)
    assert rep.welded
    keys = repair_copies(rep.vertex_index, rep.V)
    # two vertices share a key exactly when they sit at one position
    same = (keys[:, None] == keys[None, :]) & (keys[:, None] >= 0)
    at = (rep.V[:, None, :] == rep.V[None, :, :]).all(axis=2)
    off = ~np.eye(len(keys), dtype=bool)
    assert np.array_equal(same[off], at[off]) and at[off].any()
    own = repair_copies(rep.vertex_index)                 # repair's copies of one input vertex alone
    assert (keys >= 0).sum() > (0 if own is None else (own >= 0).sum())
    res = uvbake.unwrap((V, F), alpha=0.5)
    assert res.report["valid"] and res.report["pinches_welded"] > 0


def test_conformal_map_gives_the_copies_one_uv():
    V, F, pinch = _figure_eight()
    rep = repair(V, F)
    copies = np.flatnonzero(rep.vertex_index == pinch)
    keys = repair_copies(rep.vertex_index)
    apart, _ = conformal_factor(rep.V, rep.F)
    together, logf = conformal_factor(rep.V, rep.F, keys=keys)
    assert np.ptp(together[copies], axis=0).max() == 0.0
    assert np.ptp(apart[copies], axis=0).max() > 1e-6     # without the weld the copies move apart
    assert np.all(np.isfinite(logf))                      # no triangle flips or collapses


def test_unwrap_keeps_the_pinch_one_point_and_the_atlas_valid():
    V, F, pinch = _figure_eight()
    r = uvbake.unwrap((V, F), alpha=0.5)
    assert r.report["valid"] and r.report["charts_final"] == 1
    at = np.asarray(F) == pinch                          # the corners at the pinch, in the input's faces
    uv = np.asarray(r.corner_uv)[at]
    assert len(uv) == 2 and np.ptp(uv, axis=0).max() <= 1e-12    # one corner in each fan
    assert r.report["pinches_welded"] == 1


def test_the_report_counts_each_welded_pinch_once():
    V, F, _ = _two_figure_eights()
    r = uvbake.unwrap((V, F), alpha=0.5)
    assert r.report["charts_final"] == 1 and r.report["pinches_welded"] == 2
    assert uvbake.unwrap(str(ROOT / "sample_scenes" / "sphere_cap.ply"), alpha=0.5).report["pinches_welded"] == 0


def _merged_border_vertices():
    """A grid whose border vertices (0, 3) and (3, 0) are made one: a pinch on the outer border, the
    merged vertex's two fans far apart along the surface."""
    V, cells, idx = _grid()
    F = np.array([t for _, tris in cells for t in tris])
    return V, np.where(F == idx[3, 0], idx[0, 3], F), int(idx[0, 3])


def _two_figure_eights():
    """Two figure-eight holes (diagonal squares removed in pairs): two pinches in one chart."""
    V, cells, idx = _grid(9)
    F = np.array([t for (ij, tris) in cells if ij not in ((2, 2), (3, 3), (5, 5), (6, 6)) for t in tris])
    return V, F, int(idx[3, 3])


@pytest.mark.parametrize("make", [_figure_eight, _merged_border_vertices, _two_figure_eights])
@pytest.mark.parametrize("alpha", [0.0, 0.5, 0.9])
def test_pinched_meshes_unwrap_valid_with_every_triangle_its_texels(make, alpha):
    V, F, _ = make()
    r = uvbake.unwrap((V, F), alpha=alpha)
    assert r.report["valid"], r.report["atlas"]["validation"]["summary"]
    assert r.report["min_texel_share"] >= 1 / 16 and r.report["area_below_quarter"] <= 0.005
