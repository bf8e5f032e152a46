"""The second-order certificate of a returned map (the paper's Table 3): the smallest eigenvalue of
the Hessian of F with the gauge directions set aside.

F is invariant under translating and rotating the map, so H always has the two translations in its
null space and, at a stationary point, the infinitesimal rotation too. Those three directions
(orthonormalised) are the gauge; at alpha = 0 uvbake pins two vertices instead, which removes
translation, rotation and the scale gauge, and the pinned Hessian has no null space.

lambda_min is found by shift-invert Lanczos (scipy's eigsh, the ARPACK implicitly restarted Lanczos)
on H with a shift sigma < 0: the eigenvalues nearest sigma are the smallest. The inverse
(H - sigma I)^-1 is applied with the solver's own sparse Cholesky (the same symbolic analysis LM
uses), so no second ordering or LU is computed when H - sigma I is positive definite. When it is
not, H has an eigenvalue below sigma: the shift is lowered fourfold until the factorisation
succeeds, which brackets lambda_min in [sigma, sigma / 4] so it is the eigenvalue nearest sigma.
Values are those of the solver's scale-free frame (mesh and map at unit mean edge length).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.sparse.linalg as spla

from uvbake.cancel import check_cancelled
from uvbake.flatten.solvers.linalg import NotPositiveDefinite, make_solver

if TYPE_CHECKING:
    from uvbake.flatten.energy import DistortionEnergy

# A stationary point is a local minimum when lambda_min >= -NEGATIVE_TOL * max |diag H|: the same
# relative threshold as LM's saddle test (lm.SADDLE_EPS).
NEGATIVE_TOL = 1e-9
# The first shift, relative to max |diag H|: below the smallest curvature of any chart we have met
# (beetle, 19,887 vertices, alpha 0.5: lambda_min ~ 1e-5 of max diag H) so the Lanczos vectors
# converge to the low end of the spectrum.
FIRST_SHIFT = 1e-7
# Unknowns up to which the certificate is one dense eigen-decomposition (exact) instead of Lanczos:
# ARPACK's 20 restarts cost 1.3 ms on a 12-vertex chart, 600 of them 0.8 s; LAPACK on 128 x 128, 1 ms.
DENSE_MAX = 128
# Relative accuracy of the Lanczos eigenvalue (of the inverse; lambda_min inherits it).
LANCZOS_TOL = 1e-8
# Lanczos restarts (ARPACK's maxiter, about 19 solves each) before the certificate gives up and the chart
# is reported "not checked": several times what the charts measured needed (docs/decisions/atlas.md,
# eighth session); at alpha 1 a cluster of eigenvalues at the Hessian's bottom can take thousands.
LANCZOS_RESTARTS = 20


@dataclass(frozen=True)
class Certificate:
    lambda_min: float          # smallest Hessian eigenvalue off the gauge directions
    # lambda_min >= -NEGATIVE_TOL * hmax (with the gradient test done by the caller); None: not found
    # within LANCZOS_RESTARTS (lambda_min NaN)
    is_local_minimum: bool | None
    gauge_dim: int             # directions set aside (3 when nothing is pinned, 0 when pinned)
    hmax: float                # max |diag H|, the scale of the threshold
    factorisations: int = 1    # of H - sigma I (the shift search included; 0 for tiny charts)
    # unit eigenvector of lambda_min over the free unknowns (the saddle escape's direction)
    vector: np.ndarray | None = field(default=None, compare=False, repr=False)

    def to_dict(self) -> dict[str, Any]:
        return dict(lambda_min=self.lambda_min, is_local_minimum=self.is_local_minimum,
                    certificate_gauge_dim=self.gauge_dim)


def gauge_basis(energy: DistortionEnergy, uv: np.ndarray) -> np.ndarray:
    """Orthonormal columns spanning translations and rotation of ``uv`` over the free unknowns
    (empty when unknowns are pinned, which fixes the gauge)."""
    if energy.fixed.any():
        return np.zeros((energy.n_free, 0))
    if getattr(energy, "parts", None) is not None:
        return _part_gauges(energy.parts, uv)
    c = uv - uv.mean(axis=0)
    n = len(uv)
    B = np.zeros((2 * n, 3))
    B[0::2, 0] = 1.0
    B[1::2, 1] = 1.0
    B[0::2, 2] = -c[:, 1]
    B[1::2, 2] = c[:, 0]
    if np.linalg.norm(c) == 0:          # the collapsed map: rotation moves nothing
        B = B[:, :2]
    # the columns are already orthogonal (c is centred): normalise them
    return B / np.linalg.norm(B, axis=0)


def _part_gauges(parts: np.ndarray, uv: np.ndarray) -> Any:
    """gauge_basis of a map of several parts (``parts``: each vertex's), as a sparse (2n, 3k) matrix:
    each part's two translations and its rotation about its own centroid."""
    import scipy.sparse as sp

    n, k = len(uv), int(parts.max()) + 1
    count = np.bincount(parts, minlength=k)
    mean = np.stack([np.bincount(parts, weights=uv[:, j], minlength=k) for j in (0, 1)], axis=1) / count[:, None]
    c = uv - mean[parts]
    r = np.sqrt(np.bincount(parts, weights=(c * c).sum(axis=1), minlength=k))      # each rotation's norm
    t = np.sqrt(count)[parts]
    rot = np.where(r[parts] > 0, 1.0 / np.where(r > 0, r, 1.0)[parts], 0.0)       # a collapsed part: no rotation
    rows = np.concatenate([2 * np.arange(n), 2 * np.arange(n) + 1, 2 * np.arange(n), 2 * np.arange(n) + 1])
    cols = np.concatenate([3 * parts, 3 * parts + 1, 3 * parts + 2, 3 * parts + 2])
    vals = np.concatenate([1.0 / t, 1.0 / t, -c[:, 1] * rot, c[:, 0] * rot])
    B = sp.csc_matrix((vals, (rows, cols)), shape=(2 * n, 3 * k))
    keep = np.column_stack([np.ones((k, 2), bool), r > 0]).ravel()
    return B if keep.all() else B[:, np.flatnonzero(keep)]


def certify(energy: DistortionEnergy, uv: np.ndarray, *, linear_solver: str = "auto", H: Any = None,
            solver: Any = None) -> Certificate:
    """The :class:`Certificate` of ``uv`` (per-vertex UVs in the energy's frame).

    ``H`` is the Hessian at ``uv`` if already evaluated; ``solver`` a solver from
    :func:`~uvbake.flatten.solvers.linalg.make_solver` for H's pattern (the one LM or the trust region
    used: its symbolic analysis is reused) or None for a fresh one.
    """
    if not np.all(np.isfinite(uv)):               # no map to test (a solve that broke down): not checked
        return Certificate(float("nan"), None, 0, float("nan"), 0, None)
    if H is None:
        _, _, H = energy.evaluate(uv)
    if not np.all(np.isfinite(H.data)):
        return Certificate(float("nan"), None, 0, float("nan"), 0, None)
    N = gauge_basis(energy, uv)
    diag = H.diagonal()
    hmax = float(np.max(np.abs(diag))) if len(diag) else 1.0
    n = H.shape[0]
    if n <= DENSE_MAX:                   # small charts: a dense eigen-decomposition
        return _dense_certificate(H, N, hmax)
    solver = solver or make_solver(H, method=linear_solver)
    shift = FIRST_SHIFT * hmax
    factorisations = 1
    while True:
        try:
            solver.factor(H, shift)                  # H - sigma I with sigma = -shift
            break
        except NotPositiveDefinite:
            shift *= 4.0
            factorisations += 1
            if shift > 1e12 * max(hmax, 1.0):
                raise
    # Lanczos on P (H + shift I)^-1 P, P the projector off the gauge: its largest eigenvalue mu gives
    # lambda_min = 1/mu - shift, and the gauge directions map to 0 instead of to the top of the spectrum
    def apply(v):
        check_cancelled()                            # Ctrl-C / SIGTERM: stop between solves
        v = v - N @ (N.T @ v)
        w = solver.solve(v)
        return w - N @ (N.T @ w)

    op = spla.LinearOperator(H.shape, matvec=apply, dtype=np.float64)
    v0 = np.random.default_rng(0).standard_normal(n)     # seeded: same input, same bytes
    try:
        mu, vec = spla.eigsh(op, k=1, which="LA", v0=v0, tol=LANCZOS_TOL, maxiter=LANCZOS_RESTARTS)
    except spla.ArpackError:                         # no convergence in the work count (never a time: the
        # same bytes every run), or no Lanczos basis at all
        return Certificate(float("nan"), None, N.shape[1], hmax, factorisations, None)
    lmin = float(1.0 / mu[0] - shift)
    v = vec[:, 0] / np.linalg.norm(vec[:, 0])
    return Certificate(lmin, lmin >= -NEGATIVE_TOL * hmax, N.shape[1], hmax, factorisations, v)


def _dense_certificate(H, N, hmax):
    n = H.shape[0]
    N = N.toarray() if hasattr(N, "toarray") else N
    P = np.eye(n) - N @ N.T
    lam, vec = np.linalg.eigh(P @ H.toarray() @ P)
    # the gauge directions appear as zeros: set them aside by their overlap with the gauge
    keep = np.ones(n, bool)
    if N.shape[1]:
        keep[np.argsort(-np.linalg.norm(N.T @ vec, axis=0))[:N.shape[1]]] = False
    k = np.flatnonzero(keep)[np.argmin(lam[keep])]
    lmin = float(lam[k])
    return Certificate(lmin, lmin >= -NEGATIVE_TOL * hmax, N.shape[1], hmax, 0, vec[:, k])
