"""Instances: separate pieces of a mesh that are copies of one another, charted and flattened once.

    inst = find_instances(V, F, labels, pinch_keys)           # None when no piece repeats
    charts, starts, log, plan = chart_originals(inst, V, labels, pinch_keys, make_charts)
    ...                                                       # the originals' solve
    charts, results, splits = add_copies(inst, plan, V, charts, results, splits)

A kit's or a foliage mesh's pieces often repeat: the same bolt, leaf card or tile, moved, turned and
scaled (an instanced glTF scene is flattened that way on loading). Two pieces are instances of one
another when their triangles list their vertices in the same pattern (the same faces in the same
order, vertices numbered by first use) with the same labels, and one piece's vertices are the other's
turned, scaled and moved (a proper rotation, found by Kabsch's method, to REL_TOL of the piece's size
beyond float32 rounding of the coordinates).
The charting's and the solve's decisions read angles and ratios of lengths and areas, so a copy's
charts and maps are what its original gets (up to ties that rounding breaks), its UVs scaled by the
ratio of sizes (the pipeline's density equalisation does that). Validity does not rest on it: a map
without flips, overlaps or starved triangles on the original has none on a similar copy (orientation
and overlap are read in the UV plane, texel shares are ratios), and the atlas's validation checks
every copy as it checks every chart.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Callable

import numpy as np

from uvbake.mesh.arrays import pieces
from uvbake.mesh.charts import Chart

#: Largest distance between a piece's vertices and its original's, turned, scaled and moved onto them,
#: as a share of the piece's size (its largest distance from its centroid) for the two to be instances,
#: beyond what storing either piece's coordinates in float32 rounds (STORED_ROUNDING of each one's
#: largest coordinate: PLY, glTF and most OBJ files hold float32, and a small copy far from the origin
#: is only similar to that rounding).
REL_TOL = 1e-7
STORED_ROUNDING = 2.0 ** -23
#: Originals tried per pattern of faces (the first piece not yet matched each time): a kit of many
#: pieces of one pattern and different shapes (noisy copies) stops looking after these.
MAX_ORIGINALS = 8


@dataclasses.dataclass
class Instances:
    """Pieces of a mesh and which of them are copies.

    piece : (m,) int     each face's piece (vertex-connected)
    faces : (m,) int     faces grouped by piece, each piece's in mesh order (``face_start[p]`` on)
    verts : (n,) int     vertices grouped by piece, each piece's by first use (``vert_start[p]`` on)
    original : (P,) int  each piece's original (itself when it is one)
    scale : (P,) float   each piece's size over its original's
    F : (m,3) int        the mesh's faces
    """

    piece: np.ndarray
    faces: np.ndarray
    face_start: np.ndarray
    verts: np.ndarray
    vert_start: np.ndarray
    original: np.ndarray
    scale: np.ndarray
    F: np.ndarray

    @property
    def copies(self) -> int:
        """Pieces that are copies of another (charted and solved as their original)."""
        return int(np.count_nonzero(self.original != np.arange(len(self.original))))

    def kept_faces(self) -> np.ndarray:
        """Faces of the originals (and of pieces with no copy), in mesh order."""
        return np.flatnonzero(self.original[self.piece] == self.piece)

    def reduced(self, V: np.ndarray, labels: np.ndarray | None, pinch_keys: np.ndarray | None) -> tuple:
        """(V, F, labels, pinch keys, mesh face of each face, mesh vertex of each vertex) of the mesh of
        the originals only (pieces with no copy included)."""
        from uvbake.mesh.arrays import dense_ranks

        kf = self.kept_faces()
        F = self.F[kf]
        vmap, local = dense_ranks(F, len(V))
        return (V[vmap], local.reshape(-1, 3).astype(np.int64), None if labels is None else np.asarray(labels)[kf],
                None if pinch_keys is None else np.asarray(pinch_keys)[vmap], kf, vmap)

    def pieces_of(self, charts: list[Chart]) -> list[int]:
        """The piece of each chart (of the mesh: its face_index in the mesh's numbering)."""
        return [int(self.piece[c.face_index[0]]) for c in charts]

    def copies_of(self) -> dict:
        """{original piece: [its copies, in mesh order]}."""
        out: dict = {}
        for q in np.flatnonzero(self.original != np.arange(len(self.original))):   # one per copy
            out.setdefault(int(self.original[q]), []).append(int(q))
        return out

    def charts_of_copies(self, V: np.ndarray, charts: list[Chart]) -> tuple[list[Chart], list[tuple]]:
        """Every copy's charts: each chart of ``charts`` (the originals', in the mesh's numbering) made
        again on each copy of its piece, the same local faces and vertices. Returns the new charts and,
        per new chart, (index of its original in ``charts``, the copy's instance number, its scale)."""
        vrank = np.empty(len(V), np.int64)
        vrank[self.verts] = np.arange(len(self.verts)) - np.repeat(self.vert_start[:-1], np.diff(self.vert_start))
        frank = np.empty(len(self.faces), np.int64)
        frank[self.faces] = np.arange(len(self.faces)) - np.repeat(self.face_start[:-1], np.diff(self.face_start))
        copies = self.copies_of()
        out, made = [], []
        for i, (c, p) in enumerate(zip(charts, self.pieces_of(charts))):   # one per chart of the originals
            vr, fr = vrank[c.vertex_map], frank[c.face_index]
            for k, q in enumerate(copies.get(p, ()), start=1):   # one per copy of its piece
                vm = self.verts[self.vert_start[q] + vr]
                out.append(Chart(V[vm], c.F.copy(), vm, self.faces[self.face_start[q] + fr], c.label,
                                 f"{c.name} (instance {k})"))
                made.append((i, k, float(self.scale[q])))
        return out, made

    def made_for(self) -> dict:
        """{original piece: [(instance number, scale) of each copy]} (for :func:`copy_records`)."""
        return {p: [(k, float(self.scale[q])) for k, q in enumerate(qs, start=1)]
                for p, qs in self.copies_of().items()}

    def charted(self, charts: list[Chart], kept: np.ndarray, vmap: np.ndarray) -> None:
        """Charts of the reduced mesh (:meth:`reduced`) given the mesh's numbering, in place: ``kept`` the
        mesh face of each reduced face, ``vmap`` the mesh vertex of each reduced vertex."""
        for c in charts:                               # one per chart
            c.vertex_map, c.face_index = vmap[c.vertex_map], kept[c.face_index]


def find_instances(V: np.ndarray, F: np.ndarray, labels: np.ndarray | None = None,
                   pinch_keys: np.ndarray | None = None) -> Instances | None:
    """The mesh's pieces and which are instances of which (module docstring); None when none repeats.
    Pieces holding a repaired pinch (``pinch_keys`` >= 0) are never copies."""
    from uvbake.mesh.graph import components

    V, F = np.asarray(V, dtype=np.float64), np.asarray(F, dtype=np.int64)
    m, n = len(F), len(V)
    if m < 2:
        return None
    _, vlab = components(n, np.concatenate([F[:, 0], F[:, 1]]), np.concatenate([F[:, 1], F[:, 2]]))
    used, piece = np.unique(vlab[F[:, 0]], return_inverse=True)
    piece = piece.ravel()
    P = len(used)
    if P < 2:
        return None
    faces = np.argsort(piece, kind="stable")
    nf = np.bincount(piece, minlength=P)
    face_start = np.concatenate([[0], np.cumsum(nf)])
    corners = F[faces].ravel()
    uniq, first = np.unique(corners, return_index=True)
    verts = uniq[np.argsort(first, kind="stable")]               # by first use: piece by piece
    vpiece = piece[faces][np.sort(first) // 3]
    nv = np.bincount(vpiece, minlength=P)
    vert_start = np.concatenate([[0], np.cumsum(nv)])
    vrank = np.empty(n, np.int64)
    vrank[verts] = np.arange(len(verts)) - vert_start[vpiece]
    local = vrank[F[faces]]                                       # each piece's faces in local numbers
    lab = np.zeros(m, np.int64) if labels is None else np.asarray(labels, dtype=np.int64)[faces]
    alone = np.zeros(P, bool)
    if pinch_keys is not None:
        pk = np.asarray(pinch_keys)[verts]
        alone[np.unique(vpiece[pk >= 0])] = True
    original, scale = np.arange(P), np.ones(P)
    key = np.column_stack([nf, nv])
    _, group = np.unique(key, axis=0, return_inverse=True)
    group = group.ravel()
    group[alone] = -1
    by = np.argsort(group, kind="stable")
    cut = np.flatnonzero(np.diff(group[by])) + 1
    for members in pieces(by, cut):                               # one per size of piece
        if len(members) < 2 or group[members[0]] < 0:
            continue
        fs = int(nf[members[0]])
        rows = face_start[members][:, None] + np.arange(fs)
        pattern = np.concatenate([local[rows].reshape(len(members), -1), lab[rows]], axis=1)
        _, pat = np.unique(pattern, axis=0, return_inverse=True)
        pat = pat.ravel()
        for t in np.unique(pat):                                  # one per pattern of faces
            same = members[pat == t]
            if len(same) > 1:
                _match(V, verts, vert_start, same, original, scale)
    if np.all(original == np.arange(P)):
        return None
    return Instances(piece, faces, face_start, verts, vert_start, original, scale, F)


def _match(V, verts, vert_start, same, original, scale):
    """Among pieces ``same`` (one pattern of faces), mark every piece that is the first unmatched one
    turned, scaled and moved as its copy (``original``, ``scale``), up to MAX_ORIGINALS first ones."""
    k = int(vert_start[same[0] + 1] - vert_start[same[0]])
    X = V[verts[vert_start[same][:, None] + np.arange(k)]]        # (pieces, k, 3) in local order
    reach = np.abs(X).max(axis=(1, 2))
    X = X - X.mean(axis=1, keepdims=True)
    size = np.sqrt((X * X).sum(axis=2).max(axis=1))
    left = np.flatnonzero(size > 0)
    reach[left] /= size[left]                                     # float32 rounding, in units of the size
    for _ in range(MAX_ORIGINALS):                                # one per original tried
        if len(left) < 2:
            return
        o, rest = left[0], left[1:]
        A, B = X[o] / size[o], X[rest] / size[rest][:, None, None]
        # Kabsch: the proper rotation R with B ~ A R^T (each piece scaled to unit size)
        U, _, Vt = np.linalg.svd(np.einsum("ki,pkj->pij", A, B))
        d = np.sign(np.linalg.det(np.einsum("pji,pkj->pik", Vt, U)))
        D = np.ones((len(rest), 3))
        D[:, 2] = d
        R = np.einsum("pji,pj,pkj->pik", Vt, D, U)                # V diag(1, 1, d) U^T
        err = np.abs(B - np.einsum("kj,pij->pki", A, R)).max(axis=(1, 2))
        near = err <= REL_TOL + STORED_ROUNDING * (reach[o] + reach[rest])
        hit = rest[near]
        original[same[hit]] = same[o]
        scale[same[hit]] = size[hit] / size[o]
        left = rest[~near]


@dataclasses.dataclass
class Plan:
    """What the copies get once the originals are charted (:func:`chart_originals`)."""

    named: list          # the piece of each chart make_charts returned (the solve's records name them)
    made_for: dict       # {original piece: [(instance number, scale) of each copy]}
    charts: int          # charts the copies will have before the solve's splits


def chart_originals(inst: Instances, V: np.ndarray, labels: np.ndarray | None, pinch_keys: np.ndarray | None,
                    make: Callable) -> tuple[list[Chart], list, dict, Plan]:
    """``make(V, F, labels, pinch_keys=...)`` (make_charts) on the mesh of originals: its charts in the
    mesh's numbering, their starts, its log with every copy's records, and the :class:`Plan`."""
    from uvbake.mesh.charts import chart_numbers

    Vr, Fr, lab, keys, kept, vmap = inst.reduced(V, labels, pinch_keys)
    charts, starts, log = make(Vr, Fr, lab, pinch_keys=keys)
    inst.charted(charts, kept, vmap)
    # the charting's records name the pieces split_charts numbered (then their parts)
    number = chart_numbers(Fr, len(Vr), np.zeros(len(Fr), np.int64) if lab is None else np.asarray(lab))
    first = np.full(int(number.max()) + 1, len(Fr))
    np.minimum.at(first, number, np.arange(len(Fr)))
    made = inst.made_for()
    log = dict(log, **{k: copy_records(log[k], [int(p) for p in inst.piece[kept[first]]], made)
                       for k in ("cuts", "budget_cuts", "over_budget")})
    named = inst.pieces_of(charts)
    return charts, starts, log, Plan(named, made, sum(len(made.get(p, ())) for p in named))


def add_copies(inst: Instances, plan: Plan, V: np.ndarray, charts: list[Chart], results: list,
               splits: list) -> tuple[list[Chart], list, list]:
    """After the originals' solve: the charts and results with every copy's charts appended, each with
    its original's map (the pipeline's density equalisation scales it) and solver record (time_s 0,
    ``instance_of`` naming the original), and the solve's split records made for every copy."""
    new, made = inst.charts_of_copies(V, charts)
    copied = [dataclasses.replace(results[i], uv=np.array(results[i].uv, dtype=np.float64), time_s=0.0,
                                  extra=dict(results[i].extra or {}, instance_of=charts[i].name))
              for i, _, _ in made]
    return charts + new, results + copied, copy_records(splits, plan.named, plan.made_for)


_NUMBER = re.compile(r"chart (\d+)")


def copy_records(records: list, pieces_of: list, made_for: dict, key: str = "chart") -> list:
    """``records`` (log entries naming charts) with one copy per instance of the piece each names:
    ``pieces_of[i]`` is the piece of the chart numbered i in the names' numbering, ``made_for[p]`` the
    (instance number, scale) of each copy of piece p. A copy names its charts with " (instance k)"
    and scales its seam length."""
    out = []
    for rec in records:                                # one per record
        name = rec.get(key) if key in rec else (rec.get("merged") or [None])[0]
        hit = _NUMBER.match(name) if isinstance(name, str) else None
        if hit is None or int(hit.group(1)) >= len(pieces_of):
            continue
        for k, s in made_for.get(pieces_of[int(hit.group(1))], ()):
            new = dict(rec)
            if key in rec:
                new[key] = f"{rec[key]} (instance {k})"
            if "merged" in rec:
                new["merged"] = [f"{x} (instance {k})" for x in rec["merged"]]
            if "seam_length" in rec:
                new["seam_length"] = float(rec["seam_length"]) * s
            out.append(new)
    return records + out
