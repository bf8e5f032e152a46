"""uvbake_open3d: tensor and legacy Open3D meshes in, the same kind out, laid out as compute_uvatlas does."""


import numpy as np
import pytest

from conftest import SAMPLE_SCENES, run_readme_example

o3d = pytest.importorskip("open3d")
import uvbake_open3d  # noqa: E402

SIZE = 128


@pytest.fixture(scope="module")
def cap_legacy():
    """An Open3D-built object: a UV sphere cut above z = -0.3, vertex colours from position."""
    sphere = o3d.geometry.TriangleMesh.create_sphere(radius=1.0, resolution=16)
    V, F = np.asarray(sphere.vertices), np.asarray(sphere.triangles)
    sphere.remove_triangles_by_mask(V[F][:, :, 2].mean(axis=1) < -0.3)
    sphere.remove_unreferenced_vertices()
    sphere.vertex_colors = o3d.utility.Vector3dVector((np.asarray(sphere.vertices) + 1.0) / 2.0)
    return sphere


def _labels(V, F):
    return (V[F].mean(axis=1)[:, 0] > 0).astype(np.int64)                # two charts: seams


@pytest.fixture(scope="module")
def legacy_out(cap_legacy):
    V, F = np.asarray(cap_legacy.vertices), np.asarray(cap_legacy.triangles)
    return uvbake_open3d.unwrap(cap_legacy, texture_size_px=SIZE, face_labels=_labels(V, F), return_result=True)


@pytest.fixture(scope="module")
def tensor_out(cap_legacy):
    t = o3d.t.geometry.TriangleMesh.from_legacy(cap_legacy)
    V, F = t.vertex.positions.numpy(), t.triangle.indices.numpy()
    return uvbake_open3d.unwrap(t, texture_size_px=SIZE, face_labels=_labels(V, F), return_result=True)


def test_tensor_layout_mirrors_compute_uvatlas(cap_legacy, tensor_out):
    out, result = tensor_out
    assert isinstance(out, o3d.t.geometry.TriangleMesh)
    ref = o3d.t.geometry.TriangleMesh.from_legacy(cap_legacy)
    ref.compute_uvatlas(size=64)                                       # Open3D's own unwrapper
    uv = out.triangle.texture_uvs
    assert uv.dtype == ref.triangle.texture_uvs.dtype == o3d.core.float32
    assert tuple(uv.shape) == (len(result.F), 3, 2) and tuple(ref.triangle.texture_uvs.shape)[1:] == (3, 2)
    assert np.allclose(uv.numpy(), result.corner_uv, atol=1e-6)
    assert out.vertex.positions.dtype == ref.vertex.positions.dtype
    assert out.triangle.indices.dtype == ref.triangle.indices.dtype
    albedo = out.material.texture_maps["albedo"].as_tensor().numpy()
    assert albedo.dtype == np.uint8 and np.array_equal(albedo, result.image)
    assert result.report["options"]["bake"] == "vertex-colors" and result.report["valid"]
    assert "colors" in out.vertex and "normals" in out.vertex


def test_texture_agrees_with_open3d_baker(tensor_out):
    """Open3D's own bake_vertex_attr_textures on the returned mesh paints the texels uvbake painted."""
    out, result = tensor_out
    baked = out.bake_vertex_attr_textures(SIZE, {"colors"}, margin=2.0, fill=float("nan"))["colors"].numpy()
    covered = np.all(np.isfinite(baked), axis=2)
    ours = result.image.astype(float) / 255.0
    assert covered.mean() > 0.3
    assert np.median(np.abs(ours[covered] - baked[covered]).max(axis=1)) < 2.5 / 255


def test_uv_origin_is_v_up(tensor_out):
    out, result = tensor_out
    cuv = out.triangle.texture_uvs.numpy().mean(axis=1)
    rows = np.clip(((1.0 - cuv[:, 1]) * SIZE).astype(int), 0, SIZE - 1)
    cols = np.clip((cuv[:, 0] * SIZE).astype(int), 0, SIZE - 1)
    sampled = result.image[rows, cols].astype(float) / 255.0
    expected = out.vertex.colors.numpy()[result.F].mean(axis=1)
    assert np.median(np.abs(sampled - expected).max(axis=1)) < 0.05
    flipped = result.image[SIZE - 1 - rows, cols].astype(float) / 255.0          # the other convention
    assert np.median(np.abs(flipped - expected).max(axis=1)) > 0.1


def test_legacy_layout(legacy_out):
    out, result = legacy_out
    assert isinstance(out, o3d.geometry.TriangleMesh)
    uv = np.asarray(out.triangle_uvs)
    assert uv.shape == (3 * len(result.F), 2)
    assert np.allclose(uv.reshape(-1, 3, 2), result.corner_uv)
    assert np.array_equal(np.asarray(out.triangle_material_ids), np.zeros(len(result.F)))
    assert len(out.textures) == 1 and np.array_equal(np.asarray(out.textures[0]), result.image)
    assert out.has_vertex_colors() and out.has_triangle_uvs() and out.has_textures()
    back = o3d.t.geometry.TriangleMesh.from_legacy(out)                    # Open3D's own conversion
    assert np.allclose(back.triangle.texture_uvs.numpy(), result.corner_uv, atol=1e-6)


def _corners(V, F):
    return np.asarray(V)[np.asarray(F)]


def test_tensor_round_trip_through_open3d_io(tensor_out, tmp_path):
    out, result = tensor_out
    path = tmp_path / "cap.obj"
    assert o3d.t.io.write_triangle_mesh(str(path), out)
    back = o3d.t.io.read_triangle_mesh(str(path))
    assert np.allclose(back.triangle.texture_uvs.numpy(), result.corner_uv, atol=1e-6)
    assert np.allclose(_corners(back.vertex.positions.numpy(), back.triangle.indices.numpy()),
                       _corners(result.V, result.F), atol=1e-5)
    assert np.array_equal(back.material.texture_maps["albedo"].as_tensor().numpy()[:, :, :3], result.image)


def test_legacy_round_trip_through_open3d_io(legacy_out, tmp_path):
    out, result = legacy_out
    path = tmp_path / "cap.obj"
    assert o3d.io.write_triangle_mesh(str(path), out)
    back = o3d.io.read_triangle_mesh(str(path), enable_post_processing=False)
    assert np.allclose(np.asarray(back.triangle_uvs).reshape(-1, 3, 2), result.corner_uv, atol=1e-6)
    assert np.allclose(_corners(back.vertices, back.triangles), _corners(result.V, result.F), atol=1e-5)
    ids = np.unique(np.asarray(back.triangle_material_ids))
    assert len(ids) == 1
    assert np.array_equal(np.asarray(back.textures[ids[0]])[:, :, :3], result.image)


def test_sample_scene_and_bad_input():
    mesh = o3d.t.io.read_triangle_mesh(str(SAMPLE_SCENES / "disk_holes.ply"))
    out = uvbake_open3d.unwrap(mesh, texture_size_px=64, bake=None)
    assert tuple(out.triangle.texture_uvs.shape) == (len(mesh.triangle.indices), 3, 2)
    assert np.all(out.material.texture_maps["albedo"].as_tensor().numpy() == 255)
    from uvbake.errors import InputError

    with pytest.raises(InputError, match="TriangleMesh"):
        uvbake_open3d.unwrap(o3d.geometry.PointCloud())


def test_readme_example(tmp_path, monkeypatch):
    scope = run_readme_example("import uvbake_open3d", tmp_path, monkeypatch)
    assert isinstance(scope["mesh"], o3d.t.geometry.TriangleMesh)
    assert tuple(scope["uvs"].shape)[1:] == (3, 2) and scope["texture"].rows == 256
    assert scope["result"].report["charts_final"] == 8          # the scene's labels survive Open3D's reader
    assert (tmp_path / "scene_uv.obj").exists()


def test_compute_uvatlas_keywords():
    """size, gutter, nthreads mean what they mean for compute_uvatlas; max_stretch warns it is unused."""
    from uvbake.errors import InputError

    mesh = o3d.t.io.read_triangle_mesh(str(SAMPLE_SCENES / "disk_holes.ply"))
    with pytest.warns(UserWarning, match="max_stretch=0.2 has no effect.*distortion_budget"):
        out, result = uvbake_open3d.unwrap(mesh, size=64, gutter=1.5, max_stretch=0.2, parallel_partitions=2,
                                           nthreads=1, bake=None, return_result=True)
    atlas = result.report["atlas"]
    assert atlas["texture_size_px"] == 64 and atlas["gutter_px"] == 2        # 1.5 px rounded up
    assert result.report["options"]["max_stretch_open3d"] == 0.2
    assert out.material.texture_maps["albedo"].rows == 64
    _, budget = uvbake_open3d.unwrap(mesh, size=64, distortion_budget=2.5, bake=None, return_result=True)
    assert budget.report["options"]["max_stretch"] == 2.5                  # uvbake's own budget, forwarded
    for bad, match in ((dict(size=64.5), "size"), (dict(gutter=-1), "gutter"), (dict(max_stretch=2), "max_stretch"),
                       (dict(size=64, texture_size_px=128), "disagree"), (dict(nthreads=-1), "nthreads")):
        with pytest.raises(InputError, match=match):
            uvbake_open3d.unwrap(mesh, bake=None, **bad)
    # uvbake's errors in the caller's keywords: here max_stretch is UVAtlas's, the budget distortion_budget
    for bad, said in ((dict(distortion_budget=0.5), "distortion_budget=0.5 must be a number above 1"),
                      (dict(size=512, gutter=200), "gutter=200 must be a whole number of texels from 0 to 64")):
        with pytest.raises(InputError) as err:
            uvbake_open3d.unwrap(mesh, bake=None, **bad)
        assert said in str(err.value) and "max_stretch" not in str(err.value) and "gutter_px" not in str(err.value)


def test_labels_lost_by_open3d_and_found_again(tmp_path):
    path = SAMPLE_SCENES / "scene.ply"
    mesh = o3d.t.io.read_triangle_mesh(str(path))
    assert "segment" not in mesh.triangle and "label" not in mesh.triangle     # Open3D dropped them
    _, lost = uvbake_open3d.unwrap(mesh, size=64, bake=None, return_result=True)
    _, kept = uvbake_open3d.unwrap(mesh, size=64, bake=None, face_labels=path, return_result=True)
    assert lost.report["charts_input"] < kept.report["charts_input"] == 8
    # a file without labels where labels were expected: a loud warning, charts from components
    plain = tmp_path / "plain.ply"
    o3d.t.io.write_triangle_mesh(str(plain), mesh)
    with pytest.warns(UserWarning, match="has no per-face labels"):
        uvbake_open3d.unwrap(o3d.t.io.read_triangle_mesh(str(plain)), size=64, bake=None, face_labels=plain)
    from uvbake.errors import InputError

    with pytest.raises(InputError, match="triangles are not the mesh's"):
        uvbake_open3d.unwrap(mesh, size=64, bake=None, face_labels=SAMPLE_SCENES / "disk_holes.ply")
