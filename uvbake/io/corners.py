"""Per-corner UVs to per-vertex ones: vertices split at UV seams, as OBJ, glTF and host meshes need."""

from __future__ import annotations

import numpy as np


def split_corners(F: np.ndarray, corner_uv: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Split vertices per distinct (vertex, UV) pair, as glTF needs one UV per vertex.

    Returns
    -------
    source : (k,) int64 array
        The original vertex of each new vertex.
    uv : (k,2) float64 array
        Its UV.
    F_new : (m,3) int64 array
        Triangles over the new vertices.
    """
    m = len(F)
    keys = np.empty((3 * m, 3), dtype=np.float64)
    keys[:, 0] = F.reshape(-1)
    keys[:, 1:] = corner_uv.reshape(-1, 2)
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    order = np.argsort(first)  # new vertices in order of first use
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    corners = first[order]
    return F.reshape(-1)[corners], corner_uv.reshape(-1, 2)[corners], rank[inverse].reshape(m, 3)
