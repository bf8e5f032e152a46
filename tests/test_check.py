"""Tests of `uvbake check`: loading the UVs of mesh files, verdicts, exit codes and output files."""

import json

import numpy as np
import pytest

from uvbake.cli.check import load_uv_mesh, main
from uvbake.validate.report import FLIPPED_RGB, OVERLAP_RGB

# a unit square in 3D cut into two UV charts along its diagonal edge 1-3; vertices 1 and 3 have two
# UVs each (a seam), and the second chart is mirrored as a whole (as xatlas sometimes does)
SQUARE_V = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
VALID_OBJ = SQUARE_V + (
    "vt 0.1 0.1\nvt 0.4 0.1\nvt 0.1 0.4\n"  # chart 1: face 1 2 4
    "vt 0.9 0.6\nvt 0.6 0.6\nvt 0.9 0.9\n"  # chart 2 (mirrored): face 2 3 4
    "f 1/1 2/2 4/3\nf 2/4 3/6 4/5\n"
)
# the second chart moved onto the first: an overlap
OVERLAP_OBJ = SQUARE_V + (
    "vt 0.1 0.1\nvt 0.4 0.1\nvt 0.1 0.4\n"
    "vt 0.35 0.05\nvt 0.05 0.05\nvt 0.35 0.35\n"
    "f 1/1 2/2 4/3\nf 2/4 3/6 4/5\n"
)
# one chart (shared vt 2 and 3) with the second face flipped over the shared edge
FLIPPED_OBJ = SQUARE_V + (
    "vt 0.1 0.1\nvt 0.6 0.1\nvt 0.1 0.6\nvt 0.2 0.2\n"
    "f 1/1 2/2 4/3\nf 2/2 3/4 4/3\n"
)


def write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_valid_obj_with_seam_and_mirrored_chart_exits_0(tmp_path, capsys):
    path = write(tmp_path, "ok.obj", VALID_OBJ)
    uv, F = load_uv_mesh(path)
    assert F.shape == (2, 3) and uv.shape == (6, 2)  # the seam vertices keep both UVs
    assert main([str(path)]) == 0
    out = capsys.readouterr().out
    assert out.count("\n") == 1 and "valid: 2 charts, 2 triangles, 0 flipped" in out


def test_overlapping_obj_exits_1_and_writes_json_and_image(tmp_path, capsys):
    path = write(tmp_path, "bad.obj", OVERLAP_OBJ)
    js, png = tmp_path / "report.json", tmp_path / "overlaps.png"
    assert main([str(path), "--json", str(js), "--image", str(png), "--resolution", "64"]) == 1
    assert "INVALID" in capsys.readouterr().out
    doc = json.loads(js.read_text())
    assert doc["valid"] is False and doc["overlap_pairs"] == [[0, 1]] and doc["n_flipped"] == 0
    assert doc["path"] == str(path) and doc["resolution_px"] == 64
    from PIL import Image

    img = np.asarray(Image.open(png).convert("RGB"))
    assert img.shape[0] > 64 and img.shape[1:] == (64, 3)
    legend = img[64:]                                # the legend strip: dark text on white
    assert np.any(legend.max(axis=2) < 100) and np.mean(legend == 255) > 0.5
    img = img[:64]
    # (0.2, 0.15) is inside both triangles; the image has v pointing up
    assert tuple(img[63 - int(0.15 * 64), int(0.2 * 64)]) == OVERLAP_RGB
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.obj", "overlaps.png", "report.json"]


def test_flipped_face_in_one_chart_exits_1(tmp_path, capsys):
    path = write(tmp_path, "flip.obj", FLIPPED_OBJ)
    png = tmp_path / "f.png"
    assert main([str(path), "--image", str(png), "--resolution", "64"]) == 1
    assert "1 flipped" in capsys.readouterr().out
    from PIL import Image

    img = np.asarray(Image.open(png).convert("RGB"))
    assert np.any(np.all(img == FLIPPED_RGB, axis=2))


def test_ply_with_s_t_texture_coordinates(tmp_path, capsys):
    header = (
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
        "property float z\nproperty float s\nproperty float t\nelement face 2\n"
        "property list uchar int vertex_indices\nend_header\n"
    )
    body = "0 0 0 0.1 0.1\n1 0 0 0.9 0.1\n1 1 0 0.9 0.9\n0 1 0 0.1 0.9\n3 0 1 2\n3 0 2 3\n"
    path = write(tmp_path, "quad.ply", header + body)
    assert main([str(path)]) == 0
    # the same quad with vertex 1's UV dragged across the diagonal 0-2: face 0 flips
    bad = write(tmp_path, "bad.ply", header + body.replace("1 0 0 0.9 0.1", "1 0 0 0.2 0.8"))
    assert main([str(bad)]) == 1
    assert "1 flipped" in capsys.readouterr().out.splitlines()[-1]


def test_glb_scene_with_two_geometries(tmp_path, capsys):
    import trimesh
    from trimesh.visual import TextureVisuals

    def quad(uv):
        m = trimesh.Trimesh(
            vertices=[[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], faces=[[0, 1, 2], [0, 2, 3]], process=False
        )
        m.visual = TextureVisuals(uv=np.asarray(uv, float))
        return m

    a = quad([[0.1, 0.1], [0.4, 0.1], [0.4, 0.4], [0.1, 0.4]])
    b = quad([[0.6, 0.6], [0.9, 0.6], [0.9, 0.9], [0.6, 0.9]])
    scene = trimesh.Scene([a, b])
    path = tmp_path / "two.glb"
    path.write_bytes(scene.export(file_type="glb"))
    uv, F = load_uv_mesh(path)
    assert F.shape == (4, 3)
    assert main([str(path)]) == 0
    c = quad([[0.3, 0.3], [0.6, 0.3], [0.6, 0.6], [0.3, 0.6]])  # overlaps a
    path2 = tmp_path / "three.glb"
    path2.write_bytes(trimesh.Scene([a, b, c]).export(file_type="glb"))
    assert main([str(path2)]) == 1
    capsys.readouterr()


@pytest.mark.parametrize(
    "name, text, args, needle",
    [
        ("missing.obj", None, [], "no such file"),
        ("novt.obj", SQUARE_V + "f 1 2 3\nf 1 3 4\n", [], "no texture coordinates"),
        ("garbage.glb", "this is not a glb file", [], "cannot read"),
        ("ok.obj", VALID_OBJ, ["--resolution", "3"], "resolution_px"),
        ("ok.obj", VALID_OBJ, ["--frobnicate"], "unrecognized arguments"),
        ("ok.obj", VALID_OBJ, ["--json", "no/such/dir/r.json"], "does not exist"),
    ],
)
def test_bad_input_exits_2_with_one_line(tmp_path, capsys, name, text, args, needle):
    path = tmp_path / name
    if text is not None:
        path.write_text(text)
    args = [a.replace("no/such", str(tmp_path / "no/such")) for a in args]
    assert main([str(path), *args]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.count("\n") == 1 and needle in captured.err
    assert "Traceback" not in captured.err


def test_failed_run_leaves_existing_outputs_untouched(tmp_path, capsys):
    js = tmp_path / "report.json"
    js.write_text("previous good report")
    assert main([str(tmp_path / "missing.obj"), "--json", str(js)]) == 2
    assert js.read_text() == "previous good report"
    capsys.readouterr()


def test_help_returns_0(capsys):
    assert main(["--help"]) == 0
    assert "uvbake check" in capsys.readouterr().out


def test_a_uv_index_out_of_range_is_named_as_such(tmp_path, capsys):
    from uvbake.cli.check import main as check_main

    path = tmp_path / "oor.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nf 1/1 2/2 3/7\n")
    assert check_main([str(path)]) == 2
    err = capsys.readouterr().err
    assert "texture index out of range" in err and "no texture coordinates" not in err
