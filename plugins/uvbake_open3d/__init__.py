"""uvbake for Open3D: ``unwrap(mesh)`` where a workflow would call ``TriangleMesh.compute_uvatlas``.

    import open3d as o3d, uvbake_open3d
    mesh = o3d.t.io.read_triangle_mesh("sample_scenes/scene.ply")
    mesh = uvbake_open3d.unwrap(mesh, alpha=0.5, texture_size_px=512)
    mesh.triangle.texture_uvs                       # (m,3,2) float32, as compute_uvatlas leaves it
    mesh.material.texture_maps["albedo"]            # the baked texture (open3d.t.geometry.Image)
    o3d.t.io.write_triangle_mesh("scene_uv.obj", mesh)

Layout, mirrored from Open3D (checked in ``tests/test_plugin_open3d.py``):

- tensor ``open3d.t.geometry.TriangleMesh``: ``triangle.texture_uvs`` float32 ``(m,3,2)`` per corner
  (what ``compute_uvatlas`` writes); the texture as ``material.texture_maps["albedo"]`` (uint8 RGB)
  with ``material.material_name = "defaultLit"`` (what Open3D's OBJ/GLB readers produce).
- legacy ``open3d.geometry.TriangleMesh``: ``triangle_uvs`` float64 ``(3m,2)`` (corner ``3 t + k``),
  ``textures = [open3d.geometry.Image]`` and ``triangle_material_ids`` all 0 (what
  ``read_triangle_mesh`` gives for a textured OBJ).
- UV origin: Open3D's bakers (``bake_vertex_attr_textures``) and renderer use v up with image row 0 at
  v = 1 (the OBJ convention), which is uvbake's, so UVs and image bytes are passed unchanged.

A new mesh is returned (the input is not modified): uvbake may repair the input (drop duplicate or
degenerate faces, split bowties), so vertex and face counts can differ from the input's; vertex
positions keep the input's dtype and device, vertex colours are kept, vertex normals recomputed.
"""

from __future__ import annotations

import numpy as np

__all__ = ["unwrap", "to_open3d"]


def unwrap(mesh, *, alpha=0.5, texture_size_px=1024, gutter_px=4, bake="auto", return_result=False,
           **options):
    """Unwrap an Open3D triangle mesh (tensor or legacy) and return the same kind, textured.

    Parameters
    ----------
    mesh : open3d.t.geometry.TriangleMesh or open3d.geometry.TriangleMesh
    alpha, texture_size_px, gutter_px, **options
        As in :func:`uvbake.atlas.pipeline.unwrap` (``init``, ``backend``, ``face_labels``, ``workers``, ...).
    bake : {"auto", "checker", "vertex-colors", None}
        ``"auto"``: the vertex colours when the mesh has them, else a checker. ``None``: UVs only, a
        plain white texture.
    return_result : bool
        Also return the :class:`uvbake.atlas.pipeline.UnwrapResult`.

    Returns
    -------
    the input's mesh type (or (mesh, UnwrapResult))
    """
    import open3d as o3d

    from uvbake.atlas.pipeline import unwrap as _unwrap
    from uvbake.errors import InputError

    tensor = isinstance(mesh, o3d.t.geometry.TriangleMesh)
    if not tensor and not isinstance(mesh, o3d.geometry.TriangleMesh):
        raise InputError(f"uvbake_open3d.unwrap takes an open3d.t.geometry.TriangleMesh or "
                         f"open3d.geometry.TriangleMesh, got {type(mesh).__name__}")
    if bake == "auto":
        has_colors = ("colors" in mesh.vertex) if tensor else mesh.has_vertex_colors()
        bake = "vertex-colors" if has_colors else "checker"
    result = _unwrap(mesh, alpha=alpha, texture_size_px=texture_size_px, gutter_px=gutter_px, bake=bake,
                     **options)
    out = to_open3d(result, like=mesh)
    return (out, result) if return_result else out


def _texture(result):
    if result.image is not None:
        return np.ascontiguousarray(result.image, dtype=np.uint8)
    size = result.report["atlas"]["texture_size_px"]
    return np.full((size, size, 3), 255, np.uint8)


def to_open3d(result, *, like=None, tensor=None):
    """An Open3D mesh from an ``UnwrapResult``: tensor when ``like`` is a tensor mesh (or ``tensor=True``)."""
    import open3d as o3d

    if tensor is None:
        tensor = like is None or isinstance(like, o3d.t.geometry.TriangleMesh)
    image = _texture(result)
    colors = result.vertex_colors
    if tensor:
        device = like.device if like is not None else o3d.core.Device("CPU:0")
        pos_dtype, idx_dtype = o3d.core.float32, o3d.core.int64
        if like is not None and "positions" in like.vertex:
            pos_dtype = like.vertex.positions.dtype
        if like is not None and "indices" in like.triangle:
            idx_dtype = like.triangle.indices.dtype
        out = o3d.t.geometry.TriangleMesh(device)
        out.vertex.positions = o3d.core.Tensor(np.asarray(result.V), pos_dtype, device)
        out.triangle.indices = o3d.core.Tensor(np.asarray(result.F), idx_dtype, device)
        if colors is not None:
            out.vertex.colors = o3d.core.Tensor(_unit_colors(colors), o3d.core.float32, device)
        out.triangle.texture_uvs = o3d.core.Tensor(np.asarray(result.corner_uv, np.float32), o3d.core.float32,
                                                   device)
        out.compute_vertex_normals()
        out.material.set_default_properties()
        out.material.material_name = "defaultLit"
        out.material.texture_maps["albedo"] = o3d.t.geometry.Image(o3d.core.Tensor(image))
        return out
    out = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(np.asarray(result.V, np.float64)),
                                    o3d.utility.Vector3iVector(np.asarray(result.F, np.int32)))
    if colors is not None:
        out.vertex_colors = o3d.utility.Vector3dVector(_unit_colors(colors).astype(np.float64))
    out.triangle_uvs = o3d.utility.Vector2dVector(np.asarray(result.corner_uv, np.float64).reshape(-1, 2))
    out.triangle_material_ids = o3d.utility.IntVector(np.zeros(len(result.F), np.int32))
    out.textures = [o3d.geometry.Image(image)]
    out.compute_vertex_normals()
    return out


def _unit_colors(colors):
    c = np.asarray(colors)
    c = c[:, :3]
    if c.dtype.kind in "ui" or c.max(initial=0) > 1.0:
        c = c.astype(np.float64) / 255.0
    return np.ascontiguousarray(c, dtype=np.float32)
