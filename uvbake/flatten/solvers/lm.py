"""Levenberg-Marquardt on the distortion energy (the paper's Eq. 9) with the full Hessian.

Each iteration factors H + lambda I once (a rejected step counts as an iteration, as does a
factorisation that finds the damped matrix indefinite) and solves for the step
delta = -(H + lambda I)^-1 grad F. The damping follows the gain ratio
rho = (F(x) - F(x + delta)) / (predicted decrease of the quadratic model), with Nielsen's update
(H. B. Nielsen, "Damping parameter in Marquardt's method", IMM-REP-1999-05): on success
lambda *= max(1/10, 1 - (2 rho - 1)^3), on failure lambda *= nu, nu *= 2. Two additions, measured
a memory of where H + lambda I was last indefinite, and backtracking along a rejected step.
The actual decrease is computed term by term (DistortionEnergy.change), so the gain ratio stays
meaningful when the decrease is below F's rounding error. The matrix pattern never changes, so its
symbolic factorisation is computed once. Constants: docs/decisions/lm-damping.md.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from uvbake.cancel import check_cancelled
from uvbake.flatten.solvers.linalg import NotPositiveDefinite, make_solver
from uvbake.flatten.solvers.result import SolveResult, Status, final_status, floor_reached, stalled

if TYPE_CHECKING:
    from uvbake.flatten.energy import DistortionEnergy

# Damping constants, chosen by measurement (docs/decisions/lm-damping.md, bench/solver.py).
# MIN_SHRINK: an accepted step lowers lambda at most tenfold. Damping memory: after an accepted step
# lambda stays above INDEF_MARGIN times the largest lambda recently found indefinite, a memory that
# decays by INDEF_DECAY per accepted step. BACKTRACK: halvings of a rejected step (Armijo) before the
# factorisation counts as wasted.
MIN_SHRINK = 0.1
INDEF_MARGIN = 1.5
INDEF_DECAY = 0.5
INDEF_JUMP = 4.0
BACKTRACK = 4
TAU = 1e-6
# Second-order test at convergence: a stationary point where H + SADDLE_EPS * max(diag H) * I is not
# positive definite is a saddle; LM steps along the most negative curvature and goes on, at most
# MAX_ESCAPES times (docs/decisions/lm-damping.md).
SADDLE_EPS = 1e-9
MAX_ESCAPES = 20


def levenberg_marquardt(energy: DistortionEnergy, x0: np.ndarray, *, uv_fixed: np.ndarray, tol: float = 1e-8,
                        max_iter: int = 500, lambda0: float | None = None, linear_solver: str = "auto",
                        callback: Callable[[dict[str, Any]], Any] | None = None,
                        step_limit: Callable[[np.ndarray, np.ndarray], float] | None = None,
                        solver: Any = None) -> tuple[np.ndarray, SolveResult]:
    """Minimise ``energy`` (a :class:`uvbake.flatten.energy.DistortionEnergy`) from the free unknowns ``x0``.

    Parameters
    ----------
    energy : DistortionEnergy
    x0 : (k,) float array
        Free unknowns of the start map.
    uv_fixed : (n,2) float array
        Per-vertex UVs supplying the values of fixed unknowns.
    tol : float
        Stop when ||grad F|| < tol.
    max_iter : int
        Cap on iterations (factorisations).
    lambda0 : float, optional
        Initial damping; default TAU * max(diag H), small because the starts we use are close.
    callback : callable, optional
        Called after every iteration with a dict (iteration, energy, grad_norm, damping, accepted);
        returning True stops the solve.
    step_limit : callable, optional
        ``step_limit(x, delta) -> t`` in (0, 1]: the largest fraction of ``delta`` that may be taken
        (the injective solve of :mod:`uvbake.atlas.guarantee` keeps every det A > 0 this way). Each
        step, and each saddle escape, is shortened to it.
    solver : optional
        A solver of :func:`~uvbake.flatten.solvers.linalg.make_solver` for the Hessian's pattern,
        whose symbolic analysis is reused (default: a new one).

    Returns
    -------
    x : (k,) float array
    result : SolveResult
        ``extra`` holds the linear solver used and the number of saddle escapes.
    """
    t0 = time.perf_counter()
    s = _LMState(energy, np.array(x0, dtype=np.float64), uv_fixed, step_limit, solver or linear_solver)
    lam = _first_damping(lambda0, s.hmax)
    lam_min = 1e-15 * max(s.hmax, 1e-300)
    nu, lam_indef = 2.0, 0.0
    stop = Status.MAX_ITER if np.isfinite(s.f) else Status.NON_FINITE_START
    if stop == Status.MAX_ITER and max_iter > 0 and s.gnorm < tol and not s.floor:
        # a start that is already stationary still gets the second-order test (at F's floor: its global minimum)
        lam = max(lam, s.second_order_test())
    while s.it < max_iter and stop == Status.MAX_ITER:
        check_cancelled()                            # SIGINT/SIGTERM: stop within one iteration
        if floor_reached(s.floor, energy.alpha, s.gnorm, tol):
            stop = Status.AT_FLOOR
            break
        if s.gnorm < tol:
            stop = Status.CONVERGED
            break
        s.it += 1
        step = _step(energy, s.x, s.g, s.H, lam, s.solver, uv_fixed, s.zero_uv, step_limit)
        accepted = s.take(step)
        lam, nu, lam_indef = _damping(lam, nu, lam_indef, step, accepted, lam_min)
        stop = s.stop_after(step, accepted, lam)
        if stop == Status.MAX_ITER and stalled(s.history):
            stop = Status.ROUNDOFF_LIMITED
        if s.gnorm < tol and s.escapes < MAX_ESCAPES and stop == Status.MAX_ITER:
            shift = s.second_order_test()
            lam, nu = (max(lam, shift), 2.0) if shift else (lam, nu)
        if callback is not None and callback(dict(iteration=s.it, energy=s.f, grad_norm=s.gnorm, damping=lam,
                                                  accepted=accepted, reason=_reason(step))):
            stop = Status.CALLBACK if stop == Status.MAX_ITER else stop
    stop, reached = final_status(stop, s.gnorm, tol, floor_reached(s.floor, energy.alpha, s.gnorm, tol))
    return s.x, SolveResult(energy=float(s.f), grad_norm=s.gnorm, iterations=s.it, evaluations=s.n_eval,
                            converged=reached, history=np.asarray(s.history), status=stop,
                            solve_time_s=time.perf_counter() - t0,
                            extra=dict(linear_solver=s.solver.name, saddle_escapes=s.escapes))


def _first_damping(lambda0, hmax):
    return (TAU * hmax if lambda0 is None else float(lambda0)) or 1e-12


def _reason(step):
    """For the callback only."""
    return "indefinite" if step is None else step.reason


def _damping(lam, nu, lam_indef, step, accepted, lam_min):
    """Nielsen's update with the indefiniteness memory: the new (lambda, nu, lambda_indef)."""
    if accepted:
        lam = max(lam * max(MIN_SHRINK, 1.0 - (2.0 * step.rho - 1.0) ** 3), lam_min, INDEF_MARGIN * lam_indef)
        return lam, 2.0, lam_indef * INDEF_DECAY
    if step is None:
        # H + lambda I was not positive definite: remember where, and jump well past it
        return lam * INDEF_JUMP, nu, max(lam_indef, lam)
    return lam * nu, nu * 2.0, lam_indef


class _LMState:
    """LM's iterate, what is known there, and its counters."""

    def __init__(self, energy, x, uv_fixed, step_limit, solver):
        self.energy, self.uv_fixed, self.step_limit = energy, uv_fixed, step_limit
        self.zero_uv = np.zeros_like(uv_fixed)
        self.H = energy.empty_matrix()
        self.it, self.n_eval, self.escapes = 0, 0, 0
        self.history = []
        self.move(x)
        self.history.append(self.f)
        self.solver = make_solver(self.H, method=solver) if isinstance(solver, str) else solver
        diag = energy.diagonal_slots
        self.hmax = float(np.max(np.abs(self.H.data[diag]))) if len(diag) else 1.0

    def take(self, step):
        """Move to an accepted step; whether it was. The history gets F either way."""
        accepted = step is not None and step.accepted
        self.n_eval += step.evaluations if step is not None else 0
        if accepted:
            self.move(step.x_new)
        self.history.append(self.f)
        return accepted

    def move(self, x):
        self.x = x
        self.f, self.g, _ = self.energy.evaluate(self.energy.to_uv(x, self.uv_fixed), out=self.H)
        self.floor = self.energy.at_floor            # F at its floor 0: a global minimum to FLOOR_TOL
        self.n_eval += 1
        self.gnorm = float(np.linalg.norm(self.g))

    def stop_after(self, step, accepted, lam):
        """The status after an iteration: MAX_ITER to go on."""
        if accepted and np.linalg.norm(step.delta) <= 1e-15 * (1.0 + np.linalg.norm(self.x)):
            return Status.STEP_TOO_SMALL
        if not accepted and lam > 1e30 * max(self.hmax, 1.0):
            return Status.DAMPING_DIVERGED
        return Status.MAX_ITER

    def second_order_test(self):
        """At a stationary point: leave it along negative curvature if it is a saddle. Returns the
        shift where H + shift I became positive definite after an escape, else 0."""
        out = _escape_saddle(self.energy, self.x, self.f, self.H, self.solver, self.uv_fixed, self.zero_uv,
                             self.hmax, self.step_limit)
        self.it += out["factorisations"]
        self.n_eval += out["evaluations"]
        self.history.extend([self.f] * out["factorisations"])
        if out["x"] is None:
            return 0.0
        self.escapes += 1
        self.move(out["x"])
        self.history[-1] = self.f
        return out["shift"]


@dataclass
class _Step:
    x_new: np.ndarray
    delta: np.ndarray
    actual: float
    rho: float
    backtracked: bool
    evaluations: int
    reason: str

    @property
    def accepted(self):
        return self.actual > 0 and (self.rho > 0 or self.backtracked)


def _step(energy, x, g, H, lam, solver, uv_fixed, zero_uv, step_limit=None):
    """The damped Newton step from x, backtracked along its direction when it does not decrease F;
    None when H + lam I is not positive definite (or the step is not finite)."""
    try:
        solver.factor(H, lam)
        delta = -solver.solve(g)
    except NotPositiveDefinite:
        return None
    if not np.all(np.isfinite(delta)):
        return None
    if step_limit is not None:
        delta = delta * step_limit(x, delta)
    Hd = H @ delta
    pred = -(g @ delta + 0.5 * delta @ Hd)
    x_new = x + delta
    # the step actually taken (x_new - x is exact in floating point), fixed unknowns at 0
    duv = energy.to_uv(x_new - x, zero_uv)
    actual = -energy.change(energy.to_uv(x, uv_fixed), duv)
    n_eval = 1
    rho = actual / pred if pred > 0 else -1.0
    reason = f"gain {rho:.3g}"
    backtracked = False
    if not (rho > 0 and actual > 0):
        # the factorisation is paid for and delta is a descent direction (H + lambda I is
        # positive definite): try shorter steps along it, Armijo's rule, before giving up
        slope = float(g @ delta)
        t = 1.0
        for _ in range(BACKTRACK):
            t *= 0.5
            x_try = x + t * delta
            d_try = -energy.change(energy.to_uv(x, uv_fixed), energy.to_uv(x_try - x, zero_uv))
            n_eval += 1
            if d_try > -1e-4 * t * slope and d_try > 0:
                x_new, actual, rho = x_try, d_try, 0.0
                delta = x_try - x
                backtracked = True
                reason = f"backtracked to {t:g}"
                break
    return _Step(x_new, delta, actual, rho, backtracked, n_eval, reason)


def _escape_saddle(energy, x, f, H, solver, uv_fixed, zero_uv, hmax, step_limit):
    """At a stationary point: None if H is positive definite there, else a point lower along the most
    negative curvature direction (found by inverse iteration on H + shift I with the shift just past
    where it stops being indefinite, reusing the symbolic factorisation)."""
    out = dict(x=None, factorisations=1, evaluations=0, shift=0.0)
    eps = SADDLE_EPS * max(hmax, 1e-300)
    try:
        solver.factor(H, eps)
        return out                                   # a local minimum (up to the gauge directions)
    except NotPositiveDefinite:
        pass
    shift = eps
    while True:                                      # smallest shift (to a factor 2) that factors
        shift *= 4.0
        out["factorisations"] += 1
        try:
            solver.factor(H, shift)
            break
        except NotPositiveDefinite:
            if shift > 1e12 * max(hmax, 1.0):
                return out
    rng = np.random.default_rng(0)
    v = rng.standard_normal(len(x))
    for _ in range(30):                              # inverse iteration: the most negative eigenvector
        v = solver.solve(v)
        v /= np.linalg.norm(v)
    curvature = float(v @ (H @ v))
    if curvature >= 0:
        return out
    # F(x + t v) ~ F + t^2 curvature / 2 near the saddle: try steps until F decreases
    for t in (1.0, 0.5, 0.25, 0.125, 0.0625, 0.03125):
        for sign in (1.0, -1.0):
            if step_limit is not None and step_limit(x, sign * t * v) < 1.0:
                continue
            step = energy.to_uv(sign * t * v, zero_uv)
            out["evaluations"] += 1
            if energy.change(energy.to_uv(x, uv_fixed), step) < 0:
                out.update(x=x + sign * t * v, shift=shift)
                return out
    return out
