"""Splitting large charts to pack the atlas denser (uvbake.atlas.packsplit): the pieces keep the
parent's map exactly, the atlas gets denser or nothing changes, and the cut is reported."""

import numpy as np
import pytest

import uvbake
from uvbake.atlas import packsplit
from uvbake.atlas.pack import pack_charts
from uvbake.mesh.charts import split_charts

from meshgen import cut_cylinder, plane


def _strip():
    return cut_cylinder(40, 8, radius=1.0, height=1.0, sweep=1.8 * np.pi)   # one long chart


def test_a_long_chart_is_cut_and_the_atlas_packs_denser_with_the_same_map():
    V, F = _strip()
    whole = uvbake.unwrap((V, F), alpha=0.5, pack_splits=False)
    split = uvbake.unwrap((V, F), alpha=0.5)
    assert len(whole.charts) == 1 and len(split.charts) >= 2
    recs = [s for s in split.report["splits"] if s["reason"] == "packing"]
    assert len(recs) == len(split.charts) - 1 and all(s["seam_length"] > 0 for s in recs)
    assert split.report["atlas"]["efficiency"] >= whole.report["atlas"]["efficiency"] + packsplit.MIN_GAIN
    assert recs[-1]["efficiency_after"] == pytest.approx(split.report["atlas"]["efficiency"], abs=1e-12)
    assert split.report["valid"] and split.report["n_flipped_total"] == 0
    # every piece carries the parent's solved map restricted to it (before packing), exactly
    parent = whole.results[0].uv[whole.charts[0].F]                  # (m,3,2), faces in chart order
    order = np.argsort(whole.charts[0].face_index)
    by_face = parent[order]
    for c, r in zip(split.charts, split.results):
        mine = r.uv[c.F]
        ref = by_face[np.searchsorted(np.sort(whole.charts[0].face_index), c.face_index)]
        np.testing.assert_allclose(mine, ref, atol=1e-12 * np.abs(ref).max())
    # pieces' energies add up to the parent's (each piece's own, worked out once its cuts are kept)
    assert sum(r.energy for r in split.results) == pytest.approx(whole.results[0].energy, rel=1e-9)
    assert all(r.n_flipped == 0 for r in split.results)


def test_a_dense_atlas_is_left_alone_and_packed_once():
    V, F = plane(10, 8, jitter=0.1)
    calls = []

    def pack(uvs, Fs):
        calls.append(len(uvs))
        return pack_charts(uvs, Fs)

    res = uvbake.unwrap((V, F), alpha=0.5, pack_splits=False)
    assert res.report["atlas"]["efficiency"] >= packsplit.BELOW_EFFICIENCY
    out_c, out_r, packed, recs = packsplit.split_for_packing(res.charts, res.results, pack)
    assert calls == [1] and recs == [] and out_c == list(res.charts)
    assert len(split_charts(V, F)) == 1


def test_the_chart_budget_and_the_paper_switch_stop_packing_splits():
    V, F = _strip()
    capped = uvbake.unwrap((V, F), alpha=0.5, max_charts=2)
    assert len(capped.charts) <= 2
    paper = uvbake.unwrap((V, F), alpha=0.5, guarantee=False, continuation=False)
    assert not [s for s in paper.report.get("splits", []) if s.get("reason") == "packing"]


def test_the_command_line_switch(tmp_path):
    import json

    import trimesh

    from uvbake.cli import main

    V, F = _strip()
    path = tmp_path / "strip.ply"
    trimesh.Trimesh(V, F, process=False).export(path)
    charts = {}
    for flag in ([], ["--no-pack-splits"]):
        rep = tmp_path / f"r{len(flag)}.json"
        assert main([str(path), "-o", str(tmp_path / f"o{len(flag)}.obj"), "--json", str(rep), "-q", *flag]) == 0
        r = json.loads(rep.read_text())
        charts[bool(flag)] = (r["charts_final"], sum(s["reason"] == "packing" for s in r["splits"]))
    assert charts[True] == (1, 0) and charts[False][0] >= 1 + charts[False][1] and charts[False][1] >= 1


def test_a_fixed_texel_density_is_kept_through_packing_splits():
    """With --texel-density the atlas grows instead of scaling: splits are judged on full packings
    (the rectangle packer chooses its own scale) and the density stays the one asked for."""
    V, F = _strip()
    res = uvbake.unwrap((V, F), alpha=0.5, texture_size_px=None, texel_density=64.0)
    assert res.report["valid"]
    assert res.report["atlas"]["texel_density"] == pytest.approx(64.0, rel=1e-9)
