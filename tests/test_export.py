"""Textured export: OBJ+MTL+PNG and GLB round trips through trimesh and Open3D, glTF validation,
atomic writes."""

import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import uvbake.io.export as export_mod
from uvbake.errors import InputError
from uvbake.io.corners import split_corners
from uvbake.io.export import load_textured_uv, save_textured

GLTF_VALIDATOR_VERSION = "2.0.0-dev.3.10"
NODE_PREFIX_DEFAULT = Path.home() / ".cache" / "uvbake" / "node"


def seam_mesh(n=4):
    """A 2x1 bumpy grid cut at x = 1 into two charts with hand-made corner UVs, and a test image.

    Returns V, F, corner_uv, image, the indices of the seam vertices.
    """
    xs, ys = np.linspace(0, 2, 2 * n + 1), np.linspace(0, 1, n + 1)
    X, Y = np.meshgrid(xs, ys)
    V = np.column_stack([X.ravel(), Y.ravel(), 0.1 * np.sin(3 * X.ravel()) * Y.ravel()])
    idx = np.arange(X.size).reshape(n + 1, 2 * n + 1)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    F = np.vstack([np.column_stack([a, b, c]), np.column_stack([a, c, d])]).astype(np.int64)
    P = V[F]
    chart = (P[:, :, 0].mean(axis=1) > 1.0).astype(int)
    offset = np.array([[0.05, 0.05], [0.15, 0.55]])
    corner_uv = offset[chart][:, None, :] + 0.4 * P[:, :, :2]
    seam = np.flatnonzero(np.isclose(V[:, 0], 1.0))
    rng = np.random.default_rng(3)
    image = rng.integers(0, 256, size=(32, 48, 3), dtype=np.uint8)  # not square, not symmetric
    return V, F, corner_uv, image, seam


def assert_same_corners(V_ref, F_ref, uv_ref, V, F, uv, *, uv_tol):
    assert len(F) == len(F_ref)
    np.testing.assert_allclose(np.asarray(V)[np.asarray(F)], V_ref[F_ref], atol=1e-6)
    np.testing.assert_allclose(np.asarray(uv).reshape(-1, 3, 2), uv_ref, atol=uv_tol)


def seam_vertex_uv_count(V, F, uv, point):
    """How many distinct UVs the corners at 3D position ``point`` carry."""
    V, F, uv = np.asarray(V), np.asarray(F), np.asarray(uv).reshape(-1, 3, 2)
    at = np.all(np.isclose(V[F], point, atol=1e-6), axis=-1)
    return len(np.unique(np.round(uv[at], 5), axis=0))


# --------------------------------------------------------------------------------------------------
# own reader and file layout


@pytest.mark.parametrize("ext", ["obj", "glb"])
def test_round_trip_own_reader(tmp_path, ext):
    V, F, uv, image, seam = seam_mesh()
    paths = save_textured(tmp_path / f"m.{ext}", V, F, uv, image)
    expected = {"obj": ["m.obj", "m.mtl", "m.png"], "glb": ["m.glb"]}[ext]
    assert [p.name for p in paths] == expected
    assert sorted(os.listdir(tmp_path)) == sorted(expected)  # no temporary files left
    V2, F2, uv2 = load_textured_uv(paths[0])
    assert_same_corners(V, F, uv, V2, F2, uv2, uv_tol=0 if ext == "obj" else 1e-7)
    for s in seam[1:-1]:  # interior seam vertices carry one UV per chart
        assert seam_vertex_uv_count(V2, F2, uv2, V[s]) == 2


def test_obj_file_contents(tmp_path):
    V, F, uv, image, seam = seam_mesh()
    colors = np.random.default_rng(0).random((len(V), 3))
    obj, mtl, png = save_textured(tmp_path / "m.obj", V, F, uv, image, vertex_colors=colors,
                                  name="atlas")
    text = obj.read_text()
    assert "mtllib m.mtl\n" in text and "usemtl atlas\n" in text
    lines = text.splitlines()
    n_v = sum(line.startswith("v ") for line in lines)
    n_vt = sum(line.startswith("vt ") for line in lines)
    assert n_v == len(V)  # vertices kept as given
    assert n_vt == len(np.unique(uv.reshape(-1, 2), axis=0)) < 3 * len(F)  # one vt per distinct UV
    assert n_vt == len(V) + len(seam)  # seam vertices: one vt per chart
    assert "map_Kd m.png" in mtl.read_text() and "newmtl atlas" in mtl.read_text()
    from uvbake.io.obj import load_obj_uv
    mesh, _, _ = load_obj_uv(obj)
    np.testing.assert_array_equal(mesh.vertex_colors, colors)
    from PIL import Image
    assert np.array_equal(np.asarray(Image.open(png)), image)


# --------------------------------------------------------------------------------------------------
# trimesh and Open3D


def trimesh_mesh(path):
    trimesh = pytest.importorskip("trimesh")
    loaded = trimesh.load(str(path), process=False)
    if isinstance(loaded, trimesh.Scene):
        assert len(loaded.geometry) == 1
        loaded = next(iter(loaded.geometry.values()))
    return loaded


def trimesh_image(mesh):
    material = mesh.visual.material
    img = getattr(material, "image", None) or getattr(material, "baseColorTexture", None)
    return np.asarray(img.convert("RGB"))


@pytest.mark.parametrize("ext", ["obj", "glb"])
def test_round_trip_trimesh(tmp_path, ext):
    V, F, uv, image, seam = seam_mesh()
    path = save_textured(tmp_path / f"m.{ext}", V, F, uv, image)[0]
    mesh = trimesh_mesh(path)
    corner_uv = np.asarray(mesh.visual.uv)[mesh.faces]  # trimesh gives v up for both formats
    assert_same_corners(V, F, uv, mesh.vertices, mesh.faces, corner_uv, uv_tol=1e-7)
    assert seam_vertex_uv_count(mesh.vertices, mesh.faces, corner_uv, V[seam[1]]) == 2
    assert np.array_equal(trimesh_image(mesh), image)


@pytest.mark.parametrize("ext", ["obj", "glb"])
def test_round_trip_open3d(tmp_path, ext):
    o3d = pytest.importorskip("open3d")
    V, F, uv, image, seam = seam_mesh()
    path = save_textured(tmp_path / f"m.{ext}", V, F, uv, image)[0]

    legacy = o3d.io.read_triangle_mesh(str(path))
    T = np.asarray(legacy.triangles)
    tri_uv = np.asarray(legacy.triangle_uvs).reshape(-1, 3, 2)  # v up
    assert_same_corners(V, F, uv, np.asarray(legacy.vertices), T, tri_uv, uv_tol=1e-7)
    assert seam_vertex_uv_count(np.asarray(legacy.vertices), T, tri_uv, V[seam[1]]) == 2
    material_id = np.asarray(legacy.triangle_material_ids)
    assert len(material_id) == len(F) and np.all(material_id == material_id[0])
    texture = np.asarray(legacy.textures[material_id[0]])
    # the legacy mesh stores its texture bottom row first (row 0 = v 0), so it is our image flipped
    assert np.array_equal(texture[..., :3], image[::-1])

    tensor = o3d.t.io.read_triangle_mesh(str(path))
    T = tensor.triangle.indices.numpy()
    assert_same_corners(V, F, uv, tensor.vertex.positions.numpy(), T,
                        tensor.triangle.texture_uvs.numpy(), uv_tol=1e-7)
    albedo = tensor.material.texture_maps["albedo"].as_tensor().numpy()
    assert np.array_equal(albedo[..., :3], image)  # tensor meshes keep row 0 at the top


# --------------------------------------------------------------------------------------------------
# GLB details and the Khronos validator


def test_glb_splits_vertices_per_uv_only():
    V, F, uv, _, seam = seam_mesh()
    source, uv_new, F_new = split_corners(F, uv)
    assert len(source) == len(V) + len(seam)  # seam vertices once per chart, others once
    np.testing.assert_array_equal(source[F_new], F)
    np.testing.assert_array_equal(uv_new[F_new], uv)


def test_glb_texcoords_have_v_down(tmp_path):
    V, F, uv, image, _ = seam_mesh()
    path = save_textured(tmp_path / "m.glb", V, F, uv, image, vertex_colors=np.full((len(V), 3), 0.5))[0]
    data = path.read_bytes()
    js_len = int.from_bytes(data[12:16], "little")
    gltf = json.loads(data[20:20 + js_len])
    prim = gltf["meshes"][0]["primitives"][0]
    assert set(prim["attributes"]) == {"POSITION", "NORMAL", "TEXCOORD_0", "COLOR_0"}
    assert gltf["samplers"][0]["wrapS"] == 33071  # clamp: never wraps onto the far edge
    blob = data[20 + js_len + 8:]
    acc = gltf["accessors"][prim["attributes"]["TEXCOORD_0"]]
    view = gltf["bufferViews"][acc["bufferView"]]
    tex = np.frombuffer(blob, np.float32, 2 * acc["count"], view["byteOffset"]).reshape(-1, 2)
    _, uv_new, F_new = split_corners(F, uv)
    np.testing.assert_allclose(tex[:, 1], 1.0 - uv_new[:, 1], atol=1e-7)


@pytest.fixture(scope="session")
def gltf_validator_module():
    """Path of the gltf-validator npm package, installing it into a cache folder if need be.

    Looks in $UVBAKE_NODE_PREFIX (default ~/.cache/uvbake/node, where install.sh puts it); skips,
    once per session, when node is missing or the package can be neither found nor installed.
    """
    if shutil.which("node") is None:
        pytest.skip("node is not installed (needed to run the Khronos gltf-validator)")
    prefix = Path(os.environ.get("UVBAKE_NODE_PREFIX", NODE_PREFIX_DEFAULT))
    module = prefix / "node_modules" / "gltf-validator"
    if not (module / "package.json").exists():
        if shutil.which("npm") is None:
            pytest.skip(f"gltf-validator not in {prefix} and npm is not installed")
        try:
            prefix.mkdir(parents=True, exist_ok=True)
            subprocess.run(["npm", "install", "--silent", "--no-audit", "--no-fund", "--prefix",
                            str(prefix), f"gltf-validator@{GLTF_VALIDATOR_VERSION}"],
                           check=True, capture_output=True, timeout=120)
        except (OSError, subprocess.SubprocessError) as exc:
            pytest.skip(f"could not install gltf-validator into {prefix}: {exc}")
        if not (module / "package.json").exists():
            pytest.skip(f"gltf-validator not found in {prefix} after npm install")
    return module


VALIDATE_JS = """
const fs = require('fs');
const validator = require(process.argv[2]);
const data = new Uint8Array(fs.readFileSync(process.argv[3]));
validator.validateBytes(data, {uri: 'model.glb', maxIssues: 100, writeTimestamp: false})
  .then((report) => process.stdout.write(JSON.stringify(report)))
  .catch((err) => { process.stderr.write(String(err)); process.exit(2); });
"""


@pytest.mark.parametrize("colors", [False, True])
def test_glb_passes_khronos_validator(tmp_path, gltf_validator_module, colors):
    module = gltf_validator_module
    V, F, uv, image, _ = seam_mesh()
    vc = np.random.default_rng(1).random((len(V), 3)) if colors else None
    path = save_textured(tmp_path / "m.glb", V, F, uv, image, vertex_colors=vc)[0]
    script = tmp_path / "validate.js"
    script.write_text(VALIDATE_JS)
    run = subprocess.run(["node", str(script), str(module), str(path)], capture_output=True,
                         text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    report = json.loads(run.stdout)
    issues = report["issues"]
    assert issues["numErrors"] == 0, issues["messages"]
    assert issues["numWarnings"] == 0, issues["messages"]
    assert report["info"]["hasTextures"] and report["info"]["totalTriangleCount"] == len(F)


# --------------------------------------------------------------------------------------------------
# atomic writes and bad input


@pytest.mark.parametrize("ext", ["obj", "glb"])
def test_failing_image_writer_leaves_nothing(tmp_path, monkeypatch, ext):
    V, F, uv, image, _ = seam_mesh()
    old = tmp_path / f"m.{ext}"
    old.write_bytes(b"precious")

    def broken(img):
        raise OSError("disk full")

    monkeypatch.setattr(export_mod, "_png_bytes", broken)
    with pytest.raises(OSError, match="disk full"):
        save_textured(old, V, F, uv, image)
    assert sorted(os.listdir(tmp_path)) == [old.name]
    assert old.read_bytes() == b"precious"


def test_failure_after_some_files_are_complete_leaves_nothing(tmp_path, monkeypatch):
    V, F, uv, image, _ = seam_mesh()
    (tmp_path / "m.png").write_bytes(b"old png")
    real_save_obj = export_mod.save_obj

    def save_obj_then_fail(path, *args, **kwargs):  # the OBJ is written last, after PNG and MTL
        real_save_obj(path, *args, **kwargs)
        raise RuntimeError("interrupted")

    monkeypatch.setattr(export_mod, "save_obj", save_obj_then_fail)
    with pytest.raises(RuntimeError, match="interrupted"):
        save_textured(tmp_path / "m.obj", V, F, uv, image)
    assert sorted(os.listdir(tmp_path)) == ["m.png"]
    assert (tmp_path / "m.png").read_bytes() == b"old png"


def test_overwrite_keeps_permissions(tmp_path):
    V, F, uv, image, _ = seam_mesh()
    path = tmp_path / "m.glb"
    path.write_bytes(b"x")
    os.chmod(path, 0o640)
    save_textured(path, V, F, uv, image)
    assert (path.stat().st_mode & 0o777) == 0o640
    assert path.read_bytes()[:4] == b"glTF"


def test_bad_input(tmp_path):
    V, F, uv, image, _ = seam_mesh()
    with pytest.raises(InputError, match="format"):
        save_textured(tmp_path / "m.ply", V, F, uv, image)
    with pytest.raises(InputError, match="corner_uv"):
        save_textured(tmp_path / "m.glb", V, F, uv[:-1], image)
    with pytest.raises(InputError, match="image"):
        save_textured(tmp_path / "m.glb", V, F, uv, image.astype(float))
    with pytest.raises(InputError, match="does not exist"):
        save_textured(tmp_path / "nope" / "m.glb", V, F, uv, image)
    assert os.listdir(tmp_path) == []


def test_pil_image_and_rgba(tmp_path):
    from PIL import Image
    V, F, uv, image, _ = seam_mesh()
    rgba = np.dstack([image, np.full(image.shape[:2], 255, np.uint8)])
    obj = save_textured(tmp_path / "m.obj", V, F, uv, Image.fromarray(rgba))[0]
    assert np.array_equal(np.asarray(Image.open(obj.with_suffix(".png"))), rgba)


def test_save_png(tmp_path, monkeypatch):
    from PIL import Image

    from uvbake.io.export import save_png
    _, _, _, image, _ = seam_mesh()
    path = save_png(tmp_path / "t.png", image)
    assert np.array_equal(np.asarray(Image.open(path)), image)
    with pytest.raises(InputError, match="png"):
        save_png(tmp_path / "t.jpg", image)
    monkeypatch.setattr(export_mod, "_png_bytes", lambda img: (_ for _ in ()).throw(OSError("full")))
    with pytest.raises(OSError):
        save_png(tmp_path / "t.png", image[::-1])
    assert np.array_equal(np.asarray(Image.open(path)), image) and os.listdir(tmp_path) == ["t.png"]
