"""uvbake for Open3D: ``unwrap(mesh)`` where a workflow would call ``TriangleMesh.compute_uvatlas``.

    import open3d as o3d, uvbake_open3d
    mesh = o3d.t.io.read_triangle_mesh("sample_scenes/scene.ply")       # Open3D drops the PLY's labels
    mesh = uvbake_open3d.unwrap(mesh, size=512, gutter=2, face_labels="sample_scenes/scene.ply")
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


def unwrap(mesh, *, size=None, gutter=None, max_stretch=None, parallel_partitions=None, nthreads=None,
           face_labels=None, distortion_budget=None, alpha=0.5, texture_size_px=1024, gutter_px=4, bake="auto", return_result=False,
           **options):
    """Unwrap an Open3D triangle mesh (tensor or legacy) and return the same kind, textured.

    Takes ``TriangleMesh.compute_uvatlas``'s keywords with the same meaning where uvbake has the
    concept, so ``mesh.compute_uvatlas(size=512, gutter=2)`` becomes
    ``mesh = uvbake_open3d.unwrap(mesh, size=512, gutter=2)``.

    Parameters
    ----------
    mesh : open3d.t.geometry.TriangleMesh or open3d.geometry.TriangleMesh
    size : int, optional
        compute_uvatlas's texture side in pixels: the same as ``texture_size_px``.
    gutter : float, optional
        compute_uvatlas's space around the charts in pixels: ``gutter_px``, rounded up to whole texels.
    max_stretch : float in [0, 1], optional
        compute_uvatlas's stretch bound (0: none allowed, 1: any), UVAtlas's normalised stretch. uvbake's
        budget measures something else (an area factor), so the value is checked, recorded in the
        report's ``options`` and not used; a ``UserWarning`` says so and names ``distortion_budget``.
    distortion_budget : float > 1, optional
        uvbake's own distortion budget (``max_stretch`` of :func:`uvbake.atlas.pipeline.unwrap`: every
        triangle's area factor at least 1/budget of its chart's; default 4).
    parallel_partitions, nthreads : int, optional
        compute_uvatlas's threading: ``nthreads`` is ``workers`` (charts solved in parallel; 0 = all
        cores); ``parallel_partitions`` is accepted and has no effect (uvbake solves whole charts).
    face_labels : (m,) int array, or the path of the mesh file, optional
        Per-face segment labels. Open3D's readers drop PLY face properties, so a labelled PLY read with
        ``o3d.t.io.read_triangle_mesh`` arrives without its labels: pass the file's path here and uvbake
        reads them (the file's triangles must be the mesh's). A path whose file has no labels warns.
        Labels attached to a tensor mesh as ``mesh.triangle.segment`` (or ``label``, ...) are used too.
    alpha, texture_size_px, gutter_px, **options
        As in :func:`uvbake.atlas.pipeline.unwrap` (``init``, ``backend``, ``workers``, ...).
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
    from uvbake.errors import InputError, in_words

    tensor = isinstance(mesh, o3d.t.geometry.TriangleMesh)
    if not tensor and not isinstance(mesh, o3d.geometry.TriangleMesh):
        raise InputError(f"uvbake_open3d.unwrap takes an open3d.t.geometry.TriangleMesh or "
                         f"open3d.geometry.TriangleMesh, got {type(mesh).__name__}")
    texture_size_px = _same("size", size, "texture_size_px", texture_size_px, _whole_px(size, "size"))
    gutter_px = _same("gutter", gutter, "gutter_px", gutter_px, _gutter_px(gutter))
    if nthreads is not None:
        if isinstance(nthreads, bool) or not isinstance(nthreads, (int, np.integer)) or nthreads < 0:
            raise InputError(f"nthreads={nthreads!r} must be a whole number >= 0 (0: all cores)")
        options.setdefault("workers", int(nthreads) or None)
    if max_stretch is not None:
        _stretch_unused(max_stretch)
    if distortion_budget is not None:
        options["max_stretch"] = distortion_budget
    if face_labels is not None and not isinstance(face_labels, np.ndarray) and _is_path(face_labels):
        face_labels = _labels_from_file(face_labels, mesh, tensor)
    if bake == "auto":
        has_colors = ("colors" in mesh.vertex) if tensor else mesh.has_vertex_colors()
        bake = "vertex-colors" if has_colors else "checker"
    # uvbake's errors name its own parameters; say what this caller typed (their max_stretch is UVAtlas's)
    typed = {k: v for k, v, given in (("texture_size_px", "size", size), ("gutter_px", "gutter", gutter),
                                      ("max_stretch", "distortion_budget", distortion_budget),
                                      ("workers", "nthreads", nthreads)) if given is not None}
    try:
        result = _unwrap(mesh, alpha=alpha, texture_size_px=texture_size_px, gutter_px=gutter_px, bake=bake,
                         face_labels=face_labels, **options)
    except InputError as exc:
        raise type(exc)(in_words(str(exc), typed)) from None
    if max_stretch is not None:
        result.report["options"]["max_stretch_open3d"] = float(max_stretch)
    out = to_open3d(result, like=mesh)
    return (out, result) if return_result else out


def _same(open3d_name, open3d_value, name, value, converted):
    """compute_uvatlas's keyword wins over uvbake's default; both given and different is an error."""
    from uvbake.errors import InputError

    if open3d_value is None:
        return value
    defaults = {"texture_size_px": 1024, "gutter_px": 4}
    if value != defaults[name] and value != converted:
        raise InputError(f"{open3d_name}={open3d_value!r} and {name}={value!r} disagree; pass one of them")
    return converted


def _whole_px(size, name):
    from uvbake.errors import InputError

    if size is None:
        return None
    if isinstance(size, bool) or not isinstance(size, (int, np.integer)):
        raise InputError(f"{name}={size!r} must be a whole number of pixels (compute_uvatlas's texture side)")
    return int(size)


def _gutter_px(gutter):
    from uvbake.errors import InputError

    if gutter is None:
        return None
    if isinstance(gutter, bool) or not isinstance(gutter, (int, float, np.integer, np.floating)) \
            or not np.isfinite(gutter) or gutter < 0:
        raise InputError(f"gutter={gutter!r} must be a number of pixels >= 0")
    return int(np.ceil(gutter))                  # at least the space asked for


def _stretch_unused(max_stretch):
    import warnings

    from uvbake.errors import InputError

    if isinstance(max_stretch, bool) or not isinstance(max_stretch, (int, float, np.integer, np.floating)) \
            or not 0.0 <= max_stretch <= 1.0:
        raise InputError(f"max_stretch={max_stretch!r} must be in [0, 1] as for compute_uvatlas")
    warnings.warn(f"uvbake_open3d.unwrap: max_stretch={max_stretch} has no effect: it is UVAtlas's normalised "
                  "stretch, which uvbake does not measure; uvbake's own budget is distortion_budget= (an area "
                  "factor > 1, default 4), and face_labels= chooses the charts", UserWarning, stacklevel=3)


def _is_path(x):
    import os

    return isinstance(x, (str, os.PathLike))


def _labels_from_file(path, mesh, tensor):
    """The per-face labels of the file ``mesh`` was read from (Open3D's readers drop them)."""
    import warnings

    from uvbake.errors import InputError
    from uvbake.io.load import load_mesh

    source = load_mesh(path)
    F = mesh.triangle.indices.numpy() if tensor else np.asarray(mesh.triangles)
    if source.F.shape != F.shape or not np.array_equal(source.F, F):
        raise InputError(f"face_labels={str(path)!r}: its triangles are not the mesh's ({len(source.F)} in the "
                         f"file, {len(F)} in the mesh); pass the file the mesh was read from, unchanged")
    if source.face_labels is None:
        warnings.warn(f"uvbake_open3d.unwrap: face_labels={str(path)!r} has no per-face labels (a face "
                      "property named segment, label, ...); the charts come from connected components only",
                      UserWarning, stacklevel=3)
    return source.face_labels


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
