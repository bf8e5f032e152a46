"""uvbake.io: loading from every source, labels and colours, exact OBJ round trips, atomic writes."""

import os
from pathlib import Path

import numpy as np
import pytest

import uvbake.io as uio
import uvbake.io.load as uload
import uvbake.io.obj as uobj
from uvbake.errors import InputError
from uvbake.io.atomic import atomic_write
from uvbake.io.load import load_mesh
from uvbake.io.meshdata import MeshData
from uvbake.io.obj import load_obj_uv, save_obj

# ------------------------------------------------------------------------------------------------
# fixtures


def grid(nx=4, ny=3, seed=0):
    """A bumpy (nx x ny)-vertex grid: V (n,3), F (m,3) counter-clockwise."""
    rng = np.random.default_rng(seed)
    x, y = np.meshgrid(np.arange(nx, dtype=float), np.arange(ny, dtype=float))
    V = np.column_stack([x.ravel(), y.ravel(), rng.normal(size=nx * ny)])
    i = np.arange(nx * ny).reshape(ny, nx)
    a, b, c, d = i[:-1, :-1].ravel(), i[:-1, 1:].ravel(), i[1:, 1:].ravel(), i[1:, :-1].ravel()
    F = np.vstack([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    return V, F


def write_ply(path, V, faces, *, labels=None, label_name="segment", colors=None, ascii=False,
              extra_face_props=None):
    """A PLY writer independent of uvbake and trimesh; faces may be polygons of any size."""
    head = ["ply", f"format {'ascii' if ascii else 'binary_little_endian'} 1.0",
            f"element vertex {len(V)}", "property float x", "property float y", "property float z"]
    if colors is not None:
        head += [f"property uchar {c}" for c in ("red", "green", "blue")]
    head += [f"element face {len(faces)}", "property list uchar int vertex_indices"]
    props = dict(extra_face_props or {})
    if labels is not None:
        props[label_name] = labels
    head += [f"property int {name}" for name in props]
    head.append("end_header")
    out = ("\n".join(head) + "\n").encode()
    rows_v, rows_f = [], []
    for k, p in enumerate(V):
        rgb = [] if colors is None else list(colors[k])
        rows_v.append((p, rgb))
    for k, f in enumerate(faces):
        rows_f.append((list(f), [int(v[k]) for v in props.values()]))
    if ascii:
        text = "".join(" ".join(map(str, [*p, *rgb])) + "\n" for p, rgb in rows_v)
        text += "".join(" ".join(map(str, [len(f), *f, *extra])) + "\n" for f, extra in rows_f)
        out += text.encode()
    else:
        for p, rgb in rows_v:
            out += np.asarray(p, "<f4").tobytes() + np.asarray(rgb, "u1").tobytes()
        for f, extra in rows_f:
            out += np.uint8(len(f)).tobytes() + np.asarray(f, "<i4").tobytes()
            out += np.asarray(extra, "<i4").tobytes()
    Path(path).write_bytes(out)


def assert_one_line_naming(exc_info, name):
    message = str(exc_info.value)
    assert "\n" not in message
    assert str(name) in message
    assert ";" in message  # problem; fix


# ------------------------------------------------------------------------------------------------
# OBJ round trips


def test_save_obj_round_trip_is_bit_exact(tmp_path):
    V, F = grid(5, 4)
    V[0] = [1e-300, -1.0 / 3.0, 123456789.123456789]
    rng = np.random.default_rng(1)
    uv = rng.random((2 * len(F), 2)) * np.pi  # more uv than vertices: seams everywhere
    uv_faces = rng.integers(0, len(uv), F.shape)
    colors = rng.random(V.shape)
    path = tmp_path / "mesh.obj"
    save_obj(path, V, F, uv=uv, uv_faces=uv_faces, vertex_colors=colors)

    mesh = load_mesh(path)
    assert isinstance(mesh, MeshData) and mesh.source == str(path)
    assert np.array_equal(mesh.V, V) and mesh.V.dtype == np.float64
    assert np.array_equal(mesh.F, F) and mesh.F.dtype == np.int64
    assert np.array_equal(mesh.vertex_colors, colors)
    mesh2, uv2, uv_faces2 = load_obj_uv(path)
    assert np.array_equal(uv2, uv)
    assert np.array_equal(uv_faces2, uv_faces)
    assert np.array_equal(mesh2.V, V)


def test_save_obj_per_corner_and_per_vertex_uv(tmp_path):
    V, F = grid()
    corner_uv = np.random.default_rng(2).random((len(F), 3, 2))
    save_obj(tmp_path / "corner.obj", V, F, uv=corner_uv)
    _, uv, uv_faces = load_obj_uv(tmp_path / "corner.obj")
    assert np.array_equal(uv[uv_faces], corner_uv)

    vertex_uv = V[:, :2] / 7.0
    save_obj(tmp_path / "vertex.obj", V, F, uv=vertex_uv)
    _, uv, uv_faces = load_obj_uv(tmp_path / "vertex.obj")
    assert np.array_equal(uv, vertex_uv) and np.array_equal(uv_faces, F)


def test_save_obj_without_uv_writes_plain_faces_and_keeps_nan(tmp_path):
    V, F = grid()
    V[3, 1] = np.nan
    path = tmp_path / "plain.obj"
    save_obj(path, V, F, mtllib="plain.mtl", material="atlas")
    text = path.read_text()
    assert "mtllib plain.mtl\n" in text and "usemtl atlas\n" in text and "vt " not in text
    assert f"f {F[0, 0] + 1} {F[0, 1] + 1} {F[0, 2] + 1}\n" in text
    mesh, uv, uv_faces = load_obj_uv(path)
    assert uv is None and uv_faces is None and mesh.vertex_colors is None
    assert np.isnan(mesh.V[3, 1]) and np.array_equal(np.isnan(mesh.V), np.isnan(V))


def test_obj_polygons_and_negative_indices_are_fan_triangulated(tmp_path):
    path = tmp_path / "poly.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 2 0\n"
                    "f 1 2 3 4\nf -2 -3 5\n")  # quad, then a triangle with relative indices
    mesh = load_mesh(path)
    assert mesh.F.tolist() == [[0, 1, 2], [0, 2, 3], [3, 2, 4]]


def test_save_obj_rejects_bad_input_naming_the_file(tmp_path):
    V, F = grid()
    path = tmp_path / "bad.obj"
    with pytest.raises(InputError) as exc:
        save_obj(path, V, F + len(V))
    assert_one_line_naming(exc, path)
    with pytest.raises(InputError) as exc:
        save_obj(path, V, F, uv=np.zeros((3, 2)), uv_faces=F)
    assert_one_line_naming(exc, path)
    assert not path.exists()


# ------------------------------------------------------------------------------------------------
# sources: tuple, trimesh, Open3D, other file formats


def test_tuple_source_and_face_labels_argument():
    V, F = grid()
    labels = np.arange(len(F)) % 3
    mesh = load_mesh((V, F.astype(np.int32)), face_labels=labels)
    assert mesh.source == "arrays"
    assert np.array_equal(mesh.V, V) and mesh.F.dtype == np.int64 and np.array_equal(mesh.F, F)
    assert np.array_equal(mesh.face_labels, labels) and mesh.face_labels.dtype == np.int64
    assert mesh.vertex_colors is None


def test_nan_vertices_are_kept_for_the_mesh_checks():
    V, F = grid()
    V[2] = np.nan
    mesh = load_mesh((V, F))
    assert np.isnan(mesh.V[2]).all() and len(mesh.V) == len(V)


def test_trimesh_source_with_colours_and_face_attribute_label():
    import trimesh

    V, F = grid()
    rgba = np.tile(np.array([[255, 128, 0, 255]], np.uint8), (len(V), 1))
    tm = trimesh.Trimesh(V, F, vertex_colors=rgba, process=False)
    tm.face_attributes["chart_id"] = np.arange(len(F)) // 4
    mesh = load_mesh(tm)
    assert mesh.source == "trimesh.Trimesh"
    assert np.array_equal(mesh.V, V) and np.array_equal(mesh.F, F)
    np.testing.assert_allclose(mesh.vertex_colors, np.tile([1.0, 128 / 255, 0.0], (len(V), 1)))
    assert np.array_equal(mesh.face_labels, np.arange(len(F)) // 4)


def test_open3d_legacy_and_tensor_sources():
    o3d = pytest.importorskip("open3d")
    V, F = grid()
    colors = np.random.default_rng(3).random(V.shape)
    legacy = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(V), o3d.utility.Vector3iVector(F))
    legacy.vertex_colors = o3d.utility.Vector3dVector(colors)
    mesh = load_mesh(legacy)
    assert mesh.source == "open3d.geometry.TriangleMesh"
    assert np.array_equal(mesh.V, V) and np.array_equal(mesh.F, F)
    np.testing.assert_allclose(mesh.vertex_colors, colors)
    assert mesh.face_labels is None

    tensor = o3d.t.geometry.TriangleMesh()
    tensor.vertex.positions = o3d.core.Tensor(V)
    tensor.triangle.indices = o3d.core.Tensor(F.astype(np.int64))
    tensor.triangle.segment = o3d.core.Tensor((np.arange(len(F)) % 2).astype(np.int32))
    mesh = load_mesh(tensor)
    assert mesh.source == "open3d.t.geometry.TriangleMesh"
    assert np.array_equal(mesh.V, V) and np.array_equal(mesh.F, F)
    assert np.array_equal(mesh.face_labels, np.arange(len(F)) % 2)
    assert mesh.vertex_colors is None


def test_glb_scene_of_two_meshes_is_concatenated_with_transforms(tmp_path):
    import trimesh

    V, F = grid()
    a = trimesh.Trimesh(V, F, process=False)
    b = trimesh.Trimesh(V[:6], np.array([[0, 1, 5], [0, 5, 4], [1, 2, 5], [2, 3, 5]]), process=False)
    b.visual.vertex_colors = np.tile([0, 255, 0, 255], (6, 1)).astype(np.uint8)
    a.visual.vertex_colors = np.tile([255, 0, 0, 255], (len(V), 1)).astype(np.uint8)
    scene = trimesh.Scene()
    scene.add_geometry(a, node_name="a", geom_name="a")
    shift = np.eye(4)
    shift[:3, 3] = [10.0, 0.0, 0.0]
    scene.add_geometry(b, node_name="b", geom_name="b", transform=shift)
    path = tmp_path / "two.glb"
    path.write_bytes(scene.export(file_type="glb"))
    mesh = load_mesh(path)
    assert len(mesh.V) == len(V) + 6 and len(mesh.F) == len(F) + 4
    assert mesh.face_labels is None  # components keep the two meshes apart
    by_x = mesh.V[:, 0] > 5  # the shifted mesh
    assert by_x.sum() == 6
    np.testing.assert_allclose(np.sort(mesh.V[by_x, 0]), np.sort(V[:6, 0] + 10), atol=1e-6)
    green = np.isclose(mesh.vertex_colors[:, 1], 1.0)
    assert np.array_equal(green, by_x)
    assert np.array_equal(np.unique(mesh.F), np.arange(len(mesh.V)))


def test_stl_triangle_soup_is_welded_back_into_one_surface(tmp_path):
    import trimesh

    V, F = grid(5, 5)
    path = tmp_path / "grid.stl"
    path.write_bytes(trimesh.Trimesh(V, F, process=False).export(file_type="stl"))
    mesh = load_mesh(path)
    assert len(mesh.V) == len(V) and len(mesh.F) == len(F)
    np.testing.assert_allclose(mesh.V[mesh.F], V[F], atol=1e-6)  # float32 in STL


@pytest.mark.meshes
def test_research_off_meshes_keep_their_vertex_counts(shared_meshes):
    for name, n_vertices in [("halftunnel.off", 831), ("camelhead.off", 11381)]:
        mesh = load_mesh(shared_meshes / name)
        assert len(mesh.V) == n_vertices
        assert mesh.F.min() >= 0 and mesh.F.max() < n_vertices


# ------------------------------------------------------------------------------------------------
# PLY labels and colours


@pytest.mark.parametrize("name", uio.LABEL_NAMES)
@pytest.mark.parametrize("ascii", [False, True])
def test_ply_face_label_property_names(tmp_path, name, ascii):
    V, F = grid()
    labels = (np.arange(len(F)) * 7) % 5 - 1  # includes -1
    path = tmp_path / f"{name}.ply"
    write_ply(path, V, F, labels=labels, label_name=name, ascii=ascii)
    mesh = load_mesh(path)
    assert np.array_equal(mesh.face_labels, labels) and mesh.face_labels.dtype == np.int64
    assert np.array_equal(mesh.F, F)
    np.testing.assert_allclose(mesh.V, V.astype(np.float32))


def test_ply_first_label_name_in_the_list_wins_and_argument_overrides(tmp_path):
    V, F = grid()
    path = tmp_path / "two_props.ply"
    write_ply(path, V, F, extra_face_props={"region": np.full(len(F), 9),
                                            "segment": np.arange(len(F))})
    assert np.array_equal(load_mesh(path).face_labels, np.arange(len(F)))
    mine = np.zeros(len(F), np.int64)
    assert np.array_equal(load_mesh(path, face_labels=mine).face_labels, mine)


@pytest.mark.parametrize("ascii", [False, True])
def test_ply_polygon_labels_follow_their_triangles(tmp_path, ascii):
    V = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [2, 1, 0], [1, 1, 0], [0, 1, 0], [1, 2, 0]], float)
    faces = [[0, 1, 4, 5], [1, 2, 3], [4, 3, 6, 5]]  # quad, triangle, quad
    path = tmp_path / "poly.ply"
    write_ply(path, V, faces, labels=[10, 20, 30], ascii=ascii)
    mesh = load_mesh(path)
    assert len(mesh.F) == 5 and len(mesh.face_labels) == 5
    # each triangle carries the label of the polygon it came from
    for tri, label in zip(mesh.F, mesh.face_labels):
        polygon = faces[[10, 20, 30].index(label)]
        assert set(tri.tolist()) <= set(polygon)
    assert sorted(mesh.face_labels.tolist()) == [10, 10, 20, 30, 30]


def test_ply_vertex_colours_are_rgb_in_unit_range(tmp_path):
    V, F = grid()
    rgb = (np.arange(len(V) * 3).reshape(-1, 3) * 7) % 256
    path = tmp_path / "colours.ply"
    write_ply(path, V, F, colors=rgb)
    mesh = load_mesh(path)
    assert mesh.vertex_colors.shape == (len(V), 3) and mesh.vertex_colors.dtype == np.float64
    np.testing.assert_allclose(mesh.vertex_colors, rgb / 255.0)
    assert mesh.face_labels is None


# ------------------------------------------------------------------------------------------------
# errors: one line, naming the file and the fix


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match="not found") as exc:
        load_mesh(tmp_path / "nope.ply")
    assert_one_line_naming(exc, tmp_path / "nope.ply")


def test_directory(tmp_path):
    with pytest.raises(InputError, match="directory") as exc:
        load_mesh(tmp_path)
    assert_one_line_naming(exc, tmp_path)


@pytest.mark.parametrize("ext", [".ply", ".obj", ".off", ".glb", ".stl"])
def test_empty_file(tmp_path, ext):
    path = tmp_path / f"scene{ext}"
    path.write_bytes(b"")
    with pytest.raises(InputError, match=r"empty \(0 bytes\)") as exc:
        load_mesh(path)
    assert_one_line_naming(exc, path)


def test_unknown_extension(tmp_path):
    path = tmp_path / "mesh.xyz"
    path.write_text("1 2 3\n")
    with pytest.raises(InputError, match="unknown mesh format '.xyz'") as exc:
        load_mesh(path)
    assert_one_line_naming(exc, path)


@pytest.mark.parametrize("ext", [".ply", ".off", ".glb", ".obj"])
def test_text_file_with_a_mesh_extension(tmp_path, ext):
    path = tmp_path / f"notes{ext}"
    path.write_text("these are my notes, not a mesh\nsecond line\n")
    with pytest.raises(InputError, match="cannot read") as exc:
        load_mesh(path)
    assert_one_line_naming(exc, path)


def test_point_cloud_has_no_faces(tmp_path):
    path = tmp_path / "cloud.ply"
    V, _ = grid()
    head = f"ply\nformat ascii 1.0\nelement vertex {len(V)}\nproperty float x\nproperty float y\n" \
           "property float z\nend_header\n"
    path.write_text(head + "".join(f"{x} {y} {z}\n" for x, y, z in V))
    with pytest.raises(InputError, match="no faces") as exc:
        load_mesh(path)
    assert_one_line_naming(exc, path)
    with pytest.raises(InputError, match="no faces"):
        load_mesh((V, np.zeros((0, 3), np.int64)))


def test_face_index_out_of_range(tmp_path):
    V, F = grid()
    bad = F.copy()
    bad[2, 1] = len(V) + 3
    for path in (tmp_path / "bad.ply", tmp_path / "bad.obj"):
        if path.suffix == ".ply":
            write_ply(path, V, bad)
        else:
            save_obj(path, V, F)
            path.write_text(path.read_text() + f"f 1 2 {len(V) + 4}\n")
        with pytest.raises(InputError, match="out of range") as exc:
            load_mesh(path)
        assert_one_line_naming(exc, path)
    with pytest.raises(InputError, match=f"face index {-1} out of range"):
        load_mesh((V, F - 1))


def test_face_labels_wrong_length_or_not_integer(tmp_path):
    V, F = grid()
    path = tmp_path / "mesh.ply"
    write_ply(path, V, F)
    with pytest.raises(InputError, match=f"but the mesh has {len(F)} faces") as exc:
        load_mesh(path, face_labels=np.zeros(len(F) - 1, np.int64))
    assert_one_line_naming(exc, path)
    with pytest.raises(InputError, match="must be integers") as exc:
        load_mesh(path, face_labels=np.full(len(F), 0.5))
    assert_one_line_naming(exc, path)
    # integral floats are integers
    assert load_mesh((V, F), face_labels=np.ones(len(F))).face_labels.dtype == np.int64


def test_unsupported_source_type():
    with pytest.raises(InputError, match="cannot load a mesh from a dict"):
        load_mesh({"V": 1})


# ------------------------------------------------------------------------------------------------
# atomic writes


def test_atomic_write_keeps_the_old_file_when_the_block_fails(tmp_path):
    path = tmp_path / "out.txt"
    path.write_text("old content\n")
    with pytest.raises(RuntimeError, match="boom"):
        with atomic_write(path) as f:
            f.write("half of the new con")
            raise RuntimeError("boom")
    assert path.read_text() == "old content\n"
    assert os.listdir(tmp_path) == ["out.txt"]  # no temp file left


def test_atomic_write_replaces_on_success_keeping_permissions(tmp_path):
    path = tmp_path / "out.bin"
    path.write_bytes(b"old")
    os.chmod(path, 0o640)
    with atomic_write(path, "wb") as f:
        f.write(b"new")
        assert path.read_bytes() == b"old"  # not visible until the block ends
    assert path.read_bytes() == b"new"
    assert path.stat().st_mode & 0o777 == 0o640
    assert os.listdir(tmp_path) == ["out.bin"]


def test_save_obj_failing_mid_write_leaves_the_old_obj(tmp_path, monkeypatch):
    V, F = grid()
    path = tmp_path / "mesh.obj"
    save_obj(path, V, F)
    before = path.read_bytes()
    real = uobj._write_rows

    def fail_on_faces(f, tag, rows, fmt):
        if tag == "f":
            raise OSError("disk full")
        real(f, tag, rows, fmt)

    monkeypatch.setattr(uobj, "_write_rows", fail_on_faces)
    with pytest.raises(OSError, match="disk full"):
        save_obj(path, V + 1.0, F, uv=V[:, :2])
    assert path.read_bytes() == before
    assert os.listdir(tmp_path) == ["mesh.obj"]


def test_atomic_write_rejects_a_missing_folder_and_bad_mode(tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        with atomic_write(tmp_path / "no" / "out.txt"):
            pass
    with pytest.raises(InputError, match="mode"):
        with atomic_write(tmp_path / "out.txt", "a"):
            pass


def test_own_ply_reader_agrees_with_trimesh_on_a_sample_scene():
    import trimesh

    path = Path(__file__).resolve().parents[1] / "sample_scenes" / "scene.ply"
    elements = uio.read_ply_elements(path)
    tm = trimesh.load(path, process=False)
    V = np.column_stack([elements["vertex"][k] for k in "xyz"])
    assert np.array_equal(V, tm.vertices) and np.array_equal(elements["face"]["vertex_indices"], tm.faces)
    assert np.array_equal(elements["face"]["segment"], load_mesh(path).face_labels)


def test_binary_ply_with_mixed_polygons_and_no_faces_property(tmp_path):
    V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0.5, 0]], float)
    path = tmp_path / "mixed.ply"
    write_ply(path, V, [[0, 1, 2, 3], [1, 4, 2]])  # trimesh cannot read this one
    mesh = load_mesh(path)
    assert mesh.F.tolist() == [[0, 1, 2], [0, 2, 3], [1, 4, 2]] and mesh.face_labels is None


def test_own_readers_agree_with_trimesh_on_every_sample_scene_and_research_mesh():
    """Binary triangle PLY and triangle OFF are read without trimesh: same V, F, colours, labels."""
    import trimesh

    root = Path(__file__).resolve().parents[1]
    paths = sorted((root / "sample_scenes").glob("*.ply"))
    shared = root.parent / "shared" / "meshes"
    paths += sorted(shared.glob("*.off")) if shared.is_dir() else []
    read = 0
    for path in paths:
        ours = uload._read_own_ply(path) if path.suffix == ".ply" else uload._read_off_triangles(path)
        if ours is None:                                  # e.g. halftunnel's quads: trimesh reads them
            continue
        read += 1
        kw = {"fix_texture": False} if path.suffix == ".ply" else {}
        ref = uload._from_trimesh(trimesh.load(str(path), process=False, **kw), str(path))
        assert np.array_equal(ours.V, ref.V) and np.array_equal(ours.F, ref.F), path.name
        for a, b in ((ours.vertex_colors, ref.vertex_colors), (ours.face_labels, ref.face_labels)):
            assert (a is None and b is None) or np.array_equal(a, b), path.name
    assert read >= 4                                      # the four sample scenes at least


def test_off_reader_declines_what_it_does_not_handle(tmp_path):
    quads = tmp_path / "quad.off"
    quads.write_text("OFF\n4 1 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n")
    coloured = tmp_path / "colour.off"
    coloured.write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2 255 0 0\n")
    commented = tmp_path / "comment.off"
    commented.write_text("OFF # a triangle\n3 1 0\n0 0 0\n1 0 0 # x\n0 1 0\n3 0 1 2\n")
    assert uload._read_off_triangles(quads) is None and uload._read_off_triangles(coloured) is None
    mesh = uload._read_off_triangles(commented)
    assert mesh.F.tolist() == [[0, 1, 2]] and mesh.V.tolist() == [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
    assert load_mesh(quads).F.shape == (2, 3)             # trimesh still reads the others
    bad = tmp_path / "bad.off"
    bad.write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n")
    with pytest.raises(InputError, match="out of range"):
        load_mesh(bad)


def test_coff_vertex_colours_are_read(tmp_path):
    # Meshlab and Geomview write COFF: x y z then RGBA 0-255 (or RGB 0-1 floats) per vertex; trimesh drops them
    V = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]
    F = [[0, 1, 2], [1, 3, 2]]
    rgba = [[255, 0, 0, 255], [0, 255, 0, 255], [0, 0, 255, 255], [255, 255, 255, 128]]
    ints = tmp_path / "ints.off"
    ints.write_text("COFF\n4 2 0\n" + "".join(" ".join(map(str, v + c)) + "\n" for v, c in zip(V, rgba))
                    + "3 0 1 2\n3 1 3 2\n")
    floats = tmp_path / "floats.off"
    floats.write_text("COFF # rgb in [0, 1]\n4 2 0\n" + "".join(f"{v[0]} {v[1]} {v[2]} 0.5 0.25 1\n" for v in V)
                      + "3 0 1 2\n3 1 3 2\n")
    a, b = load_mesh(ints), load_mesh(floats)
    assert a.V.tolist() == V and a.F.tolist() == F and b.F.tolist() == F
    assert np.allclose(a.vertex_colors, np.array(rgba)[:, :3] / 255.0, rtol=0, atol=1e-12)
    assert np.allclose(b.vertex_colors, [[0.5, 0.25, 1.0]] * 4, rtol=0, atol=1e-12)
    plain = tmp_path / "plain.off"
    plain.write_text("OFF\n4 2 0\n" + "".join(" ".join(map(str, v)) + "\n" for v in V) + "3 0 1 2\n3 1 3 2\n")
    assert load_mesh(plain).vertex_colors is None


@pytest.mark.parametrize("encoding", ["binary_little_endian", "ascii"])
@pytest.mark.parametrize("ptype, fmt, values", [("uchar", "B", (255, 51, 0)), ("ushort", "H", (65535, 13107, 0)),
                                                ("float", "f", (1.0, 0.2, 0.0)), ("float", "f", (255.0, 51.0, 0.0))])
def test_ply_colours_of_any_depth_come_out_in_unit_range(tmp_path, ptype, fmt, values, encoding):
    # 16-bit colours (some scanners) over 65535, not taken as 8-bit and clipped; float 0-255 over 255;
    # in ASCII files too (trimesh clips 16-bit ones to 255)
    import struct

    V = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
    head = (f"ply\nformat {encoding} 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
            f"property float z\nproperty {ptype} red\nproperty {ptype} green\nproperty {ptype} blue\n"
            "element face 1\nproperty list uchar int vertex_indices\nend_header\n").encode()
    if encoding == "ascii":
        body = "".join(" ".join(map(str, (*v, *values))) + "\n" for v in V).encode() + b"3 0 1 2\n"
    else:
        body = b"".join(struct.pack("<fff" + 3 * fmt, *v, *values) for v in V) + struct.pack("<Biii", 3, 0, 1, 2)
    path = tmp_path / "c.ply"
    path.write_bytes(head + body)
    assert np.allclose(load_mesh(path).vertex_colors, [[1.0, 0.2, 0.0]] * 3, rtol=0, atol=1e-7)


# ---------------------------------------------------------------------------------------- issue 15


def _sheet_ply(encoding):
    """A 7 x 7 grid sheet (98 triangles) written by trimesh as ASCII or binary PLY bytes."""
    import trimesh

    s, t = np.meshgrid(np.arange(8.0), np.arange(8.0), indexing="ij")
    V = np.column_stack([s.ravel(), t.ravel(), np.zeros(64)])
    idx = np.arange(64).reshape(8, 8)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    F = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return trimesh.Trimesh(V, F, process=False).export(file_type="ply", encoding=encoding), len(F)


@pytest.mark.parametrize("encoding", ["ascii", "binary"])
def test_a_truncated_ply_is_refused(tmp_path, encoding):
    data, m = _sheet_ply(encoding)
    assert len(load_mesh(_write(tmp_path / "whole.ply", data)).F) == m
    if encoding == "ascii":                        # the last 49 face lines are missing
        lines = data.split(b"\n")
        cut = b"\n".join(lines[: len(lines) - 1 - m // 2]) + b"\n"
    else:                                          # the last 49 faces (13 bytes each) are missing
        cut = data[: len(data) - 13 * (m // 2)]
    with pytest.raises(InputError, match=r"98 face.*truncated"):
        load_mesh(_write(tmp_path / "cut.ply", cut))


def test_a_truncated_off_is_refused(tmp_path):
    path = _write(tmp_path / "t.off", b"OFF\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2\n")
    with pytest.raises(InputError, match="2 faces.*truncated"):
        load_mesh(path)


BOM = b"\xef\xbb\xbf"


@pytest.mark.parametrize("ext, body", [
    ("obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n"),
    ("off", b"OFF\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2\n3 1 3 2\n"),
    ("ply", b"ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
            b"element face 2\nproperty list uchar int vertex_indices\nend_header\n"
            b"0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2\n3 1 3 2\n"),
])
def test_a_utf8_byte_order_mark_is_not_data(tmp_path, ext, body):
    plain = load_mesh(_write(tmp_path / f"plain.{ext}", body))
    marked = load_mesh(_write(tmp_path / f"bom.{ext}", BOM + body))
    assert len(marked.V) == 4 and np.array_equal(marked.V, plain.V) and np.array_equal(marked.F, plain.F)


def _write(path, data):
    path.write_bytes(data)
    return path


def _two_material_obj(path, materials):
    """A 4 x 2 grid of quads (16 triangles) whose columns take ``materials`` in turn (None: no usemtl)."""
    lines = [f"v {x} {y} 0" for y in range(3) for x in range(5)]
    for col in range(4):
        if materials[col] is not None:
            lines.append(f"usemtl {materials[col]}")
        for row in range(2):
            a = row * 5 + col + 1
            lines.append(f"f {a} {a + 1} {a + 6} {a + 5}")
    path.write_text("\n".join(lines) + "\n")
    return path


def test_obj_materials_label_the_faces(tmp_path):
    # each quad is two triangles; labels number the materials in order of first use, faces before any
    # usemtl being a label of their own
    m = load_mesh(_two_material_obj(tmp_path / "a.obj", [None, "wood", "metal", "wood"]))
    assert m.face_labels.tolist() == [0] * 4 + [1] * 4 + [2] * 4 + [1] * 4
    m = load_mesh(_two_material_obj(tmp_path / "b.obj", ["wood", "metal", "metal", "glass"]))
    assert m.face_labels.tolist() == [0] * 4 + [1] * 8 + [2] * 4
    # one material, or the same one named twice: no labels
    assert load_mesh(_two_material_obj(tmp_path / "c.obj", ["wood", None, "wood", None])).face_labels is None
    assert load_mesh(_two_material_obj(tmp_path / "d.obj", [None] * 4)).face_labels is None
    # ignored on request; face_labels given still override
    assert load_mesh(tmp_path / "a.obj", materials=False).face_labels is None
    assert load_mesh(tmp_path / "a.obj", face_labels=np.zeros(16, int)).face_labels.tolist() == [0] * 16
