"""Holes filled with light fans for the solve (uvbake.flatten.holes)."""

from pathlib import Path

import numpy as np
import pytest

from uvbake.flatten.energy import DistortionEnergy
from uvbake.flatten.holes import HOLE_WEIGHT, hole_fans, holes, with_hole_fans
from uvbake.flatten.options import SolveOptions
from uvbake.flatten.solve import solve_chart

from meshgen import bumpy_disk, grid

ROOT = Path(__file__).resolve().parent.parent


def _grid_without(cells, nu=12, nv=12):
    """A planar grid with the cells ``cells`` ((i, j) of its (nu-1) x (nv-1) squares) removed."""
    st, F = grid(nu, nv)
    cell = np.concatenate([np.arange((nu - 1) * (nv - 1))] * 2)        # both triangles of each square
    drop = np.isin(cell, [i * (nv - 1) + j for i, j in cells])
    F = F[~drop]
    used = np.unique(F)
    remap = np.full(len(st), -1)
    remap[used] = np.arange(len(used))
    return np.column_stack([st[used], np.zeros(len(used))]), remap[F], st[used]


def test_holes_are_counted_and_only_holes_get_fans():
    V, F, st = _grid_without([(3, 3), (3, 4), (4, 3), (4, 4), (7, 7)])  # a 2x2 hole and a 1x1 hole
    assert holes(F) == 2 and holes(bumpy_disk(n=6)[1]) == 0
    Vh, Sh, Fh = hole_fans(V, F, st)
    assert len(Vh) == 2 and len(Fh) == 8 + 4                             # one fan triangle per border edge
    assert np.allclose(np.sort(Vh[:, 0]), [4 / 11, 7.5 / 11], atol=1e-12)
    Va, Fa, w, Sa = with_hole_fans(V, F, st)
    assert np.array_equal(Va[:len(V)], V) and np.array_equal(Fa[:len(F)], F)
    assert np.array_equal(w, np.r_[np.ones(len(F)), np.full(12, HOLE_WEIGHT)])
    # the identity map is an isometry of the plane: the fans too are positive and undistorted
    e = DistortionEnergy(Va, Fa, alpha=0.5, weights=w)
    assert np.all(e.determinants(Sa) > 0) and e.value(Sa) == pytest.approx(0.0, abs=1e-20)


def test_a_hole_not_star_shaped_about_its_mean_is_left_open():
    # a C-shaped hole: the mean of its border lies in the notch, outside the hole
    c_shape = [(3, 3), (3, 4), (3, 5), (3, 6), (4, 3), (5, 3), (6, 3), (6, 4), (6, 5), (6, 6)]
    V, F, st = _grid_without(c_shape)
    assert holes(F) == 1 and hole_fans(V, F, st) is None
    Va, Fa, w, _ = with_hole_fans(V, F, st)
    assert Va is V and Fa is F and w is None


def test_a_chart_without_holes_solves_to_the_same_bits_with_fill_holes_on():
    V, F = bumpy_disk(n=8)
    plain = solve_chart((V, F), SolveOptions(alpha=0.5))
    filled = solve_chart((V, F), SolveOptions(alpha=0.5, fill_holes=True))
    assert np.array_equal(plain.uv, filled.uv) and plain.energy == filled.energy


def test_filled_holes_keep_the_sphere_caps_hole_from_folding_over():
    """The shipped spherical cap at alpha 0.5: its conformal map solved as is folds one hole's border
    over (overlapping triangles); with the holes filled nothing overlaps, F of the chart's own triangles
    is within 1 % of the plain minimum's, and the result holds only the chart's own vertices."""
    from uvbake.atlas.conformal import conformal_factor
    from uvbake.io import load_mesh
    from uvbake.validate.core import overlap_pairs

    mesh = load_mesh(str(ROOT / "sample_scenes" / "sphere_cap.ply"))
    V, F = mesh.V, mesh.F
    assert holes(F) == 2
    start, _ = conformal_factor(V, F)
    plain = solve_chart((V, F), SolveOptions(alpha=0.5), start=start)
    filled = solve_chart((V, F), SolveOptions(alpha=0.5, fill_holes=True), start=start)
    assert len(overlap_pairs(plain.uv, F)) > 0
    assert filled.uv.shape == (len(V), 2) and filled.n_flipped == 0 and filled.converged
    assert len(overlap_pairs(filled.uv, F)) == 0
    # the reported F is the chart's own (no fan triangle in it), at its own scale
    from uvbake.mesh.arrays import unit_scale

    Vn, unit = unit_scale(V, F)
    assert filled.energy == pytest.approx(DistortionEnergy(Vn, F, alpha=0.5).value(filled.uv / unit), rel=1e-12)
    assert plain.energy <= filled.energy <= 1.01 * plain.energy


def test_the_atlas_pipeline_fills_holes_and_paper_mode_does_not():
    """unwrap's guarantee solve fills holes: the cap stays one valid chart at alpha 0.5, with no
    overlap split (before: split in two, then cut for packing, 5 charts). ``guarantee=False`` (--paper)
    solves the paper's plain F, whose map of the cap overlaps itself."""
    import uvbake

    path = str(ROOT / "sample_scenes" / "sphere_cap.ply")
    res = uvbake.unwrap(path, alpha=0.5)
    assert res.report["charts_final"] == 1 and res.report["valid"]
    assert not [s for s in res.report["splits"] if s.get("reason") == "overlap"]
    paper = uvbake.unwrap(path, alpha=0.5, guarantee=False)
    assert not paper.report["valid"]
