"""A textured GLB/OBJ renders as its baked texture: the file, read back by Open3D's own reader and
rendered offscreen, matches the render of the texture on the atlas (issue 17).

Viewers multiply glTF ``COLOR_0`` (and OBJ vertex colours) with the texture, so a colour bake written
beside its vertex colours shows the colours squared. ``UnwrapResult.save`` therefore writes the texture
alone unless ``keep_vertex_colors=True``; the second test shows the comparison catches that case.
"""

import numpy as np
import pytest

from pytest_uvbake.compare import compare_images
from pytest_uvbake.plugin import DEFAULT_MAD_TOL, DEFAULT_SSIM_MIN

from conftest import SAMPLE_SCENES

SIZE, VIEW = 256, 128


@pytest.fixture(scope="module")
def scene():
    from uvbake.atlas.pipeline import unwrap

    r = unwrap(SAMPLE_SCENES / "scene.ply", texture_size_px=SIZE, bake="vertex-colors")
    assert r.vertex_colors is not None           # the input is vertex-coloured: the case at stake
    return r


@pytest.fixture(scope="module")
def expected(scene):
    from uvbake.render import preview

    return preview(scene.V, scene.F, scene.corner_uv, scene.image, size_px=VIEW)


def _render_file(path):
    """Read with Open3D (as a viewer would) and render with the file's own UVs, texture and colours."""
    import open3d as o3d

    from uvbake.render import preview

    model = o3d.io.read_triangle_model(str(path))
    assert len(model.meshes) == 1
    mesh = model.meshes[0].mesh
    texture = np.asarray(model.materials[model.meshes[0].material_idx].albedo_img)[:, :, :3]
    colors = np.asarray(mesh.vertex_colors) if mesh.has_vertex_colors() else None
    return preview(np.asarray(mesh.vertices), np.asarray(mesh.triangles),
                   np.asarray(mesh.triangle_uvs).reshape(-1, 3, 2), np.ascontiguousarray(texture),
                   size_px=VIEW, vertex_colors=colors), colors


@pytest.mark.parametrize("ext", [".glb", ".obj"])
def test_exported_file_renders_as_its_texture(scene, expected, tmp_path, ext):
    path = tmp_path / f"scene{ext}"
    scene.save(path)
    got, colors = _render_file(path)
    assert colors is None                       # no vertex colours beside the baked texture
    c = compare_images(got, expected)
    # the plugin's golden tolerances (mean absolute difference in levels, SSIM)
    assert c.mad <= DEFAULT_MAD_TOL and c.ssim >= DEFAULT_SSIM_MIN, c


def test_kept_vertex_colors_are_multiplied_and_caught(scene, expected, tmp_path):
    path = tmp_path / "scene.glb"
    scene.save(path, keep_vertex_colors=True)
    got, colors = _render_file(path)
    assert colors is not None and len(colors) > 0
    c = compare_images(got, expected)
    assert c.mad > DEFAULT_MAD_TOL, c           # the colours squared: far outside the golden tolerance
