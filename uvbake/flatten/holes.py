"""A chart's holes filled with light triangles for the solve, so their borders cannot fold over.

A free boundary lets a hole shrink where the energy gains by it, and its border can then cross
itself: the spherical cap of ``sample_scenes`` (two holes) solved at alpha 0.3 overlapped itself in
22 pairs of triangles and at alpha 0.5 in 4, all along one hole. Each hole is filled for the solve by
a fan of triangles from a vertex at the mean of its border (in 3D and in the start map), weighed
HOLE_WEIGHT in F: an overlap at the hole would flip a fan triangle, which F then pays for like any
flip, while the fan's pull on the chart stays small. Only the chart's own triangles are reported (UVs,
F, flips); the fan vertices are dropped after the solve. A lightweight form of the scaffold of Jiang
et al., "Simplicial complex augmentation framework for bijective maps" (SIGGRAPH Asia 2017), which
meshes the whole exterior.

The outer border is the longest loop in 3D; a hole whose fan is not positively oriented in the start
map (a border not star-shaped about its mean) or has a triangle shaped worse than FAN_QUALITY (a long,
narrow hole) is left open.

Measured on the cap (``docs/decisions/atlas-speed.md``): weight 0.1 leaves no overlap at alpha 0.1 to
0.9, raises the least texel share (alpha 0.5: 0.096 -> 0.261) and costs 0.1-0.3 % of F; 0.01 left 3
overlapping pairs at alpha 0.5; 0.3 raised F 0.5 % and doubled the iterations at alpha 0.9.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from uvbake.mesh.arrays import signed_areas, triangle_areas, unique_sorted
from uvbake.mesh.topology import _edges, boundary_edges, boundary_loops

if TYPE_CHECKING:
    from uvbake.flatten.energy import DistortionEnergy

#: Weight of a fan triangle in F (a chart triangle's is 1).
HOLE_WEIGHT = 0.1
#: A hole is filled only when every fan triangle is at least this well shaped (4 sqrt(3) area / sum of
#: squared edges: 1 equilateral, 0 degenerate). Long holes make fans of slivers whose distortion swamps
#: the chart's: beetle's 38,656-triangle chart has 10 holes, 624 fan triangles of median quality 0.13;
#: filled, its charts stopped at F 40-150 (step too small) instead of converging at 2-15. The cap's
#: fans: 0.49.
FAN_QUALITY = 0.3


def holes(F: np.ndarray) -> int:
    """Holes of a disk with holes (boundary loops less one), from its Euler characteristic."""
    F = np.asarray(F, dtype=np.int64)
    if not len(F):
        return 0
    _, edges, _ = _edges(F, int(F.max()) + 1)
    return max(0, 1 - (len(unique_sorted(F)) - len(edges) + len(F)))


def hole_fans(V: np.ndarray, F: np.ndarray, start: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The fans filling the holes of the chart (V, F) whose fan is positive in ``start``: (fan vertices
    (h,3), their start UVs (h,2), fan triangles (k,3) indexing the chart's vertices then the fan
    vertices), or None when no hole is filled."""
    n = len(V)
    border = boundary_edges(F, n)                      # oriented as in their triangle: the chart on their left
    if len(border) == 0:
        return None
    loop, length = boundary_loops(V, border)
    if len(length) < 2:
        return None
    hole = np.ones(len(length), bool)
    hole[int(np.argmax(length))] = False               # the outer border
    count = np.bincount(loop).astype(np.float64)
    centre = np.stack([np.bincount(loop, weights=V[border[:, 0], k]) for k in range(3)], axis=1) / count[:, None]
    centre_uv = np.stack([np.bincount(loop, weights=start[border[:, 0], k]) for k in range(2)], axis=1) / count[:, None]
    # the fan triangle of border half-edge (a, b): (b, a, centre), oriented as the chart's triangles
    fans = np.column_stack([border[:, 1], border[:, 0], n + loop])
    uv = np.concatenate([start, centre_uv])
    xyz = np.concatenate([V, centre])
    edges = np.linalg.norm(xyz[fans[:, [1, 2, 0]]] - xyz[fans], axis=2)
    quality = 4.0 * np.sqrt(3.0) * triangle_areas(xyz, fans) / np.maximum((edges ** 2).sum(axis=1), 1e-300)
    bad = (signed_areas(uv, fans) <= 0) | (quality < FAN_QUALITY)
    hole &= np.bincount(loop, weights=bad, minlength=len(length)) == 0
    if not hole.any():
        return None
    new = np.cumsum(hole) - 1                          # fan vertex index among the filled holes
    keep = hole[loop]
    fans = np.column_stack([border[keep, 1], border[keep, 0], n + new[loop[keep]]])
    return centre[hole], centre_uv[hole], fans


def with_hole_fans(V: np.ndarray, F: np.ndarray, start: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray | None,
                                                                             np.ndarray]:
    """(V, F, weights, start) of the chart with its holes filled (see hole_fans); the chart's own
    vertices and triangles come first. Unchanged, with weights None, when no hole is filled."""
    fans = hole_fans(V, F, start)
    if fans is None:
        return V, F, None, start
    Vh, Sh, Fh = fans
    w = np.concatenate([np.ones(len(F)), np.full(len(Fh), HOLE_WEIGHT)])
    return np.concatenate([V, Vh]), np.concatenate([F, Fh]), w, np.concatenate([start, Sh])


def chart_energy(energy: DistortionEnergy, uv: np.ndarray, m: int) -> float:
    """F of the chart's own ``m`` triangles (the first ones) at ``uv``."""
    d_area, d_angle = energy.per_triangle(uv)
    return float(np.dot(energy.w[:m], (energy.alpha * d_area + (1.0 - energy.alpha) * d_angle)[:m]))
