"""Regenerate the sample scenes uvbake ships: ``python sample_scenes/make_scenes.py [--out DIR]``.

Every scene is a 2D domain (a disk, rectangle or annulus, with circular holes) meshed by Delaunay
triangulation of boundary samples and a jittered hexagonal point set, relaxed by a few Laplacian
sweeps, then lifted to 3D. The output is deterministic (fixed seed, no clock, no platform paths):
running the script twice gives byte-identical files. Every mesh is checked before it is written:
manifold, consistently oriented, no unreferenced vertex, smallest angle above MIN_ANGLE_DEG, and
each chart a single disk with the expected number of holes.

Files (binary little-endian PLY, float32 positions, uchar colours, int ``segment`` face property):
  disk_holes.ply        bumpy height field over a disk with 3 holes, one chart
  sphere_cap.ply        part of the unit sphere with z > -0.3 and 2 holes, one chart
  scene.ply             bent rippled sheet, 8 charts of varied size and aspect in a ``segment`` face
                        property (crease lines, some slanted), vertex colours; chart 0 with 2 holes,
                        chart 5 with 1
  multi_component.ply   4 separate patches (saddle, cone annulus, dome, half cylinder), no labels
  README.md             the table of the above
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
from scipy import sparse
from scipy.sparse.csgraph import connected_components
from scipy.spatial import Delaunay

SEED = 20240611
MIN_ANGLE_DEG = 20.0
HERE = Path(__file__).resolve().parent


# ------------------------------------------------------------------------------------------------
# 2D meshing


def circle_points(center, radius, h, phase=0.0):
    """Points on a circle spaced about h apart (at least 12)."""
    n = max(12, math.ceil(2 * math.pi * radius / h))
    t = phase + 2 * math.pi * np.arange(n) / n
    return np.column_stack([center[0] + radius * np.cos(t), center[1] + radius * np.sin(t)])


def segment_points(a, b, h, include_end=False):
    """Points from a towards b spaced about h apart; a included, b only when include_end."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    n = max(1, math.ceil(np.linalg.norm(b - a) / h))
    t = np.arange(n + 1 if include_end else n) / n
    return a + t[:, None] * (b - a)


def rectangle_points(x0, y0, x1, y1, h):
    corners = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]
    return np.vstack([segment_points(corners[i], corners[(i + 1) % 4], h) for i in range(4)])


def _new_points(points, existing, tol=1e-9):
    """The points farther than tol from every existing point and every earlier kept point."""
    keep = []
    for p in points:
        others = np.vstack([existing, *keep])
        if np.min(np.linalg.norm(others - p, axis=1)) > tol:
            keep.append(p[None])
    return np.vstack(keep)


def hex_points(x0, y0, x1, y1, h, rng, jitter=0.12):
    """A jittered hexagonal lattice of spacing h covering the box."""
    dy = h * math.sqrt(3) / 2
    rows = []
    for j in range(int((y1 - y0) / dy) + 2):
        x = np.arange(x0 - h, x1 + h, h) + (h / 2 if j % 2 else 0.0)
        rows.append(np.column_stack([x, np.full_like(x, y0 + j * dy)]))
    p = np.vstack(rows)
    return p + rng.uniform(-jitter * h, jitter * h, p.shape)


def mesh_domain(fixed, hole_of_fixed, free, inside, outside_triangle, *, sweeps=6):
    """Delaunay-triangulate fixed (boundary) and free points, drop triangles outside the domain.

    fixed : (a,2) boundary and crease points, kept in place.
    hole_of_fixed : (a,) int, k > 0 for points on hole k (a triangle with all three corners on one
        hole lies inside it and is dropped), 0 otherwise.
    free : (b,2) interior points, moved by Laplacian sweeps while ``inside`` stays true.
    outside_triangle : function of (t,2) centroids -> bool mask of triangles to drop.
    Returns P (k,2) and counter-clockwise triangles T (t,3) with every point used.
    """
    n_fixed = len(fixed)
    P = np.vstack([fixed, free])
    for sweep in range(sweeps + 1):
        T = Delaunay(P).simplices.astype(np.int64)
        a, b, c = P[T[:, 0]], P[T[:, 1]], P[T[:, 2]]
        cross = (b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0]
        T[cross < 0] = T[cross < 0][:, [0, 2, 1]]
        hole = np.concatenate([hole_of_fixed, np.zeros(len(P) - n_fixed, np.int64)])
        on_one_hole = (hole[T[:, 0]] > 0) & (hole[T] == hole[T[:, :1]]).all(axis=1)
        T = T[~on_one_hole & ~outside_triangle(P[T].mean(axis=1))]
        if sweep == sweeps:
            break
        # Laplacian sweep of free points over the kept triangles
        E = np.vstack([T[:, [0, 1]], T[:, [1, 2]], T[:, [2, 0]]])
        E = np.vstack([E, E[:, ::-1]])
        sums = np.zeros_like(P)
        np.add.at(sums, E[:, 0], P[E[:, 1]])
        deg = np.bincount(E[:, 0], minlength=len(P))
        target = np.where(deg[:, None] > 0, sums / np.maximum(deg, 1)[:, None], P)
        move = np.arange(len(P)) >= n_fixed
        move &= inside(target)
        P = np.where(move[:, None], target, P)
    used = np.zeros(len(P), bool)
    used[T] = True
    remap = np.cumsum(used) - 1
    return P[used], remap[T]


# ------------------------------------------------------------------------------------------------
# topology and quality checks (the script refuses to write a mesh that fails them)


def edge_counts(F):
    E = np.sort(np.vstack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    return np.unique(E, axis=0, return_counts=True)


def topology(F):
    """(components, boundary loops, Euler characteristic) of a triangle list; asserts manifold."""
    used = np.unique(F)
    F = np.searchsorted(used, F)
    E, counts = edge_counts(F)
    assert counts.max() <= 2, "non-manifold edge"
    directed = np.vstack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    assert len(np.unique(directed, axis=0)) == len(directed), "inconsistent orientation"
    boundary = E[counts == 1]
    bdeg = np.bincount(boundary.ravel(), minlength=len(used))
    assert np.all((bdeg == 0) | (bdeg == 2)), "boundary touches itself at a vertex"
    return (
        _components(len(used), E),
        _components(len(used), boundary) - int(np.sum(bdeg == 0)),
        len(used) - len(E) + len(F),
    )


def _components(n, E):
    """Number of connected components of the graph on n vertices with edges E (k,2)."""
    graph = sparse.coo_matrix((np.ones(len(E)), (E[:, 0], E[:, 1])), shape=(n, n))
    return connected_components(graph, directed=False)[0]


def min_angle_deg(V, F):
    angles = []
    for k in range(3):
        a, b, c = V[F[:, k]], V[F[:, (k + 1) % 3]], V[F[:, (k + 2) % 3]]
        u, w = b - a, c - a
        cos = np.sum(u * w, 1) / (np.linalg.norm(u, axis=1) * np.linalg.norm(w, axis=1))
        angles.append(np.degrees(np.arccos(np.clip(cos, -1, 1))))
    return float(np.min(angles))


# ------------------------------------------------------------------------------------------------
# scenes


def disk_holes(rng):
    h = 0.045
    holes = [((-0.42, 0.22), 0.2), ((0.38, 0.36), 0.15), ((0.12, -0.45), 0.22)]
    fixed = [circle_points((0, 0), 1.0, h)] + [circle_points(c, r, h) for c, r in holes]
    hole_id = np.concatenate([np.full(len(p), k) for k, p in enumerate(fixed)])
    fixed = np.vstack(fixed)

    def sdf(p):  # > 0 outside the domain
        d = np.linalg.norm(p, axis=1) - 1.0
        for c, r in holes:
            d = np.maximum(d, r - np.linalg.norm(p - c, axis=1))
        return d

    free = hex_points(-1, -1, 1, 1, h, rng)
    free = free[sdf(free) < -0.55 * h]
    P, F = mesh_domain(fixed, hole_id, free, lambda p: sdf(p) < -0.3 * h, lambda c: sdf(c) > 0)
    x, y = P[:, 0], P[:, 1]
    z = 0.3 * (x**2 - 0.5 * y**2) + 0.07 * np.sin(5 * x) * np.sin(4 * y)
    return np.column_stack([x, y, z]), F, None, None


def _rotation_to(d):
    """Orthonormal e1, e2 perpendicular to unit vector d."""
    e1 = np.cross(d, [0.0, 0.0, 1.0] if abs(d[2]) < 0.9 else [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(d, e1)


def sphere_cap(rng):
    h = 0.08
    z_cut = -0.3
    holes = []
    for polar, azimuth, radius in [(50, 30, 0.26), (80, 200, 0.2)]:
        p, a = math.radians(polar), math.radians(azimuth)
        holes.append((np.array([math.sin(p) * math.cos(a), math.sin(p) * math.sin(a), math.cos(p)]), radius))

    def sdf(q):  # geodesic distance outside the domain on the unit sphere (> 0 outside)
        q = q / np.linalg.norm(q, axis=1, keepdims=True)
        d = np.arccos(np.clip(q[:, 2], -1, 1)) - math.acos(z_cut)
        for c, r in holes:
            d = np.maximum(d, r - np.arccos(np.clip(q @ c, -1, 1)))
        return d

    loops = [circle_points((0, 0), math.sqrt(1 - z_cut**2), h)]
    loops = [np.column_stack([loops[0], np.full(len(loops[0]), z_cut)])]
    for c, r in holes:
        e1, e2 = _rotation_to(c)
        n = max(12, math.ceil(2 * math.pi * math.sin(r) / h))
        t = 2 * math.pi * np.arange(n) / n
        loops.append(math.cos(r) * c + math.sin(r) * (np.outer(np.cos(t), e1) + np.outer(np.sin(t), e2)))
    hole_id = np.concatenate([np.full(len(p), k) for k, p in enumerate(loops)])
    # Fibonacci sphere with spacing about h, jittered a little along the sphere
    n = int(round(4 * math.pi / (math.sqrt(3) / 2 * h * h)))
    k = np.arange(n) + 0.5
    zf = 1 - 2 * k / n
    phi = math.pi * (3 - math.sqrt(5)) * k
    rf = np.sqrt(1 - zf**2)
    free = np.column_stack([rf * np.cos(phi), rf * np.sin(phi), zf])
    free = free[sdf(free) < -0.55 * h]

    def to_plane(q):  # stereographic projection from the south pole (conformal)
        return q[:, :2] / (1 + q[:, 2:3])

    def to_sphere(p):
        s = np.sum(p * p, axis=1, keepdims=True)
        return np.column_stack([2 * p / (1 + s), (1 - s) / (1 + s)])

    P, F = mesh_domain(to_plane(np.vstack(loops)), hole_id, to_plane(free),
                       lambda p: sdf(to_sphere(p)) < -0.3 * h,
                       lambda c: sdf(to_sphere(c)) > 0, sweeps=0)
    return to_sphere(P), F, None, None


def _at(a, b, u=None, v=None):
    """The point of the line through a and b with the given u (or v)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    t = (u - a[0]) / (b[0] - a[0]) if u is not None else (v - a[1]) / (b[1] - a[1])
    return tuple(a + t * (b - a))


# scene.ply's sheet (u, v in [0, W] x [0, H] before bending) and its segmentation, laid out as a scan
# segmentation would leave it: 8 charts of varied size and aspect (2 large, 2 medium, 4 small), cut by
# crease polylines (each end on the border or on another crease; some slanted or kinked), with holes
# (scan gaps) in charts 0 and 5, and one seed point per chart that fixes its label.
SCENE_W, SCENE_H = 3.0, 2.0
_C1 = [(0.0, 1.1), (1.6, 1.1), (3.0, 1.15)]                       # the long crease across the sheet
_C3 = [(1.6, 0.55), (3.0, 0.5)]
SCENE_CREASES = [
    _C1,
    [(1.6, 0.0), (1.6, 1.1)],
    _C3,
    [_at(*_C3, u=2.4), _at(*_C1[1:], u=2.3)],
    [(0.8, 1.1), (0.9, SCENE_H)],
    [_at(*_C1[1:], u=2.2), (2.2, SCENE_H)],
    [(2.2, 1.6), (3.0, 1.6)],
]
SCENE_HOLES = [((0.55, 0.45), 0.17), ((1.12, 0.7), 0.12), ((1.5, 1.55), 0.14)]
SCENE_SEEDS = [  # one point inside each chart, in label order
    (0.3, 0.2),     # 0: large, 2 holes
    (2.3, 0.25),    # 1: wide strip
    (2.0, 0.8),     # 2: medium, slanted side
    (2.7, 0.8),     # 3: medium, slanted side
    (0.4, 1.5),     # 4: tall
    (1.3, 1.8),     # 5: large, 1 hole
    (2.6, 1.4),     # 6: small
    (2.6, 1.8),     # 7: small strip
]


def _point_segment_distance(p, a, b):
    a, b = np.asarray(a, float), np.asarray(b, float)
    t = np.clip((p - a) @ (b - a) / np.dot(b - a, b - a), 0, 1)
    return np.linalg.norm(p - (a + t[:, None] * (b - a)), axis=1)


def _split_at_ends(polylines, others=()):
    """Straight pieces of the polylines, split wherever an end of a polyline (theirs or others') lies."""
    ends = [np.asarray(p, float) for line in [*polylines, *others] for p in (line[0], line[-1])]
    pieces = []
    for line in polylines:
        for a, b in zip(line[:-1], line[1:]):
            a, b = np.asarray(a, float), np.asarray(b, float)
            cuts = sorted({float((p - a) @ (b - a) / np.dot(b - a, b - a)) for p in ends
                           if _point_segment_distance(p[None], a, b)[0] < 1e-9})
            nodes = [a] + [a + t * (b - a) for t in cuts if 1e-9 < t < 1 - 1e-9] + [b]
            pieces += list(zip(nodes[:-1], nodes[1:]))
    return pieces


def _labels_by_crease(P, F, creases, seeds):
    """Label the faces by the edge-connected pieces the crease segments cut the mesh into.

    Pieces are numbered by the seed point that lies in them; every piece must hold exactly one seed.
    """

    half = np.vstack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    face = np.tile(np.arange(len(F)), 3)
    key = np.sort(half, axis=1)
    order = np.lexsort((key[:, 1], key[:, 0]))
    key, face = key[order], face[order]
    pair = np.all(key[1:] == key[:-1], axis=1)                     # interior edges: two half-edges
    a, b, fa, fb = key[:-1][pair, 0], key[:-1][pair, 1], face[:-1][pair], face[1:][pair]
    cut = np.zeros(len(a), bool)                                   # both ends on one crease piece
    for s, t in creases:
        cut |= (_point_segment_distance(P[a], s, t) < 1e-9) & (_point_segment_distance(P[b], s, t) < 1e-9)
    graph = sparse.coo_matrix((np.ones(int((~cut).sum())), (fa[~cut], fb[~cut])), shape=(len(F), len(F)))
    n, piece = connected_components(graph, directed=False)
    centroids = P[F].mean(axis=1)
    seed_piece = [piece[np.argmin(np.linalg.norm(centroids - np.asarray(q), axis=1))] for q in seeds]
    assert sorted(seed_piece) == list(range(n)), f"{n} pieces for {len(seeds)} seeds"
    relabel = np.empty(n, np.int64)
    relabel[seed_piece] = np.arange(n)
    return relabel[piece]


def _scene_colors(u, v):
    """Smooth colour waves over the sheet, about one period per large chart, so every chart's texture
    varies inside it (a chart moved in the atlas changes its texels, not only its outline)."""
    return 0.5 + 0.5 * np.column_stack([np.cos(2 * math.pi * u / 1.5),
                                        np.cos(2 * math.pi * v / 1.25 + 0.6 * u),
                                        np.cos(math.pi * (u + v) / 1.1)])


def scene(rng):
    """A bent, rippled 3 x 2 sheet split by crease lines into 8 labelled charts of varied size."""
    h = 0.05
    W, H = SCENE_W, SCENE_H
    holes = SCENE_HOLES
    border = [(0.0, 0.0), (W, 0.0), (W, H), (0.0, H), (0.0, 0.0)]
    border_pieces = _split_at_ends([border], SCENE_CREASES)
    crease_pieces = _split_at_ends(SCENE_CREASES)
    outline = np.vstack([segment_points(a, b, h) for a, b in border_pieces])
    fixed = [outline] + [circle_points(c, r, h) for c, r in holes]
    hole_id = np.concatenate([np.full(len(p), k) for k, p in enumerate(fixed)])
    crease = np.vstack([segment_points(a, b, h, include_end=True) for a, b in crease_pieces])
    crease = _new_points(crease, np.vstack(fixed))
    fixed = np.vstack(fixed + [crease])
    hole_id = np.concatenate([hole_id, np.zeros(len(crease), np.int64)])

    def sdf(p):
        d = np.maximum(np.maximum(-p[:, 0], p[:, 0] - W), np.maximum(-p[:, 1], p[:, 1] - H))
        for c, r in holes:
            d = np.maximum(d, r - np.linalg.norm(p - c, axis=1))
        return d

    def line_dist(p):
        return np.min([_point_segment_distance(p, a, b) for a, b in crease_pieces], axis=0)

    def inside(p):
        return (sdf(p) < -0.3 * h) & (line_dist(p) > 0.3 * h)

    free = hex_points(0, 0, W, H, h, rng)
    free = free[(sdf(free) < -0.55 * h) & (line_dist(free) > 0.55 * h)]
    P, F = mesh_domain(fixed, hole_id, free, inside, lambda c: sdf(c) > 0)
    labels = _labels_by_crease(P, F, crease_pieces, SCENE_SEEDS)

    u, v = P[:, 0], P[:, 1]
    R = 1.4
    phi = (u - W / 2) / R
    ripple = 0.06 * np.sin(2 * math.pi * v / 1.0) * np.sin(math.pi * u / W)
    X = np.column_stack([R * np.sin(phi), v, R * (1 - np.cos(phi))])
    normal = np.column_stack([-np.sin(phi), np.zeros_like(phi), np.cos(phi)])
    X = X + ripple[:, None] * normal
    return X, F, _scene_colors(u, v), labels


def multi_component(rng):
    h = 0.05
    parts = []

    # saddle square
    fixed = rectangle_points(-0.5, -0.5, 0.5, 0.5, h)
    free = hex_points(-0.5, -0.5, 0.5, 0.5, h, rng)
    box = lambda p: np.maximum(np.abs(p[:, 0]), np.abs(p[:, 1])) - 0.5  # noqa: E731
    free = free[box(free) < -0.55 * h]
    P, F = mesh_domain(fixed, np.zeros(len(fixed), np.int64), free,
                       lambda p: box(p) < -0.3 * h, lambda c: box(c) > 0)
    parts.append((np.column_stack([P, 0.6 * (P[:, 0] ** 2 - P[:, 1] ** 2)]), F))

    # cone annulus, 0.2 < r < 0.5
    fixed = [circle_points((0, 0), 0.5, h), circle_points((0, 0), 0.2, h)]
    hole_id = np.concatenate([np.zeros(len(fixed[0]), np.int64), np.ones(len(fixed[1]), np.int64)])
    ring = lambda p: np.abs(np.linalg.norm(p, axis=1) - 0.35) - 0.15  # noqa: E731
    free = hex_points(-0.5, -0.5, 0.5, 0.5, h, rng)
    free = free[ring(free) < -0.55 * h]
    P, F = mesh_domain(np.vstack(fixed), hole_id, free, lambda p: ring(p) < -0.3 * h,
                       lambda c: ring(c) > 0)
    parts.append((np.column_stack([P, 0.6 * np.linalg.norm(P, axis=1)]), F))

    # dome disk
    fixed = circle_points((0, 0), 0.5, h)
    disk = lambda p: np.linalg.norm(p, axis=1) - 0.5  # noqa: E731
    free = hex_points(-0.5, -0.5, 0.5, 0.5, h, rng)
    free = free[disk(free) < -0.55 * h]
    P, F = mesh_domain(fixed, np.zeros(len(fixed), np.int64), free,
                       lambda p: disk(p) < -0.3 * h, lambda c: disk(c) > 0)
    parts.append((np.column_stack([P, 0.35 * (1 - np.sum(P * P, axis=1) / 0.25)]), F))

    # half cylinder of radius 0.35, unrolled as a pi*0.35 x 1 rectangle
    L = math.pi * 0.35
    fixed = rectangle_points(0, 0, L, 1.0, h)
    rect = lambda p: np.maximum(np.abs(p[:, 0] - L / 2) - L / 2, np.abs(p[:, 1] - 0.5) - 0.5)  # noqa: E731
    free = hex_points(0, 0, L, 1.0, h, rng)
    free = free[rect(free) < -0.55 * h]
    P, F = mesh_domain(fixed, np.zeros(len(fixed), np.int64), free,
                       lambda p: rect(p) < -0.3 * h, lambda c: rect(c) > 0)
    t = P[:, 0] / 0.35
    parts.append((np.column_stack([0.35 * np.cos(t), P[:, 1] - 0.5, 0.35 * np.sin(t)]), F))

    offsets = [(0.0, 0.0, 0.0), (1.4, 0.0, 0.0), (0.0, 1.4, 0.0), (1.4, 1.4, 0.0)]
    V, Fs, base = [], [], 0
    for (P3, F), off in zip(parts, offsets):
        V.append(P3 + off)
        Fs.append(F + base)
        base += len(P3)
    return np.vstack(V), np.vstack(Fs), None, None


# ------------------------------------------------------------------------------------------------
# writing


def ply_bytes(V, F, colors=None, labels=None, comment=""):
    """Binary little-endian PLY: float32 xyz, optional uchar rgb, int32 ``segment`` per face."""
    head = ["ply", "format binary_little_endian 1.0", f"comment {comment}",
            f"element vertex {len(V)}", "property float x", "property float y", "property float z"]
    vdt = [("x", "<f4"), ("y", "<f4"), ("z", "<f4")]
    if colors is not None:
        head += ["property uchar red", "property uchar green", "property uchar blue"]
        vdt += [("red", "u1"), ("green", "u1"), ("blue", "u1")]
    head += [f"element face {len(F)}", "property list uchar int vertex_indices"]
    fdt = [("n", "u1"), ("vertex_indices", "<i4", (3,))]
    if labels is not None:
        head.append("property int segment")
        fdt.append(("segment", "<i4"))
    head.append("end_header")
    vdata = np.zeros(len(V), dtype=vdt)
    for k, name in enumerate("xyz"):
        vdata[name] = V[:, k]
    if colors is not None:
        rgb = np.clip(np.round(colors * 255), 0, 255).astype(np.uint8)
        for k, name in enumerate(("red", "green", "blue")):
            vdata[name] = rgb[:, k]
    fdata = np.zeros(len(F), dtype=fdt)
    fdata["n"] = 3
    fdata["vertex_indices"] = F
    if labels is not None:
        fdata["segment"] = labels
    return ("\n".join(head) + "\n").encode("ascii") + vdata.tobytes() + fdata.tobytes()


SCENES = {
    "disk_holes.ply": (disk_holes, "bumpy height field over a disk with 3 holes", 1, (4,)),
    "sphere_cap.ply": (sphere_cap, "unit sphere above z=-0.3 with 2 holes", 1, (3,)),
    "scene.ply": (scene, "bent rippled sheet, 8 charts of varied size in face property 'segment', "
                  "vertex colours", 8,
                  (3, 1, 1, 1, 1, 2, 1, 1)),
    "multi_component.ply": (multi_component, "saddle, cone annulus, dome, half cylinder; no labels", 4,
                            (1, 2, 1, 1)),
}


def build(name):
    """(file bytes, table row) of one scene, after checking it."""
    make, what, n_charts, loops = SCENES[name]
    rng = np.random.default_rng(SEED)
    V, F, colors, labels = make(rng)
    V = V.astype(np.float32).astype(np.float64)  # check what is written
    assert np.isfinite(V).all()
    assert np.array_equal(np.unique(F), np.arange(len(V))), "unreferenced vertex"
    angle = min_angle_deg(V, F)
    assert angle > MIN_ANGLE_DEG, f"{name}: smallest angle {angle:.1f} deg"
    n_comp, n_loops, chi = topology(F)
    if labels is None:
        assert n_comp == n_charts
        charts = _component_faces(F)
    else:
        assert n_comp == 1
        charts = [F[labels == k] for k in range(n_charts)]
    found = []
    for f in charts:
        c, b, x = topology(f)
        assert c == 1 and x == 2 - b, f"{name}: chart is not a disk with holes"
        found.append(b)
    assert tuple(found) == loops, f"{name}: boundary loops {found}, expected {loops}"
    data = ply_bytes(V, F, colors, labels, comment=f"uvbake sample scene {name}: {what}")
    row = (name, what, len(V), len(F), n_charts, n_loops, angle, len(data))
    return data, row


def _component_faces(F):
    """Face index lists of the connected components, ordered by smallest face index."""
    n = F.max() + 1
    E = np.vstack([F[:, [0, 1]], F[:, [1, 2]]])
    graph = sparse.coo_matrix((np.ones(len(E)), (E[:, 0], E[:, 1])), shape=(n, n))
    roots = connected_components(graph, directed=False)[1][F[:, 0]]
    _, first, inv = np.unique(roots, return_index=True, return_inverse=True)
    order = np.argsort(first)
    return [F[inv == k] for k in order]


def readme(rows):
    lines = [
        "# Sample scenes",
        "",
        "Generated by `python sample_scenes/make_scenes.py` (deterministic; `--out DIR` writes elsewhere).",
        "Binary little-endian PLY; every mesh is manifold, consistently oriented, without unreferenced",
        f"vertices, smallest angle above {MIN_ANGLE_DEG:g} degrees, and each chart is one disk with holes.",
        "",
        "| file | what | vertices | faces | charts | boundary loops | min angle (deg) | bytes |",
        "|---|---|---:|---:|---:|---:|---:|---:|",
    ]
    for name, what, nv, nf, nc, nl, angle, size in rows:
        lines.append(f"| {name} | {what} | {nv} | {nf} | {nc} | {nl} | {angle:.1f} | {size} |")
    return "\n".join(lines) + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=HERE, help="output folder (default: this folder)")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    rows = []
    for name in SCENES:
        data, row = build(name)
        (args.out / name).write_bytes(data)
        rows.append(row)
        print(f"{name}: {row[2]} vertices, {row[3]} faces, {row[4]} charts, {row[5]} loops, "
              f"min angle {row[6]:.1f} deg, {row[7]} bytes")
    (args.out / "README.md").write_text(readme(rows), encoding="utf-8", newline="\n")


if __name__ == "__main__":
    main()
