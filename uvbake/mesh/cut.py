"""Segmentation: cut charts that cannot be flattened (closed, handles) or flattened badly (flips).

    labels = bisect(V, F)                       # (m,) in {0,1}: a short cut into two balanced parts
    labels = split_where(V, F, bad_faces)       # (m,) in {0,1}: the bad faces go to side 1
    labels = cut_to_disks(V, F)                 # (m,) in 0..k-1: every label a disk with holes
    seam_length(V, F, labels)                   # total 3D length of the edges between labels

Method. Everything works on the dual graph (one node per triangle, one edge per shared mesh edge,
weighted by the shared edge's 3D length). A scalar field over the triangles orders them, and the cut
is the *sweep cut* of that order with the least conductance

    cut length(S) / min(area(S), area(rest)),      S = the k lowest triangles, k in [q m, (1-q) m]

evaluated for every k at once with sorting and cumulative sums. The field is the Fiedler vector of
the dual Laplacian (generalised with the triangle areas as mass, shift-invert Lanczos) for
:func:`bisect`, and a harmonic field (0 on the bad triangles, 1 on the triangles farthest from them)
for :func:`split_where`: both have level sets that run across narrow necks, which is where short
seams are. The two sides are then made valid charts: each keeps its largest edge-connected piece
(stray pieces change side) and every vertex where one side would meet itself in two fans (a
bowtie) hands its smaller fans to the other side; the two repairs alternate until nothing changes.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike
from scipy.sparse.csgraph import dijkstra

from uvbake.errors import ChartError, InputError
from uvbake.mesh.arrays import _list, check_arrays, dense_ranks, triangle_areas, unique_sorted, unit_normals
from uvbake.mesh.graph import components
from uvbake.mesh.topology import face_adjacency, topology

__all__ = ["bisect", "split_where", "cut_to_disks", "seam_length"]

#: Least share of the triangles on either side of a cut (before the validity repairs).
MIN_FRACTION = 0.1


# ------------------------------------------------------------------------------------------ graphs
def _dual_edges(F, n):
    """Pairs of triangles sharing an edge: (fi, fj, ea, eb, hi, hj), see
    :func:`uvbake.mesh.charts.face_adjacency` (ea, eb: the shared edge's vertices)."""
    fi, fj, e, hi, hj = face_adjacency(F, n, return_halfedges=True)
    return fi, fj, e[:, 0], e[:, 1], hi, hj


def _corner_fans(F, n, i, j):
    """Fan label of every corner when triangles are joined only across the half-edge pairs (i, j).

    Parameters
    ----------
    F : (m,3) int array
    n : int                      number of vertices
    i, j : (d,) int arrays       half-edge ids (3 f + k, the half-edge from corner k to k+1) to join

    Returns
    -------
    (3m,) int array: corners with the same label sit at the same vertex in one edge-connected fan.
    """
    m = len(F)
    va = F.ravel()
    nxt = (np.arange(3 * m) // 3) * 3 + (np.arange(3 * m) % 3 + 1) % 3
    # half-edge h runs from corner h to corner nxt[h]; match the corners of i and j by vertex
    same_dir = va[j] == va[i]
    rows = np.concatenate([i, nxt[i]])
    cols = np.concatenate([np.where(same_dir, j, nxt[j]), np.where(same_dir, nxt[j], j)])
    return components(3 * m, rows, cols)[1]


def _edge_lengths(V, ea, eb):
    return np.linalg.norm(V[ea] - V[eb], axis=1)


#: Dihedral angles (between the two triangles' normals) from which an edge starts to be a crease, and
#: is a full one: below the first, a smooth surface's facets, cuts stay shortest in length.
CREASE_START, CREASE_ANGLE = np.radians(20.0), np.radians(60.0)
#: Cost per unit length of cutting a full crease: a valley (concave: shaded and occluded, the seam is
#: hidden) and a ridge (convex: the shading changes there anyway). A flat edge costs its length.
VALLEY_COST, RIDGE_COST = 0.25, 0.5


def seam_costs(V: np.ndarray, F: np.ndarray, fi: np.ndarray, fj: np.ndarray, ea: np.ndarray,
               eb: np.ndarray) -> np.ndarray:
    """Cost of a seam along each shared edge (triangles fi, fj; vertices ea, eb): its 3D length,
    discounted on creases and most on valleys, so that every shortest cut prefers the edges where a
    texture seam shows least. Triangles must be consistently oriented (outward normals on a closed
    surface: a valley is an edge where the neighbour rises above the triangle's plane)."""
    cos, valley = dihedrals(V, F, fi, fj, ea, eb)
    sharp = np.clip((np.arccos(cos) - CREASE_START) / (CREASE_ANGLE - CREASE_START), 0.0, 1.0)
    return _edge_lengths(V, ea, eb) * (1.0 - (1.0 - np.where(valley, VALLEY_COST, RIDGE_COST)) * sharp)


def dihedrals(V: np.ndarray, F: np.ndarray, fi: np.ndarray, fj: np.ndarray, ea: np.ndarray,
              eb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(cos, valley) of each shared edge (triangles fi, fj; vertices ea, eb): the cosine of the angle
    between the two unit normals, and whether fj rises above fi's plane (a concave edge)."""
    nrm = unit_normals(V, F)
    cos = np.clip(np.einsum("ij,ij->i", nrm[fi], nrm[fj]), -1.0, 1.0)
    far = F[fj].sum(axis=1) - ea - eb                   # fj's corner off the shared edge
    return cos, np.einsum("ij,ij->i", nrm[fi], V[far] - V[ea]) > 0


def seam_length(V: ArrayLike, F: ArrayLike, labels: ArrayLike) -> float:
    """Total 3D length of the mesh edges whose two triangles carry different labels.

    Parameters
    ----------
    V : (n,3) float array
    F : (m,3) int array
    labels : (m,) int array

    Returns
    -------
    float
    """
    V, F = check_arrays(V, F)
    labels = np.asarray(labels)
    fi, fj, ea, eb, _, _ = _dual_edges(F, len(V))
    cut = labels[fi] != labels[fj]
    return float(_edge_lengths(V, ea[cut], eb[cut]).sum())


# ------------------------------------------------------------------------------------------ fields
def _laplacian(m, fi, fj, w):
    W = sp.coo_matrix((np.concatenate([w, w]), (np.concatenate([fi, fj]), np.concatenate([fj, fi]))),
                      shape=(m, m)).tocsr()
    return (sp.diags(np.asarray(W.sum(axis=1)).ravel()) - W).tocsc()


def _dense_laplacian(m, fi, fj, w):
    """``_laplacian(m, fi, fj, w).toarray()`` without scipy.sparse's conversions (about 1 ms a call: most
    of a small closed part's cut). Each degree is summed as scipy's row sum sums it (add.reduceat over
    the row's entries by column), so the values are the sparse ones to the bit; a pair of triangles
    sharing two edges takes the sparse path."""
    rows, cols, vals = np.concatenate([fi, fj]), np.concatenate([fj, fi]), np.concatenate([w, w])
    o = np.lexsort((cols, rows))
    rows, cols, vals = rows[o], cols[o], vals[o]
    if len(rows) > 1 and np.any((rows[1:] == rows[:-1]) & (cols[1:] == cols[:-1])):
        return _laplacian(m, fi, fj, w).toarray()
    L = np.zeros((m, m))
    L[rows, cols] = -vals
    if len(rows):                             # each row's sum as scipy's row sum takes it (add.reduceat)
        start = np.flatnonzero(np.r_[True, rows[1:] != rows[:-1]])
        L[rows[start], rows[start]] = np.add.reduceat(vals, start)
    return L


def _bfs_field(m, fi, fj, w, start):
    g = sp.coo_matrix((w, (fi, fj)), shape=(m, m)).tocsr()
    return dijkstra(g, directed=False, indices=start)


def _factor(A):
    """A solve function for the SPD sparse matrix A: CHOLMOD when installed, SuperLU otherwise."""
    from uvbake.flatten.solvers.linalg import cholmod_available

    if cholmod_available():
        from sksparse.cholmod import cholesky

        return cholesky(A.tocsc())
    from scipy.sparse.linalg import splu

    return splu(A.tocsc(), permc_spec="COLAMD").solve


#: Pieces of at most this many triangles get their Fiedler vector from a dense eigensolver (one LAPACK
#: call; LOBPCG's setup cost 9 ms on a 20-triangle closed part, 300 such parts 2.6 s).
DENSE_FIEDLER = 256


def _fiedler(m, fi, fj, w, mass):
    """The dual Laplacian's Fiedler vector (L x = lambda M x, M = diag(mass)), shape (m,).

    LOBPCG on two vectors, M-orthogonal to the constants, preconditioned with an exact factorisation
    of L + 1e-3 M (10-15 solves on 40k triangles); ARPACK shift-invert if it fails, and a graph
    distance field from a pseudo-peripheral triangle as the last resort.
    """
    import warnings

    from scipy.sparse.linalg import LinearOperator, eigsh, lobpcg

    if 8 < m <= DENSE_FIEDLER:                      # small pieces: the dense generalized eigenproblem
        from scipy.linalg import eigh

        L = _dense_laplacian(m, fi, fj, w / w.mean())
        x = eigh(L, np.diag(mass / mass.mean()), subset_by_index=[1, 1])[1][:, 0]
        if np.all(np.isfinite(x)) and np.ptp(x) > 0:
            # LAPACK's sign is its own (it can differ between CPUs' kernels): the largest entry positive
            return x if x[np.argmax(np.abs(x))] > 0 else -x
    elif m > 8:
        L = _laplacian(m, fi, fj, w / w.mean())
        M = sp.diags(mass / mass.mean()).tocsc()
        try:
            solve = _factor(L + 1e-3 * M)              # both factors solve a whole block at once
            P = LinearOperator((m, m), matvec=solve, matmat=solve, dtype=np.float64)
            X0 = np.random.default_rng(0).standard_normal((m, 2))
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                vals, vecs = lobpcg(L, X0, B=M, M=P, Y=np.ones((m, 1)), largest=False, tol=1e-5, maxiter=60)
            x = vecs[:, np.argmin(vals)]
            if np.all(np.isfinite(x)) and np.ptp(x) > 0:
                return x
        except Exception:                    # noqa: BLE001 - any numerical failure falls through
            pass
        try:
            v0 = np.random.default_rng(0).uniform(0.5, 1.5, m)
            vals, vecs = eigsh(L, k=2, M=M, sigma=-1e-4, which="LM", v0=v0, tol=1e-6)
            x = vecs[:, np.argmax(vals)]
            if np.all(np.isfinite(x)) and np.ptp(x) > 0:
                return x
        except Exception:                    # noqa: BLE001
            pass
    # fallback: graph distance from a pseudo-peripheral triangle (double sweep)
    far = int(np.argmax(_bfs_field(m, fi, fj, w, 0)))
    return _bfs_field(m, fi, fj, w, far)


def _harmonic(m, fi, fj, w, seeds):
    """Harmonic field on the dual graph: 0 on `seeds`, 1 on the triangles farthest from them."""
    d = dijkstra(sp.coo_matrix((w, (fi, fj)), shape=(m, m)).tocsr(), directed=False,
                 indices=seeds, min_only=True)
    far = d >= 0.8 * d.max()
    fixed = np.zeros(m, bool)
    fixed[seeds] = True
    fixed |= far
    u = np.where(far, 1.0, 0.0)
    free = np.flatnonzero(~fixed)
    if len(free):
        L = _laplacian(m, fi, fj, w / w.mean()).tocsr()
        A = L[free][:, free].tocsc()
        b = -(L[free][:, np.flatnonzero(fixed)] @ u[fixed])
        u[free] = _factor(A)(b)
    # break ties by distance so the sweep order is total and grows outwards from the seeds
    return u + 1e-9 * d / max(d.max(), 1e-300)


# ------------------------------------------------------------------------------------------- sweep
def prefix_cuts(field: np.ndarray, fi: np.ndarray, fj: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Triangles in ``field``'s order, and the seam length cut[k] (k = 0..m) of every prefix of k of
    them: the total weight ``w`` of the dual edges (fi, fj) with exactly one end in the prefix."""
    m = len(field)
    order = np.argsort(field, kind="stable")
    rank = np.empty(m, np.int64)
    rank[order] = np.arange(m)
    lo, hi = np.minimum(rank[fi], rank[fj]), np.maximum(rank[fi], rank[fj])
    # the dual edge is cut by prefixes of size k with lo < k <= hi
    diff = np.zeros(m + 2)
    np.add.at(diff, lo + 1, w)
    np.add.at(diff, hi + 1, -w)
    return order, np.cumsum(diff)[: m + 1]


def _sweep(field, fi, fj, w, mass, min_fraction, max_fraction=None):
    """Labels (m,) in {0,1}: side 0 = the prefix of `field`'s order with the least conductance."""
    m = len(field)
    order, cut = prefix_cuts(field, fi, fj, w)
    a = np.concatenate([[0.0], np.cumsum(mass[order])])
    bal = np.minimum(a, a[-1] - a)
    k = np.arange(m + 1)
    kmin = max(1, int(np.ceil(min_fraction * m)))
    kmax = min(m - 1, int(np.floor((1 - min_fraction if max_fraction is None else max_fraction) * m)))
    if kmin > kmax:
        kmin, kmax = 1, m - 1
    ok = (k >= kmin) & (k <= kmax) & (bal > 0)
    score = np.where(ok, cut / np.where(bal > 0, bal, 1.0), np.inf)
    best = int(np.argmin(score))
    labels = np.ones(m, np.int64)
    labels[order[:best]] = 0
    return labels


def _make_valid(F, n, labels, fi, fj, hi, hj, max_rounds=100):
    """Make both sides edge-connected and free of bowtie vertices (in place; returns labels, ok)."""
    m = len(F)
    for _ in range(max_rounds):
        changed = False
        # 1. each side keeps its largest edge-connected piece; stray pieces change side
        same = labels[fi] == labels[fj]
        nc, comp = components(m, fi[same], fj[same])
        if nc > 2:
            size = np.bincount(comp, minlength=nc)
            first = np.full(nc, m)
            np.minimum.at(first, comp, np.arange(m))
            side = labels[first]
            keep = np.zeros(nc, bool)
            for s in (0, 1):                          # two sides, not a loop over triangles
                cs = np.flatnonzero(side == s)
                if len(cs):
                    keep[cs[np.argmax(size[cs])]] = True
            flip = ~keep[comp]
            if flip.any():
                labels[flip] = 1 - labels[flip]
                changed = True
        # 2. bowties: a vertex where one side has several fans hands all but its largest to the other
        same = labels[fi] == labels[fj]
        fan = _corner_fans(F, n, hi[same], hj[same])
        nf = fan.max() + 1
        fan_size = np.bincount(fan, minlength=nf)
        corner = np.arange(3 * m)
        fan_corner = np.full(nf, 3 * m)
        np.minimum.at(fan_corner, fan, corner)
        fan_v = F.ravel()[fan_corner]
        fan_s = labels[fan_corner // 3]
        key = fan_v * 2 + fan_s
        o = np.lexsort((-fan_size, key))
        ko = key[o]
        extra = o[np.concatenate([[False], ko[1:] == ko[:-1]])]   # every fan but the largest per key
        if len(extra):
            move = np.zeros(nf, bool)
            move[extra] = True
            faces = unique_sorted(corner[move[fan]] // 3)
            labels[faces] = 1 - labels[faces]
            changed = True
        if not changed:
            return labels, bool(labels.min() == 0 and labels.max() == 1)
    return labels, False


def _prepare(V: ArrayLike, F: ArrayLike, where: str) -> tuple[np.ndarray, ...]:
    V, F = check_arrays(V, F, where=where)
    m = len(F)
    if m < 2:
        raise InputError(f"{where}: a chart of {m} triangle cannot be split; pass at least two triangles")
    n = len(V)
    fi, fj, ea, eb, hi, hj = _dual_edges(F, n)
    nc, comp = components(m, fi, fj)
    if nc > 1:
        other = np.flatnonzero(comp != comp[0])
        raise InputError(f"{where}: the chart has {nc} edge-connected pieces (triangles {_list(other)} are "
                         "not connected to triangle 0); split it with uvbake.split_charts first")
    w = seam_costs(V, F, fi, fj, ea, eb)
    w = np.maximum(w, 1e-12 * max(w.max(initial=0.0), 1e-300))
    return V, F, fi, fj, w, hi, hj


def _mass(V, F, weights, where):
    if weights is None:
        mass = triangle_areas(V, F)
        if not mass.sum() > 0:
            mass = np.ones(len(F))
        return np.maximum(mass, 1e-12 * mass.max())
    mass = np.asarray(weights, dtype=np.float64)
    if mass.shape != (len(F),) or not np.all(np.isfinite(mass)) or (mass < 0).any() or not mass.sum() > 0:
        raise InputError(f"{where}: weights have shape {mass.shape} or hold negative/NaN values; pass one "
                         f"non-negative number per triangle ({len(F)})")
    return np.maximum(mass, 1e-12 * mass.max())


# ------------------------------------------------------------------------------------------ public
#: Quantiles of the field whose level sets bisect tries, in order, when its sweep's and the median's
#: sides cannot both be made valid (a side meeting itself at a vertex: a holey torus's label region).
FALLBACK_LEVELS = (0.4, 0.6, 0.3, 0.7, 0.2, 0.8)


def bisect(V: ArrayLike, F: ArrayLike, *, weights: ArrayLike | None = None, seed_faces: ArrayLike | None = None,
           min_fraction: float = MIN_FRACTION) -> np.ndarray:
    """Split one edge-connected chart into two edge-connected parts along a short cut.

    Parameters
    ----------
    V : (n,3) float array
    F : (m,3) int array             one edge-connected chart (m >= 2)
    weights : (m,) float array, optional
        What the cut balances: each side gets at least `min_fraction` of the triangles and the cut
        minimises ``cut length / min(weight of side 0, weight of side 1)``. Default: triangle areas.
    seed_faces : (s,) int array, optional
        Triangles to cut away: they start on side 1, the triangles farthest from them on side 0, and
        the cut follows a level set of the harmonic field between the two. Default: a spectral cut
        (the Fiedler vector of the dual graph's Laplacian).
    min_fraction : float
        Least share of the triangles on either side before the validity repairs (default 0.1).

    Returns
    -------
    (m,) int array of labels in {0, 1}; both sides are non-empty and edge-connected and no vertex
    joins two fans of one side, so each side is a valid chart (:func:`uvbake.mesh.charts.check_chart`)
    whenever the input is one. When seeds are given, side 1 is the side holding most of them.
    """
    V, F, fi, fj, w, hi, hj = _prepare(V, F, "bisect")
    m = len(F)
    mass = _mass(V, F, weights, "bisect")
    if seed_faces is None:
        field = _fiedler(m, fi, fj, w, mass)
    else:
        seeds = unique_sorted(np.asarray(seed_faces, dtype=np.int64).ravel())
        if len(seeds) == 0 or seeds.min() < 0 or seeds.max() >= m:
            raise InputError(f"bisect: seed_faces must be triangle indices in 0..{m - 1} (got {_list(seeds)})")
        if len(seeds) == m:
            field = _fiedler(m, fi, fj, w, mass)
            seeds = None  # type: ignore[assignment]  # (no side to keep: every triangle is a seed)
        else:
            field = _harmonic(m, fi, fj, w, seeds)
    # a seeded cut keeps the seeds' side (the sweep's prefix) at most half of the chart
    labels = _sweep(field, fi, fj, w, mass, min_fraction, None if seed_faces is None else 0.5)
    labels, ok = _make_valid(F, len(V), labels, fi, fj, hi, hj)
    if not ok:
        # the repairs emptied a side or did not settle: fall back to the median of the field
        labels = (field > np.median(field)).astype(np.int64)
        if labels.min() == labels.max():
            labels = (np.argsort(np.argsort(field, kind="stable")) >= m // 2).astype(np.int64)
        labels, ok = _make_valid(F, len(V), labels, fi, fj, hi, hj)
        for q in FALLBACK_LEVELS if not ok else ():     # other level sets, nearest the median first
            labels, ok = _make_valid(F, len(V), (field > np.quantile(field, q)).astype(np.int64), fi, fj, hi, hj)
            if ok:
                break
        if not ok:
            raise ChartError(f"bisect: could not cut the chart of {m} triangles into two valid parts; "
                             "repair the mesh (uvbake.mesh.repair.repair) or give it segment labels")
    if seed_faces is not None and seeds is not None:
        on1 = labels[seeds].mean()
        if on1 < 0.5:
            labels = 1 - labels
    elif seed_faces is None:
        # deterministic orientation: side 0 holds triangle 0
        if labels[0] == 1:
            labels = 1 - labels
    return labels


def split_where(V: ArrayLike, F: ArrayLike, bad_faces: ArrayLike, *, min_fraction: float = MIN_FRACTION) -> np.ndarray:
    """Cut a chart so that its bad triangles (flipped, overlapping) go to one side along a short cut.

    Parameters
    ----------
    V : (n,3) float array
    F : (m,3) int array             one edge-connected chart (m >= 2)
    bad_faces : (b,) int array      triangle indices (or an (m,) bool mask)
    min_fraction : float            least share of the triangles on either side before the repairs

    Returns
    -------
    (m,) int array of labels in {0, 1}: side 1 holds most of the bad triangles (all of them unless
    they lie in several far-apart clusters; the pipeline splits again then). Both sides are
    non-empty, edge-connected and valid charts whenever the input is one. With no bad triangles, or
    with bad triangles almost everywhere, this is :func:`bisect`.
    """
    V, F = check_arrays(V, F, where="split_where")
    m = len(F)
    bad = np.asarray(bad_faces)
    if bad.dtype == bool:
        if bad.shape != (m,):
            raise InputError(f"split_where: the bad-triangle mask has shape {bad.shape}; pass one bool per "
                             f"triangle ({m}) or triangle indices")
        bad = np.flatnonzero(bad)
    bad = unique_sorted(bad.astype(np.int64).ravel())
    if len(bad) and (bad.min() < 0 or bad.max() >= m):
        raise InputError(f"split_where: bad triangles {_list(bad[(bad < 0) | (bad >= m)])} are outside "
                         f"0..{m - 1}; pass indices into this chart's triangles")
    if len(bad) == 0 or len(bad) >= (1 - min_fraction) * m:
        return bisect(V, F, min_fraction=min_fraction)
    try:
        return bisect(V, F, seed_faces=bad, min_fraction=min_fraction)
    except ChartError:
        return bisect(V, F, min_fraction=min_fraction)


def cut_to_disks(V: ArrayLike, F: ArrayLike, *, max_charts: int = 64, manifold: bool = False) -> np.ndarray:
    """Label the triangles so that every label is one disk with holes (genus 0, at least one boundary).

    Closed pieces and pieces with handles are bisected (:func:`bisect`) until every piece is a disk
    with holes: a closed sphere-like piece becomes two charts, a torus two annuli. Pieces that already
    are disks with holes keep one label. Few charts and short seams: each cut is the least-conductance
    cut of the piece, and nothing valid is cut.

    Parameters
    ----------
    V : (n,3) float array
    F : (m,3) int array             a manifold, consistently oriented mesh (any number of pieces)
    max_charts : int                raise when more charts than this would be needed
    manifold : bool                 the caller has checked that (V, F) is manifold (skip that check)

    Returns
    -------
    (m,) int array of labels 0..k-1, numbered by first triangle. Every label's triangles pass
    :func:`uvbake.mesh.charts.check_chart`.

    Raises
    ------
    ChartError  for non-manifold edges or vertices (repair first), or when `max_charts` is exceeded.
    """
    V, F = check_arrays(V, F, where="cut_to_disks")
    n, m = len(V), len(F)
    fi, fj, ea, eb, hi, hj = _dual_edges(F, n)
    if not manifold:
        _check_manifold(F, n)
    _, labels = components(m, fi, fj)
    labels = labels.astype(np.int64)
    todo = list(range(labels.max() + 1))
    next_label = labels.max() + 1
    while todo:                                     # one iteration per chart
        c = todo.pop()
        fidx = np.flatnonzero(labels == c)
        vmap, local = dense_ranks(F[fidx], n)
        Fc = local.reshape(-1, 3)
        topo = topology(Fc, len(vmap))
        if topo.genus == 0 and topo.n_boundary_loops >= 1 and topo.n_components == 1:
            continue
        if next_label >= max_charts:
            raise ChartError(f"cut_to_disks: more than max_charts={max_charts} charts would be needed "
                             f"(piece of {len(fidx)} triangles, genus {topo.genus}); raise max_charts")
        sub = bisect(V[vmap], Fc)
        labels[fidx[sub == 1]] = next_label
        if not (topo.genus == 0 and topo.n_components == 1):
            # (bisect's two sides are edge-connected and manifold: cut from a closed sphere-like piece,
            # each is a disk with holes already, which the check would only confirm)
            todo += [c, next_label]
        next_label += 1
    # renumber by first triangle
    first = np.full(labels.max() + 1, m)
    np.minimum.at(first, labels, np.arange(m))
    used = np.flatnonzero(first < m)
    rank = np.full(labels.max() + 1, -1)
    rank[used[np.argsort(first[used])]] = np.arange(len(used))
    return rank[labels]


def _check_manifold(F, n):
    """Raise a ChartError naming non-manifold edges or vertices."""
    from uvbake.mesh.topology import nonmanifold_vertices

    he = F[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    key = np.minimum(he[:, 0], he[:, 1]) * n + np.maximum(he[:, 0], he[:, 1])
    uk, cnt = np.unique(key, return_counts=True)
    if (cnt > 2).any():
        bad = uk[cnt > 2]
        pairs = ", ".join(f"({k // n},{k % n})" for k in bad[:5])
        raise ChartError(f"cut_to_disks: {len(bad)} non-manifold edges ({pairs}); run uvbake.mesh.repair.repair first")
    bow = nonmanifold_vertices(F, n)
    if len(bow):
        raise ChartError(f"cut_to_disks: {len(bow)} non-manifold vertices ({_list(bow)}); "
                         "run uvbake.mesh.repair.repair first")
