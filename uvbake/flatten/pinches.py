"""Pinches: a chart's boundary passing twice through one input vertex, held together for the solves.

Repair splits a non-manifold vertex into one copy per fan (:mod:`uvbake.mesh.repair`). When two of
those fans end up in one chart, the chart's boundary passes through the same point of the input
twice: a pinch. The copies are separate vertices, so a free-boundary map (conformal or the paper's
F) may move them apart and fold one fan over the other; the overlap check then cuts the chart in two.
Ball-pivoting surfaces are full of pinches: Open3D's rebuilt knot of ``bench/stress.py`` has 453
split vertices, and 198 of the 200 overlap splits it got came from charts holding two copies of one
(a triangle of each overlapping pair touched a copied vertex).

Here the copies of a pinch are welded for the solve: the map gives the point one UV, so the fans
cannot drift apart and cross there, and the texture is continuous at it. The chart is unchanged
(vertices, triangles, seams); only the solve sees the welded vertex, and every copy gets its UV.

Which vertices are copies of one input vertex is the caller's knowledge, given as ``keys``: one
integer per vertex, equal and non-negative for copies a repair made, negative otherwise. Vertices at
the same position that the input itself kept apart are never welded (the input's own cuts stay cuts),
unless repair welded the input (a soup, or weld=True: then what stays apart is repair's choice), nor
are copies on a boundary edge that has a twin with the same keys (the two sides of a cut).
"""

from __future__ import annotations

import numpy as np

from uvbake.mesh.arrays import unique_sorted
from uvbake.mesh.topology import _edges


def repair_copies(vertex_index: np.ndarray, V: np.ndarray | None = None) -> np.ndarray | None:
    """``keys`` of a repaired mesh: each vertex's input vertex where repair made several copies of it,
    -1 elsewhere; None when repair copied no vertex (``vertex_index``: the repair's input vertex of
    each output vertex). With ``V`` (when repair welded coincident vertices: a soup, or weld=True),
    vertices at exactly one position that the weld left apart (it would have made a bowtie) are copies
    too: such an input's vertex identity carries no intent, repair chose what stays apart."""
    vertex_index = np.asarray(vertex_index, dtype=np.int64)
    if V is not None:
        _, at, count = np.unique(np.asarray(V), axis=0, return_inverse=True, return_counts=True)
        at = at.ravel()
        shared = count[at] > 1
        if shared.any():                               # key a position by its first input vertex
            first = np.full(len(count), np.iinfo(np.int64).max)
            np.minimum.at(first, at, vertex_index)
            vertex_index = np.where(shared, first[at], vertex_index)
    copies = np.bincount(vertex_index)[vertex_index] > 1
    return np.where(copies, vertex_index, -1) if copies.any() else None


def pinch_representatives(keys: np.ndarray, F: np.ndarray, group: np.ndarray | None = None,
                          boundary: np.ndarray | None = None) -> np.ndarray | None:
    """Each vertex's representative (the lowest-index copy of its pinch, else itself), or None when
    there is no pinch. A pinch: boundary vertices with the same non-negative key (and the same
    ``group``, a vertex's chart when several are laid end to end), none of them on a boundary edge
    whose keys repeat on another boundary edge (the sides of a cut). ``boundary``: the boundary
    half-edges of F when the caller has them."""
    keys = np.asarray(keys, dtype=np.int64)
    n = len(keys)
    bnd = _edges(F, n)[2] if boundary is None else boundary
    bv = unique_sorted(bnd)
    bv = bv[keys[bv] >= 0]
    if len(bv) < 2:
        return None
    key = keys[bv] if group is None else np.column_stack([group[bv], keys[bv]])
    order = np.lexsort(key.T[::-1]) if key.ndim == 2 else np.argsort(key, kind="stable")
    k = key[order]
    same = (k[1:] == k[:-1]).reshape(len(k) - 1, -1).all(axis=1)
    if not same.any():
        return None
    cls = np.full(n, -1, np.int64)                     # a class per (group, key) of the boundary copies
    cls[bv[order]] = np.concatenate([[0], np.cumsum(~same)])
    # a boundary edge between copies whose classes repeat on another boundary edge: the sides of a cut
    a, b = cls[bnd[:, 0]], cls[bnd[:, 1]]
    both = (a >= 0) & (b >= 0)
    ekey = np.minimum(a, b)[both] * (cls.max() + 1) + np.maximum(a, b)[both]
    s = np.sort(ekey)
    on_cut = np.isin(ekey, s[1:][s[1:] == s[:-1]])
    size = np.bincount(cls[bv])
    weld = (size[cls[bv]] > 1) & ~np.isin(cls[bv], np.concatenate([a[both][on_cut], b[both][on_cut]]))
    if not weld.any():
        return None
    first = np.full(len(size), n, np.int64)
    np.minimum.at(first, cls[bv[weld]], bv[weld])
    rep = np.arange(n)
    rep[bv[weld]] = first[cls[bv[weld]]]
    closed = _closed_by(rep, bnd, group)
    if closed is not None:         # welding would leave these charts no boundary to flatten: theirs stay apart
        apart = np.isin(np.zeros(n, np.int64) if group is None else group, closed)
        rep[apart] = np.arange(n)[apart]
        if np.array_equal(rep, np.arange(n)):
            return None
    return rep


def _closed_by(rep, bnd, group):
    """The groups (charts; [0] for one) whose every boundary half-edge finds its opposite once the copies
    are welded to ``rep`` (a slit whose two sides are copies, closed up), or None."""
    a, b = rep[bnd[:, 0]], rep[bnd[:, 1]]
    n = len(rep)
    fwd, rev = a * n + b, b * n + a
    left = ~np.isin(fwd, rev)                          # boundary half-edges still without an opposite
    g = np.zeros(n, np.int64) if group is None else np.asarray(group)
    had, has = unique_sorted(g[bnd[:, 0]]), unique_sorted(g[bnd[left, 0]])
    closed = np.setdiff1d(had, has)
    return closed if len(closed) else None


def welded(F: np.ndarray, rep: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(kept, F', back): the vertices the welded mesh keeps (indices into the original ones, in
    order), its triangles on them, and each original vertex's index among them (``uv[back]`` gives
    every copy its pinch's UV)."""
    kept = unique_sorted(rep)
    index = np.full(len(rep), -1, np.int64)
    index[kept] = np.arange(len(kept))
    return kept, index[rep[F]], index[rep]



def pinches_end_to_end(keys: list, Fs: list, sizes: list) -> tuple[np.ndarray | None, np.ndarray]:
    """:func:`pinch_representatives` of several charts laid end to end (``keys``: per chart its
    vertices' pinch keys or None; ``Fs``: its triangles; ``sizes``: its vertex count): (representatives
    over all their vertices, or None; each chart's first vertex in that numbering)."""
    nv = np.asarray(sizes, dtype=np.int64)
    off = np.cumsum(nv) - nv
    if all(k is None for k in keys):
        return None, off
    K = np.concatenate([np.full(n, -1, np.int64) if k is None else np.asarray(k, dtype=np.int64)
                        for n, k in zip(nv, keys)])
    F = np.concatenate([np.asarray(F, dtype=np.int64) + o for F, o in zip(Fs, off)])
    return pinch_representatives(K, F, np.repeat(np.arange(len(Fs)), nv)), off


def pinch_count(keys: list, Fs: list, sizes: list) -> int:
    """Pinches over several charts (as in :func:`pinches_end_to_end`): the points where copies of one
    input vertex are welded, each counted once."""
    rep, _ = pinches_end_to_end(keys, Fs, sizes)
    return 0 if rep is None else len(unique_sorted(rep[rep != np.arange(len(rep))]))
