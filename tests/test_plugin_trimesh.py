"""uvbake_trimesh: a Trimesh in, a textured Trimesh out; seams survive trimesh's own writers and readers."""


import numpy as np
import pytest

from conftest import SAMPLE_SCENES, run_readme_example

trimesh = pytest.importorskip("trimesh")
import uvbake_trimesh  # noqa: E402

SIZE = 128


@pytest.fixture(scope="module")
def hemisphere():
    """A trimesh-built object: an icosphere cut open at the equator, with vertex colours."""
    sphere = trimesh.creation.icosphere(subdivisions=3)
    keep = sphere.triangles_center[:, 2] > -0.2
    mesh = trimesh.Trimesh(sphere.vertices, sphere.faces[keep], process=False)
    mesh.remove_unreferenced_vertices()
    mesh.visual.vertex_colors = np.column_stack([(mesh.vertices + 1) / 2 * 255, np.full(len(mesh.vertices), 255)]
                                                ).astype(np.uint8)
    return mesh


@pytest.fixture(scope="module")
def textured(hemisphere):
    halves = (hemisphere.triangles_center[:, 0] > 0).astype(np.int64)      # two charts: seams to keep
    return uvbake_trimesh.unwrap(hemisphere, alpha=0.5, texture_size_px=SIZE, face_labels=halves,
                                 return_result=True)


def test_unwrap_returns_textured_trimesh(hemisphere, textured):
    out, result = textured
    assert isinstance(out, trimesh.Trimesh)
    assert isinstance(out.visual, trimesh.visual.TextureVisuals)
    assert result.report["options"]["bake"] == "vertex-colors"          # "auto" picked the colours
    assert out.visual.uv.shape == (len(out.vertices), 2)
    assert np.array_equal(np.asarray(out.visual.material.image), result.image)
    # same triangles, same 3D corners; per-corner UVs are the atlas's
    assert len(out.faces) == len(result.F)
    assert np.allclose(out.vertices[out.faces], result.V[result.F])
    assert np.allclose(uvbake_trimesh.corner_uv(out), result.corner_uv)
    assert len(out.vertices) > len(result.V)                           # vertices split along seams
    assert out.metadata["uvbake"]["valid"] is True
    assert len(hemisphere.visual.vertex_colors) == len(hemisphere.vertices)      # input untouched


def test_texture_matches_vertex_colours_with_v_up(textured):
    out, result = textured
    cuv = uvbake_trimesh.corner_uv(out).mean(axis=1)
    img = result.image
    rows = np.clip(((1.0 - cuv[:, 1]) * SIZE).astype(int), 0, SIZE - 1)
    cols = np.clip((cuv[:, 0] * SIZE).astype(int), 0, SIZE - 1)
    sampled = img[rows, cols].astype(float)
    expected = result.vertex_colors[result.F].mean(axis=1)
    expected = expected * 255 if expected.max() <= 1.0 else expected
    assert np.median(np.abs(sampled - expected[:, :3]).max(axis=1)) < 12


@pytest.mark.parametrize("ext", ["obj", "glb"])
def test_round_trip_keeps_seams(textured, tmp_path, ext):
    out, _ = textured
    path = tmp_path / f"hemi.{ext}"
    uvbake_trimesh.export(out, path)
    for back in (uvbake_trimesh.load(path), trimesh.load(path, force="mesh")):   # ours, and trimesh's defaults
        assert len(back.faces) == len(out.faces)
        assert len(back.vertices) == len(out.vertices)                 # seam vertices not welded
        assert np.abs(uvbake_trimesh.corner_uv(back) - uvbake_trimesh.corner_uv(out)).max() < 1e-6
        assert np.allclose(back.vertices[back.faces], out.vertices[out.faces], atol=1e-6)
        assert np.array_equal(np.asarray(uvbake_trimesh.texture_image(back).convert("RGB")),
                              np.asarray(uvbake_trimesh.texture_image(out).convert("RGB")))
    if ext == "obj":
        assert (tmp_path / "hemi.mtl").exists() and (tmp_path / "hemi.png").exists()


def test_welding_by_position_would_break_seams(textured, tmp_path):
    out, _ = textured
    welded = out.copy()
    welded.merge_vertices(merge_tex=True)              # what trimesh does when told to merge by position
    assert len(welded.vertices) < len(out.vertices)
    assert np.abs(uvbake_trimesh.corner_uv(welded) - uvbake_trimesh.corner_uv(out)).max() > 0.01
    # export's check compares what was written with what it read back; a welded mesh reads back as
    # written, so it passes the check, but its seams are gone: the UVs no longer match the atlas
    uvbake_trimesh.export(out, tmp_path / "ok.obj")    # the unwelded one round-trips (checked inside)


def test_sample_scene_and_bad_input():
    mesh = trimesh.load(SAMPLE_SCENES / "disk_holes.ply", process=False)
    out = uvbake_trimesh.unwrap(mesh, texture_size_px=64, bake=None)
    assert out.visual.material.image.size == (64, 64)
    assert len(out.faces) == len(mesh.faces)
    from uvbake.errors import InputError

    with pytest.raises(InputError, match="trimesh.Trimesh"):
        uvbake_trimesh.unwrap(trimesh.Scene())


def test_readme_example(tmp_path, monkeypatch):
    scope = run_readme_example("import uvbake_trimesh", tmp_path, monkeypatch)
    assert isinstance(scope["textured"].visual, trimesh.visual.TextureVisuals)
    assert (tmp_path / "disk_holes_uv.glb").exists()
    assert np.abs(uvbake_trimesh.corner_uv(scope["again"]) - uvbake_trimesh.corner_uv(scope["textured"])).max() < 1e-6


def test_signature_of_trimesh_unwrap(hemisphere):
    """Trimesh.unwrap(image=None): the image is assigned to the material, nothing is baked."""
    import inspect

    from PIL import Image

    ours = list(inspect.signature(uvbake_trimesh.unwrap).parameters)
    theirs = list(inspect.signature(trimesh.Trimesh.unwrap).parameters)
    assert ours[:len(theirs)] == ["mesh", *theirs[1:]]                 # (self | mesh, image)
    img = Image.new("RGB", (32, 16), (10, 200, 30))
    out, result = uvbake_trimesh.unwrap(hemisphere, img, texture_size_px=64, return_result=True)
    assert result.image is None and result.report["options"]["bake"] is None
    assert np.array_equal(np.asarray(uvbake_trimesh.texture_image(out)), np.asarray(img))


def test_export_to_an_unsupported_format_is_a_uvbake_error(textured, tmp_path):
    from uvbake.errors import UvbakeError

    out, _ = textured
    with pytest.raises(UvbakeError, match=r"path='.*x\.xyz'.*\.obj, \.glb"):
        uvbake_trimesh.export(out, tmp_path / "x.xyz")
    assert not list(tmp_path.iterdir())
