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
  V, F and the exact UVs.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from uvbake.errors import InputError

#: Face property names read as per-face segment labels, first found wins.
LABEL_NAMES = ("segment", "label", "segment_id", "chart", "chart_id", "region")

#: File extensions load_mesh accepts (OBJ is parsed here, the rest by trimesh).
MESH_EXTENSIONS = (".ply", ".obj", ".off", ".glb", ".gltf", ".stl")


@dataclass
class MeshData:
    """A triangle mesh as uvbake's stages expect it.

    Attributes
    ----------
    V : (n,3) float64 array
        Vertex positions (NaN kept as read).
    F : (m,3) int64 array
        Triangles, indices into V, all in ``[0, n)``.
    vertex_colors : (n,3) float64 array in [0,1], or None
        RGB per vertex (alpha dropped).
    face_labels : (m,) int64 array, or None
        Segment label per face.
    source : str
        The path read, or a short description ("arrays", "trimesh.Trimesh", ...).
    """

    V: np.ndarray
    F: np.ndarray
    vertex_colors: np.ndarray | None
    face_labels: np.ndarray | None
    source: str

    @property
    def n_vertices(self) -> int:
        return len(self.V)

    @property
    def n_faces(self) -> int:
        return len(self.F)


# --------------------------------------------------------------------------------------------------
# loading


def load_mesh(source, *, face_labels=None) -> MeshData:
    """Read a triangle mesh from a file, arrays, a trimesh or an Open3D mesh.

    Parameters
    ----------
    source : str or Path or (V, F) tuple or trimesh.Trimesh or open3d TriangleMesh
        A path to a PLY, OBJ, OFF, GLB/GLTF or STL file; a tuple of ``V (n,3)`` and ``F (m,3)``;
        a ``trimesh.Trimesh`` (or ``trimesh.Scene``); a legacy ``open3d.geometry.TriangleMesh`` or
        a tensor ``open3d.t.geometry.TriangleMesh``.
    face_labels : (m,) integer array_like, optional
        Segment label per (triangulated) face; overrides labels stored in the source.

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
    if ext == ".obj":
        return load_obj_uv(path)[0]

    import trimesh

    kwargs = {"fix_texture": False} if ext == ".ply" else {}
    try:
        loaded = trimesh.load(name, process=False, **kwargs)
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


def _from_arrays(source: tuple) -> MeshData:
    if len(source) != 2:
        raise InputError(f"a tuple source must be (V, F), got {len(source)} items; pass (V, F)")
    return _make(source[0], source[1], None, None, "arrays")


def _from_trimesh(mesh, name: str) -> MeshData:
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


def _from_trimesh_scene(scene, name: str) -> MeshData:
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


def _from_open3d_legacy(mesh) -> MeshData:
    colors = None
    if mesh.has_vertex_colors():
        colors = np.asarray(mesh.vertex_colors)
    return _make(np.asarray(mesh.vertices), np.asarray(mesh.triangles), colors, None,
                 "open3d.geometry.TriangleMesh")


def _from_open3d_tensor(mesh) -> MeshData:
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


def _make(V, F, colors, labels, name: str) -> MeshData:
    """Check shapes and index ranges, convert dtypes, and build a MeshData."""
    V = np.asarray(V)
    F = np.asarray(F)
    if V.ndim != 2 or V.shape[1] != 3 or not np.issubdtype(V.dtype, np.number):
        raise InputError(f"{name}: vertices must be an (n,3) number array, got shape {V.shape}; "
                         "pass V as an (n,3) float array")
    if F.size == 0:
        raise InputError(f"{name}: holds no faces ({len(V)} vertices); "
                         "give a triangle mesh (reconstruct a surface first)")
    if F.ndim != 2 or F.shape[1] != 3:
        raise InputError(f"{name}: faces must be an (m,3) array of triangles, got shape {F.shape}; "
                         "triangulate the mesh")
    F = _as_int(F, name, "face indices")
    lo, hi = int(F.min()), int(F.max())
    if lo < 0 or hi >= len(V):
        bad = lo if lo < 0 else hi
        raise InputError(f"{name}: face index {bad} out of range for {len(V)} vertices; "
                         "export the mesh again (indices must be 0..n-1)")
    if colors is not None:
        colors = np.asarray(colors, dtype=np.float64)
        if colors.ndim != 2 or len(colors) != len(V) or colors.shape[1] < 3:
            colors = None  # unusable colours are dropped, never a reason to refuse the mesh
        else:
            colors = colors[:, :3]
            if colors.max(initial=0.0) > 1.0:  # 0..255 stored as numbers
                colors = colors / 255.0
            colors = np.clip(colors, 0.0, 1.0)
    if labels is not None:
        labels = _check_labels(labels, len(F), name, "face labels")
    return MeshData(V=V.astype(np.float64, copy=True), F=F, vertex_colors=colors,
                    face_labels=labels, source=name)


def _as_int(a: np.ndarray, name: str, what: str) -> np.ndarray:
    if np.issubdtype(a.dtype, np.integer) or a.dtype == bool:
        return a.astype(np.int64)
    if np.issubdtype(a.dtype, np.floating):
        if np.all(np.isfinite(a)) and np.all(a == np.round(a)):
            return a.astype(np.int64)
    raise InputError(f"{name}: {what} must be integers (got {a.dtype} with non-integer values); "
                     "pass integer values")


def _check_labels(labels, m: int, name: str, what: str) -> np.ndarray:
    labels = np.asarray(labels)
    if labels.ndim == 2 and labels.shape[1] == 1:
        labels = labels[:, 0]
    if labels.ndim != 1 or len(labels) != m:
        raise InputError(f"{name}: {what} has shape {labels.shape} but the mesh has {m} faces; "
                         "give one integer label per face")
    return _as_int(labels, name, what)


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


_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
    "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}


def read_ply_elements(path) -> dict:
    """Parse a PLY file (ASCII or binary, any list lengths) into ``{element: {property: values}}``.

    Scalar properties become arrays; list properties become an (count,k) array when every row has
    the same length, else a list of arrays. This is uvbake's own reader, used when trimesh cannot
    read a file (binary PLY with mixed polygon sizes) or drops a face property.
    """
    with open(path, "rb") as f:
        lines = []
        while True:
            line = f.readline()
            if not line:
                raise ValueError("no end_header line")
            line = line.decode("ascii", "replace").strip()
            lines.append(line)
            if line == "end_header":
                break
        body = f.read()
    if not lines or lines[0] != "ply":
        raise ValueError("does not start with 'ply'")
    fmt, elements = None, []
    for line in lines[1:]:
        parts = line.split()
        if parts[:1] == ["format"]:
            fmt = parts[1]
        elif parts[:1] == ["element"]:
            elements.append((parts[1], int(parts[2]), []))
        elif parts[:1] == ["property"]:
            if parts[1] == "list":
                elements[-1][2].append((parts[4], _PLY_TYPES[parts[2]], _PLY_TYPES[parts[3]]))
            else:
                elements[-1][2].append((parts[2], _PLY_TYPES[parts[1]], None))
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise ValueError(f"unknown format {fmt!r}")
    if fmt == "ascii":
        return _ply_ascii(body, elements)
    return _ply_binary(body, elements, "<" if fmt == "binary_little_endian" else ">")


def _ply_ascii(body: bytes, elements) -> dict:
    tokens = body.split()
    pos, out = 0, {}
    for name, count, props in elements:
        columns = {p[0]: [] for p in props}
        for _ in range(count):
            for prop, dtype, item in props:
                if item is None:
                    columns[prop].append(tokens[pos])
                    pos += 1
                else:
                    k = int(tokens[pos])
                    columns[prop].append(np.array(tokens[pos + 1: pos + 1 + k], dtype=float).astype(item))
                    pos += 1 + k
        out[name] = {p[0]: _ply_column(columns[p[0]], p) for p in props}
    return out


def _ply_binary(body: bytes, elements, endian: str) -> dict:
    pos, out = 0, {}
    for name, count, props in elements:
        fixed = []  # try one record layout, using the first row's list lengths
        probe = pos
        for prop, dtype, item in props:
            if item is None:
                fixed.append((prop, endian + dtype))
                probe += np.dtype(dtype).itemsize
            else:
                k = int(np.frombuffer(body, endian + dtype, 1, probe)[0]) if count else 0
                fixed += [(f"{prop}__n", endian + dtype), (prop, endian + item, (k,))]
                probe += np.dtype(dtype).itemsize + k * np.dtype(item).itemsize
        layout = np.dtype(fixed)
        if pos + count * layout.itemsize <= len(body):
            data = np.frombuffer(body, layout, count, pos)
            lists = [p[0] for p in props if p[2] is not None]
            if all(np.all(data[f"{p}__n"] == data.dtype[p].shape[0]) for p in lists):
                out[name] = {p[0]: np.array(data[p[0]]) for p in props}
                pos += count * layout.itemsize
                continue
        columns = {p[0]: [] for p in props}  # rows of different lengths: walk them
        for _ in range(count):
            for prop, dtype, item in props:
                size = np.dtype(dtype).itemsize
                value = np.frombuffer(body, endian + dtype, 1, pos)[0]
                pos += size
                if item is None:
                    columns[prop].append(value)
                else:
                    k = int(value)
                    columns[prop].append(np.frombuffer(body, endian + item, k, pos).copy())
                    pos += k * np.dtype(item).itemsize
        out[name] = {p[0]: _ply_column(columns[p[0]], p) for p in props}
    return out


def _ply_column(values, prop):
    name, dtype, item = prop
    if item is None:
        return np.array(values).astype(dtype)
    if values and all(len(v) == len(values[0]) for v in values):
        return np.array(values, dtype=item).reshape(len(values), -1)
    return values


def _ply_face_property_names(path) -> list:
    names, in_face = [], False
    with open(path, "rb") as f:
        for raw_line in f:
            parts = raw_line.decode("ascii", "replace").split()
            if parts[:1] == ["end_header"]:
                break
            if parts[:1] == ["element"]:
                in_face = parts[1:2] == ["face"]
            elif parts[:1] == ["property"] and in_face:
                names.append(parts[-1])
    return names


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
            rgb = np.column_stack([vertex[k] for k in names])
            colors = rgb / 255.0 if rgb.dtype == np.uint8 else rgb.astype(np.float64)
            break
    return _make(V, F, colors, labels, name)


def _fan_triangulate(raw_faces):
    """Triangles of polygons in file order, and how many triangles each polygon gave."""
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


def load_obj_uv(path):
    """Read an OBJ file exactly as written: mesh, texture coordinates and their faces.

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    mesh : MeshData
        ``v`` lines in file order (``v x y z r g b`` gives colours), ``f`` lines fan-triangulated.
    uv : (k,2) float64 array or None
        The ``vt`` lines.
    uv_faces : (m,3) int64 array or None
        Indices into ``uv`` per triangle corner, when every face has them.
    """
    name = str(path)
    path = Path(path)
    if not path.exists():
        raise InputError(f"{name}: file not found; check the path")
    if path.is_dir():
        raise InputError(f"{name}: is a directory, not a mesh file; pass the path of a mesh file inside it")
    if path.stat().st_size == 0:
        raise InputError(f"{name}: file is empty (0 bytes); export the mesh again")
    verts, colors, uvs, tris, tri_uv = [], [], [], [], []
    all_uv = True
    try:
        with open(path, encoding="utf-8", errors="strict") as f:
            for line_no, line in enumerate(f, 1):
                parts = line.split()
                if not parts or parts[0].startswith("#"):
                    continue
                tag = parts[0]
                if tag == "v":
                    verts.append([float(t) for t in parts[1:4]])
                    if len(verts[-1]) != 3:
                        raise ValueError(f"line {line_no}: a 'v' line needs 3 coordinates")
                    colors.append([float(t) for t in parts[4:7]] if len(parts) >= 7 else None)
                elif tag == "vt":
                    uvs.append([float(t) for t in parts[1:3]])
                elif tag == "f":
                    corners = [c.split("/") for c in parts[1:]]
                    if len(corners) < 3:
                        raise ValueError(f"line {line_no}: a face needs at least 3 corners")
                    vi = [_obj_index(c[0], len(verts)) for c in corners]
                    ti = [_obj_index(c[1], len(uvs)) if len(c) > 1 and c[1] else None
                          for c in corners]
                    for j in range(1, len(vi) - 1):
                        tris.append([vi[0], vi[j], vi[j + 1]])
                        tri_uv.append([ti[0], ti[j], ti[j + 1]])
                    all_uv = all_uv and None not in ti
    except (ValueError, UnicodeDecodeError) as exc:
        reason = " ".join(str(exc).split())[:120]
        raise InputError(f"{name}: cannot read as OBJ ({reason}); "
                         "check that it is a valid OBJ file or export it again") from None
    if not verts:
        raise InputError(f"{name}: cannot read as OBJ (no 'v' lines); "
                         "check that it is a valid OBJ file or export it again")
    vertex_colors = None
    if all(c is not None for c in colors):
        vertex_colors = np.asarray(colors, dtype=np.float64)
    F = np.asarray(tris, dtype=np.int64).reshape(-1, 3)
    mesh = _make(np.asarray(verts, dtype=np.float64), F, vertex_colors, None, name)
    uv = np.asarray(uvs, dtype=np.float64).reshape(-1, 2) if uvs else None
    uv_faces = None
    if uv is not None and tri_uv and all_uv:
        uv_faces = np.asarray(tri_uv, dtype=np.int64)
        if uv_faces.min() < 0 or uv_faces.max() >= len(uv):
            raise InputError(f"{name}: texture index out of range for {len(uv)} 'vt' lines; "
                             "export the mesh again")
    return mesh, uv, uv_faces


def _obj_index(token: str, count: int) -> int:
    """0-based index from an OBJ index (1-based, or negative = relative to the end so far)."""
    i = int(token)
    if i == 0:
        raise ValueError("index 0 (OBJ indices start at 1)")
    return i - 1 if i > 0 else count + i


def save_obj(path, V, F, *, uv=None, uv_faces=None, vertex_colors=None, mtllib=None,
             material=None) -> None:
    """Write a triangle mesh as OBJ, atomically and with full float precision.

    Parameters
    ----------
    path : str or Path
    V : (n,3) float array
    F : (m,3) int array, 0-based
    uv : (k,2) float array, or (m,3,2) per-corner UVs, optional
        Written as ``vt`` lines. Per-corner UVs (the atlas layout) need no ``uv_faces``.
    uv_faces : (m,3) int array, optional
        Indices into ``uv`` per corner. Defaults to ``F`` when ``k == n`` (per-vertex UVs).
    vertex_colors : (n,3) float array in [0,1], optional
        Written as ``v x y z r g b``.
    mtllib, material : str, optional
        Written as ``mtllib <mtllib>`` and ``usemtl <material>`` lines.

    Numbers are written with ``%.17g``, so reading the file back gives bit-identical V and UVs.
    """
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F)
    name = str(path)
    if V.ndim != 2 or V.shape[1] != 3:
        raise InputError(f"{name}: V must be (n,3), got shape {V.shape}; pass vertex positions")
    if F.ndim != 2 or F.shape[1] != 3 or (F.size and (F.min() < 0 or F.max() >= len(V))):
        raise InputError(f"{name}: F must be (m,3) with indices in 0..{len(V) - 1}; "
                         "pass triangles indexing V")
    F = _as_int(F, name, "F")
    if uv is not None:
        uv = np.asarray(uv, dtype=np.float64)
        if uv.ndim == 3 and uv.shape == (len(F), 3, 2) and uv_faces is None:
            uv = uv.reshape(-1, 2)
            uv_faces = np.arange(len(uv)).reshape(-1, 3)
        elif uv_faces is None and uv.shape == (len(V), 2):
            uv_faces = F
        if uv.ndim != 2 or uv.shape[1] != 2 or uv_faces is None:
            raise InputError(f"{name}: uv must be (k,2) with uv_faces (m,3), (n,2) per vertex or "
                             f"(m,3,2) per corner, got shape {uv.shape}; pass matching uv_faces")
        uv_faces = _as_int(np.asarray(uv_faces), name, "uv_faces")
        if uv_faces.shape != F.shape or uv_faces.min() < 0 or uv_faces.max() >= len(uv):
            raise InputError(f"{name}: uv_faces must be (m,3)={F.shape} with indices in "
                             f"0..{len(uv) - 1}; pass one uv index per face corner")
    elif uv_faces is not None:
        raise InputError(f"{name}: uv_faces given without uv; pass uv too")
    if vertex_colors is not None:
        vertex_colors = np.asarray(vertex_colors, dtype=np.float64)
        if vertex_colors.shape != V.shape:
            raise InputError(f"{name}: vertex_colors must be (n,3)={V.shape}, got "
                             f"{vertex_colors.shape}; pass one RGB colour per vertex")

    with atomic_write(path, "w") as f:
        f.write("# written by uvbake\n")
        if mtllib:
            f.write(f"mtllib {mtllib}\n")
        rows = V if vertex_colors is None else np.hstack([V, vertex_colors])
        _write_rows(f, "v", rows, "%.17g")
        if uv is not None:
            _write_rows(f, "vt", uv, "%.17g")
        if material:
            f.write(f"usemtl {material}\n")
        if uv is None:
            _write_rows(f, "f", F + 1, "%d")
        else:
            corners = np.stack([F + 1, uv_faces + 1], axis=-1).reshape(len(F), 6)
            _write_rows(f, "f", corners, "%d/%d")


def _write_rows(f, tag: str, rows: np.ndarray, fmt: str) -> None:
    if len(rows) == 0:
        return
    per_row = rows.shape[1] // fmt.count("%")
    line = tag + (" " + fmt) * per_row + "\n"
    flat = rows.reshape(len(rows), -1)
    f.write("".join(line % tuple(r) for r in flat.tolist()))


# --------------------------------------------------------------------------------------------------
# atomic writes


@contextlib.contextmanager
def atomic_write(path, mode: str = "w"):
    """Open a temporary file beside ``path``; on success it replaces ``path``, on error it is removed.

    Parameters
    ----------
    path : str or Path
        The file to write; its folder must exist.
    mode : {"w", "wb"}
        Text (UTF-8, ``\\n`` newlines) or binary.

    Yields
    ------
    file object
        Write to it inside the ``with`` block. If the block raises, ``path`` is left as it was.
    """
    if mode not in ("w", "wb"):
        raise InputError(f"atomic_write mode must be 'w' or 'wb', got {mode!r}; pass 'w' or 'wb'")
    path = Path(path)
    folder = path.parent
    if not folder.is_dir():
        raise InputError(f"{path}: folder {folder} does not exist; create it first")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=folder)
    try:
        kwargs = {"encoding": "utf-8", "newline": "\n"} if mode == "w" else {}
        with os.fdopen(fd, mode, **kwargs) as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, _default_mode(path))
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def _default_mode(path: Path) -> int:
    """Permissions the file would get from a plain open(): the old file's, else 0o666 minus umask."""
    try:
        return path.stat().st_mode & 0o777
    except OSError:
        umask = os.umask(0)
        os.umask(umask)
        return 0o666 & ~umask
