"""The records solvers return: one status enum and one result type for every backend.

As scipy's ``OptimizeResult``: an integer :class:`Status` says why a solve stopped, and
``MESSAGES[status]`` says it in words (the ``stop_reason`` strings of the reports).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Any

import numpy as np


class Status(IntEnum):
    """Why a solve stopped. Codes 0-9: both backends; 10 and up: nlopt's own ends (L-BFGS)."""

    CONVERGED = 0
    MAX_ITER = 1
    MAX_EVAL = 2
    CALLBACK = 3
    NON_FINITE_START = 4
    STEP_TOO_SMALL = 5
    DAMPING_DIVERGED = 6
    AT_FLOOR = 7  # every term of F within FLOOR_TOL^2 of 0 (alpha = 1, or a developable chart): F's global minimum
    NLOPT_SUCCESS = 10
    NLOPT_STOPVAL = 11
    NLOPT_FTOL = 12
    NLOPT_XTOL = 13
    NLOPT_MAXTIME = 14
    NLOPT_OTHER = 15
    ROUNDOFF_LIMITED = 16
    FORCED_STOP = 17
    NLOPT_FAILURE = 18
    REFRESH = 19  # internal to L-BFGS: a planned restart with a new preconditioner, never returned


#: The words of each status (the ``stop_reason`` of reports; NLOPT_OTHER and NLOPT_FAILURE add detail).
MESSAGES: dict[Status, str] = {
    Status.CONVERGED: "converged",
    Status.MAX_ITER: "max_iter",
    Status.MAX_EVAL: "max_eval",
    Status.CALLBACK: "stopped by callback",
    Status.NON_FINITE_START: "non-finite start",
    Status.STEP_TOO_SMALL: "step too small",
    Status.DAMPING_DIVERGED: "damping diverged",
    Status.AT_FLOOR: "at floor",
    Status.NLOPT_SUCCESS: "nlopt success",
    Status.NLOPT_STOPVAL: "nlopt stopval",
    Status.NLOPT_FTOL: "nlopt ftol",
    Status.NLOPT_XTOL: "nlopt xtol",
    Status.NLOPT_MAXTIME: "nlopt maxtime",
    Status.NLOPT_OTHER: "nlopt result",
    Status.ROUNDOFF_LIMITED: "roundoff limited",
    Status.FORCED_STOP: "forced stop",
    Status.NLOPT_FAILURE: "nlopt failure",
    Status.REFRESH: "refresh",
}


# F stalled at rounding: it fell by at most STALL_RTOL |F| over the last STALL iterations (a bent tube of
# sliver triangles, 35k faces: F exact to 14 digits after 10 iterations, its gradient norm held at 2e-6 by
# rounding, 1000 iterations and 130 s CPU to max_iter). Both second-order backends stop there.
STALL = 20
STALL_RTOL = 1e-12


def stalled(history: Sequence[float] | np.ndarray) -> bool:
    """Whether F fell by at most STALL_RTOL |F| over the last STALL iterations (rounding, not progress)."""
    return len(history) > STALL and history[-STALL - 1] - history[-1] <= STALL_RTOL * abs(history[-1])


def floor_reached(floor: bool, alpha: float, grad_norm: float, tol: float) -> bool:
    """Whether a second-order solve stops at F's floor 0 (``floor``: DistortionEnergy.at_floor at the
    iterate). At alpha = 1 as soon as it is there: the minima form a continuum and the gradient test
    comes only linearly. Below 1 the minimum is isolated and Newton reaches the gradient test in a step
    or two, so the floor decides nothing but that the global minimum needs no certificate."""
    return bool(floor) and (alpha == 1.0 or grad_norm < tol)


def final_status(stop: Status, grad_norm: float, tol: float, floor: bool) -> tuple[Status, bool]:
    """A second-order backend's status at its end (a run cut at MAX_ITER that reached the tolerance or
    F's floor says so) and whether it reached a minimum."""
    reached = bool(grad_norm < tol or floor)
    if stop == Status.MAX_ITER and reached:
        stop = Status.AT_FLOOR if floor else Status.CONVERGED
    return stop, reached


def minimum_flag(status: Status | None, converged: bool, cert: Any) -> bool | None:
    """``is_local_minimum`` of a chart's result: True at F's floor (a global minimum to
    :data:`uvbake.flatten.energy.FLOOR_TOL`, nothing to certify), else converged and certified; None
    without a certificate."""
    if status == Status.AT_FLOOR:
        return True
    return bool(converged and cert.is_local_minimum) if cert else None


@dataclass
class SolveResult:
    """What one backend run (:func:`~uvbake.flatten.solvers.lm.levenberg_marquardt` or
    :func:`~uvbake.flatten.solvers.lbfgs.lbfgs`) reports besides the end point.

    Attributes
    ----------
    energy, grad_norm : float
        F and the Euclidean norm of its gradient over the free unknowns at the end point.
    iterations, evaluations : int
        Iterations (LM: factorisations; L-BFGS: improving evaluations) and F+gradient evaluations.
    converged : bool
        grad_norm < tol, or F at its floor 0 (``Status.AT_FLOOR``: alpha = 1, or a developable chart).
    history : (k,) float array
        F at the start and after every iteration.
    status : Status
        Why the run stopped; ``message`` says it in words.
    solve_time_s : float
    extra : dict
        Backend details: LM ``linear_solver``, ``saddle_escapes``; L-BFGS ``restarts``,
        ``nlopt_results``, ``preconditioner``, ``preconditioner_builds``.
    """

    energy: float
    grad_norm: float
    iterations: int
    evaluations: int
    converged: bool
    history: np.ndarray
    status: Status
    message: str = ""
    solve_time_s: float = 0.0
    extra: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not self.message:
            self.message = MESSAGES[self.status]

    @property
    def stop_reason(self) -> str:
        """The status in words (as the reports spell it)."""
        return self.message


@dataclass
class ParamResult:
    """One chart's parameterization.

    Attributes
    ----------
    uv : (n,2) float array
        Per-vertex UVs in the surface's own length units.
    energy : float
        The paper's F (unweighted sum over triangles) at ``uv``.
    grad_norm : float
        Euclidean norm of grad F, with mesh and map scaled to unit mean edge length (scale-free).
    iterations : int
        Solver iterations (for LM: factorisations, rejected steps included).
    converged : bool
        True when grad_norm fell under the tolerance, or F reached its floor 0 (every triangle's terms
        within :data:`uvbake.flatten.energy.FLOOR_TOL`: at alpha = 1 its area, on a developable chart an
        isometry).
    n_flipped : int
        Triangles whose Jacobian determinant is <= 0 (flipped or collapsed).
    history : (k,) float array
        F after each iteration at the target alpha, starting with the F of the map it started from
        (after a continuation stage, whose own history is in ``extra["continuation"]``).
    time_s : float
        Wall time of init plus solve.
    status : Status
        Why the last solver run stopped (``stop_reason`` in words).
    lambda_min : float
        Smallest Hessian eigenvalue at ``uv`` off the rigid-motion gauge, in the solver's scale-free
        frame (the paper's Table 3 certificate; :mod:`uvbake.flatten.solvers.certificate`); NaN when
        not computed.
    is_local_minimum : bool or None
        Converged and lambda_min non-negative (to 1e-9 of the Hessian's largest diagonal entry); True
        with lambda_min NaN when the solve stopped at F's floor (``Status.AT_FLOOR``), a
        global minimum to :data:`uvbake.flatten.energy.FLOOR_TOL`.
    """

    uv: np.ndarray
    energy: float
    grad_norm: float
    iterations: int
    converged: bool
    n_flipped: int
    history: np.ndarray
    time_s: float
    alpha: float = 0.5
    init: str = "lscm"
    backend: str = "lm"
    energy_init: float = float("nan")
    stop_reason: str = ""
    n_evaluations: int = 0
    extra: dict[str, Any] = field(default_factory=dict)
    status: Status | None = None
    lambda_min: float = float("nan")
    is_local_minimum: bool | None = None
    #: when the map has flipped triangles: the solver's last iterate without any (chart units), or None
    flip_free_uv: np.ndarray | None = field(default=None, repr=False, compare=False)

    def certificate_line(self) -> str:
        """The summary line of the second-order certificate."""
        if self.is_local_minimum is None:
            return "local minimum: not certified"
        if self.status == Status.AT_FLOOR:
            return "local minimum: yes, global (F at its floor 0)"
        if not self.converged:                     # not "no": its Hessian may well be positive definite
            return f"local minimum: not certified (stopped before the gradient test), lambda_min = {self.lambda_min:.3g}"
        return f"local minimum: {'yes' if self.is_local_minimum else 'no (saddle)'}, lambda_min = {self.lambda_min:.3g}"

    def to_dict(self, *, with_uv: bool = False) -> dict[str, Any]:
        """JSON-ready summary (UVs left out unless asked)."""
        d = {
            "alpha": self.alpha,
            "init": self.init,
            "backend": self.backend,
            "vertices": int(len(self.uv)),
            "energy": float(self.energy),
            "energy_init": float(self.energy_init),
            "grad_norm": float(self.grad_norm),
            "iterations": int(self.iterations),
            "evaluations": int(self.n_evaluations),
            "converged": bool(self.converged),
            "stop_reason": self.stop_reason,
            "n_flipped": int(self.n_flipped),
            "time_s": float(self.time_s),
            # null where no certificate was found (standard JSON has no NaN)
            "lambda_min": float(self.lambda_min) if np.isfinite(self.lambda_min) else None,
            "is_local_minimum": self.is_local_minimum,
            "history": [float(h) for h in self.history],
        }
        d.update(self.extra)
        if with_uv:
            d["uv"] = np.asarray(self.uv).tolist()
        return d
