"""unwrap(): the whole pipeline, and its guarantee that the atlas has no flips and no overlaps."""

import json

import numpy as np
import pytest

import uvbake
from uvbake.atlas.pipeline import unwrap
from uvbake.errors import InputError

from meshgen import bumpy_disk, grid, helical_strip


def assert_valid_atlas(res):
    v = uvbake.validate(res.corner_uv, res.F, chart_ids=res.chart_ids)
    assert v.valid and len(v.flipped) == 0 and len(v.overlap_pairs) == 0
    assert res.report["valid"] and res.report["n_flipped_total"] == 0
    assert res.corner_uv.min() >= 0 and res.corner_uv.max() <= 1
    json.dumps(res.report)                                    # JSON-ready


def test_a_chart_that_overlaps_itself_is_split_and_validates():
    V, F = helical_strip()
    whole = uvbake.parameterize(V, F, alpha=0.5)
    assert whole.n_flipped == 0
    assert len(uvbake.validate(whole.uv, F).overlap_pairs) > 0     # the fixture really overlaps
    res = unwrap((V, F), alpha=0.5, texture_size_px=256)
    assert_valid_atlas(res)
    assert len(uvbake.split_charts(V, F)) == 1 and res.report["charts_final"] >= 2
    # predicted from the conformal map by the charting stage, or found after the solve: split once
    over = [s for s in res.report["budget_cuts"] + res.report["splits"] if s.get("reason") == "overlap"]
    assert over and over[0]["bad"] > 0 and over[0]["parts"] == 2
    assert res.report["seam_length_added"] > 0
    # the paper's formulation as is keeps the overlap and says so
    paper = unwrap((V, F), alpha=0.5, texture_size_px=256, guarantee=False)
    assert not paper.report["valid"] and paper.report["charts_final"] == 1


def test_random_start_on_a_curved_disk_ends_flip_free():
    V, F = bumpy_disk(14, amp=0.6)
    for alpha in (0.5, 0.9):
        res = unwrap((V, F), alpha=alpha, init="random", seed=4, texture_size_px=256)
        assert_valid_atlas(res)
        assert all(r.converged for r in res.results)


def test_closed_sphere_and_torus_become_valid_atlases():
    import trimesh

    for mesh in (trimesh.creation.icosphere(subdivisions=3), trimesh.creation.torus(1.0, 0.35)):
        V, F = np.asarray(mesh.vertices), np.asarray(mesh.faces)
        with pytest.raises(uvbake.ChartError, match="closed|handle"):
            unwrap((V, F), auto_cut=False)
        res = unwrap((V, F), alpha=0.5, texture_size_px=256)
        assert_valid_atlas(res)
        assert res.report["cuts"] and res.report["charts_final"] >= 2
        assert sum(len(c.F) for c in res.charts) == len(F)


def test_bowtie_vertices_are_repaired_with_a_report_entry():
    st, F = grid(5, 5)
    V = np.column_stack([st, 0.1 * np.sin(3 * st[:, 0])])
    # remove the two cells diagonal to each other at the centre vertex 12: its two remaining fans
    # meet only there, while the rest of the grid still connects them (one chart, one bowtie)
    n_cells = 16
    Fb = np.delete(F, [6, 6 + n_cells, 9, 9 + n_cells], axis=0)
    Vb = V
    np.testing.assert_array_equal(uvbake.mesh.topology.nonmanifold_vertices(Fb, len(Vb)), [12])
    assert len(uvbake.split_charts(Vb, Fb, check=False)) == 1
    res = unwrap((Vb, Fb), alpha=0.5, texture_size_px=128)
    assert_valid_atlas(res)
    kinds = {a["kind"] for a in res.report["repair"]["actions"]}
    assert "split_nonmanifold_vertices" in kinds, kinds
    with pytest.raises(uvbake.ChartError, match="non-manifold vertices"):
        unwrap((Vb, Fb), repair=False)


def test_report_shows_the_price_of_the_guarantee():
    V, F = helical_strip()
    rep = unwrap((V, F), alpha=0.5, texture_size_px=256).report
    d = rep["distortion"]["final"]
    assert d["angle_distortion_mean"] >= 1 and d["area_distortion_mean"] >= 0
    assert d["charts"] == rep["charts_final"]
    assert 1 / 16 <= rep["min_texel_share"] <= 1 and 0 <= rep["area_below_quarter"] <= 0.005


@pytest.mark.parametrize("kwargs, match", [
    (dict(texture_size_px=8), "texture_size_px"), (dict(texture_size_px=100.5), "texture_size_px"),
    (dict(gutter_px=-1), "gutter_px"), (dict(bake="plasma"), "bake"), (dict(alpha=2), "alpha"),
    (dict(texture_size_px=(512, 8)), "texture_size_px"), (dict(texture_size_px=(64, 32), gutter_px=5), "gutter_px"),
    # the gutter mip_levels derives is held to an eighth of the texture too, and the fix names sizes that work
    (dict(mip_levels=8), r"mip_levels=8 needs a 545-texel gutter, more than 128 .* mip_levels=5 or fewer, or a "
                         r"texture_size_px of at least 4480"),
    (dict(mip_levels=1, texture_size_px=16), r"needs a 6-texel gutter, more than 2 .*; pass a texture_size_px of at "
                                             r"least 48"),
])
def test_bad_options(kwargs, match):
    V, F = bumpy_disk(6)
    with pytest.raises(uvbake.InputError, match=match):
        unwrap((V, F), **kwargs)


def test_vertex_colours_requested_without_colours_is_an_error():
    V, F = bumpy_disk(6)
    with pytest.raises(uvbake.InputError, match="no vertex colours"):
        unwrap((V, F), bake="vertex-colors")


def test_splits_and_cuts_add_up():
    V, F = helical_strip(turns=2.0)
    rep = unwrap((V, F), alpha=0.5, texture_size_px=256).report
    assert rep["budget_cuts"]                                 # the fixture needs cuts (it overlaps itself)
    # one piece; each budget cut or overlap split adds parts - 1 charts (a slit adds none), each
    # split after the solve too
    assert rep["charts_input"] == 1 + sum(c["parts"] - 1 for c in rep["budget_cuts"])
    assert rep["charts_final"] == rep["charts_input"] + sum(s["parts"] - 1 for s in rep["splits"])
    assert rep["valid"]
    seams = [c["seam_length"] for c in rep["cuts"]] + [c.get("seam_length", 0.0) for c in rep["budget_cuts"]] \
        + [s["seam_length"] for s in rep["splits"]]
    assert all(x > 0 for x in seams)
    assert rep["seam_length_added"] == pytest.approx(sum(seams), rel=1e-12)


# ---------------------------------------------------------------------------------------- issue 15


def _soup(n):
    """n separate triangles (no shared vertex)."""
    base = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    i = np.arange(n)
    V = (base[None] + np.column_stack([3.0 * (i % 40), 3.0 * (i // 40), 0 * i])[:, None, :]).reshape(-1, 3)
    return V, np.arange(3 * n).reshape(-1, 3)


def test_many_small_pieces_become_many_charts_never_one():
    # the speck rule once dropped all but the largest of 100,000 one-triangle pieces ("dropped
    # 99,999 small pieces", an atlas of one triangle); here 3,000 pieces, where it dropped 2,999
    from uvbake.mesh.repair import repair

    rep = repair(*_soup(3000))
    assert len(rep.F) == 3000 and not any(a["kind"] == "drop_small_components" for a in rep.actions)
    V, F = _soup(30)
    r = unwrap((V, F), texture_size_px=128, gutter_px=1)
    assert r.report["charts_final"] == 30 and len(r.F) == 30 and r.report["valid"]
    assert not any(a["kind"] == "drop_small_components" for a in r.report["repair"]["actions"])


def test_packing_many_charts_reports_charts_placed_while_it_runs():
    # a kit's packing is most of its command: the progress moves per 64 charts placed in each trial
    # (a work count, the same on every run), not once at the end
    V, F = _soup(300)
    seen = []
    r = unwrap((V, F), texture_size_px=256, gutter_px=1,
               progress=lambda stage, done, total: seen.append((stage, done, total)))
    packing = [(d, n) for s, d, n in seen if s == "pack"]
    assert r.report["charts_final"] == 300
    running = [(d, n) for d, n in packing if d < n]
    assert running and {n for _, n in running} == {300}
    assert {d for d, _ in running} == {64, 128, 192, 256}           # each trial's counts
    assert packing[-1] == (1, 1)                                    # the stage's end
    seen2 = []
    unwrap((V, F), texture_size_px=256, gutter_px=1, progress=lambda *a: seen2.append(a))
    assert seen2 == seen                                            # the same calls on every run


def test_too_many_pieces_are_refused_before_any_work_with_the_reason(monkeypatch):
    from uvbake.atlas import pipeline

    def no_charts(*args, **kwargs):
        raise AssertionError("charts were built before the refusal")

    monkeypatch.setattr("uvbake.atlas.charting.make_charts", no_charts)
    V, F = _soup(pipeline.MAX_PIECES + 1)
    with pytest.raises(uvbake.InputError, match=f"{pipeline.MAX_PIECES + 1} separate pieces") as err:
        unwrap((V, F))
    assert "labels" not in str(err.value)
    # a connected grid whose every quad has a label of its own: the labels are named as a cause, and
    # OBJ materials with the option that ignores them (the CLI's words: --ignore-materials)
    from uvbake.cli.common import cli_words

    n = 80
    V, F = grid(n + 1, n + 1)
    V = np.column_stack([V, np.zeros(len(V))])
    with pytest.raises(uvbake.InputError, match=f"{n * n} separate pieces") as err:
        unwrap((V, F), face_labels=np.arange(len(F)) % (n * n))      # each quad: its two triangles
    assert "coarser face labels" in str(err.value) and "--ignore-materials" in cli_words(str(err.value))


@pytest.mark.parametrize("scale", [2.0 ** 990, 1e300, 1e-300])
def test_coordinates_at_any_finite_scale_unwrap(scale):
    st, F = grid(6, 5, jitter=0.2)
    V = np.column_stack([st, 0.3 * st[:, 0] ** 2])
    ref = unwrap((V, F), texture_size_px=64, gutter_px=1)
    with np.errstate(over="raise", invalid="raise", divide="raise"):
        r = unwrap((V * scale, F), texture_size_px=64, gutter_px=1)
    assert r.report["valid"] and r.report["all_converged"]
    assert np.array_equal(r.V, V * scale)                # the input's own coordinates are exported
    e_ref = sum(c["energy"] for c in ref.report["charts"])
    e = sum(c["energy"] for c in r.report["charts"])
    assert abs(e - e_ref) <= 1e-9 + 1e-6 * e_ref


@pytest.mark.parametrize("e", [70, -80])
def test_far_from_unit_size_every_figure_and_option_is_in_the_inputs_units(e):
    # past 2**64 the mesh is worked on scaled by a power of two; what the user reads and gives is not
    s = 2.0 ** e
    V, F = bumpy_disk(8)
    ref = unwrap((V, F), texture_size_px=64, gutter_px=1)
    r = unwrap((V * s, F), texture_size_px=64, gutter_px=1)
    assert r.report["coordinate_exponent"] != 0 and "coordinate_exponent" not in ref.report
    assert np.allclose(r.corner_uv, ref.corner_uv, rtol=0, atol=1e-9)   # scaling by 2**e is exact; a margin anyway
    for key, p in (("texel_density", -1), ("texel_size_world", 1), ("scale", -1)):
        assert r.report["atlas"][key] == pytest.approx(ref.report["atlas"][key] * s ** p, rel=1e-9, abs=0)
    assert r.report["seam_length_added"] == pytest.approx(ref.report["seam_length_added"] * s, rel=1e-9, abs=0)
    for a, b in zip(r.report["charts"], ref.report["charts"]):
        assert a["area_3d"] == pytest.approx(b["area_3d"] * s * s, rel=1e-9, abs=0)
    for c, c0, res, res0 in zip(r.charts, ref.charts, r.results, ref.results):
        assert np.allclose(c.V, c0.V * s, rtol=1e-12, atol=0) and np.allclose(res.uv, res0.uv * s, rtol=1e-12, atol=0)
    # a texel density per input unit grows the same atlas at any scale
    d = ref.report["atlas"]["texel_density"]
    g0 = unwrap((V, F), texture_size_px=None, texel_density=d, gutter_px=1).report
    g1 = unwrap((V * s, F), texture_size_px=None, texel_density=d / s, gutter_px=1).report
    assert (g1["atlas"]["width_px"], g1["atlas"]["height_px"]) == (g0["atlas"]["width_px"], g0["atlas"]["height_px"])
    assert g1["atlas"]["texel_density"] == pytest.approx(d / s, rel=1e-9, abs=0)


def test_a_rectangular_atlas_keeps_each_charts_map_up_to_a_similarity_in_texels():
    # (width, height) = (512, 256): UVs in [0,1]^2 span 512 texels across and 256 down, so every chart
    # must be scaled by the same texels per unit both ways: in texel coordinates each triangle keeps
    # the angles of its chart's solved map, and the baked texture is 512 wide and 256 high
    from uvbake.mesh.arrays import signed_areas

    V, F = bumpy_disk(10)
    res = unwrap((V, F), alpha=0.5, texture_size_px=(512, 256), bake="checker")
    assert_valid_atlas(res)
    assert res.image.shape == (256, 512, 3)
    atlas = res.report["atlas"]
    assert (atlas["width_px"], atlas["height_px"]) == (512, 256) and res.report["options"]["texture_size_px"] == [512, 256]

    def angles(P):                                            # (m,3) corner angles of triangles P (m,3,2)
        e = np.roll(P, -1, axis=1) - P
        f = np.roll(P, 1, axis=1) - P
        cos = (e * f).sum(-1) / (np.linalg.norm(e, axis=-1) * np.linalg.norm(f, axis=-1))
        return np.arccos(np.clip(cos, -1, 1))

    texels = res.corner_uv * np.array([512.0, 256.0])
    for c, r in zip(res.charts, res.results):
        own = np.asarray(r.uv)[c.F]
        assert np.allclose(angles(texels[c.face_index]), angles(own), rtol=0, atol=1e-6)
        # and the same orientation (no mirror): signed areas agree in sign
        assert np.all(np.sign(signed_areas(texels[c.face_index].reshape(-1, 2), np.arange(3 * len(c.F)).reshape(-1, 3)))
                      == np.sign(signed_areas(np.asarray(r.uv), c.F)))


@pytest.mark.parametrize("levels, size", [(1, 48), (6, 1120), (8, 4480)])
def test_the_least_texture_a_mip_levels_error_names_is_the_least_accepted(levels, size):
    # the least side with room for the gutter that the levels halve evenly: it passes, the next smaller
    # such side does not; and the most levels a 1024 texture holds is what the error offers
    from uvbake.atlas.pipeline import check_texture, mip_levels_within, mip_room
    from uvbake.atlas.shapepack import mip_gutter_px

    assert mip_room(levels, mip_gutter_px(levels)) == size
    assert check_texture(size, None, None, levels) == size
    with pytest.raises(uvbake.InputError, match="an eighth of the texture"):
        check_texture(size - 2 ** (levels - 1), None, None, levels)
    assert mip_levels_within(1024 // 8) == 5 and mip_gutter_px(6) > 1024 // 8 >= mip_gutter_px(5)


def test_charts_that_no_packing_can_hold_are_refused_before_the_solve(monkeypatch):
    # 100 separate triangles, 2 texels apart, in 16 x 16 texels: even as points they need more room
    # (100 disks of radius 1 against (16 - 2 + 2)^2 texels); the run stops after charting, not after
    # solving every chart and searching the packing
    from uvbake.atlas import pipeline

    rng = np.random.default_rng(0)
    V = (rng.random((300, 3)) + np.repeat(np.arange(100), 3)[:, None] * 2.0)
    F = np.arange(300).reshape(100, 3)
    monkeypatch.setattr(pipeline, "_stage_solve", lambda run: (_ for _ in ()).throw(AssertionError("solved")))
    with pytest.raises(uvbake.InputError, match="100 charts cannot fit a 16x16-texel atlas with gutter_px=2"):
        unwrap((V, F), texture_size_px=16, gutter_px=2)
    # a bound, never a guess: 4 charts in the same atlas pass it (and pack: tests/test_pack.py)
    pipeline._check_room(4, dict(texture_size_px=16, texel_density=None, gutter_px=2, mip_levels=None, guarantee=True))


def test_no_chart_spans_two_obj_materials(tmp_path):
    # a flat 10 x 10 grid, its left and right halves under two materials: one chart without them,
    # two along the material border with them, as xatlas keeps charts within a material
    n = 10
    lines = ["mtllib m.mtl"] + [f"v {x} {y} 0" for y in range(n + 1) for x in range(n + 1)]
    for half, name in ((range(n // 2), "left"), (range(n // 2, n), "right")):
        lines.append(f"usemtl {name}")
        lines += [f"f {y * (n + 1) + x + 1} {y * (n + 1) + x + 2} {(y + 1) * (n + 1) + x + 2} {(y + 1) * (n + 1) + x + 1}"
                  for y in range(n) for x in half]
    path = tmp_path / "two.obj"
    path.write_text("\n".join(lines) + "\n")
    res = uvbake.unwrap(str(path), texture_size_px=256)
    assert res.report["valid"] and res.report["options"]["materials"] is True
    assert len(res.charts) == 2
    x = res.V[res.F].mean(axis=1)[:, 0]
    for c in range(2):
        side = x[res.chart_ids == c] < n / 2
        assert side.all() or not side.any()                 # each chart on one side of the border
    assert len(uvbake.unwrap(str(path), texture_size_px=256, materials=False).charts) == 1
    with pytest.raises(InputError, match="materials"):
        uvbake.unwrap(str(path), materials="yes")
