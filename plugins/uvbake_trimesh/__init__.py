"""uvbake for trimesh: ``unwrap(mesh)`` returns a ``trimesh.Trimesh`` with ``TextureVisuals``.

An alternative to ``Trimesh.unwrap()`` (xatlas)::

    import trimesh, uvbake_trimesh
    mesh = trimesh.load("sample_scenes/disk_holes.ply", process=False)
    textured = uvbake_trimesh.unwrap(mesh, alpha=0.5, texture_size_px=512)
    textured.visual.uv            # (k,2) per-vertex UVs, v up; vertices are split along seams
    textured.visual.material.image
    uvbake_trimesh.export(textured, "disk_holes.glb")   # or .obj: seams kept (see below)

Seams. trimesh keeps one UV per vertex, so every vertex on a seam becomes one vertex per chart it
belongs to (same position, different UVs). trimesh can undo that: ``Trimesh(process=True)`` and
``merge_vertices()`` with ``merge_tex=True`` weld vertices by position alone, and its OBJ loader welds
by position when ``merge_tex`` is set. The returned mesh is built with ``process=False`` and
:func:`export` writes it without any merging; :func:`load` reads a file back the same way
(``process=False``, ``maintain_order=True``), so the per-corner UVs survive the round trip
(``tests/test_plugin_trimesh.py`` checks OBJ and GLB through trimesh's own writer and reader).
"""

from __future__ import annotations

import numpy as np

__all__ = ["unwrap", "export", "load", "corner_uv", "texture_image"]


def unwrap(mesh, image=None, *, alpha=0.5, texture_size_px=1024, gutter_px=4, bake="auto",
           return_result=False, **options):
    """Unwrap a ``trimesh.Trimesh`` into a validated atlas and return a textured copy.

    Parameters
    ----------
    mesh : trimesh.Trimesh
        Not modified. Per-face segment labels may be given as ``face_labels=``.
    image : PIL.Image, optional
        As in ``Trimesh.unwrap(image=None)``: the image to assign to the material; nothing is baked.
    alpha, texture_size_px, gutter_px, **options
        As in :func:`uvbake.atlas.pipeline.unwrap` (``init``, ``backend``, ``face_labels``, ``workers``, ...).
    bake : {"auto", "checker", "vertex-colors", None}
        ``"auto"``: the vertex colours when the mesh has them, else a checker. ``None``: a plain white
        texture (UVs only).
    return_result : bool
        Also return the :class:`uvbake.atlas.pipeline.UnwrapResult` (report, charts, solver records).

    Returns
    -------
    trimesh.Trimesh (or (Trimesh, UnwrapResult))
        Vertices split along seams (``k >= n``), ``visual = TextureVisuals(uv=(k,2), image=PIL image)``,
        ``metadata["uvbake"]`` with the report's summary.
    """
    import trimesh

    from uvbake.atlas.pipeline import unwrap as _unwrap
    from uvbake.errors import InputError

    if not isinstance(mesh, trimesh.Trimesh):
        raise InputError(f"uvbake_trimesh.unwrap takes a trimesh.Trimesh, got {type(mesh).__name__}; "
                         "for a Scene use scene.dump(concatenate=True)")
    if image is not None:
        if not hasattr(image, "convert"):
            raise InputError(f"image must be a PIL image, as for Trimesh.unwrap, got {type(image).__name__}")
        bake = None
    elif bake == "auto":
        bake = "vertex-colors" if _has_vertex_colors(mesh) else "checker"
    result = _unwrap(mesh, alpha=alpha, texture_size_px=texture_size_px, gutter_px=gutter_px, bake=bake,
                     **options)
    out = to_trimesh(result, image=image)
    return (out, result) if return_result else out


def _has_vertex_colors(mesh):
    vis = mesh.visual
    return getattr(vis, "kind", None) == "vertex"


def to_trimesh(result, *, image=None):
    """A textured ``trimesh.Trimesh`` (vertices split per (vertex, UV)) from an ``UnwrapResult``
    (its baked texture, or ``image`` when given)."""
    import trimesh
    from PIL import Image

    from uvbake.io.corners import split_corners

    source, uv, F_new = split_corners(result.F, result.corner_uv)
    if image is None:
        texture = result.image
        if texture is None:
            size = result.report["atlas"]["texture_size_px"]
            texture = np.full((size, size, 3), 255, np.uint8)
        image = Image.fromarray(texture)
    material = trimesh.visual.material.SimpleMaterial(image=image, diffuse=[255, 255, 255, 255])
    visual = trimesh.visual.TextureVisuals(uv=uv, material=material)
    out = trimesh.Trimesh(vertices=result.V[source], faces=F_new, visual=visual, process=False,
                          validate=False)
    out.metadata["uvbake"] = dict(valid=result.report.get("valid"), charts=result.report.get("charts_final"),
                                  alpha=result.report.get("options", {}).get("alpha"),
                                  texture_size_px=result.report.get("atlas", {}).get("texture_size_px"))
    return out


def corner_uv(mesh) -> np.ndarray:
    """(m,3,2) per-corner UVs of a textured trimesh (v up)."""
    return np.asarray(mesh.visual.uv, dtype=np.float64)[np.asarray(mesh.faces)]


def texture_image(mesh):
    """The texture of a textured trimesh as a PIL image (``SimpleMaterial.image`` or, after a GLB
    round trip, ``PBRMaterial.baseColorTexture``), or None."""
    mat = getattr(mesh.visual, "material", None)
    img = getattr(mat, "image", None)
    if img is None:
        img = getattr(mat, "baseColorTexture", None)
    return img


#: Formats that keep per-corner UVs and a texture (what :func:`export` writes).
EXPORT_EXTENSIONS = (".obj", ".glb", ".gltf")


def export(mesh, path, *, verify=True, **kwargs):
    """Write a textured mesh with trimesh's own exporter, keeping seams (no vertex merging).

    OBJ (with its MTL and PNG beside it), GLB/GLTF, or anything ``Trimesh.export`` writes.
    ``kwargs`` go to ``Trimesh.export``. With ``verify`` (default) the file is read back with
    :func:`load` and a ``uvbake.errors.UvbakeError`` is raised if any per-corner UV did not survive.
    """
    from pathlib import Path

    from uvbake.errors import InputError, OutputError

    path = Path(path)
    if path.suffix.lower() not in EXPORT_EXTENSIONS:
        raise InputError(f"path={str(path)!r}: cannot write a textured mesh as {path.suffix or '(no extension)'!r}; "
                         f"use one of {', '.join(EXPORT_EXTENSIONS)}")
    if not path.parent.is_dir():
        raise InputError(f"path={str(path)!r}: folder {path.parent} does not exist; create it first")
    if path.suffix.lower() == ".obj":
        kwargs.setdefault("include_texture", True)
        kwargs.setdefault("include_normals", False)
        kwargs.setdefault("mtl_name", f"{path.stem}.mtl")        # not trimesh's shared "material.mtl"
        mat = getattr(mesh.visual, "material", None)
        if mat is not None and getattr(mat, "name", None) in (None, "material", "material_0"):
            mesh = mesh.copy()
            mesh.visual.material.name = path.stem                # texture written as <stem>.png
    try:
        out = mesh.export(str(path), **kwargs)
    except OSError as exc:
        from uvbake.io.atomic import write_error

        raise write_error(path, exc, "path=") from None
    except Exception as exc:  # trimesh raises many types; ours names the path
        raise OutputError(f"path={str(path)!r}: trimesh could not write it ({type(exc).__name__}: "
                          f"{' '.join(str(exc).split())[:120]}); write .obj or .glb") from None
    if verify:
        from uvbake.errors import UvbakeError

        back = load(path)
        want = corner_uv(mesh)
        got = corner_uv(back) if hasattr(back.visual, "uv") and back.visual.uv is not None else None
        if got is None or got.shape != want.shape or np.abs(got - want).max() > 1e-5:
            raise UvbakeError(f"{path}: trimesh did not keep the per-corner UVs (seams welded or UVs "
                              "dropped); write .obj or .glb, and do not merge_vertices(merge_tex=True)")
    return out


def load(path):
    """Read a textured mesh back with trimesh without welding seams (``process=False``)."""
    import trimesh

    kwargs = dict(process=False, force="mesh")
    if str(path).lower().endswith(".obj"):
        kwargs["maintain_order"] = True
    return trimesh.load(str(path), **kwargs)
