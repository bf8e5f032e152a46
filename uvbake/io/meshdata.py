"""MeshData: the checked arrays every loader returns."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from uvbake.errors import InputError


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


def _make(V: ArrayLike, F: ArrayLike, colors: ArrayLike | None, labels: ArrayLike | None, name: str) -> MeshData:
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


def _check_labels(labels: ArrayLike, m: int, name: str, what: str) -> np.ndarray:
    labels = np.asarray(labels)
    if labels.ndim == 2 and labels.shape[1] == 1:
        labels = labels[:, 0]
    if labels.ndim != 1 or len(labels) != m:
        raise InputError(f"{name}: {what} has shape {labels.shape} but the mesh has {m} faces; "
                         "give one integer label per face")
    return _as_int(labels, name, what)
