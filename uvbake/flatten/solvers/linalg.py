"""Sparse symmetric solves and the positive-definite test: the only factorisations of the package.

CHOLMOD (through scikit-sparse, the optional ``cholmod`` extra) analyses the pattern once and then
refactors A + beta I in place each LM iteration, as a simplicial L D L^T whose pivots D must all be
positive (the positive-definite test). Without it, SuperLU (scipy) factors each matrix from scratch
with a symmetric minimum-degree ordering and diagonal pivots only; the matrix is positive definite exactly when every
pivot is on the diagonal (a zero diagonal pivot makes SuperLU pivot off it) and positive (with a
symmetric permutation the pivots are those of A = L D L^T, Sylvester's law). Timings: bench/solver.py
and docs/decisions/linear-solvers.md.
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Callable, Iterator

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from uvbake.errors import InputError
from uvbake.flatten.options import LINEAR_SOLVERS

#: Matrices of at least this many unknowns are factored supernodal (L L^T in dense blocks), smaller ones
#: simplicial (L D L^T). Where the two cross depends on the CPU; past it the supernodal factor wins
#: by a factor that grows with the chart (measurements: docs/decisions/linear-solvers.md).
SUPERNODAL_FROM = 50_000


def cholmod_mode(unknowns: int) -> str:
    """CHOLMOD's factorisation for a system whose largest independent block has ``unknowns`` unknowns:
    "supernodal" from SUPERNODAL_FROM on, else "simplicial". A count, so the same on every machine."""
    return "supernodal" if unknowns >= SUPERNODAL_FROM else "simplicial"


class NotPositiveDefinite(Exception):
    """The damped matrix was not positive definite: raise the damping and try again."""


def cholmod_available() -> bool:
    """Whether scikit-sparse's CHOLMOD can be imported (the optional ``cholmod`` extra). The first call
    imports it (every module of the package asks here first), with OpenMP held to one thread."""
    if "sksparse.cholmod" in sys.modules:
        return True
    try:
        _import_cholmod()
    except ImportError:
        return False
    return True


def _import_cholmod() -> None:
    """Import CHOLMOD with OMP_THREAD_LIMIT=1 for the OpenMP runtime it loads, unless the user set it.

    CHOLMOD 3's supernodal factorisation runs its scatter loops as a team of CHOLMOD_OMP_NUM_THREADS
    (4) threads, a num_threads clause that neither OMP_NUM_THREADS nor threadpoolctl's limit reaches;
    on two cores the team doubled the factorisation's CPU (docs/decisions/linear-solvers.md). The
    runtime reads its thread limit once, when loaded, so the variable is set only around the import and
    the process's environment is left as it was (a runtime already loaded keeps its own settings)."""
    key = "OMP_THREAD_LIMIT"
    ours = key not in os.environ
    if ours:
        os.environ[key] = "1"
    try:
        import sksparse.cholmod  # noqa: F401
    finally:
        if ours:
            del os.environ[key]


# (len(sys.modules) when made, threadpoolctl.ThreadpoolController): one_blas_thread's cached scan
_POOLS: tuple | None = None


@contextlib.contextmanager
def one_blas_thread(user_api: str | None = None) -> Iterator[None]:
    """One thread in every BLAS (``user_api="blas"``) or native pool (None) loaded, restored on exit.

    threadpoolctl's ``threadpool_limits`` reads /proc/self/maps at every call to find the pools, a few
    ms (docs/decisions/atlas-speed.md); the scan is kept and redone whenever the number of loaded modules
    changed, as it does when a new BLAS comes in (numpy, scipy and CHOLMOD load theirs on import).
    """
    from threadpoolctl import ThreadpoolController

    global _POOLS
    cholmod_available()          # CHOLMOD's BLAS loaded first, so the limit reaches it too
    pools = _POOLS
    if pools is None or pools[0] != len(sys.modules):
        pools = _POOLS = (len(sys.modules), ThreadpoolController())
    with pools[1].limit(limits=1, user_api=user_api):
        yield


def make_solver(pattern: sp.spmatrix, *, method: str = "auto") -> CholmodSolver | SuperLUSolver:
    """A solver for matrices with the pattern of ``pattern`` (CSC).

    method : {"auto", "cholmod", "superlu"}
        "auto" takes CHOLMOD when scikit-sparse is installed, SuperLU otherwise.
    """
    if method not in LINEAR_SOLVERS:
        raise InputError(f"linear_solver={method!r} is not one of 'auto', 'cholmod', 'superlu'")
    if method == "cholmod" or (method == "auto" and cholmod_available()):
        return CholmodSolver(pattern)
    return SuperLUSolver(pattern)


def is_positive_definite(M: sp.spmatrix, *, method: str = "auto") -> bool:
    """Whether the symmetric sparse matrix M is positive definite (one factorisation)."""
    solver = make_solver(sp.csc_matrix(M), method=method)
    try:
        solver.factor(sp.csc_matrix(M), 0.0)
    except NotPositiveDefinite:
        return False
    return True


def cholesky_lower(M: sp.spmatrix) -> object:
    """CHOLMOD's supernodal P M P^T = L L^T of a positive definite M (raises NotPositiveDefinite).

    Needs scikit-sparse (ImportError otherwise); returns its ``Factor`` (``solve_L``, ``apply_P``, ...).
    """
    cholmod_available()
    from sksparse.cholmod import CholmodNotPositiveDefiniteError, cholesky

    try:
        return cholesky(sp.csc_matrix(M, dtype=np.float64), mode="supernodal")   # a true LL^T
    except CholmodNotPositiveDefiniteError as exc:
        raise NotPositiveDefinite(str(exc)) from None


class CholmodSolver:
    """CHOLMOD with the symbolic factorisation of ``pattern`` computed once and reused."""

    name = "cholmod"

    def __init__(self, pattern: sp.spmatrix) -> None:
        cholmod_available()                              # the first import holds OpenMP to one thread
        from sksparse.cholmod import analyze

        # AMD order. Below SUPERNODAL_FROM unknowns (most charts' Hessians) a simplicial L D L^T, the
        # faster there; it factors indefinite matrices without complaint, so factor() reads D's signs:
        # LM must never step from a saddle. A joint batch of small charts (uvbake.flatten.joint) stays
        # far below the threshold, so the size compared is that of one chart.
        self._factor = analyze(sp.csc_matrix(pattern, dtype=np.float64), mode=cholmod_mode(pattern.shape[0]),
                               ordering_method="amd")

    def factor(self, A: sp.spmatrix, beta: float) -> None:
        """Factor A + beta I (same pattern as at construction); NotPositiveDefinite unless every pivot
        of D is positive (Sylvester's law of inertia: P (A + beta I) P^T = L D L^T). A supernodal L L^T
        stops at a non-positive pivot itself, but not at a NaN: D (its diagonal squared) is read too."""
        from sksparse.cholmod import CholmodNotPositiveDefiniteError

        try:
            self._factor.cholesky_inplace(A, beta=beta)
        except CholmodNotPositiveDefiniteError as exc:
            raise NotPositiveDefinite(str(exc)) from None
        if not np.all(self._factor.D() > 0):             # NaN fails too
            raise NotPositiveDefinite("a non-positive pivot")

    def solve(self, b: np.ndarray) -> np.ndarray:
        return self._factor(b)


class SuperLUSolver:
    """SuperLU (scipy) in symmetric mode with diagonal pivots; refactors from scratch every time."""

    name = "superlu"

    def __init__(self, pattern: sp.spmatrix) -> None:
        self._eye = sp.identity(pattern.shape[0], format="csc")
        self._lu: spla.SuperLU | None = None

    def factor(self, A: sp.spmatrix, beta: float) -> None:
        """Factor A + beta I; NotPositiveDefinite unless every pivot is a positive diagonal entry."""
        M = (A + beta * self._eye).tocsc()
        try:
            lu = spla.splu(M, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                           options=dict(SymmetricMode=True))
        except RuntimeError as exc:          # exactly singular
            raise NotPositiveDefinite(str(exc)) from None
        if not np.array_equal(lu.perm_r, lu.perm_c):
            # SuperLU left the diagonal: a zero diagonal pivot, impossible for a positive definite M
            raise NotPositiveDefinite("an off-diagonal pivot (a zero diagonal pivot)")
        if np.any(lu.U.diagonal() <= 0):
            raise NotPositiveDefinite("a non-positive pivot")
        self._lu = lu

    def solve(self, b: np.ndarray) -> np.ndarray:
        assert self._lu is not None, "factor() first"
        return self._lu.solve(b)


Solver = Callable[[np.ndarray], np.ndarray]
