"""Mesh input and output: one loader for every kind of source, an exact OBJ writer, atomic writes.

    mesh = load_mesh("scene.ply")                 # or (V, F), a trimesh.Trimesh, an Open3D mesh
    mesh.V, mesh.F, mesh.vertex_colors, mesh.face_labels
    save_obj("out.obj", V, F, uv=uv, uv_faces=uv_faces)

Loading rules (what the rest of uvbake can rely on):

- Vertices are never merged, reordered or dropped (files are read with ``process=False``), except
  STL, which stores no shared vertices: there exactly equal positions are merged, in order of first
  use, so the mesh is connected.
- Polygons are fan-triangulated in order; a polygon's label goes to each of its triangles.
- NaN or infinite coordinates are kept as they are (the mesh checks name them), but face indices
  must lie in ``[0, n)``.
- Per-face labels come from the ``face_labels`` argument, else from the first face property named
  one of :data:`LABEL_NAMES` (PLY files, a Trimesh's ``face_attributes`` or the PLY data it was read
  from, a tensor Open3D mesh's ``triangle`` attributes), else ``None`` (charts then come from
  connected components).
- A file holding a scene of several meshes (GLB/GLTF, multi-object OBJ read by trimesh) is
  concatenated with each mesh's transform applied. Labels stay ``None``: the meshes share no
  vertices, so connected components already keep them apart, and a per-mesh label would make a
  mesh of several pieces one disconnected "chart".
- OBJ files are read by :func:`load_obj_uv` (not trimesh), so the ``v`` order and ``f`` indices
  are kept even where texture seams exist: reading back what :func:`save_obj` wrote gives the same
  V, F and the exact UVs. Their faces are labelled by material (``usemtl``) when they use two or
  more (``materials=False``: not).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from uvbake.errors import InputError
from uvbake.io.formats import MESH_EXTENSIONS
from uvbake.io.meshdata import MeshData, _check_labels, _make
from uvbake.io.obj import load_obj_uv
from uvbake.io.ply import BOM, _ply_face_property_names, _ply_header, check_ply_complete, read_ply_elements

#: Face property names read as per-face segment labels, first found wins.
LABEL_NAMES = ("segment", "label", "segment_id", "chart", "chart_id", "region")


# --------------------------------------------------------------------------------------------------
# loading


def load_mesh(source: Any, *, face_labels: ArrayLike | None = None, materials: bool = True) -> MeshData:
    """Read a triangle mesh from a file, arrays, a trimesh or an Open3D mesh.

    Parameters
    ----------
    source : str or Path or (V, F) tuple or trimesh.Trimesh or open3d TriangleMesh
        A path to a PLY, OBJ, OFF, GLB/GLTF or STL file; a tuple of ``V (n,3)`` and ``F (m,3)``;
        a ``trimesh.Trimesh`` (or ``trimesh.Scene``); a legacy ``open3d.geometry.TriangleMesh`` or
        a tensor ``open3d.t.geometry.TriangleMesh``.
    face_labels : (m,) integer array_like, optional
        Segment label per (triangulated) face; overrides labels stored in the source.
    materials : bool
        Label an OBJ file's faces by their material (``usemtl``) when it uses two or more, so no chart
        spans two materials (False: materials are ignored).

    Returns
    -------
    MeshData

    Raises
    ------
    InputError
        The file is missing, empty, of an unknown or unreadable format, holds no faces, or has
        out-of-range face indices; or ``face_labels`` has the wrong length or is not integer.
    """
    if isinstance(source, (str, os.PathLike)):
        mesh = _load_path(Path(source))
        if not materials and Path(source).suffix.lower() == ".obj":
            mesh.face_labels = None
    elif isinstance(source, tuple):
        mesh = _from_arrays(source)
    elif hasattr(source, "vertex") and hasattr(source, "triangle"):
        mesh = _from_open3d_tensor(source)
    elif hasattr(source, "has_triangles") and hasattr(source, "vertices"):
        mesh = _from_open3d_legacy(source)
    elif hasattr(source, "geometry") and hasattr(source, "dump"):
        mesh = _from_trimesh_scene(source, "trimesh.Scene")
    elif hasattr(source, "faces") and hasattr(source, "vertices"):
        mesh = _from_trimesh(source, "trimesh.Trimesh")
    else:
        raise InputError(
            f"cannot load a mesh from a {type(source).__name__}; pass a file path, a (V, F) tuple, "
            "a trimesh.Trimesh or an Open3D TriangleMesh"
        )
    if face_labels is not None:
        mesh.face_labels = _check_labels(face_labels, len(mesh.F), mesh.source, "face_labels")
    return mesh


def _load_path(path: Path) -> MeshData:
    name = str(path)
    ext = _check_path(path, name)
    if ext == ".obj":
        return load_obj_uv(path)[0]
    # own readers for the common files: importing trimesh costs ~0.6 s of CPU (it pulls networkx)
    simple = _read_own_ply(path) if ext == ".ply" else _read_off_triangles(path) if ext == ".off" else None
    if simple is not None:
        return simple

    if ext == ".ply":
        check_ply_complete(path, name)
    elif ext == ".off":
        _check_off_complete(path, name)
    loaded = _trimesh_load(path, name, ext)
    if isinstance(loaded, MeshData):
        return loaded
    if hasattr(loaded, "geometry") and hasattr(loaded, "dump"):
        mesh = _from_trimesh_scene(loaded, name)
    elif getattr(loaded, "faces", None) is None or not hasattr(loaded, "vertices"):
        n_points = len(getattr(loaded, "vertices", ()))
        raise InputError(
            f"{name}: holds no faces (a point cloud or lines, {n_points} vertices); "
            "give a triangle mesh (reconstruct a surface first)"
        )
    else:
        mesh = _from_trimesh(loaded, name)
    if ext == ".stl":
        mesh = _merge_exact_duplicates(mesh)
    return mesh


def _check_path(path: Path, name: str) -> str:
    """The file exists, is not empty and has a known extension; return the extension (lower case)."""
    if not path.exists():
        raise InputError(f"{name}: file not found; check the path")
    if path.is_dir():
        raise InputError(f"{name}: is a directory, not a mesh file; pass the path of a mesh file inside it")
    ext = path.suffix.lower()
    if ext not in MESH_EXTENSIONS:
        raise InputError(
            f"{name}: unknown mesh format {ext or '(no extension)'!r}; "
            f"use one of {', '.join(MESH_EXTENSIONS)}"
        )
    if path.stat().st_size == 0:
        raise InputError(f"{name}: file is empty (0 bytes); export the mesh again")
    return ext


def _trimesh_load(path: Path, name: str, ext: str) -> Any:
    """What ``trimesh.load`` reads from the file (or, for a PLY it cannot read, our own reader's MeshData)."""
    import trimesh

    from uvbake.cancel import check_cancelled

    check_cancelled()             # trimesh's import swallows KeyboardInterrupt in optional imports
    kwargs: dict[str, Any] = {"fix_texture": False} if ext == ".ply" else {}
    try:
        with open(path, "rb") as fh:
            bom = fh.read(len(BOM)) == BOM
        if bom:   # a UTF-8 byte-order mark (Windows tools) is not part of the format
            import io

            return trimesh.load(io.BytesIO(path.read_bytes()[len(BOM):]), file_type=ext[1:],
                                process=False, **kwargs)
        return trimesh.load(name, process=False, **kwargs)
    except Exception as exc:  # trimesh raises anything from KeyError to struct.error
        if ext == ".ply":  # e.g. binary PLY with polygons of mixed sizes
            try:
                return _mesh_from_ply_elements(read_ply_elements(path), name)
            except InputError:
                raise
            except (ValueError, KeyError, IndexError, TypeError):
                pass
        reason = " ".join(str(exc).split()) or type(exc).__name__
        raise InputError(
            f"{name}: cannot read as {ext[1:].upper()} ({reason[:120]}); "
            f"check that it is a valid {ext[1:].upper()} file or export it again"
        ) from None


def _check_off_complete(path: Path, name: str) -> None:
    """Raise InputError if an OFF file holds fewer vertex and face lines than its counts declare."""
    data = path.read_bytes()
    if data.startswith(BOM):
        data = data[len(BOM):]
    rows = [line.split(b"#", 1)[0].split() for line in data.split(b"\n")]
    rows = [r for r in rows if r]
    if not rows or not rows[0][0].upper().endswith(b"OFF"):
        return                                    # not ours to judge: the reader reports it
    counts, body = (rows[0][1:], rows[1:]) if len(rows[0]) > 1 else (rows[1] if len(rows) > 1 else [], rows[2:])
    try:
        nv, nf = int(counts[0]), int(counts[1])
    except (IndexError, ValueError):
        return
    if len(body) < nv + nf:
        raise InputError(f"{name}: cannot read as OFF: the header declares {nv} vertices and {nf} faces but the file holds only "
                         f"{len(body)} data lines; the file is truncated, export or copy it again")


def _from_arrays(source: tuple) -> MeshData:
    if len(source) != 2:
        raise InputError(f"a tuple source must be (V, F), got {len(source)} items; pass (V, F)")
    return _make(source[0], source[1], None, None, "arrays")


def _from_trimesh(mesh: Any, name: str) -> MeshData:
    labels = None
    attrs = getattr(mesh, "face_attributes", None) or {}
    found = _first_label_name(attrs)
    if found is not None:
        labels = attrs[found]
    raw = (getattr(mesh, "metadata", None) or {}).get("_ply_raw")
    raw_faces = None
    if labels is None and raw is not None:
        labels, raw_faces = _labels_from_ply_raw(raw)
    if labels is None and raw is not None and name.lower().endswith(".ply") and os.path.exists(name):
        # trimesh keeps the raw PLY data; if a label property is in the header, read it ourselves
        if _first_label_name(_ply_face_property_names(name)) is not None:
            return _mesh_from_ply_elements(read_ply_elements(name), name)
    F = np.asarray(mesh.faces)
    if labels is not None and raw_faces is not None and len(labels) != len(F):
        # polygons: trimesh triangulates them grouped by size, we triangulate in file order
        F, counts = _fan_triangulate(raw_faces)
        labels = np.repeat(np.asarray(labels), counts)
    return _make(mesh.vertices, F, _trimesh_colors(mesh), labels, name)


def _from_trimesh_scene(scene: Any, name: str) -> MeshData:
    import trimesh

    meshes = [g for g in scene.dump(concatenate=False) if isinstance(g, trimesh.Trimesh)]
    meshes = [g for g in meshes if len(g.faces)]
    if not meshes:
        raise InputError(f"{name}: the scene holds no triangle mesh; export the geometry as a mesh")
    parts = [_from_trimesh(g, name) for g in meshes]
    offsets = np.cumsum([0] + [len(p.V) for p in parts[:-1]])
    V = np.concatenate([p.V for p in parts])
    F = np.concatenate([p.F + o for p, o in zip(parts, offsets)])
    colors = None
    if all(p.vertex_colors is not None for p in parts):
        colors = np.concatenate([p.vertex_colors for p in parts])
    return MeshData(V=V, F=F, vertex_colors=colors, face_labels=None, source=name)


def _from_open3d_legacy(mesh: Any) -> MeshData:
    colors = None
    if mesh.has_vertex_colors():
        colors = np.asarray(mesh.vertex_colors)
    return _make(np.asarray(mesh.vertices), np.asarray(mesh.triangles), colors, None,
                 "open3d.geometry.TriangleMesh")


def _from_open3d_tensor(mesh: Any) -> MeshData:
    name = "open3d.t.geometry.TriangleMesh"
    if "positions" not in mesh.vertex or "indices" not in mesh.triangle:
        raise InputError(f"{name}: has no vertex positions or triangle indices; give a triangle mesh")
    colors = mesh.vertex["colors"].numpy() if "colors" in mesh.vertex else None
    labels = None
    for key in LABEL_NAMES:
        if key in mesh.triangle:
            labels = mesh.triangle[key].numpy().reshape(-1)
            break
    return _make(mesh.vertex["positions"].numpy(), mesh.triangle["indices"].numpy(), colors,
                 labels, name)


def _trimesh_colors(mesh):
    visual = getattr(mesh, "visual", None)
    if visual is None or getattr(visual, "kind", None) != "vertex":
        return None
    return np.asarray(visual.vertex_colors)[:, :3].astype(np.float64) / 255.0


def _first_label_name(names):
    for key in LABEL_NAMES:
        if key in names:
            return key
    return None


def _labels_from_ply_raw(raw):
    """Labels and raw face lists from trimesh's parsed PLY elements (None when absent)."""
    face = raw.get("face") if hasattr(raw, "get") else None
    if not face or not face.get("length"):
        return None, None
    data = face.get("data")
    if isinstance(data, np.ndarray) and data.dtype.names:
        names = data.dtype.names
        key = _first_label_name(names)
        index_key = next((k for k in ("vertex_indices", "vertex_index") if k in names), None)
        raw_faces = None
        if index_key is not None:
            column = data[index_key]
            raw_faces = column["f1"] if column.dtype.names else column
        return (None if key is None else data[key]), raw_faces
    if isinstance(data, dict):
        key = _first_label_name(data)
        index_key = next((k for k in ("vertex_indices", "vertex_index") if k in data), None)
        return (None if key is None else data[key]), (None if index_key is None else data[index_key])
    return None, None


def _mesh_from_ply_elements(elements: dict, name: str) -> MeshData:
    vertex = elements.get("vertex", {})
    if not all(k in vertex for k in "xyz"):
        raise ValueError("no vertex x, y, z properties")
    V = np.column_stack([vertex[k] for k in "xyz"]).astype(np.float64)
    face = elements.get("face", {})
    index_key = next((k for k in ("vertex_indices", "vertex_index") if k in face), None)
    if index_key is None or len(face[index_key]) == 0:
        raise InputError(f"{name}: holds no faces (a point cloud or lines, {len(V)} vertices); "
                         "give a triangle mesh (reconstruct a surface first)")
    F, counts = _fan_triangulate(face[index_key])
    key = _first_label_name(face)
    labels = None if key is None else np.repeat(face[key], counts)
    colors = None
    for names in (("red", "green", "blue"), ("r", "g", "b"),
                  ("diffuse_red", "diffuse_green", "diffuse_blue")):
        if all(k in vertex for k in names):
            colors = _unit_colors(np.column_stack([vertex[k] for k in names]))
            break
    return _make(V, F, colors, labels, name)


def _unit_colors(rgb: np.ndarray) -> np.ndarray:
    """Colours in [0, 1]: 8-bit integers over 255, 16-bit ones (some scanners) over 65535, wider integers
    over whichever of the two their values fit; floats as they are, or over 255 when some exceed 1."""
    if np.issubdtype(rgb.dtype, np.integer):
        bits16 = rgb.dtype.itemsize == 2 or (rgb.dtype.itemsize > 2 and rgb.max(initial=0) > 255)
        return np.clip(rgb / (65535.0 if bits16 else 255.0), 0.0, 1.0)
    rgb = rgb.astype(np.float64)
    return np.clip(rgb / 255.0 if rgb.max(initial=0.0) > 1.0 else rgb, 0.0, 1.0)


def _read_own_ply(path: Path) -> MeshData | None:
    """A binary PLY of triangles, or an ASCII one whose colours are not 8-bit (trimesh clips 16-bit ones
    to 255), read without trimesh; None for anything else (trimesh reads it)."""
    with open(path, "rb") as f:
        head = f.read(256).split(b"\n")
    if len(head) < 2 or head[0].strip() != b"ply":
        return None
    if not head[1].startswith(b"format binary") and not _wide_ascii_colours(path):
        return None
    try:
        elements = read_ply_elements(path)
    except (ValueError, KeyError, IndexError, TypeError):
        return None
    faces = elements.get("face", {}).get("vertex_indices", elements.get("face", {}).get("vertex_index"))
    if not isinstance(faces, np.ndarray) or faces.ndim != 2 or faces.shape[1] != 3 or "vertex" not in elements:
        return None
    try:
        return _mesh_from_ply_elements(elements, str(path))
    except ValueError as exc:
        if isinstance(exc, InputError):
            raise
        return None


def _wide_ascii_colours(path: Path) -> bool:
    """Whether ``path`` is an ASCII PLY whose vertex colours are stored wider than 8 bits."""
    try:
        fmt, elements, _ = _ply_header(path, body=False)     # the header only: most ASCII files are 8-bit
    except (ValueError, KeyError, IndexError):
        return False
    props = {name: dtype for el, _, plist in elements if el == "vertex" for name, dtype, item in plist if item is None}
    return fmt == "ascii" and any(props.get(c) not in (None, "u1") for c in ("red", "r", "diffuse_red"))


def _read_off_triangles(path: Path) -> MeshData | None:
    """A plain ``OFF`` file of triangles, or a ``COFF`` one (vertex colours: RGB or RGBA, 0-255 integers or
    0-1 floats; trimesh drops them), read without trimesh; None for anything else."""
    try:
        text = path.read_text(encoding="ascii")
    except (UnicodeDecodeError, OSError):
        return None
    if "#" in text:                                   # comments: cut each line's, one line at a time
        text = " ".join(line.split("#", 1)[0] for line in text.splitlines())
    tokens = text.split()
    if len(tokens) < 4 or tokens[0] not in ("OFF", "COFF"):
        return None
    try:
        nv, nf = int(tokens[1]), int(tokens[2])
        body = np.array(tokens[4:], dtype=np.float64)
    except ValueError:
        return None
    # triangles only: trimesh orders the triangles of polygons by corner, not in file order
    per = (len(body) - 4 * nf) / nv - 3 if nv > 0 else 0      # numbers per vertex after x y z
    if nv < 0 or nf <= 0 or per not in ((0,) if tokens[0] == "OFF" else (3, 4)):
        return None
    k = 3 + int(per)
    faces = body[k * nv:].reshape(nf, 4)
    if not np.all(faces[:, 0] == 3) or not np.all(faces[:, 1:] == np.rint(faces[:, 1:])):
        return None
    rows = body[:k * nv].reshape(nv, k)
    colors = None
    if per:
        colors = _unit_colors(rows[:, 3:6])
    return _make(rows[:, :3], faces[:, 1:].astype(np.int64), colors, None, str(path))


def _fan_triangulate(raw_faces):
    """Triangles of polygons in file order, and how many triangles each polygon gave."""
    if isinstance(raw_faces, np.ndarray) and raw_faces.ndim == 2:   # polygons of one size
        n, k = raw_faces.shape
        j = np.arange(1, max(k - 1, 1))
        raw = raw_faces.astype(np.int64)
        tris = np.stack([np.repeat(raw[:, :1], len(j), axis=1), raw[:, j], raw[:, j + 1]], axis=2)
        return tris.reshape(-1, 3), np.full(n, max(k - 2, 0), dtype=np.int64)
    tris, counts = [], []
    for poly in raw_faces:
        poly = [int(i) for i in np.asarray(poly).reshape(-1)]
        k = max(len(poly) - 2, 0)
        tris.extend([poly[0], poly[j], poly[j + 1]] for j in range(1, len(poly) - 1))
        counts.append(k)
    return np.asarray(tris, dtype=np.int64).reshape(-1, 3), np.asarray(counts, dtype=np.int64)


def _merge_exact_duplicates(mesh: MeshData) -> MeshData:
    """Merge vertices with bit-identical positions (STL triangle soups), keeping first-use order."""
    _, first, inverse = np.unique(mesh.V, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)  # unique rows sorted by first occurrence
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    keep = first[order]
    colors = None if mesh.vertex_colors is None else mesh.vertex_colors[keep]
    return MeshData(V=mesh.V[keep], F=rank[inverse.reshape(-1)][mesh.F], vertex_colors=colors,
                    face_labels=mesh.face_labels, source=mesh.source)


# --------------------------------------------------------------------------------------------------
# OBJ


# --------------------------------------------------------------------------------------------------
# atomic writes


