"""Candidate overlap pairs: grouping, bounding-box pairs, the half-edge topology filter."""

from __future__ import annotations

import numpy as np

from uvbake.mesh.arrays import unique_sorted
from uvbake.validate import budgets


def _row_ids(keys):
    """Ids 0..k-1 of the distinct rows of an (N,c) int64 array (equal rows get equal ids)."""
    order = np.lexsort(keys.T[::-1])
    sk = keys[order]
    new = np.ones(len(sk), bool)
    new[1:] = np.any(sk[1:] != sk[:-1], axis=1)
    ids = np.empty(len(sk), np.int64)
    ids[order] = np.cumsum(new) - 1
    return ids


def _half_edges(vid):
    """Twin matching of the half-edges of the welded mesh (half-edge ``3 f + k`` goes from corner k
    of face f to corner k + 1).

    Returns
    -------
    twin : (3m,) int64
        Index of a half-edge going the opposite way along the same edge, or -1.
    dup : (3m,) bool
        The same directed edge occurs more than once (a fold or a non-manifold edge).
    """
    nv = int(vid.max()) + 1
    src, dst = vid.reshape(-1), vid[:, [1, 2, 0]].reshape(-1)
    key = (np.minimum(src, dst) * nv + np.maximum(src, dst)) * 2 + (src > dst)
    order = np.argsort(key)
    k = key[order]
    same_dir = k[1:] == k[:-1]
    dup = np.zeros(len(k), bool)
    dup[order[1:][same_dir]] = True
    dup[order[:-1][same_dir]] = True
    pair = ((k[1:] >> 1) == (k[:-1] >> 1)) & ~same_dir  # consecutive in sort: p->q then q->p
    pair &= src[order[1:]] != dst[order[1:]]
    twin = np.full(len(k), -1, np.int64)
    twin[order[:-1][pair]] = order[1:][pair]
    twin[order[1:][pair]] = order[:-1][pair]
    return twin, dup


def _edge_components(vid, twin):
    """Chart of every face: connected components of faces joined through twin half-edges.

    Two faces are joined when one has the welded edge p->q and the other q->p, as in an oriented
    mesh. Faces meeting at a point only, or along an edge traversed the same way by both (two charts
    glued by welding, one mirrored), stay apart; a fold keeps its twin edges and stays one chart.

    Parameters
    ----------
    vid : (m,3) int64 welded corner ids
    twin : (3m,) int64 from :func:`_half_edges`

    Returns
    -------
    chart : (m,) int64, charts numbered 0..k-1
    """
    from uvbake.mesh.graph import components

    m = len(vid)
    h = np.flatnonzero(twin >= 0)
    u, v = h // 3, twin[h] // 3
    _, labels = components(m, u, v)
    return np.unique(labels, return_inverse=True)[1].astype(np.int64).reshape(m)


def _group_pairs(group, item, m, group_filter=None, unique=True, budget=None, with_groups=False,
                 max_keys=None):
    """Keys ``i * m + j`` (i < j) of the pairs of items that share a group, chunked to bound memory.

    Parameters
    ----------
    group, item : (n,) int64 arrays (group >= 0, 0 <= item < m)
    m : int
    group_filter : callable, optional
        ``group_filter(i, j, g) -> (k,) bool``: which of the pairs (i, j) found in group g to keep.
    unique : bool
        Sort and de-duplicate the keys (a pair may share several groups).
    budget : int, optional
        Stop after about this many raw pairs (before filtering).
    with_groups : bool
        Also return the group of every key (then keys are neither sorted nor de-duplicated).
    max_keys : int, optional
        Stop once this many pairs passed the filter (the rest of the enumeration is skipped).

    Returns
    -------
    keys : (p,) int64
    groups : (p,) int64, only ``with_groups``
    complete : bool
        False when the budget stopped the enumeration.
    """
    if len(group) < 2:
        z = np.zeros(0, np.int64)
        return (z, z, True) if with_groups else (z, True)
    if int(group.max()) < (1 << 62) // max(m, 1):
        order = np.argsort(group * m + item)
    else:
        order = np.lexsort((item, group))
    g, it = group[order], item[order]
    n = len(g)
    new = np.ones(n, bool)
    new[1:] = g[1:] != g[:-1]
    starts = np.flatnonzero(new)
    ends = np.append(starts[1:], n)
    pos = np.arange(n)
    cnt = ends[np.cumsum(new) - 1] - pos - 1  # partners after each element in its group
    csum = np.cumsum(cnt)
    keys = [np.zeros(0, np.int64)]
    groups = [np.zeros(0, np.int64)]
    complete = budget is None or csum[-1] <= budget
    limit = csum[-1] if complete else max(int(budget), 0)
    s, kept = 0, 0
    while s < n:
        if max_keys is not None and kept >= max_keys:
            complete = False
            break
        base = csum[s - 1] if s else 0
        if base >= limit and not complete:
            break
        e = max(int(np.searchsorted(csum, min(base + budgets.CHUNK, limit), side="right")), s + 1)
        c = cnt[s:e]
        a = np.repeat(pos[s:e], c)
        first = np.cumsum(c) - c
        b = a + 1 + (np.arange(len(a)) - np.repeat(first, c))
        i, j = it[a], it[b]  # i <= j: items are sorted within a group
        ok = i != j
        if group_filter is not None:
            ok &= group_filter(i, j, g[a])
        k = i[ok] * m + j[ok]
        kept += len(k)
        if with_groups:
            groups.append(g[a][ok])
        keys.append(unique_sorted(k) if unique and not with_groups else k)
        s = e
    out = np.concatenate(keys)
    if with_groups:
        return out, np.concatenate(groups), bool(complete)
    return (unique_sorted(out) if unique else np.sort(out)), bool(complete)


def _raw_budget(m):
    """Raw pairs a pass may enumerate for m faces."""
    return max(budgets.MIN_RAW_PAIRS, budgets.RAW_PAIRS_PER_FACE * m)


def corner_boxes(corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each face's box (bmin, bmax), (m,2) each, from its corners (m,3,2): the same values as
    ``corners.min(axis=1)`` and ``max``, 5x faster than numpy's reduction over a 3-long axis."""
    c0, c1, c2 = corners[:, 0], corners[:, 1], corners[:, 2]
    return np.minimum(np.minimum(c0, c1), c2), np.maximum(np.maximum(c0, c1), c2)


def grid_cells(bmin: np.ndarray, bmax: np.ndarray, faces: np.ndarray, widen: float = 1.0) -> tuple | None:
    """The cells of a uniform grid that the boxes [bmin, bmax] of ``faces`` touch: (face, cell key) of
    every touch, each face's lowest cell (k,2) and the grid's rows; None when the boxes span nothing.

    Cells are about as wide as a typical box's geometric mean side (times ``widen``): a sliver's box is
    long and thin, and cells as wide as its long side would hold every sliver lying beside it (measured
    in docs/decisions/atlas-speed.md); they are doubled until there are at most 16 touches a face.
    ``floor`` is monotone, so boxes meeting at a point both touch that point's cell.
    """
    wh = (bmax - bmin)[faces]
    lo = bmin[faces].min(axis=0)
    span = float((bmax[faces].max(axis=0) - lo).max())
    if span == 0.0:
        return None
    cell = max(widen * float(np.median(np.sqrt(wh[:, 0] * wh[:, 1]))), span / 65536.0)
    while True:
        c0 = np.floor((bmin[faces] - lo) / cell).astype(np.int64)
        c1 = np.floor((bmax[faces] - lo) / cell).astype(np.int64)
        ny_cells = c1[:, 1] - c0[:, 1] + 1
        ncell = (c1[:, 0] - c0[:, 0] + 1) * ny_cells
        if ncell.sum() <= 16 * len(faces) + 1024:
            break
        cell *= 2.0
    ny = int(c1[:, 1].max()) + 1
    f = np.repeat(faces, ncell)
    k = np.arange(len(f)) - np.repeat(np.cumsum(ncell) - ncell, ncell)
    nyc = np.repeat(ny_cells, ncell)
    key = (np.repeat(c0[:, 0], ncell) + k // nyc) * ny + np.repeat(c0[:, 1], ncell) + k % nyc
    return f, key, c0, ny


def _bbox_pairs(corners, live, disjoint=None, confirm=None, max_pairs=None):
    """Pairs (i<j) of live faces whose bounding boxes overlap with positive area (and, with
    ``confirm``, that it confirms), enumerated in bounded chunks.

    A uniform grid hashes every box into the cells it touches; a pair is kept only in the cell that
    holds the lower-left corner of the boxes' intersection, so no pair is produced twice. With
    ``confirm`` (the exact overlap test) candidates are decided chunk by chunk and never stored, so
    memory stays bounded however many boxes overlap, and no candidate is ever left undecided.

    Parameters
    ----------
    corners : (m,3,2) float64
    live : (m,) bool
        Faces that take part.
    disjoint : callable, optional
        ``disjoint(i, j) -> (k,) bool``: pairs known to be disjoint, dropped.
    confirm : callable, optional
        ``confirm(i, j) -> (k,) bool``: pairs to keep among the remaining candidates.
    max_pairs : int, optional
        Stop after about this many kept pairs (the layout is then known to be invalid).

    Returns
    -------
    pairs : (p,2) int64
    complete : bool
        False when ``max_pairs`` stopped the enumeration.
    n_candidates : int
        Pairs handed to ``confirm`` (or kept, without it).
    """
    m = len(corners)
    faces = np.flatnonzero(live)
    if len(faces) < 2:
        return np.zeros((0, 2), np.int64), True, 0
    bmin, bmax = corner_boxes(corners)
    grid = grid_cells(bmin, bmax, faces)
    if grid is None:
        return np.zeros((0, 2), np.int64), True, 0
    f, key, c0, ny = grid
    cx = np.zeros(m, np.int64)
    cy = np.zeros(m, np.int64)
    cx[faces], cy[faces] = c0[:, 0], c0[:, 1]
    x0, y0 = np.ascontiguousarray(bmin.T)
    x1, y1 = np.ascontiguousarray(bmax.T)
    n_cand = [0]

    def keep(i, j, g):
        # home cell = cell of the intersection's lower-left corner (floor is monotone)
        ok = np.maximum(cx[i], cx[j]) * ny + np.maximum(cy[i], cy[j]) == g
        idx = np.flatnonzero(ok)
        a, b = i[idx], j[idx]
        strict = (np.maximum(x0[a], x0[b]) < np.minimum(x1[a], x1[b])) & (
            np.maximum(y0[a], y0[b]) < np.minimum(y1[a], y1[b])
        )
        if disjoint is not None:
            s_idx = np.flatnonzero(strict)
            strict[s_idx[disjoint(a[s_idx], b[s_idx])]] = False
        s_idx = np.flatnonzero(strict)
        n_cand[0] += len(s_idx)
        if confirm is not None and len(s_idx):
            strict[s_idx[~confirm(a[s_idx], b[s_idx])]] = False
        ok[idx] = strict
        return ok

    keys, complete = _group_pairs(key, f, m, group_filter=keep, unique=False, max_keys=max_pairs)
    return np.stack([keys // m, keys % m], axis=1), complete, n_cand[0]


def _topology_filter(corners, vid, sign, twin, dup):
    """A test of pairs of faces whose disjointness follows from the mesh around what they share.

    - Two faces sharing a welded edge traversed in opposite directions, with the same non-zero
      orientation, have their third vertices strictly on opposite sides of it.
    - A *safe* vertex has all its faces of the same non-zero orientation, forming one fan (no
      directed edge twice; 0 unmatched incident half-edges, a cycle, or 2, a chain) whose corner
      angles sum to less than 3 pi for a cycle (so winding once, exactly 2 pi) or less than
      2 pi - 1e-6 for a chain. The faces' wedges at that vertex are then disjoint, and each face lies
      inside its wedge, so two faces sharing a safe vertex cannot overlap.

    Parameters
    ----------
    corners : (m,3,2) float64
    vid : (m,3) int64
    sign : (m,) int8 exact orientations
    twin, dup : from :func:`_half_edges`

    Returns
    -------
    disjoint : callable ``(i, j) -> (k,) bool``
    """
    nv = int(vid.max()) + 1
    v = vid.reshape(-1)
    fsign = np.repeat(sign, 3)
    n_inc = np.bincount(v, minlength=nv)
    same = (np.bincount(v[fsign > 0], minlength=nv) == n_inc) | (
        np.bincount(v[fsign < 0], minlength=nv) == n_inc
    )
    src, dst = v, vid[:, [1, 2, 0]].reshape(-1)
    unmatched = twin < 0
    n_unmatched = np.bincount(src[unmatched], minlength=nv) + np.bincount(dst[unmatched], minlength=nv)
    bad = np.zeros(nv, bool)
    bad[src[dup]] = True
    bad[dst[dup]] = True
    u = corners[:, [1, 2, 0]] - corners  # to the next corner
    w = corners[:, [2, 0, 1]] - corners  # to the previous corner
    cross = u[..., 0] * w[..., 1] - u[..., 1] * w[..., 0]
    dot = u[..., 0] * w[..., 0] + u[..., 1] * w[..., 1]
    angle_sum = np.bincount(v, weights=np.arctan2(np.abs(cross), dot).reshape(-1), minlength=nv)
    safe = same & ~bad & (
        ((n_unmatched == 0) & (angle_sum < 3.0 * np.pi))
        | ((n_unmatched == 2) & (angle_sum < 2.0 * np.pi - 1e-6))
    )
    nxt = [1, 2, 0]

    def disjoint(i, j):
        va, vb = vid[i], vid[j]
        consistent = (sign[i] == sign[j]) & (sign[i] != 0)
        out = np.zeros(len(i), bool)
        for k in range(3):
            safe_k = safe[va[:, k]]
            for c in range(3):
                # shared corner a_k == b_c: safe vertex, or edge a_k -> a_k+1 == b_c -> b_c-1
                twin_edge = consistent & (va[:, nxt[k]] == vb[:, (c + 2) % 3])
                out |= (va[:, k] == vb[:, c]) & (safe_k | twin_edge)
        return out

    return disjoint
