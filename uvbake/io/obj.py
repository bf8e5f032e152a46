"""OBJ reading of texture coordinates and exact OBJ writing."""

from __future__ import annotations

import io
import os
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from uvbake.errors import InputError
from uvbake.io.atomic import atomic_write
from uvbake.io.meshdata import MeshData, _as_int, _make


def load_obj_uv(path: str | os.PathLike[str]) -> tuple[MeshData, np.ndarray | None, np.ndarray | None]:
    """Read an OBJ file exactly as written: mesh, texture coordinates and their faces.

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    mesh : MeshData
        ``v`` lines in file order (``v x y z r g b`` gives colours), ``f`` lines fan-triangulated.
        Faces under two or more materials (``usemtl``) are labelled by material, numbered in order of
        first use (faces before any ``usemtl`` form one more label), as xatlas keeps charts within a
        material; one material or none: no labels.
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
    try:
        # utf-8-sig: a byte-order mark (Windows tools) is not part of the first line
        with open(path, encoding="utf-8-sig", errors="strict") as f:
            verts, colors, uvs, tris, tri_uv, all_uv, materials = _parse_obj(f)
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
    labels = _material_labels(materials, len(F))
    mesh = _make(np.asarray(verts, dtype=np.float64), F, vertex_colors, labels, name)
    uv = np.asarray(uvs, dtype=np.float64).reshape(-1, 2) if uvs else None
    uv_faces = None
    if uv is not None and tri_uv and all_uv:
        uv_faces = np.asarray(tri_uv, dtype=np.int64)
        if uv_faces.min() < 0 or uv_faces.max() >= len(uv):
            raise InputError(f"{name}: texture index out of range for {len(uv)} 'vt' lines; "
                             "export the mesh again")
    return mesh, uv, uv_faces


def _material_labels(materials, m):
    """Per-triangle labels from ``materials`` ([(first triangle, name)] in file order), or None when the
    faces use fewer than two materials."""
    starts = [0] + [t for t, _ in materials]
    names = [None] + [name for _, name in materials]
    counts = np.diff(np.asarray(starts + [m]))
    used = [name for name, c in zip(names, counts) if c > 0]
    if len(set(used)) < 2:
        return None
    number = {name: i for i, name in enumerate(dict.fromkeys(used))}
    return np.repeat(np.asarray([number.get(name, 0) for name in names], dtype=np.int64), counts)


def _parse_obj(lines):
    """The v (with colours), vt and fan-triangulated f lines of an OBJ file, and where each ``usemtl``
    starts (first triangle, material); ValueError names a bad line."""
    verts, colors, uvs, tris, tri_uv, materials = [], [], [], [], [], []
    all_uv = True
    for line_no, line in enumerate(lines, 1):
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
            uv = [float(t) for t in parts[1:3]]
            if not uv:
                raise ValueError(f"line {line_no}: a 'vt' line needs a coordinate")
            uvs.append(uv + [0.0] * (2 - len(uv)))      # 'vt u' means v = 0 (OBJ spec)
        elif tag == "f":
            all_uv = _parse_face(parts, line_no, len(verts), len(uvs), tris, tri_uv) and all_uv
        elif tag == "usemtl":
            materials.append((len(tris), " ".join(parts[1:])))
    return verts, colors, uvs, tris, tri_uv, all_uv, materials


def _parse_face(parts, line_no, n_verts, n_uvs, tris, tri_uv):
    """Append the fan triangles of one f line; True when every corner has a texture index."""
    corners = [c.split("/") for c in parts[1:]]
    if len(corners) < 3:
        raise ValueError(f"line {line_no}: a face needs at least 3 corners")
    vi = [_obj_index(c[0], n_verts) for c in corners]
    ti = [_obj_index(c[1], n_uvs) if len(c) > 1 and c[1] else None for c in corners]
    for j in range(1, len(vi) - 1):
        tris.append([vi[0], vi[j], vi[j + 1]])
        tri_uv.append([ti[0], ti[j], ti[j + 1]])
    return None not in ti


def _obj_index(token: str, count: int) -> int:
    """0-based index from an OBJ index (1-based, or negative = relative to the end so far)."""
    i = int(token)
    if i == 0:
        raise ValueError("index 0 (OBJ indices start at 1)")
    return i - 1 if i > 0 else count + i


def save_obj(path: str | os.PathLike[str], V: ArrayLike, F: ArrayLike, *, uv: np.ndarray | None = None,
             uv_faces: np.ndarray | None = None, vertex_colors: ArrayLike | None = None,
             mtllib: str | None = None, material: str | None = None,
             as_text: bool = False) -> str | None:
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

    as_text : bool
        Return the file's text instead of writing it (``path`` only names it in messages).

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
    uv, uv_faces = _check_uv(name, V, F, uv, uv_faces)
    if vertex_colors is not None:
        vertex_colors = np.asarray(vertex_colors, dtype=np.float64)
        if vertex_colors.shape != V.shape:
            raise InputError(f"{name}: vertex_colors must be (n,3)={V.shape}, got "
                             f"{vertex_colors.shape}; pass one RGB colour per vertex")

    text = _obj_text(V, F, uv, uv_faces, vertex_colors, mtllib, material)
    if as_text:
        return text
    with atomic_write(path, "w") as f:
        f.write(text)
    return None


def _obj_text(V: np.ndarray, F: np.ndarray, uv: np.ndarray | None, uv_faces: np.ndarray | None,
              vertex_colors: np.ndarray | None, mtllib: str | None, material: str | None) -> str:
    f = io.StringIO()
    f.write("# written by uvbake\n")
    if mtllib:
        f.write(f"mtllib {mtllib}\n")
    rows = V if vertex_colors is None else np.hstack([V, vertex_colors])
    _write_rows(f, "v", rows, "%.17g")
    if uv is not None:
        _write_rows(f, "vt", uv, "%.17g")
    if material:
        f.write(f"usemtl {material}\n")
    if uv is None or uv_faces is None:           # _check_uv gives both or neither
        _write_rows(f, "f", F + 1, "%d")
    else:
        corners = np.stack([F + 1, uv_faces + 1], axis=-1).reshape(len(F), 6)
        _write_rows(f, "f", corners, "%d/%d")
    return f.getvalue()


def _check_uv(name, V, F, uv, uv_faces):
    """UVs as (k,2) with uv_faces (m,3), from per-vertex, per-corner or indexed input."""
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
    return uv, uv_faces


def _write_rows(f: io.StringIO, tag: str, rows: np.ndarray, fmt: str) -> None:
    if len(rows) == 0:
        return
    per_row = rows.shape[1] // fmt.count("%")
    line = tag + (" " + fmt) * per_row + "\n"
    flat = rows.reshape(len(rows), -1)
    f.write("".join(line % tuple(r) for r in flat.tolist()))
