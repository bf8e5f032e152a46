"""The uvbake command: the main job end to end, and one-line errors with non-zero exits."""

import json
import shutil
import subprocess
import sys

import numpy as np
import pytest

from uvbake.cli import main
from uvbake.cli.unwrap import certificate_summary
from uvbake.io.obj import load_obj_uv

from conftest import SAMPLE_SCENES


@pytest.fixture
def scene(tmp_path):
    dst = tmp_path / "scene.ply"
    shutil.copy(SAMPLE_SCENES / "scene.ply", dst)
    return dst


def test_unwrap_scene_writes_textured_mesh_and_report(scene, tmp_path, capsys):
    out, rep, tex = tmp_path / "out.obj", tmp_path / "report.json", tmp_path / "checker.png"
    before = scene.read_bytes()
    assert main([str(scene), "--alpha", "0.5", "-o", str(out), "--json", str(rep), "--bake", str(tex),
                 "--texture-size", "256"]) == 0
    assert scene.read_bytes() == before
    report = json.loads(rep.read_text())
    assert report["valid"] and report["all_converged"] and report["n_flipped_total"] == 0
    assert len(report["charts"]) == 8 and report["charts_input"] == 8
    assert all(c["grad_norm"] < 1e-8 and c["alpha"] == 0.5 for c in report["charts"])
    assert 0.3 < report["atlas"]["efficiency"] <= 1
    from PIL import Image

    with Image.open(tex) as im:
        assert im.size == (256, 256)
    mesh, uv, uv_faces = load_obj_uv(out)
    corner = uv[uv_faces]                                        # (m,3,2)
    assert corner.min() >= 0 and corner.max() <= 1
    # packing only rotates, translates and scales each chart by the common scale: undoing the scale
    # must give back each chart's energy (F is invariant under rotation and translation)
    import uvbake
    from uvbake.flatten.energy import DistortionEnergy

    charts = uvbake.split_charts(mesh.V, mesh.F, uvbake.load_mesh(scene).face_labels)
    scale = report["atlas"]["scale"]
    energies = []
    for c in charts:
        per_vertex = np.zeros((len(c.V), 2))
        per_vertex[c.F.ravel()] = corner[c.face_index].reshape(-1, 2) / scale
        energies.append(DistortionEnergy(c.V, c.F, alpha=0.5).value(per_vertex))
    assert sorted(energies) == pytest.approx(sorted(c["energy"] for c in report["charts"]), rel=1e-5)
    assert len(uv) > len(mesh.V)                                 # seams split in UV
    assert "8 chart(s)" in capsys.readouterr().out


def test_a_rectangular_texture_is_baked_and_reported_at_its_width_and_height(scene, tmp_path, capsys):
    rep, tex = tmp_path / "report.json", tmp_path / "checker.png"
    assert main([str(scene), "-o", str(tmp_path / "out.glb"), "--json", str(rep), "--bake", str(tex),
                 "--texture-size", "256x128"]) == 0
    report = json.loads(rep.read_text())
    assert report["valid"] and (report["atlas"]["width_px"], report["atlas"]["height_px"]) == (256, 128)
    from PIL import Image

    with Image.open(tex) as im:
        assert im.size == (256, 128)
    assert "of 256x128 px" in capsys.readouterr().out


def test_default_output_sits_beside_the_input(scene):
    assert main([str(scene), "-q"]) == 0
    assert (scene.parent / "scene_uv.obj").exists()


@pytest.mark.parametrize("args, message", [
    (["missing.ply"], "not found"),
    (["{scene}", "--alpha", "1.5"], "alpha"),
    (["{scene}", "--max-iter", "-3"], "--max-iter"),
    (["{scene}", "--texture-size", "0"], "--texture-size"),
    (["{scene}", "--texture-size", "512x8"], "--texture-size: 8 must be within [16, 16384]"),
    (["{scene}", "--texture-size", "2048x1024x2"], "is not PX or WIDTHxHEIGHT"),
    (["{scene}", "--texture-size", "64x32", "--gutter", "5"], "an eighth of --texture-size 64x32's shorter side"),
    (["{scene}", "--gutter", "-2"], "--gutter"),
    (["{scene}", "--max-stretch", "1"], "argument --max-stretch: 1 must be above 1.0"),
    (["{scene}", "--max-charts", "0"], "argument --max-charts: 0 must be at least 1"),
    (["{scene}", "--mip-levels", "2", "--gutter", "4"], "--gutter 4 is less than the 10 texels --mip-levels 2"),
    (["{scene}", "--mip-levels", "0"], "--mip-levels 0"),
    (["{scene}", "--mip-levels", "6"], "--mip-levels 6 needs a 138-texel gutter, more than 128 (an eighth of "
                                       "--texture-size 1024); use --mip-levels 5 or fewer, or a --texture-size of at least 1120"),
    (["{scene}", "--texel-density", "-5"], "--texel-density: -5 must be above 0"),
    (["{scene}", "--texel-density", "5000", "--texture-size", "64"], "cannot fit --texture-size 64 at --texel-density 5000"),
    (["{scene}", "--texture-size", "1004", "--mip-levels", "4"], "--texture-size 1004 is not a multiple of 8 (--mip-levels 4 "
                                                                "halves it 3 times); pass a texture size divisible by 8"),
    (["{scene}", "--bake", "{tmp}/texture.jpg"], "must end in .png"),
    (["{scene}", "-o", "{tmp}/out.fbx"], "must end in .obj or .glb"),
    (["{scene}", "-o", "{scene}"], "is the input"),
    (["{scene}", "-o", "{tmp}/nowhere/out.obj"], "does not exist"),
    (["{empty}"], "empty"),
    (["{text}"], "{text_name}"),
    (["{nan}"], "1 vertex has NaN or infinite coordinates (vertices 5)"),
])
def test_bad_input_is_one_line_and_exit_2(args, message, scene, tmp_path, capsys):
    empty = tmp_path / "empty.ply"
    empty.write_bytes(b"")
    text = tmp_path / "notes.ply"
    text.write_text("this is not a mesh\n")
    nan = tmp_path / "nan.obj"
    # one NaN vertex among many valid faces: an error, not a silent repair
    nan.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nv 2 0 0\nv nan 1 0\n"
                   "f 1 2 3\nf 2 4 3\nf 2 5 4\nf 5 6 4\n")
    fill = dict(scene=scene, tmp=tmp_path, empty=empty, text=text, nan=nan, text_name=text.name)
    args = [a.format(**fill) for a in args]
    before = {p: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()}
    code = main(args)
    err = capsys.readouterr().err
    assert code == 2
    assert message.format(**fill) in err
    assert err.count("\n") == 1 and "Traceback" not in err
    after = {p: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()}
    assert after == before                       # nothing written, nothing overwritten


def test_console_script_exits_nonzero_without_traceback(tmp_path):
    closed = tmp_path / "octa.obj"
    closed.write_text("v 1 0 0\nv -1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1\n"
                      "f 1 3 5\nf 3 2 5\nf 2 4 5\nf 4 1 5\nf 3 1 6\nf 2 3 6\nf 4 2 6\nf 1 4 6\n")
    proc = subprocess.run([sys.executable, "-m", "uvbake.cli", str(closed), "--no-auto-cut"],
                          capture_output=True, text=True)
    assert proc.returncode == 2
    assert "closed" in proc.stderr and "Traceback" not in proc.stderr
    assert "leave --no-auto-cut out" in proc.stderr and "auto_cut" not in proc.stderr    # the flag typed
    assert not (tmp_path / "octa_uv.obj").exists()


def test_help_reads_well():
    proc = subprocess.run([sys.executable, "-m", "uvbake.cli", "--help"], capture_output=True, text=True)
    assert proc.returncode == 0
    for word in ("--alpha", "--init", "--backend", "--json", "segment"):
        assert word in proc.stdout


def test_library_errors_reach_the_command_line_in_flags():
    # the library names its parameters; a command line user typed flags, so the one-line error says those
    from uvbake.cli.common import cli_words

    assert cli_words("the charts cannot fit a 16x16-texel atlas with gutter_px=4; reduce gutter_px or increase "
                     "texture_size_px") == ("the charts cannot fit a 16x16-texel atlas with --gutter 4; reduce "
                                            "--gutter or increase --texture-size")
    assert cli_words("texture_size_px=(2048, 1020) is wrong, mip_levels=3") == "--texture-size 2048x1020 is wrong, --mip-levels 3"
    assert cli_words("a gutter_pxs or my_texel_density stay") == "a gutter_pxs or my_texel_density stay"


def test_a_chart_budget_the_guarantee_could_not_keep_is_said(scene, capsys):
    # scene.ply has 8 labels, so 8 charts at least: --max-charts 3 cannot be kept, and the run says so
    assert main([str(scene), "--max-charts", "3"]) == 0
    err = capsys.readouterr().err
    assert "note: --max-charts 3 not kept: 8 charts (8 from charting); a valid atlas comes first" in err
    assert main([str(scene), "--max-charts", "8"]) == 0
    assert "not kept" not in capsys.readouterr().err


def test_summary_says_when_overlapping_charts_push_packing_past_100_percent(capsys):
    # an invalid atlas (e.g. --paper) whose charts overlap counts shared texels more than once
    from uvbake.cli.unwrap import _summary

    rep = {"triangles": 10, "charts_final": 1, "charts_input": 1, "valid": False, "charts": [],
           "atlas": {"texture_size_px": 1024, "efficiency": 2.406, "texel_density": 259.5},
           "timings": {"cli_total_s": 1.0}, "options": {}, "splits": []}
    _summary(rep, 0.5, [])
    out = capsys.readouterr().out
    assert "packing 240.6% of 1024 px (overlapping charts counted more than once)" in out
    rep["atlas"]["efficiency"], rep["valid"] = 0.573, True
    _summary(rep, 0.5, [])
    out = capsys.readouterr().out
    assert "packing 57.3% of 1024 px at" in out and "overlapping" not in out


def test_the_certificate_line_counts_charts_at_the_floor_as_minima():
    # alpha 1 charts stopped at F's floor are global minima with no lambda_min (null in the report)
    floor = dict(is_local_minimum=True, lambda_min=None)
    assert certificate_summary([floor, floor]) == "local minimum: yes, global (F at its floor 0)"
    assert certificate_summary([floor, dict(is_local_minimum=True, lambda_min=0.25)]) == \
        "local minimum: yes, lambda_min = 0.25"
    assert certificate_summary([floor, dict(is_local_minimum=False, lambda_min=-0.5, converged=True)]) == \
        "local minimum: no (1 of 2 charts: 1 at a saddle), lambda_min = -0.5"
    assert certificate_summary([dict(is_local_minimum=None, lambda_min=None)]) == "local minimum: not certified"


def test_charts_stopped_early_are_not_certified_and_get_the_advice_their_stop_calls_for():
    # a solve stopped before the gradient test is not a certified minimum, which is not "no": its
    # Hessian may well be positive definite (lambda_min > 0)
    stopped = dict(is_local_minimum=False, lambda_min=3e-4, converged=False)
    ok = dict(is_local_minimum=True, lambda_min=0.25, converged=True)
    assert certificate_summary([ok, stopped, stopped]) == \
        "local minimum: not certified (2 of 3 charts: 2 stopped before the gradient test), lambda_min = 0.0003"
    saddle = dict(is_local_minimum=False, lambda_min=-0.5, converged=True)
    assert certificate_summary([saddle, stopped]).startswith("local minimum: no (2 of 2 charts: 1 at a saddle, 1 stopped")
    from uvbake.cli.unwrap import _unconverged

    chart = dict(name="chart 3", grad_norm=4.1e-7, iterations=23)
    # only a solve cut at its iteration or evaluation limit is told to raise --max-iter
    assert _unconverged(chart | dict(stop_reason="max_iter")).endswith("; raise --max-iter")
    assert _unconverged(chart | dict(stop_reason="max_eval")).startswith("warning: chart 3 stopped before convergence")
    for reason in ("step too small", "roundoff limited"):
        line = _unconverged(chart | dict(stop_reason=reason))
        assert line.startswith("note: chart 3 stopped where") and "--max-iter" not in line and "4.10e-07" in line
    assert "--max-iter" not in _unconverged(chart | dict(stop_reason="damping diverged"))
    # one chart's own line says the same
    from uvbake.flatten.solve import parameterize

    from meshgen import bumpy_disk

    r = parameterize(*bumpy_disk(), alpha=0.5, max_iter=1)
    assert not r.converged and r.is_local_minimum is False
    assert r.certificate_line().startswith("local minimum: not certified (stopped before the gradient test)")


def test_ignore_materials_lets_charts_span_them(tmp_path):
    # a flat strip of two quads under two materials: two charts by default, one with --ignore-materials
    obj = tmp_path / "strip.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nv 1 1 0\nv 2 1 0\n"
                   "usemtl a\nf 1 2 5 4\nusemtl b\nf 2 3 6 5\n")
    for flags, charts in (([], 2), (["--ignore-materials"], 1)):
        rep = tmp_path / f"r{charts}.json"
        assert main([str(obj), "-q", "-o", str(tmp_path / f"o{charts}.obj"), "--json", str(rep), *flags]) == 0
        report = json.loads(rep.read_text())
        assert report["charts_final"] == charts and report["options"]["materials"] is (charts == 2)


def test_a_distortion_budget_left_unkept_is_warned_about():
    from uvbake.cli.unwrap import _budget_warnings

    rep = dict(options=dict(max_stretch=1.5, guarantee=True), min_texel_share=0.5)
    assert _budget_warnings(rep) == []                                  # 0.5 >= 1/2.25
    rep["min_texel_share"] = 0.12
    (w,) = _budget_warnings(rep)
    assert "0.12" in w and "0.444" in w and "--max-stretch 1.5" in w
    rep["options"]["guarantee"] = False                                  # --paper promises nothing
    assert _budget_warnings(rep) == []
