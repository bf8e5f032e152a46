"""The weighted area/angle distortion of Mejia, Acosta and Ruiz-Salguero (2017), vectorised.

For triangle t with 3D vertices x1, x2, x3 we take an orthonormal basis (e1, e2) of its plane,
right-handed about its normal n = (x2-x1) x (x3-x1), and the isometric 2D coordinates of its corners
about the centroid, R (2x3). Q = R^T (R R^T)^-1 is the right pseudo-inverse of R, and with the UVs of
the corners U_t (2x3) the Jacobian of the affine map from the triangle to the plane is A = U_t Q (the
centroid drops out because the columns of R sum to zero, so A is linear in U and invariant to
translating the map). Writing a = Q[:, 0] and b = Q[:, 1] (3-vectors), u and v the corner UVs:

    A11 = a.u   A12 = b.u   A21 = a.v   A22 = b.v
    D_area  = (det A - 1)^2
    D_angle = (A11 - A22)^2 + (A12 + A21)^2          (the paper's Eq. 6)
    F       = sum_t w_t [alpha D_area + (1 - alpha) D_angle]

w_t = 1 is the paper's F; other weights (the triangle areas) serve the LSCM initial map.

At alpha = 1 F's least value, 0, is taken by every area-preserving map: a continuum of minima, along
which the Hessian is singular, so Newton's iterates reach it only linearly and the gradient test
takes hundreds of iterations on a large chart. Since F >= 0, a map with every term
w_t D_area <= FLOOR_TOL^2 has F within m FLOOR_TOL^2 of the global minimum; the solvers stop there
(``at_floor``).
At alpha < 1 the minima are isolated and the gradient test is cheap, but F's floor is still 0 where a
chart is developable (a cylinder's or a cone's chart, a box's faces: an isometry; at alpha 0 any
conformal map): with every term (area where alpha > 0, angle where alpha < 1) within FLOOR_TOL^2 the
map is near that global minimum, so once the gradient test passes no certificate is needed (the
conformal start of such a chart is already there, and the certificate's factorisation and Lanczos
cost more than the rest of its solve; uvbake.flatten.solvers.result.floor_reached).

Per-triangle unknowns are ordered [u1 u2 u3 v1 v2 v3]; globally the map is the interleaved vector
x = [u_0, v_0, u_1, v_1, ...] of length 2n, so vertex i owns entries 2i and 2i+1. D_angle is
quadratic in x (r1 = A11 - A22 and r2 = A12 + A21 are linear), det A is a quadratic form in x, and so

    grad D_area = 2 (det - 1) grad(det)
    Hess D_area = 2 grad(det) grad(det)^T + 2 (det - 1) Hess(det)     (indefinite where det < 1)

Every quantity is computed for all triangles at once with numpy; the 6x6 blocks are scattered into
a CSC matrix whose pattern (the mesh's vertex adjacency, two unknowns per vertex) is built once.
"""

from __future__ import annotations

import copy
from typing import Any

import numpy as np
import scipy.sparse as sp

from uvbake.errors import InputError

#: At alpha = 1 a solve stops when every triangle's area is within this fraction of its own
#: (w_t (det A - 1)^2 <= FLOOR_TOL^2): a texel share off by at most 0.1 %. Beetle's 38,656-triangle
#: chart reaches it after 57 iterations, the gradient test after 687 (docs/decisions/solver.md).
FLOOR_TOL = 1e-3


def triangle_frames(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Isometric 2D corner coordinates of every triangle and the pseudo-inverse of their frame.

    Parameters
    ----------
    V : (n,3) float array
    F : (m,3) int array

    Returns
    -------
    R : (m,2,3) float array
        Corner coordinates in the triangle's own right-handed orthonormal frame, about its centroid.
    Q : (m,3,2) float array
        R^T (R R^T)^-1, so that the Jacobian of a map with corner UVs U (2x3) is A = U Q.
    area : (m,) float array
        Triangle areas.
    """
    X = V[F]                                          # (m,3,3) corners
    e12 = X[:, 1] - X[:, 0]
    e13 = X[:, 2] - X[:, 0]
    normal = np.cross(e12, e13)
    dblarea = np.linalg.norm(normal, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        e1 = e12 / np.linalg.norm(e12, axis=1)[:, None]
        n = normal / dblarea[:, None]
    e2 = np.cross(n, e1)
    C = X - ((X[:, 0] + X[:, 1] + X[:, 2]) / 3.0)[:, None, :]      # about the centroid (X.mean's sums)
    # sums of three products written out: numpy's einsum takes 10-20x longer on such short axes
    # (docs/decisions/atlas-speed.md)
    x = C[:, :, 0] * e1[:, 0, None] + C[:, :, 1] * e1[:, 1, None] + C[:, :, 2] * e1[:, 2, None]
    y = C[:, :, 0] * e2[:, 0, None] + C[:, :, 1] * e2[:, 1, None] + C[:, :, 2] * e2[:, 2, None]
    R = np.stack([x, y], axis=1)                      # (m,2,3)
    xx, yy, xy = _dot3(x, x), _dot3(y, y), _dot3(x, y)  # R R^T
    det = xx * yy - xy * xy
    inv = np.empty((len(F), 2, 2))
    inv[:, 0, 0] = yy
    inv[:, 1, 1] = xx
    inv[:, 0, 1] = -xy
    inv[:, 1, 0] = -xy
    with np.errstate(invalid="ignore", divide="ignore"):
        inv /= det[:, None, None]
    Q = x[:, :, None] * inv[:, 0, None, :] + y[:, :, None] * inv[:, 1, None, :]      # R^T (R R^T)^-1
    return R, Q, 0.5 * dblarea


def jacobians(Q: np.ndarray, F: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Per-triangle Jacobians A (m,2,2) of the map with per-vertex UVs ``uv (n,2)``."""
    return corner_jacobians(uv[F], Q)


def corner_jacobians(U: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """Per-triangle Jacobians A (m,2,2) of the map with per-corner UVs ``U (m,3,2)`` (corner k, coordinate c)."""
    A = np.empty((len(U), 2, 2))
    for c in range(2):                                # A[c, j] = sum_k U[k, c] Q[k, j], as DistortionEnergy's terms
        for j in range(2):
            A[:, c, j] = _dot3(U[:, :, c], Q[:, :, j])
    return A


def _dot3(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Row-wise dot products of two (m,3) arrays, summed in one fixed order (x0 y0 + x1 y1) + x2 y2."""
    return x[:, 0] * y[:, 0] + x[:, 1] * y[:, 1] + x[:, 2] * y[:, 2]


class DistortionEnergy:
    """The paper's F on one chart: value, gradient and sparse Hessian, with a fixed sparsity pattern.

    Parameters
    ----------
    V : (n,3) float array
        Chart vertices (every vertex referenced by F).
    F : (m,3) int array
    alpha : float in [0, 1]
        Weight of the area term; 1 - alpha weighs the angle term.
    weights : (m,) float array, optional
        Per-triangle weights w_t (default 1, the paper's F).
    fixed : (2n,) bool array, optional
        Unknowns held fixed (e.g. pinned vertices). Gradients and Hessians are then returned for the
        free unknowns only, in their order.
    parts : (n,) int array, optional
        The vertex's part (0..k-1), when the mesh is several charts solved as one problem (F is then
        their sum; each part has its own translation and rotation gauge). None: one part.
    """

    def __init__(self, V, F, *, alpha, weights=None, fixed=None, parts=None):
        alpha = self._check_alpha(alpha)
        self.V = np.asarray(V, dtype=np.float64)
        self.F = np.asarray(F, dtype=np.int64)
        self.alpha = alpha
        self.n = len(self.V)
        self.parts = None if parts is None else np.asarray(parts, dtype=np.int64)
        self._part_count = None
        _, Q, self.area = triangle_frames(self.V, self.F)
        self.a = np.ascontiguousarray(Q[:, :, 0])
        self.b = np.ascontiguousarray(Q[:, :, 1])
        m = len(self.F)
        self.w = np.ones(m) if weights is None else np.asarray(weights, dtype=np.float64)
        self.min_det = np.inf            # the least det A of the last value-and-gradient evaluation
        self.at_floor = False            # ... and whether F was at its floor 0 there (to FLOOR_TOL)
        # global unknown of each per-triangle local unknown [u1 u2 u3 v1 v2 v3]
        self.dof = np.concatenate([2 * self.F, 2 * self.F + 1], axis=1)      # (m,6)
        N = 2 * self.n
        self.fixed = np.zeros(N, bool) if fixed is None else np.asarray(fixed, bool)
        self.free_index = np.full(N, -1, dtype=np.int64)
        self.free_index[~self.fixed] = np.arange(int((~self.fixed).sum()))
        self.n_free = int((~self.fixed).sum())
        self._build_pattern()
        self._g1 = np.concatenate([self.a, -self.b], axis=1)                  # (m,6): grad r1 = [a, -b]
        self._g2 = np.concatenate([self.b, self.a], axis=1)                   # grad r2 = [b, a]
        # Hess(det): u-v block a_k b_l - b_k a_l and its transpose
        self._Huv = np.einsum("mk,ml->mkl", self.a, self.b) - np.einsum("mk,ml->mkl", self.b, self.a)
        # A = QQ^T x_t: the Jacobian's entries (A11, A12, A21, A22) from the local unknowns
        self._QQ = np.zeros((m, 6, 4))
        self._QQ[:, :3, 0], self._QQ[:, :3, 1] = self.a, self.b
        self._QQ[:, 3:, 2], self._QQ[:, 3:, 3] = self.a, self.b
        self._angle_cache = None

    def with_alpha(self, alpha: float) -> DistortionEnergy:
        """The same chart's energy at another alpha (geometry and sparsity pattern shared, not rebuilt)."""
        other = copy.copy(self)
        other.alpha = float(DistortionEnergy._check_alpha(alpha))
        other._angle_cache = None
        return other

    @staticmethod
    def _check_alpha(alpha):
        alpha = float(alpha)
        if not 0.0 <= alpha <= 1.0 or not np.isfinite(alpha):
            raise InputError(f"alpha={alpha!r} is outside [0, 1]; pass a weight between 0 (angles only) "
                             "and 1 (areas only)")
        return alpha

    # -- sparsity pattern, built once ------------------------------------------------------------
    def _build_pattern(self):
        if self.fixed.any():
            self._build_pattern_general()
        else:
            self._build_pattern_free()

    def _build_pattern_general(self):
        """The Hessian's CSC pattern and every triangle's slots in it, for any fixed unknowns: the 36
        (row, column) keys of each triangle's six unknowns, made unique."""
        fi = self.free_index[self.dof]                                        # (m,6), -1 if fixed
        rows = np.broadcast_to(fi[:, :, None], (len(fi), 6, 6)).ravel()
        cols = np.broadcast_to(fi[:, None, :], (len(fi), 6, 6)).ravel()
        keep = (rows >= 0) & (cols >= 0)
        N = self.n_free
        key = cols[keep] * N + rows[keep]                                      # CSC order: column major
        uniq, inverse = np.unique(key, return_inverse=True)
        self._hkeep = keep
        self._hslot = inverse
        self._all_free = bool(keep.all())
        slot_full = np.full(len(keep), -1, dtype=np.int64)
        slot_full[keep] = inverse
        self._hslot_full = slot_full.reshape(len(fi), 36)                     # (m,36), -1 where fixed
        self._nnz = len(uniq)
        self._indices = (uniq % N).astype(np.int32)
        ucol = uniq // N
        self._indptr = np.searchsorted(ucol, np.arange(N + 1)).astype(np.int32)
        self._diag = np.flatnonzero(self._indices == ucol)
        gi = fi.ravel()
        self._gkeep = gi >= 0
        self._gslot = gi[self._gkeep]

    def _build_pattern_free(self):
        """_build_pattern when every unknown is free (unknown 2v + c is vertex v's u or v), from the
        vertex pairs: np.unique over 9 keys a triangle instead of 36. Vertex pair (r, c) holds the
        four entries (2r + i, 2c + j); in CSC order column 2c + j lists rows 2r, 2r + 1 for each row
        vertex r of column vertex c in turn, so every slot follows by arithmetic. The arrays are
        those of the general build (tests/test_energy.py compares them)."""
        F, n = self.F, self.n
        m = len(F)
        vkey = (F[:, None, :] * n + F[:, :, None]).reshape(-1)                # (m,3,3): column vertex b, row a
        pairs, inverse = np.unique(vkey, return_inverse=True)
        rv, cv = pairs % n, pairs // n
        k = np.bincount(cv, minlength=n)                                      # row vertices per column vertex
        first = np.cumsum(k) - k                                              # its first pair
        start = 4 * first                                                     # its first slot
        rank = np.arange(len(pairs)) - first[cv]
        # slot of entry (row 2 rv + i, column 2 cv + j) of pair p: start + j 2k + 2 rank + i
        base = (start[cv] + 2 * rank)[inverse.reshape(m, 3, 3)]               # (m, row vertex a, column vertex b)
        twok = (2 * k)[F]                                                     # (m, b)
        i = np.repeat(np.arange(2), 3)                                        # local unknown p: vertex p % 3, i = p // 3
        a = np.tile(np.arange(3), 2)
        slot = base[:, a[:, None], a[None, :]] + i[:, None] + i[None, :] * twok[:, None, a]
        self._hslot_full = slot.reshape(m, 36)
        self._hslot = self._hslot_full.reshape(-1)
        self._hkeep = np.ones(m * 36, bool)
        self._all_free = True
        self._nnz = 4 * len(pairs)
        N = 2 * n
        indptr = np.empty(N + 1, np.int64)
        indptr[0:N:2], indptr[1:N:2], indptr[N] = start, start + 2 * k, self._nnz
        self._indptr = indptr.astype(np.int32)
        rows = np.empty(self._nnz, np.int64)                                  # column by column
        at = start[cv] + 2 * rank
        for j in range(2):
            for ii in range(2):
                rows[at + j * (2 * k)[cv] + ii] = 2 * rv + ii
        self._indices = rows.astype(np.int32)
        ucol = np.repeat(np.arange(N), np.diff(indptr))
        self._diag = np.flatnonzero(rows == ucol)
        gi = self.dof.ravel()
        self._gkeep = np.ones(len(gi), bool)
        self._gslot = gi

    def empty_matrix(self) -> sp.csc_matrix:
        """A CSC matrix with the Hessian's pattern and zero values."""
        return sp.csc_matrix((np.zeros(self._nnz), self._indices, self._indptr),
                             shape=(self.n_free, self.n_free))

    @property
    def diagonal_slots(self) -> np.ndarray:
        """Positions of the diagonal entries in the CSC data array."""
        return self._diag

    # -- per-triangle quantities -----------------------------------------------------------------
    def _terms(self, uv):
        U = uv[self.F]                                                         # (m,3,2)
        u, v = U[:, :, 0], U[:, :, 1]
        A11, A12 = _dot3(u, self.a), _dot3(u, self.b)     # as jacobians(), product for product
        A21, A22 = _dot3(v, self.a), _dot3(v, self.b)
        return A11, A12, A21, A22

    def per_triangle(self, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """D_area and D_angle of every triangle, each (m,)."""
        A11, A12, A21, A22 = self._terms(uv)
        det = A11 * A22 - A12 * A21
        return (det - 1.0) ** 2, (A11 - A22) ** 2 + (A12 + A21) ** 2

    def value(self, uv: np.ndarray) -> float:
        """F at per-vertex UVs ``uv (n,2)``."""
        d_area, d_angle = self.per_triangle(uv)
        return float(np.dot(self.w, self.alpha * d_area + (1.0 - self.alpha) * d_angle))

    def change(self, uv: np.ndarray, duv: np.ndarray) -> float:
        """F(uv + duv) - F(uv), computed term by term so it stays accurate when tiny.

        Subtracting two values of F near convergence loses everything below F's rounding error
        (about 1e-16 F), which is larger than the decrease of a step once the gradient is small.
        Expanding each term exactly avoids the cancellation:
        (d1 - 1)^2 - (d0 - 1)^2 = (d1 - d0)(d1 + d0 - 2), r1^2 - r0^2 = dr (2 r0 + dr),
        with d1 - d0 = A11 dA22 + dA11 A22 + dA11 dA22 - (A12 dA21 + dA12 A21 + dA12 dA21).
        """
        A11, A12, A21, A22 = self._terms(uv)
        B11, B12, B21, B22 = self._terms(duv)
        d0 = A11 * A22 - A12 * A21
        dd = A11 * B22 + B11 * A22 + B11 * B22 - (A12 * B21 + B12 * A21 + B12 * B21)
        r1, r2 = A11 - A22, A12 + A21
        s1, s2 = B11 - B22, B12 + B21
        per = (self.alpha * dd * (2.0 * d0 + dd - 2.0)
               + (1.0 - self.alpha) * (s1 * (2.0 * r1 + s1) + s2 * (2.0 * r2 + s2)))
        return float(np.dot(self.w, per))

    def determinants(self, uv: np.ndarray) -> np.ndarray:
        """det A of every triangle (m,); <= 0 means flipped or collapsed."""
        A11, A12, A21, A22 = self._terms(uv)
        return A11 * A22 - A12 * A21

    def _local(self, uv, hessian):
        A11, A12, A21, A22 = self._terms(uv)
        det = A11 * A22 - A12 * A21
        self.min_det = float(det.min()) if len(det) else np.inf
        r1 = A11 - A22
        r2 = A12 + A21
        al, w = self.alpha, self.w
        gdet = np.concatenate([self.a * A22[:, None] - self.b * A21[:, None],
                               self.b * A11[:, None] - self.a * A12[:, None]], axis=1)
        ca = 2.0 * al * w * (det - 1.0)
        cg = 2.0 * (1.0 - al) * w
        g = ca[:, None] * gdet + cg[:, None] * (r1[:, None] * self._g1 + r2[:, None] * self._g2)
        f = float(np.dot(w, al * (det - 1.0) ** 2 + (1.0 - al) * (r1 ** 2 + r2 ** 2)))
        # F is a sum of m non-negative terms: over m FLOOR_TOL^2 some term is over FLOOR_TOL^2 (no pass needed)
        self.at_floor = f <= len(det) * FLOOR_TOL * FLOOR_TOL and self._at_floor(det, r1, r2)
        if not hessian:
            return f, g, None
        # the part that varies: 2 alpha w gdet gdet^T + ca Hess(det) (Hess(det) lives in the u-v blocks);
        # the angle term's constant part is added after the scatter (evaluate)
        sg = np.sqrt(2.0 * al * w)[:, None] * gdet                  # symmetric to the last bit
        H = sg[:, :, None] * sg[:, None, :]
        Huv = ca[:, None, None] * self._Huv
        H[:, :3, 3:] += Huv
        H[:, 3:, :3] += np.transpose(Huv, (0, 2, 1))
        return f, g, H

    def _at_floor(self, det, r1, r2):
        """Whether every triangle's weighted terms of F are within FLOOR_TOL^2 of 0: the area term where
        alpha > 0, the angle term where alpha < 1 (F >= 0, so such a map is a global minimum to that
        tolerance)."""
        if not len(det):
            return False
        tol2 = FLOOR_TOL * FLOOR_TOL
        if self.alpha > 0 and float(np.max(self.w * (det - 1.0) ** 2)) > tol2:
            return False
        return self.alpha == 1 or float(np.max(self.w * (r1 * r1 + r2 * r2))) <= tol2

    @property
    def _angle_data(self):
        """The angle term's Hessian (constant) in the CSC data layout, scattered once."""
        if self._angle_cache is None:
            # 2 (1 - alpha) w (g1 g1^T + g2 g2^T)
            c = np.sqrt(2.0 * (1.0 - self.alpha) * self.w)[:, None]
            g1, g2 = c * self._g1, c * self._g2
            self._angle_cache = self._scatter_blocks(g1[:, :, None] * g1[:, None, :] + g2[:, :, None] * g2[:, None, :])
        return self._angle_cache

    def projection_correction(self, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """What lifts each triangle's Hessian block h_t (in the Jacobian's coordinates A11, A12, A21,
        A22) to its projection onto the positive semidefinite cone: the triangles ``rows`` whose block
        is indefinite and their corrections E (s,4,4), PSD, with h_t^+ = h_t + E (the clamping of Teran
        et al. 2005, in closed form; H_t = QQ h_t QQ^T, so H_t^+ is PSD as well).

        With the orthonormal conformal pair c1 = (1,0,0,1)/sqrt2, c2 = (0,1,-1,0)/sqrt2, the
        anticonformal pair n1 = (1,0,0,-1)/sqrt2, n2 = (0,1,1,0)/sqrt2 and
        A = p1 c1 + p2 c2 + q1 n1 + q2 n2: det = (|p|^2 - |q|^2)/2, grad det = (p, -q), Hess det =
        diag(1,1,-1,-1), and the angle term's Hessian is 4 (1 - alpha) w on the anticonformal pair. So
        h = s g g^T + diag(dc, dc, da, da) with s = 2 alpha w, dc = s (det - 1),
        da = 4 (1 - alpha) w - dc: eigenvalue dc across p in the conformal plane, da across q in the
        anticonformal one, and a 2x2 block B on (p/|p|, -q/|q|), whose negative part is B itself,
        lambda_- (B - lambda_+ I) / (lambda_+ - lambda_-) or nothing.
        """
        A11, A12, A21, A22 = self._terms(uv)
        det = A11 * A22 - A12 * A21
        r = np.sqrt(0.5)
        p1, p2, q1, q2 = r * (A11 + A22), r * (A12 - A21), r * (A11 - A22), r * (A12 + A21)
        P2, Q2 = p1 * p1 + p2 * p2, q1 * q1 + q2 * q2
        s = 2.0 * self.alpha * self.w
        dc = s * (det - 1.0)
        da = 4.0 * (1.0 - self.alpha) * self.w - dc
        x, y, z = dc + s * P2, s * np.sqrt(P2 * Q2), da + s * Q2
        mean, rad = 0.5 * (x + z), np.hypot(0.5 * (x - z), y)
        rows = np.flatnonzero((dc < 0) | (da < 0) | (mean < rad))
        if not len(rows):
            return rows, np.zeros((0, 4, 4))
        p1, p2, q1, q2, P2, Q2 = p1[rows], p2[rows], q1[rows], q2[rows], P2[rows], Q2[rows]
        x, y, z, dc, da = x[rows], y[rows], z[rows], dc[rows], da[rows]
        lo, hi = mean[rows] - rad[rows], mean[rows] + rad[rows]
        # unit directions in A-coordinates (arbitrary ones where p or q vanishes)
        with np.errstate(invalid="ignore", divide="ignore"):
            ip = np.where(P2 > 0, r / np.sqrt(P2), 0.0)
            iq = np.where(Q2 > 0, r / np.sqrt(Q2), 0.0)
        ph1, ph2 = np.where(P2 > 0, p1 * ip, r), p2 * ip            # p/|p| on (c1, c2), times r
        qh1, qh2 = np.where(Q2 > 0, -q1 * iq, r), -q2 * iq          # -q/|q| on (n1, n2), times r
        b1 = np.stack([ph1, ph2, -ph2, ph1], axis=1)                  # p/|p|
        b2 = np.stack([qh1, qh2, qh2, -qh1], axis=1)                  # -q/|q|
        bp = np.stack([-ph2, ph1, -ph1, -ph2], axis=1)                # across p (conformal)
        bq = np.stack([-qh2, qh1, qh1, qh2], axis=1)                  # across q (anticonformal)
        # the negative part of B, negated, in the (b1, b2) basis
        both = hi <= 0
        with np.errstate(invalid="ignore", divide="ignore"):
            f = np.where(both, -1.0, np.where(lo < 0, lo / (hi - lo), 0.0))
        shift = np.where(both, 0.0, hi)
        c11, c12, c22 = f * (x - shift), f * y, f * (z - shift)
        E = (c11[:, None, None] * (b1[:, :, None] * b1[:, None, :])
             + c12[:, None, None] * (b1[:, :, None] * b2[:, None, :] + b2[:, :, None] * b1[:, None, :])
             + c22[:, None, None] * (b2[:, :, None] * b2[:, None, :])
             + np.maximum(-dc, 0.0)[:, None, None] * (bp[:, :, None] * bp[:, None, :])
             + np.maximum(-da, 0.0)[:, None, None] * (bq[:, :, None] * bq[:, None, :]))
        return rows, E

    def projected_hessian(self, uv: np.ndarray, H: sp.csc_matrix,
                          out: sp.csc_matrix | None = None) -> sp.csc_matrix:
        """The Hessian with every triangle's block projected onto the PSD cone in the Jacobian's
        coordinates (``H`` the true one at ``uv``, same pattern; ``out`` refilled in place if given):
        positive semidefinite always, and equal to H on triangles whose block already is."""
        rows, E = self.projection_correction(uv)
        data = H.data.copy()
        if len(rows):
            QQ = self._QQ[rows]
            data += self._scatter_blocks(QQ @ E @ np.transpose(QQ, (0, 2, 1)), rows)
        if out is None:
            out = self.empty_matrix()
        out.data[:] = data
        return out

    def value_and_gradient(self, uv: np.ndarray) -> tuple[float, np.ndarray]:
        """F and its gradient over the free unknowns (interleaved u, v per vertex)."""
        f, g, _ = self._local(uv, hessian=False)
        return f, self._scatter_gradient(g)

    def gradient(self, uv: np.ndarray) -> np.ndarray:
        return self.value_and_gradient(uv)[1]

    def evaluate(self, uv: np.ndarray, out: sp.csc_matrix | None = None) -> tuple[float, np.ndarray, sp.csc_matrix]:
        """F, gradient and Hessian (CSC, fixed pattern; ``out`` is refilled in place if given)."""
        f, g, H = self._local(uv, hessian=True)
        data = self._scatter_blocks(H)
        data += self._angle_data
        if out is None:
            out = self.empty_matrix()
        out.data[:] = data
        return f, self._scatter_gradient(g), out

    def _scatter_blocks(self, blocks, rows=None):
        """Sum per-triangle 6x6 blocks (of all triangles, or of the triangles ``rows``) into the CSC data."""
        if rows is None and self._all_free:
            return np.bincount(self._hslot, weights=blocks.ravel(), minlength=self._nnz)
        slots = (self._hslot_full if rows is None else self._hslot_full[rows]).ravel()
        keep = slots >= 0
        return np.bincount(slots[keep], weights=blocks.ravel()[keep], minlength=self._nnz)

    def _scatter_gradient(self, g):
        return np.bincount(self._gslot, weights=g.ravel()[self._gkeep], minlength=self.n_free)

    def center(self, y: np.ndarray) -> np.ndarray:
        """``y`` (2n,) without its translation part: each part's mean (u, v) taken off its vertices."""
        y = y.reshape(-1, 2)
        if self.parts is None:
            return (y - y.mean(axis=0)).ravel()
        if self._part_count is None:
            self._part_count = np.bincount(self.parts).astype(np.float64)
        mean = np.stack([np.bincount(self.parts, weights=y[:, k]) for k in (0, 1)], axis=1) / self._part_count[:, None]
        return (y - mean[self.parts]).ravel()

    # -- conversions between per-vertex UVs and the free-unknown vector --------------------------
    def to_vector(self, uv: np.ndarray) -> np.ndarray:
        return np.asarray(uv, dtype=np.float64).reshape(-1)[~self.fixed].copy()

    def to_uv(self, x: np.ndarray, uv_fixed: np.ndarray) -> np.ndarray:
        """Per-vertex UVs from the free unknowns ``x``, taking fixed unknowns from ``uv_fixed``."""
        full = np.asarray(uv_fixed, dtype=np.float64).reshape(-1).copy()
        full[~self.fixed] = x
        return full.reshape(-1, 2)


def optimal_scale(energy: DistortionEnergy, uv: np.ndarray) -> float:
    """The uniform scale s > 0 minimising F(s * uv), in closed form.

    det A scales with s^2 and D_angle with s^2, so with w = s^2,
    F(w) = alpha sum (w d_t - 1)^2 + (1 - alpha) w c, a quadratic in w whose minimiser is
    w* = (alpha sum d_t - (1 - alpha) c / 2) / (alpha sum d_t^2). At alpha = 0 the minimiser is the
    collapsed map, so the map is instead scaled to the surface's own total area.
    """
    A11, A12, A21, A22 = energy._terms(uv)
    d = A11 * A22 - A12 * A21
    c = float(np.dot(energy.w, (A11 - A22) ** 2 + (A12 + A21) ** 2))
    al = energy.alpha
    sum_d = float(np.dot(energy.w, d))
    sum_d2 = float(np.dot(energy.w, d * d))
    if al > 0 and sum_d2 > 0:
        w = (al * sum_d - 0.5 * (1.0 - al) * c) / (al * sum_d2)
        if w > 0:
            return float(np.sqrt(w))
    # fall back: match total unsigned UV area to the 3D area
    uv_area = float(np.dot(energy.area, np.abs(d)))
    return float(np.sqrt(energy.area.sum() / uv_area)) if uv_area > 0 else 1.0


def optimal_scales(energy: DistortionEnergy, uv: np.ndarray, face_parts: np.ndarray) -> np.ndarray:
    """:func:`optimal_scale` of each part of a map of several (``face_parts``: each triangle's part,
    0..k-1), all parts at once: a (k,) array."""
    A11, A12, A21, A22 = energy._terms(uv)
    d = A11 * A22 - A12 * A21
    parts = np.asarray(face_parts)
    k = int(parts.max()) + 1 if len(parts) else 0
    w, al = energy.w, energy.alpha
    c = np.bincount(parts, weights=w * ((A11 - A22) ** 2 + (A12 + A21) ** 2), minlength=k)
    sum_d = np.bincount(parts, weights=w * d, minlength=k)
    sum_d2 = np.bincount(parts, weights=w * d * d, minlength=k)
    uv_area = np.bincount(parts, weights=energy.area * np.abs(d), minlength=k)
    area = np.bincount(parts, weights=energy.area, minlength=k)
    with np.errstate(divide="ignore", invalid="ignore"):
        fit = (al * sum_d - 0.5 * (1.0 - al) * c) / (al * sum_d2)
        by_area = np.where(uv_area > 0, area / uv_area, 1.0)
    return np.sqrt(np.where((al > 0) & (sum_d2 > 0) & (fit > 0), fit, by_area))


def scaled_start(uv: np.ndarray, scale: Any, parts: np.ndarray | None = None) -> np.ndarray:
    """``uv * scale`` about each part's centroid (``scale`` one number, or one per part with ``parts``
    each vertex's part). F ignores translations, and a map the solve shrinks keeps the digits of its
    shape only near the origin: at alpha 0-0.1 a very rough chart's F can fall all the way to the
    collapsed map, which the density scaling later blows back up (docs/decisions/atlas.md)."""
    uv = np.asarray(uv, dtype=np.float64)
    p = np.zeros(len(uv), np.int64) if parts is None else np.asarray(parts)
    k = int(p.max()) + 1 if len(p) else 0
    count = np.maximum(np.bincount(p, minlength=k), 1)
    mean = np.stack([np.bincount(p, weights=uv[:, j], minlength=k) for j in (0, 1)], axis=1) / count[:, None]
    s = np.broadcast_to(np.asarray(scale, dtype=np.float64), (k,)) if parts is not None else np.full(1, float(scale))
    return (uv - mean[p]) * s[p][:, None]
