"""Segmentation: short, valid cuts for bisection, flip repair and closed / handled charts."""

import time

import numpy as np
import pytest

from uvbake.errors import ChartError, InputError
from uvbake.io.load import load_mesh
from uvbake.mesh.charts import check_chart, split_charts
from uvbake.mesh.cut import bisect, cut_to_disks, seam_length, split_where
from uvbake.mesh.topology import topology

from conftest import shared_mesh
from meshgen import bumpy_disk, grid, torus


def sphere(subdiv=3):
    import trimesh

    s = trimesh.creation.icosphere(subdivisions=subdiv)
    return np.asarray(s.vertices, float), np.asarray(s.faces, np.int64)


def _parts_valid(V, F, labels, k=None):
    """Every label is one valid chart (check_chart raises otherwise)."""
    charts = split_charts(V, F, labels)            # also splits labels that are not edge-connected
    assert len(charts) == len(np.unique(labels))
    if k is not None:
        assert len(charts) == k
    return charts


def test_bisect_bumpy_disk_gives_two_valid_balanced_parts():
    V, F = bumpy_disk(20)
    lab = bisect(V, F)
    assert set(np.unique(lab)) == {0, 1}
    charts = _parts_valid(V, F, lab, 2)
    assert min(len(c.F) for c in charts) >= 0.1 * len(F)


def test_bisect_cuts_a_long_strip_across_its_width():
    st, F = grid(61, 7)
    V = np.column_stack([6.0 * st[:, 0], 1.0 * st[:, 1], 0.1 * np.sin(4 * st[:, 0])])
    lab = bisect(V, F)
    _parts_valid(V, F, lab, 2)
    L = seam_length(V, F, lab)
    assert 1.0 <= L < 1.6, L                       # about the width (1), far below the length (6)
    assert min(np.bincount(lab)) >= 0.1 * len(F)


def _folded_strip(fold_at, up):
    """A 6 x 1 strip (grid 61 x 7, normals +z) folded by 90 degrees across its length at x = fold_at:
    the part beyond the fold turns up (a valley on the normals' side) or down (a ridge)."""
    st, F = grid(61, 7)
    x, y = 6.0 * st[:, 0], st[:, 1]
    beyond = x > fold_at
    z = np.where(beyond, (x - fold_at) * (1.0 if up else -1.0), 0.0)
    return np.column_stack([np.where(beyond, fold_at, x), y, z]), F


@pytest.mark.parametrize("up", [True, False])
def test_seam_costs_discount_creases_and_valleys_most(up):
    from uvbake.mesh.cut import RIDGE_COST, VALLEY_COST, _dual_edges, seam_costs

    V, F = _folded_strip(2.4, up)
    fi, fj, ea, eb, _, _ = _dual_edges(F, len(V))
    length = np.linalg.norm(V[ea] - V[eb], axis=1)
    cost = seam_costs(V, F, fi, fj, ea, eb)
    on_fold = np.isclose(V[ea, 0], 2.4, atol=1e-12) & np.isclose(V[eb, 0], 2.4, atol=1e-12) & \
        np.isclose(V[ea, 2], 0.0, atol=1e-12) & np.isclose(V[eb, 2], 0.0, atol=1e-12)
    assert on_fold.sum() == 6                                   # the fold's 6 edges
    assert np.allclose(cost[on_fold], (VALLEY_COST if up else RIDGE_COST) * length[on_fold], rtol=1e-12)
    assert np.allclose(cost[~on_fold], length[~on_fold], rtol=1e-12)   # flat elsewhere: the length


@pytest.mark.parametrize("up", [True, False])
def test_bisect_cuts_along_a_crease_rather_than_across_the_middle(up):
    # flat, the strip is cut across its middle (x = 3); folded at x = 2.4, the cut moves to the fold
    def cut_position(V, F, lab):
        along = V[:, 0] + np.abs(V[:, 2])                        # arclength along the strip
        c = along[F].mean(axis=1)
        return c[lab == 0].max(), c[lab == 1].min()

    st, F = grid(61, 7)
    flat = np.column_stack([6.0 * st[:, 0], st[:, 1], np.zeros(len(st))])
    lo, hi = sorted(cut_position(flat, F, bisect(flat, F)))
    assert 2.8 < lo <= hi < 3.2                                 # the middle, within two grid columns
    V, F = _folded_strip(2.4, up)
    lab = bisect(V, F)
    _parts_valid(V, F, lab, 2)
    lo, hi = sorted(cut_position(V, F, lab))
    assert 2.25 < lo <= hi < 2.55                               # at the fold, within 1.5 grid steps (0.1)
    assert seam_length(V, F, lab) < 1.1


def test_bisect_is_deterministic_and_rejects_disconnected_input():
    V, F = bumpy_disk(12)
    assert np.array_equal(bisect(V, F), bisect(V, F))
    F2 = np.vstack([F, F + len(V)])
    V2 = np.vstack([V, V + 5])
    with pytest.raises(InputError, match="edge-connected pieces"):
        bisect(V2, F2)


def test_cut_to_disks_sphere_two_disks():
    V, F = sphere(3)
    lab = cut_to_disks(V, F)
    charts = _parts_valid(V, F, lab, 2)
    for c in charts:
        topo = topology(c.F)
        assert topo.genus == 0 and topo.n_boundary_loops == 1
    # a single closed loop around the sphere: under 1.5 x the great circle
    assert seam_length(V, F, lab) < 1.5 * 2 * np.pi


def test_cut_to_disks_torus_all_parts_disks_with_holes():
    V, F = torus(32, 16, r=0.6)
    lab = cut_to_disks(V, F)
    charts = _parts_valid(V, F, lab)
    assert 2 <= len(charts) <= 4
    for c in charts:
        assert check_chart(c.V, c.F).genus == 0


def test_cut_to_disks_leaves_disks_alone_and_handles_several_pieces():
    V, F = bumpy_disk(10)
    assert np.array_equal(cut_to_disks(V, F), np.zeros(len(F)))
    Vs, Fs = sphere(2)
    V2 = np.vstack([V, Vs + 5])
    F2 = np.vstack([F, Fs + len(V)])
    lab = cut_to_disks(V2, F2)
    _parts_valid(V2, F2, lab, 3)
    assert np.all(lab[: len(F)] == 0)


def test_cut_to_disks_rejects_nonmanifold_input():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0]], float)
    with pytest.raises(ChartError, match="non-manifold vertices.*repair"):
        cut_to_disks(V, np.array([[0, 1, 2], [0, 3, 4]]))


@pytest.mark.parametrize("name", ["cow.off", "fandisk.off", "bumpy.off"])
def test_cut_to_disks_research_meshes(name):
    m = load_mesh(shared_mesh(name))
    t = time.perf_counter()
    lab = cut_to_disks(m.V, m.F)
    dt = time.perf_counter() - t
    charts = _parts_valid(m.V, m.F, lab)
    assert len(charts) == 2                          # closed genus 0: one cut, two charts
    assert dt < 10


def test_split_where_separates_a_bad_patch():
    V, F = bumpy_disk(24)
    c = V[F].mean(axis=1)
    bad = np.flatnonzero(np.linalg.norm(c[:, :2] - [0.6, 0.6], axis=1) < 0.2)
    lab = split_where(V, F, bad)
    charts = _parts_valid(V, F, lab, 2)
    assert np.mean(lab[bad] == 1) >= 0.9            # the bad faces go together to side 1 ...
    assert np.sum(lab == 1) <= 0.55 * len(F)        # ... which is not most of the chart
    assert min(len(c.F) for c in charts) >= 1
    # a bool mask works too, and the cut is reasonably short (not longer than the chart's width x 2)
    mask = np.zeros(len(F), bool)
    mask[bad] = True
    assert np.array_equal(split_where(V, F, mask), lab)
    assert seam_length(V, F, lab) < 4.0


def test_split_where_two_bad_clusters_and_fallbacks():
    V, F = bumpy_disk(16)
    c = V[F].mean(axis=1)
    bad = np.flatnonzero((np.linalg.norm(c[:, :2] - [0.7, 0.7], axis=1) < 0.15)
                         | (np.linalg.norm(c[:, :2] + [0.7, 0.7], axis=1) < 0.15))
    lab = split_where(V, F, bad)
    _parts_valid(V, F, lab, 2)
    assert np.mean(lab[bad] == 1) >= 0.5
    for b in ([], np.arange(len(F))):               # nothing bad / everything bad: plain bisection
        lab = split_where(V, F, b)
        _parts_valid(V, F, lab, 2)
    with pytest.raises(InputError, match="outside"):
        split_where(V, F, [len(F)])


@pytest.mark.parametrize("up", [True, False])
def test_seam_placement_measures_the_share_of_seams_on_creases_and_valleys(up):
    from uvbake.analysis.metrics import seam_placement
    from uvbake.mesh.cut import RIDGE_COST, VALLEY_COST

    V, F = _folded_strip(2.4, up)
    along = V[:, 0] + np.abs(V[:, 2])
    uv = np.column_stack([along, V[:, 1]])[F]                     # the strip unfolded, per corner
    beyond = along[F].mean(axis=1) > 2.4
    uv[beyond] += [0.5, 0.0]                                    # cut at the fold: the far side moves
    s = seam_placement(V, F, uv)
    assert np.isclose(s["seam_length"], 1.0, rtol=1e-12)
    assert s["on_creases"] == pytest.approx(1.0, abs=1e-12)
    assert s["on_valleys"] == pytest.approx(1.0 if up else 0.0, abs=1e-12)
    assert s["cost_per_length"] == pytest.approx(VALLEY_COST if up else RIDGE_COST, rel=1e-12)
    uv2 = np.column_stack([along, V[:, 1]])[F]
    uv2[along[F].mean(axis=1) > 3.0] += [0.5, 0.0]              # cut across the flat part instead
    s2 = seam_placement(V, F, uv2)
    assert s2["on_creases"] == 0.0 and s2["cost_per_length"] == pytest.approx(1.0, rel=1e-12)


def test_small_pieces_take_the_dense_fiedler_vector_the_iterative_one_approximates(monkeypatch):
    import uvbake.mesh.cut as cut
    from uvbake.mesh.topology import face_adjacency

    V, F = bumpy_disk(10)                                # 162 jittered triangles (a simple eigenvalue)
    m = len(F)
    fi, fj, e = face_adjacency(F, len(V))
    w = np.linalg.norm(V[e[:, 0]] - V[e[:, 1]], axis=1)
    X = V[F]
    mass = 0.5 * np.linalg.norm(np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0]), axis=1)
    assert m <= cut.DENSE_FIEDLER
    dense = cut._fiedler(m, fi, fj, w, mass)
    monkeypatch.setattr(cut, "DENSE_FIEDLER", 0)
    lobpcg = cut._fiedler(m, fi, fj, w, mass)
    # the same generalized eigenvector up to sign and LOBPCG's tolerance (1e-5 on the residual)
    cos = abs(dense @ (mass * lobpcg)) / np.sqrt((dense @ (mass * dense)) * (lobpcg @ (mass * lobpcg)))
    assert cos == pytest.approx(1.0, abs=1e-4)
    # M-orthogonal to the constants, as LOBPCG's is constrained to be; its sign fixed (largest entry > 0)
    assert abs(mass @ dense) <= 1e-9 * np.abs(mass * dense).sum()
    assert dense[np.argmax(np.abs(dense))] > 0


def test_dense_laplacian_is_the_sparse_one():
    """Small pieces build their dual Laplacian densely (no scipy.sparse conversions): the off-diagonal
    entries are the sparse construction's exactly and each degree within two ulps (bit-equal with the
    scipy releases so far, which keeps the cuts the same)."""
    import uvbake.mesh.cut as cut
    from uvbake.mesh.topology import face_adjacency

    rng = np.random.default_rng(4)
    for V, F in (sphere(1), sphere(2), bumpy_disk(6), torus(12, 6, r=0.5)):
        V = V * rng.uniform(0.5, 2.0, 3) + rng.normal(0, 0.02, V.shape)
        fi, fj, e = face_adjacency(F, len(V))
        w = np.linalg.norm(V[e[:, 0]] - V[e[:, 1]], axis=1)
        w = w / w.mean()
        dense = cut._dense_laplacian(len(F), fi, fj, w)
        sparse = cut._laplacian(len(F), fi, fj, w).toarray()
        off = ~np.eye(len(F), dtype=bool)
        assert np.array_equal(dense[off], sparse[off])                  # the weights, exactly
        # the degrees: sums of the same (at most three) weights; to the bit with the row sum of scipy's
        # releases so far (add.reduceat by column), within two ulps whatever order a release adds them in
        np.testing.assert_array_max_ulp(np.diag(dense), np.diag(sparse), maxulp=2)
        assert np.allclose(dense.sum(axis=1), 0.0, atol=1e-12)         # a Laplacian: rows sum to zero
    # a pair listed twice (two triangles sharing two edges) takes the sparse path: the same matrix
    fi2, fj2, w2 = np.array([0, 0, 1]), np.array([1, 1, 2]), np.array([0.5, 0.25, 1.0])
    assert np.array_equal(cut._dense_laplacian(3, fi2, fj2, w2), cut._laplacian(3, fi2, fj2, w2).toarray())


def test_cut_to_disks_cuts_each_closed_sphere_of_a_kit_into_two_disks():
    """A closed genus-0 piece is bisected once and its two sides are not checked again (each is a disk
    with holes by bisect's contract): every part of a kit of spheres is a disk, two per sphere."""
    Vs, Fs = sphere(1)
    V = np.vstack([Vs + 3 * k for k in range(5)])
    F = np.vstack([Fs + k * len(Vs) for k in range(5)])
    lab = cut_to_disks(V, F)
    charts = _parts_valid(V, F, lab, 10)
    for c in charts:
        topo = topology(c.F)
        assert topo.genus == 0 and topo.n_boundary_loops == 1 and topo.n_components == 1


def test_bisect_tries_other_level_sets_when_the_median_cannot_be_made_valid(monkeypatch):
    # a label's region of a holey torus (a randomised sweep's draw), where the Fiedler sweep's and the
    # median's sides each met themselves at a vertex on the machine that found it. Whether they do there
    # hangs on the field's last bits, so the first two attempts are made to fail here on any CPU: a later
    # level set must cut the region validly (without the fallback bisect raises)
    from pathlib import Path

    from uvbake.mesh import cut

    real, calls = cut._make_valid, []

    def sweep_and_median_fail(*args):
        labels, ok = real(*args)
        calls.append(ok)
        return (labels, False) if len(calls) <= 2 else (labels, ok)

    monkeypatch.setattr(cut, "_make_valid", sweep_and_median_fail)
    d = np.load(Path(__file__).parent / "data" / "holey_torus_region.npz")
    V, F = d["V"], d["F"].astype(np.int64)
    labels = bisect(V, F)
    assert len(calls) >= 3 and calls[-1]
    assert set(np.unique(labels)) == {0, 1} and min(np.bincount(labels)) >= 0.1 * len(F)
    for k in (0, 1):                                   # each side a valid chart
        used, inv = np.unique(F[labels == k], return_inverse=True)
        check_chart(V[used], inv.reshape(-1, 3))
