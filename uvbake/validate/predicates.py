"""Exact orientation predicates (Shewchuk's filter, exact fallback) and triangle-pair overlap tests."""

from __future__ import annotations

import numpy as np

_EPS = 2.0**-53


_CCW_ERR = (3.0 + 16.0 * _EPS) * _EPS  # Shewchuk's ccwerrboundA


_TINY = 1e-280  # below this the products may have underflowed: decide exactly


def _orient(ax, ay, bx, by, cx, cy):
    """Exact sign of cross(b - a, c - a) for arrays of points.

    Parameters
    ----------
    ax, ay, bx, by, cx, cy : (k,) float64 arrays

    Returns
    -------
    sign : (k,) int8 array in {-1, 0, 1}
    n_exact : int
        How many signs the float filter could not decide and were computed in exact arithmetic.
    """
    left = (bx - ax) * (cy - ay)
    right = (by - ay) * (cx - ax)
    det = left - right
    sign = np.sign(det).astype(np.int8)
    idx = np.flatnonzero(np.abs(det) <= _error_bound(left, right))
    a = np.stack([ax[idx], ay[idx]], axis=1)
    b = np.stack([bx[idx], by[idx]], axis=1)
    c = np.stack([cx[idx], cy[idx]], axis=1)
    sign[idx], n = _orient_undecided(a, b, c)
    return sign, n


def _error_bound(left, right):
    """Shewchuk's forward error bound on left - right (ccwerrboundA), floored at _TINY so that
    results near underflow are decided exactly."""
    err = np.abs(left)
    err += np.abs(right)
    err *= _CCW_ERR
    return np.maximum(err, _TINY, out=err)


def _orient_undecided(a, b, c):
    """Exact signs of cross(b - a, c - a) for the few determinants the float filter left undecided.

    Parameters
    ----------
    a, b, c : (k,2) float64 arrays

    Returns
    -------
    sign : (k,) int8
    n_exact : int
        Determinants that needed exact arithmetic (zeros recognisable from the floats do not).
    """
    sign = np.zeros(len(a), np.int8)
    if len(a) == 0:
        return sign, 0
    bax, bay = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
    cax, cay = c[:, 0] - a[:, 0], c[:, 1] - a[:, 1]
    # exactly zero: a zero difference (x - y == 0 iff x == y) in each product, or c == b
    zero = ((bax == 0) | (cay == 0)) & ((bay == 0) | (cax == 0))
    zero |= np.all(b == c, axis=1)
    hard = np.flatnonzero(~zero)
    if len(hard):
        sign[hard] = _orient_exact(a[hard], b[hard], c[hard])
    return sign, int(len(hard))


def _orient_exact(a, b, c):
    """Sign of cross(b - a, c - a) in exact dyadic-rational arithmetic (Python ints, no Python loop).

    Every coordinate is m * 2**e with an integer m, |m| < 2**53; scaling the six coordinates of a
    determinant by 2**-min(e) makes them integers, whose determinant numpy evaluates exactly in an
    object array.
    """
    pts = np.concatenate([a, b, c], axis=1)  # (k,6)
    mant, expo = np.frexp(pts)
    mi = np.ldexp(mant, 53).astype(np.int64)  # exact
    big = np.iinfo(np.int64).max
    e = np.where(mi == 0, big, expo.astype(np.int64) - 53)
    emin = e.min(axis=1, keepdims=True)
    emin = np.where(emin == big, 0, emin)
    shift = np.where(mi == 0, 0, e - emin)
    X = mi.astype(object) << shift.astype(object)
    ax, ay, bx, by, cx, cy = (X[:, i] for i in range(6))
    det = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
    return (det > 0).astype(np.int8) - (det < 0).astype(np.int8)


def _interiors_overlap(P, Q):
    """Whether the open interiors of counter-clockwise triangles P and Q intersect, exactly.

    They are disjoint exactly when one of the six edge lines has the other triangle wholly on its
    outer side or on it (the edges of the Minkowski difference P - Q are edges of P and of Q).

    Parameters
    ----------
    P, Q : (k,3,2) float64 arrays, each triangle counter-clockwise and of non-zero area

    Returns
    -------
    overlap : (k,) bool
    n_exact : int
    """
    overlap = np.ones(len(P), bool)
    n_exact = 0
    for T, U in ((P, Q), (Q, P)):
        live = np.flatnonzero(overlap)
        sep, n = _separated_by_edges(T[live], U[live])
        overlap[live[sep]] = False
        n_exact += n
    return overlap, n_exact


def _separated_by_edges(T, U):
    """(k,) bool: some edge line of counter-clockwise T has all three points of U on or right of it.

    Parameters
    ----------
    T, U : (k,3,2) float64 arrays
    """
    k = len(T)
    nxt = np.array([1, 2, 0])
    e = T[:, nxt] - T  # (k,3,2) edge vectors
    d = U[:, None, :, :] - T[:, :, None, :]  # (k,3 edges,3 points,2)
    left = e[:, :, None, 0] * d[..., 1]
    right = e[:, :, None, 1] * d[..., 0]
    det = left - right
    sign = np.sign(det).astype(np.int8)
    unsure = np.flatnonzero(np.abs(det) <= _error_bound(left, right))
    n = 0
    if len(unsure):
        kk, ee, pp = np.unravel_index(unsure, (k, 3, 3))
        s, n = _orient_undecided(T[kk, ee], T[kk, nxt[ee]], U[kk, pp])
        sign.reshape(-1)[unsure] = s
    return np.any(np.all(sign <= 0, axis=2), axis=1), n
