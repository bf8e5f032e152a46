"""Reading texture coordinates back from a mesh file: the one reader behind ``load_textured_uv`` and
``uvbake check``.

    for part in read_uv("atlas.glb"):
        part.V, part.F, part.corner_uv      # corner_uv is None when that geometry has no UVs

OBJ is read exactly (:func:`uvbake.io.obj.load_obj_uv`: ``v`` order and ``f`` indices kept, one part).
Every other format (.glb, .gltf, .ply) is read by trimesh without processing, one part per geometry
of the file in order, untransformed. UVs are v up (trimesh undoes glTF's ``1 - v``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from uvbake.errors import InputError
from uvbake.io.obj import load_obj_uv

__all__ = ["UVPart", "read_uv"]


@dataclass(frozen=True)
class UVPart:
    """One geometry of a file: positions, triangles and per-corner UVs (``None`` when it has none)."""

    V: np.ndarray
    F: np.ndarray
    corner_uv: np.ndarray | None


def read_uv(path: str | os.PathLike[str]) -> list[UVPart]:
    """The geometries of a mesh file with their per-corner texture coordinates, in file order.

    Parameters
    ----------
    path : str or path
        .obj (``vt``), .glb/.gltf (``TEXCOORD_0``) or .ply (``s,t`` or ``u,v``).

    Returns
    -------
    list of UVPart
        Geometries without triangles are left out.
    """
    if Path(path).suffix.lower() == ".obj":
        mesh, uv, uv_faces = load_obj_uv(path)
        corner_uv = None if uv is None or uv_faces is None else uv[uv_faces]
        return [UVPart(mesh.V, mesh.F, corner_uv)] if len(mesh.F) else []
    return _read_trimesh(os.fspath(path))


def _read_trimesh(path: str) -> list[UVPart]:
    import trimesh  # heavy import (~0.5 s); only non-OBJ files need it

    try:
        loaded = trimesh.load(path, process=False)
    except Exception as exc:  # trimesh raises many types for unreadable files
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise InputError(
            f"cannot read {path}: {msg}; pass a valid .obj, .glb, .gltf or .ply mesh"
        ) from None
    geoms: list[Any] = list(loaded.geometry.values()) if isinstance(loaded, trimesh.Scene) else [loaded]
    parts = []
    for g in geoms:
        F = np.asarray(getattr(g, "faces", np.zeros((0, 3))), dtype=np.int64)
        if F.ndim != 2 or len(F) == 0:
            continue
        V = np.asarray(g.vertices, dtype=np.float64)
        uv = getattr(getattr(g, "visual", None), "uv", None)
        corner_uv = None
        if uv is not None and len(uv) == len(V):
            corner_uv = np.asarray(uv, dtype=np.float64)[:, :2][F]
        parts.append(UVPart(V, F, corner_uv))
    return parts
