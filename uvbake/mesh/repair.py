"""Mesh repair: turn what reconstruction produces into manifold, consistently oriented charts' input.

    res = repair(V, F)
    res.V, res.F                  # repaired mesh
    res.face_index                # (m',) input triangle of every output triangle (labels follow it)
    res.vertex_index              # (n',) input vertex of every output vertex (colours follow it)
    res.actions, res.warnings     # what was done (JSON-ready) and one-line warnings

The steps, in order (each vectorised over triangles, half-edges and corners):

1. drop triangles touching a vertex with NaN or infinite coordinates;
2. weld duplicated boundary vertices (positions within ``weld_tol`` x mean edge length) where they
   *zip* boundary edges: two boundary edges whose ends coincide become one interior edge. Welds
   that would create a collapsed triangle, a non-manifold edge or a bowtie vertex are undone, so
   touching-but-separate parts and the copies made by steps 5-6 are never glued back;
3. drop degenerate triangles (a repeated vertex, or twice the area <= 1e-12 x longest edge², the
   criterion of :func:`uvbake.mesh.charts.check_chart`);
4. drop duplicated triangles (same vertex set, either orientation; the first is kept);
5. non-manifold edges (more than two triangles): the two triangles that are consistently oriented
   and best aligned stay joined, the others are detached by copying the edge's vertices;
6. non-manifold (bowtie) vertices: one copy of the vertex per edge-connected fan (the largest fan
   keeps the original index); with face labels, also a vertex where one label's triangles form
   several fans (its region touches itself there: a chart never spans two labels, so each label's
   region must be manifold on its own): every fan of that label there but its largest gets a copy;
7. consistent winding per connected piece: a BFS spanning tree of the dual graph gives each triangle's
   flip parity (pointer jumping, no Python loop); the orientation of the majority is kept. A
   non-orientable piece (Moebius strip) is cut along the edges where the parity disagrees and
   re-oriented; if that does not settle it an :class:`InputError` names the triangles;
8. drop pieces with fewer than ``min_component_faces`` triangles (specks; never the largest piece);
9. drop unreferenced vertices.

The steps run again on their own output until a pass changes nothing (at most 4 passes), so
``repair`` is idempotent: repairing a repaired mesh returns it unchanged with no actions, and a clean
mesh comes back with equal arrays.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike
from scipy.sparse.csgraph import breadth_first_order

from uvbake.errors import InputError
from uvbake.mesh.arrays import _list, unique_sorted
from uvbake.mesh.cut import _corner_fans
from uvbake.mesh.graph import components
from uvbake.mesh.topology import nonmanifold_vertices

__all__ = ["repair", "RepairResult"]

MAX_PASSES = 4


@dataclass
class RepairResult:
    """A repaired mesh and what was done to it.

    Attributes
    ----------
    V : (n',3) float64 array      repaired vertices
    F : (m',3) int64 array        repaired triangles
    face_index : (m',) int array  input triangle of each output triangle
    vertex_index : (n',) int array  input vertex of each output vertex (copies share their original)
    actions : list of dict        ``{"kind", "count", "examples", ...}``, JSON-ready
    warnings : list of str        one line each
    """

    V: np.ndarray
    F: np.ndarray
    face_index: np.ndarray
    vertex_index: np.ndarray
    actions: list = field(default_factory=list)
    warnings: list = field(default_factory=list)

    @property
    def changed(self) -> bool:
        return bool(self.actions)

    @property
    def welded(self) -> bool:
        """Coincident vertices were welded (step 2)."""
        return any(a["kind"] == "weld_vertices" for a in self.actions)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (no arrays but the counts)."""
        return {
            "n_vertices": int(len(self.V)),
            "n_faces": int(len(self.F)),
            "n_input_vertices": int(self.vertex_index.max() + 1) if len(self.vertex_index) else 0,
            "actions": self.actions,
            "warnings": list(self.warnings),
        }


def _ex(ids, limit=5):
    return [int(i) for i in np.asarray(ids).ravel()[:limit]]


def _edge_keys(F, n):
    he = F[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    return he, np.minimum(he[:, 0], he[:, 1]) * n + np.maximum(he[:, 0], he[:, 1])


def _mean_edge(V, F):
    if len(F) == 0:
        return 1.0
    X = V[F]
    e = np.linalg.norm(X[:, [1, 2, 0]] - X, axis=2)
    s = float(np.mean(e))
    return s if s > 0 else 1.0


# ------------------------------------------------------------------------------------------- steps
def _weld(V, F, weld_tol):
    """Representative vertex (n,) after zipping coincident boundary edges (identity where none)."""
    from scipy.spatial import cKDTree

    n = len(V)
    rep = np.arange(n)
    he, key = _edge_keys(F, n)
    _, inv, cnt = np.unique(key, return_inverse=True, return_counts=True)
    bhe = he[cnt[inv] == 1]
    if len(bhe) < 2:
        return rep
    bv = unique_sorted(bhe)
    tol = weld_tol * _mean_edge(V, F)
    # clusters of boundary vertices at (nearly) the same position
    _, first, ex_inv = np.unique(V[bv], axis=0, return_index=True, return_inverse=True)
    rows, cols = [np.arange(len(bv))], [first[ex_inv.ravel()]]
    if tol > 0:
        pairs = cKDTree(V[bv]).query_pairs(r=tol, output_type="ndarray")
        rows.append(pairs[:, 0])
        cols.append(pairs[:, 1])
    rows, cols = np.concatenate(rows), np.concatenate(cols)
    _, cl = components(len(bv), rows, cols)
    if cl.max() + 1 == len(bv):
        return rep
    cid = np.arange(n) + (cl.max() + 1)
    cid[bv] = cl                                    # cluster id per vertex (singletons elsewhere)
    cu, cv = cid[bhe[:, 0]], cid[bhe[:, 1]]
    ckey = np.minimum(cu, cv) * (cid.max() + 1) + np.maximum(cu, cv)
    order = np.argsort(ckey, kind="stable")
    ks = ckey[order]
    uk, start, kc = np.unique(ks, return_index=True, return_counts=True)
    zip_groups = np.flatnonzero((kc == 2) & (uk // (cid.max() + 1) != uk % (cid.max() + 1)))
    if len(zip_groups) == 0:
        return rep
    e1, e2 = bhe[order[start[zip_groups]]], bhe[order[start[zip_groups] + 1]]
    # match ends by cluster: e1[0] with whichever end of e2 is in its cluster
    flip = cid[e2[:, 0]] != cid[e1[:, 0]]
    e2 = np.where(flip[:, None], e2[:, ::-1], e2)
    a = np.concatenate([e1[:, 0], e1[:, 1]])
    b = np.concatenate([e2[:, 0], e2[:, 1]])
    keep = a != b
    a, b = a[keep], b[keep]
    if len(a) == 0:
        return rep
    _, grp = components(n, a, b)
    welded = np.zeros(n, bool)
    welded[a] = welded[b] = True
    root = np.full(grp.max() + 1, n)
    np.minimum.at(root, grp[welded], np.flatnonzero(welded))
    rep = np.where(welded, root[grp], np.arange(n))
    # undo welds that would collapse a triangle, make a non-manifold edge or a bowtie vertex
    bow0 = set(nonmanifold_vertices(F, n).tolist())
    for _ in range(8):
        G = rep[F]
        bad_v = []
        rpt = (G[:, 0] == G[:, 1]) | (G[:, 1] == G[:, 2]) | (G[:, 2] == G[:, 0])
        bad_v.append(G[rpt].ravel())
        gh, gk = _edge_keys(G, n)
        uk2, inv2, c2 = np.unique(gk, return_inverse=True, return_counts=True)
        _, k0 = _edge_keys(F, n)
        _, inv0, c0 = np.unique(k0, return_inverse=True, return_counts=True)
        new_nm = (c2[inv2] > 2) & (c0[inv0] <= 2)
        bad_v.append(gh[new_nm].ravel())
        bow = nonmanifold_vertices(G[~rpt], n)
        bad_v.append(np.array([v for v in bow.tolist() if v not in bow0], dtype=np.int64))
        bad_v = np.concatenate(bad_v)
        undo_groups = unique_sorted(grp[welded & np.isin(rep, bad_v)])
        if len(undo_groups) == 0:
            break
        back = welded & np.isin(grp, undo_groups)
        rep[back] = np.flatnonzero(back)
        welded &= ~back
    return rep


def _nonmanifold(V, F, n):
    """Split non-manifold edges and bowtie vertices; returns (vertex_of_corner (3m,), nm_edges, bowties)."""
    he, key = _edge_keys(F, n)
    order = np.argsort(key, kind="stable")
    ks = key[order]
    uk, start, cnt = np.unique(ks, return_index=True, return_counts=True)
    # pairs of half-edges to join: every manifold edge, and the best pair of every non-manifold one
    two = cnt == 2
    ji, jj = [order[start[two]]], [order[start[two] + 1]]
    nm = np.flatnonzero(cnt > 2)
    nm_edges = np.stack([uk[nm] // n, uk[nm] % n], axis=1)
    if len(nm):
        c = cnt[nm]
        cmax = int(c.max())
        aa, bb = np.triu_indices(cmax, 1)
        g = np.repeat(np.arange(len(nm)), len(aa))
        pa, pb = np.tile(aa, len(nm)), np.tile(bb, len(nm))
        ok = pb < c[g]
        g, pa, pb = g[ok], pa[ok], pb[ok]
        hi, hj = order[start[nm][g] + pa], order[start[nm][g] + pb]
        X = V[F]
        nrm = np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0])
        nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-300)
        consistent = he[hi, 0] == he[hj, 1]
        dot = np.einsum("ij,ij->i", nrm[hi // 3], nrm[hj // 3])
        score = np.where(consistent, dot, -dot) + np.where(consistent, 0.5, 0.0)
        o = np.lexsort((-score, g))
        firsts = o[np.concatenate([[True], g[o][1:] != g[o][:-1]])]
        ji.append(hi[firsts])
        jj.append(hj[firsts])
    ji, jj = np.concatenate(ji), np.concatenate(jj)
    fan = _corner_fans(F, n, ji, jj)
    return fan, nm_edges


def _vertices_per_fan(F, n, fan):
    """New corner -> vertex map: one vertex per (vertex, fan); the largest fan keeps the index."""
    m = len(F)
    vc = F.ravel()
    nf = fan.max() + 1
    size = np.bincount(fan, minlength=nf)
    fan_corner = np.full(nf, 3 * m)
    np.minimum.at(fan_corner, fan, np.arange(3 * m))
    fan_v = vc[fan_corner]
    o = np.lexsort((fan_corner, -size, fan_v))
    is_first = np.concatenate([[True], fan_v[o][1:] != fan_v[o][:-1]])
    new_id = np.empty(nf, np.int64)
    new_id[o[is_first]] = fan_v[o[is_first]]
    extra = o[~is_first]
    extra = extra[np.argsort(fan_corner[extra])]        # new vertices in order of first use
    new_id[extra] = n + np.arange(len(extra))
    vmap = np.concatenate([np.arange(n), fan_v[extra]])
    return new_id[fan].reshape(-1, 3), vmap, unique_sorted(fan_v[extra])


def _orient_parity(F, n):
    """Per-triangle flip bit making the winding consistent, and the violated dual edges."""
    m = len(F)
    he, key = _edge_keys(F, n)
    order = np.argsort(key, kind="stable")
    ks = key[order]
    same = np.flatnonzero(ks[1:] == ks[:-1])
    hi, hj = order[same], order[same + 1]
    fi, fj = hi // 3, hj // 3
    need = (he[hi, 0] == he[hj, 0]).astype(np.int8)         # same direction: one of them must flip
    nc, comp = components(m, fi, fj)
    first = np.full(nc, m)
    np.minimum.at(first, comp, np.arange(m))
    # a virtual root joined to one triangle per piece: one BFS covers every piece
    r = np.concatenate([fi, fj, np.full(nc, m)])
    c = np.concatenate([fj, fi, first])
    g = sp.coo_matrix((np.ones(len(r)), (r, c)), shape=(m + 1, m + 1)).tocsr()
    _, pred = breadth_first_order(g, m, directed=True, return_predecessors=True)
    pred = pred[:m].copy()
    pred[pred == m] = np.flatnonzero(pred == m)
    pred[pred < 0] = np.flatnonzero(pred < 0)
    # parity of the tree edge to the parent
    W = sp.coo_matrix((np.concatenate([need, need]) + 1, (np.concatenate([fi, fj]), np.concatenate([fj, fi]))),
                      shape=(m, m)).tocsr()
    par = (np.asarray(W[np.arange(m), pred]).ravel() - 1).clip(0).astype(np.int8)
    par[pred == np.arange(m)] = 0
    p = pred.copy()
    for _ in range(int(np.ceil(np.log2(m + 1))) + 1):       # pointer jumping: O(log depth) rounds
        par = par ^ par[p]
        p = p[p]
    viol = (par[fi] ^ par[fj]) != need
    # keep the majority's orientation in each piece
    nflip = np.bincount(comp, weights=par, minlength=nc)
    size = np.bincount(comp, minlength=nc)
    par = np.where(nflip[comp] * 2 > size[comp], 1 - par, par).astype(bool)
    return par, hi[viol], hj[viol], fi[viol], fj[viol], hi[~viol], hj[~viol]


# -------------------------------------------------------------------------------------------- pass
def soup_like(F: np.ndarray, n: int) -> bool:
    """True when most edges are unshared: a triangle soup (every triangle with its own corners), which
    welding repairs. A mesh the user cut on purpose has few boundary edges and keeps its cuts."""
    if len(F) == 0:
        return False
    _, key = _edge_keys(F, n)
    _, cnt = np.unique(key, return_counts=True)
    return bool(np.count_nonzero(cnt == 1) > 0.5 * len(cnt))


def _one_pass(V: np.ndarray, F: np.ndarray, fidx: np.ndarray, vidx: np.ndarray, min_component_faces: int | None,
              weld_tol: float, weld: bool = True, labels: np.ndarray | None = None
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, list, list]:
    """One pass of every step; fidx/vidx give the input ids (examples are reported in them), ``labels``
    the input's face labels or None.

    Returns V, F, face_index, vertex_index (into the original input), actions, warnings.
    """
    p = RepairResult(V, F, fidx, vidx)                # the mesh as the steps change it
    _drop_nonfinite(p)
    if len(p.F) and weld:
        _weld_step(p, weld_tol)
    for step in (_drop_degenerate, _drop_duplicates, _split_nonmanifold, _orient):
        if len(p.F):
            step(p)
        if step is _split_nonmanifold and labels is not None and len(p.F):
            _split_label_pinches(p, labels[p.face_index])
    if len(p.F):
        _drop_specks(p, min_component_faces)
    _drop_unreferenced(p)
    return p.V, p.F, p.face_index, p.vertex_index, p.actions, p.warnings


def _drop_nonfinite(p: RepairResult) -> None:
    """Step 1: triangles touching a vertex with NaN or infinite coordinates."""
    bad_v = ~np.isfinite(p.V).all(axis=1)
    if bad_v.any():
        drop = bad_v[p.F].any(axis=1)
        if drop.any():
            p.actions.append({"kind": "drop_nonfinite_faces", "count": int(drop.sum()),
                              "examples": _ex(p.face_index[drop]), "vertices": _ex(np.flatnonzero(bad_v))})
            p.warnings.append(f"dropped {_count(drop.sum(), 'triangle')} with NaN/infinite vertex coordinates "
                              f"(triangles {_list(p.face_index[drop])})")
            p.F, p.face_index = p.F[~drop], p.face_index[~drop]


def _weld_step(p: RepairResult, weld_tol: float) -> None:
    """Step 2: weld coincident boundary vertices that zip boundary edges (a soup, or when asked: a cut
    the user made, with duplicated positions along it, is their seam)."""
    n = len(p.V)
    rep = _weld(p.V, p.F, weld_tol)
    moved = np.flatnonzero(rep != np.arange(n))
    if len(moved):
        p.actions.append({"kind": "weld_vertices", "count": int(len(moved)),
                          "examples": [[int(p.vertex_index[a]), int(p.vertex_index[rep[a]])] for a in moved[:5]]})
        p.F = rep[p.F]


def _drop_degenerate(p: RepairResult) -> None:
    """Step 3: degenerate triangles."""
    F = p.F
    X = p.V[F]
    e = np.linalg.norm(X[:, [1, 2, 0]] - X, axis=2)
    dbl = np.linalg.norm(np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0]), axis=1)
    scale = max(float(np.mean(e)), np.finfo(float).tiny)
    rpt = (F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 2] == F[:, 0])
    deg = rpt | (dbl <= 1e-12 * np.maximum(e.max(axis=1), scale) ** 2)
    if deg.any():
        p.actions.append({"kind": "drop_degenerate_faces", "count": int(deg.sum()),
                          "examples": _ex(p.face_index[deg]), "repeated_vertex": int(rpt.sum())})
        p.F, p.face_index = F[~deg], p.face_index[~deg]


def _drop_duplicates(p: RepairResult) -> None:
    """Step 4: duplicated triangles (the first is kept)."""
    _, first = np.unique(np.sort(p.F, axis=1), axis=0, return_index=True)
    if len(first) < len(p.F):
        keep = np.zeros(len(p.F), bool)
        keep[first] = True
        p.actions.append({"kind": "drop_duplicate_faces", "count": int((~keep).sum()),
                          "examples": _ex(p.face_index[~keep])})
        p.F, p.face_index = p.F[keep], p.face_index[keep]


def _split_nonmanifold(p: RepairResult) -> None:
    """Steps 5-6: non-manifold edges and vertices: one vertex per fan."""
    F, n, vidx = p.F, len(p.V), p.vertex_index
    fan, nm_edges = _nonmanifold(p.V, F, n)
    G, vmap, split_v = _vertices_per_fan(F, n, fan)
    if len(vmap) <= n:
        return
    _, key = _edge_keys(G, len(vmap))
    _, cnt = np.unique(key, return_counts=True)
    if (cnt > 2).any():
        # the best-pair rule left some edges shared: detach every triangle at those edges
        fan = _nonmanifold_full_detach(F, n)
        G, vmap, split_v = _vertices_per_fan(F, n, fan)
        _, key = _edge_keys(G, len(vmap))
        uk, cnt = np.unique(key, return_counts=True)
        if (cnt > 2).any():
            nn = len(vmap)
            bad = uk[cnt > 2]
            pairs = ", ".join(f"({vidx[vmap[k // nn]]},{vidx[vmap[k % nn]]})" for k in bad[:5])
            raise InputError(f"repair: {len(bad)} non-manifold edges (input vertices {pairs}) cannot be "
                             "separated by duplicating vertices; remove the triangles around them")
    if len(nm_edges):
        p.actions.append({"kind": "split_nonmanifold_edges", "count": int(len(nm_edges)),
                          "examples": [[int(a), int(b)] for a, b in vidx[nm_edges[:5]]]})
        p.warnings.append(f"split {_count(len(nm_edges), 'non-manifold edge')} (edges "
                       f"{', '.join(f'({a},{b})' for a, b in vidx[nm_edges[:5]])}) by detaching triangles")
    p.actions.append({"kind": "split_nonmanifold_vertices", "count": int(len(vmap) - n),
                      "examples": _ex(vidx[split_v])})
    p.F, p.V, p.vertex_index = G, p.V[vmap], vidx[vmap]


def _split_label_pinches(p: RepairResult, labels: np.ndarray) -> None:
    """Step 6, labelled meshes: at a vertex where a label's triangles form several fans (triangles joined
    only across edges of two triangles of that label), every fan of that label but its largest gets a
    vertex of its own; the vertex's other triangles stay together."""
    F, n = p.F, len(p.V)
    _, key = _edge_keys(F, n)
    order = np.argsort(key, kind="stable")
    _, start, cnt = np.unique(key[order], return_index=True, return_counts=True)
    i, j = order[start[cnt == 2]], order[start[cnt == 2] + 1]
    same = labels[i // 3] == labels[j // 3]
    fan = _corner_fans(F, n, i[same], j[same])
    vc = F.ravel()
    lab = np.repeat(np.unique(labels, return_inverse=True)[1].ravel(), 3)
    first = np.unique(fan, return_index=True)[1]                  # a corner of every fan (fans are 0..k-1)
    size = np.bincount(fan)
    # fans of one (vertex, label), largest first (ties: the lower fan id): all but the first are split off
    o = np.lexsort((np.arange(len(first)), -size, lab[first], vc[first]))
    pair = vc[first][o] * (int(lab.max()) + 1) + lab[first][o]
    off = np.zeros(len(first), bool)
    off[o[1:][pair[1:] == pair[:-1]]] = True
    if not off.any():
        return
    fan = np.unique(np.where(off[fan], fan, len(first) + vc), return_inverse=True)[1].ravel()
    G, vmap, split_v = _vertices_per_fan(F, n, fan)
    p.actions.append({"kind": "split_label_pinches", "count": int(len(vmap) - n),
                      "examples": _ex(p.vertex_index[split_v])})
    p.F, p.V, p.vertex_index = G, p.V[vmap], p.vertex_index[vmap]


def _orient(p: RepairResult) -> None:
    """Step 7: consistent winding (a non-orientable piece is cut where the parity disagrees)."""
    F, n, fidx = p.F, len(p.V), p.face_index
    flip, vhi, vhj, vfi, vfj, okhi, okhj = _orient_parity(F, n)
    if len(vfi):
        # non-orientable: cut along the edges where the parity disagrees, then orient again
        fan = _corner_fans(F, n, okhi, okhj)
        G, vmap, _ = _vertices_per_fan(F, n, fan)
        flip2, _, _, wfi, wfj, _, _ = _orient_parity(G, len(vmap))
        if len(wfi):
            faces = unique_sorted(np.concatenate([fidx[vfi], fidx[vfj]]))
            raise InputError(f"repair: the mesh is not orientable around triangles {_list(faces)} (a "
                             "Moebius-like strip); cut it there or give those triangles their own segment label")
        p.actions.append({"kind": "cut_nonorientable", "count": int(len(vfi)),
                          "examples": _ex(unique_sorted(fidx[vfi]))})
        p.warnings.append(f"cut a non-orientable piece along {_count(len(vfi), 'edge')} (at triangles "
                       f"{_list(unique_sorted(fidx[vfi]))}) so it can be oriented")
        p.F, p.V, p.vertex_index, flip = G, p.V[vmap], p.vertex_index[vmap], flip2
    if flip.any():
        p.actions.append({"kind": "flip_faces", "count": int(flip.sum()), "examples": _ex(fidx[flip])})
        p.F = p.F.copy()
        p.F[flip] = p.F[flip][:, [0, 2, 1]]


def _drop_specks(p: RepairResult, min_component_faces: int | None) -> None:
    """Step 8: pieces with fewer than ``min_component_faces`` triangles (never the largest piece)."""
    F, mm = p.F, len(p.F)
    thr = min(10, mm // 1000) if min_component_faces is None else min_component_faces
    he, key = _edge_keys(F, len(p.V))
    order = np.argsort(key, kind="stable")
    ks = key[order]
    same = np.flatnonzero(ks[1:] == ks[:-1])
    fi, fj = order[same] // 3, order[same + 1] // 3
    nc, comp = components(mm, fi, fj)
    if nc <= 1 or thr <= 1:
        return
    size = np.bincount(comp, minlength=nc)
    small = size < thr
    small[np.argmax(size)] = False
    drop = small[comp]
    if drop.sum() > SPECK_SHARE * mm:
        # not specks but the mesh itself (e.g. a triangle soup): keep every piece as a chart
        drop[:] = False
    if drop.any():
        p.actions.append({"kind": "drop_small_components", "count": int(small.sum()),
                          "faces": int(drop.sum()), "examples": _ex(p.face_index[drop]),
                          "min_component_faces": int(thr)})
        p.warnings.append(f"dropped {_count(small.sum(), 'small piece')} (< {thr} triangles each, "
                          f"{_count(drop.sum(), 'triangle')}: {_list(p.face_index[drop])})")
        p.F, p.face_index = F[~drop], p.face_index[~drop]


def _count(n: int | np.integer, noun: str) -> str:
    """'1 edge', '3 edges': a count and its noun in the number it takes."""
    n = int(n)
    return f"{n} {noun}{'s' * (n != 1)}"


def _drop_unreferenced(p: RepairResult) -> None:
    """Step 9: unreferenced vertices."""
    used = np.zeros(len(p.V), bool)
    used[p.F.ravel()] = True
    if not used.all():
        p.actions.append({"kind": "drop_unreferenced_vertices", "count": int((~used).sum()),
                          "examples": _ex(p.vertex_index[~used])})
        new = np.cumsum(used) - 1
        p.F = new[p.F]
        p.V, p.vertex_index = p.V[used], p.vertex_index[used]


def _nonmanifold_full_detach(F, n):
    """Fans when triangles are joined only across edges of exactly two triangles."""
    _, key = _edge_keys(F, n)
    order = np.argsort(key, kind="stable")
    ks = key[order]
    uk, start, cnt = np.unique(ks, return_index=True, return_counts=True)
    two = cnt == 2
    return _corner_fans(F, n, order[start[two]], order[start[two] + 1])


# ------------------------------------------------------------------------------------------ public
#: Small pieces are dropped as specks only while together they hold at most this share of the triangles.
SPECK_SHARE = 0.01


def repair(V: ArrayLike, F: ArrayLike, *, min_component_faces: int | None = None, weld_tol: float = 1e-9,
           weld: bool | None = None, face_labels: ArrayLike | None = None) -> RepairResult:
    """Repair a triangle mesh so its pieces can become charts (see the module notes for the steps).

    Parameters
    ----------
    V : (n,3) float array           vertex positions (NaN/inf allowed: their triangles are dropped)
    F : (m,3) int array             triangles; indices must lie in [0, n)
    min_component_faces : int, optional
        Pieces with fewer triangles are dropped as specks (never the largest piece, and only while
        they hold at most ``SPECK_SHARE`` (1%) of the triangles: more is the mesh, not noise). Default
        ``min(10, m // 1000)``: nothing on meshes under 2,000 triangles, 10 from 10,000 on.
    weld_tol : float
        Boundary vertices closer than ``weld_tol`` x mean edge length count as one position
        (default 1e-9; 0 welds exactly equal positions only).
    weld : bool or None
        Weld coincident boundary vertices (step 2): None (default) only when the input is soup-like
        (most edges unshared, :func:`soup_like`), True always, False never. Boundaries of a mesh
        the user cut stay cuts unless they ask.
    face_labels : (m,) int array, optional
        Per-triangle segment labels: each label's region is made manifold on its own too (step 6).

    Returns
    -------
    :class:`RepairResult`

    Raises
    ------
    InputError  for malformed arrays (shapes, indices out of range) and for what duplicating
                vertices cannot fix, naming the elements.
    """
    V, F = _check_repair_input(V, F, min_component_faces, weld_tol)
    if weld not in (None, True, False):
        raise InputError(f"repair: weld={weld!r} must be True, False or None (weld only soup-like input)")
    labels = None if face_labels is None else np.asarray(face_labels).reshape(-1)
    if labels is not None and len(labels) != len(F):
        raise InputError(f"repair: face_labels has {len(labels)} entries for {len(F)} triangles; give one per triangle")
    fidx, vidx = np.arange(len(F)), np.arange(len(V))
    actions, warns = [], []
    if weld is None:
        weld = soup_like(F, len(V))                  # decided once, on the input
    for p in range(MAX_PASSES):                       # a handful of passes to a fixed point
        V2, F2, fi, vi, act, w = _one_pass(V, F, fidx, vidx, min_component_faces, weld_tol, weld, labels)
        if not act:
            break
        for a in act:
            a["pass"] = p + 1
        actions += act
        warns += w
        V, F, fidx, vidx = V2, F2, fi, vi
    if len(F) == 0:
        raise InputError("repair: no usable triangles are left (all were NaN, degenerate or specks); "
                         "check the input mesh")
    return RepairResult(V, F, fidx, vidx, actions, warns)


def _check_repair_input(V: ArrayLike, F: ArrayLike, min_component_faces: int | None, weld_tol: float
                        ) -> tuple[np.ndarray, np.ndarray]:
    try:
        V = np.asarray(V, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError("repair: vertices are not numeric; pass V as an (n,3) float array") from None
    F = np.asarray(F)
    if V.ndim != 2 or V.shape[1] != 3:
        raise InputError(f"repair: vertices have shape {V.shape}, expected (n,3); pass 3D positions")
    if F.ndim != 2 or F.shape[1] != 3:
        raise InputError(f"repair: faces have shape {F.shape}, expected (m,3); triangulate the mesh first")
    if not np.issubdtype(F.dtype, np.integer):
        if np.issubdtype(F.dtype, np.floating) and np.all(np.isfinite(F)) and np.all(F == np.round(F)):
            F = F.astype(np.int64)
        else:
            raise InputError("repair: face indices are not integers; pass F as an (m,3) int array")
    F = F.astype(np.int64)
    if len(F) and (F.min() < 0 or F.max() >= len(V)):
        bad = np.flatnonzero((F < 0).any(1) | (F >= len(V)).any(1))
        raise InputError(f"repair: triangles {_list(bad)} index vertices outside 0..{len(V) - 1}; fix the face list")
    if min_component_faces is not None and (int(min_component_faces) != min_component_faces or min_component_faces < 0):
        raise InputError(f"repair: min_component_faces={min_component_faces!r} must be a non-negative integer")
    if not (np.isfinite(weld_tol) and weld_tol >= 0):
        raise InputError(f"repair: weld_tol={weld_tol!r} must be a non-negative number (relative to the mean edge)")
    return V, F
