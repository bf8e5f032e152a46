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
from dataclasses import dataclass

import numpy as np

from uvbake.cancel import check_cancelled
from uvbake.flatten.solvers.linalg import NotPositiveDefinite, make_solver
from uvbake.flatten.solvers.result import SolveResult, Status

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


def levenberg_marquardt(energy, x0, *, uv_fixed, tol=1e-8, max_iter=500, lambda0=None,
                        linear_solver="auto", callback=None, step_limit=None):
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

    Returns
    -------
    x : (k,) float array
    result : SolveResult
        ``extra`` holds the linear solver used and the number of saddle escapes.
    """
    t0 = time.perf_counter()
    x = np.array(x0, dtype=np.float64)
    H = energy.empty_matrix()
    f, g, H = energy.evaluate(energy.to_uv(x, uv_fixed), out=H)
    n_eval = 1
    solver = make_solver(H, method=linear_solver)
    diag = energy.diagonal_slots
    gnorm = float(np.linalg.norm(g))
    hmax = float(np.max(np.abs(H.data[diag]))) if len(diag) else 1.0
    lam = (TAU * hmax if lambda0 is None else float(lambda0)) or 1e-12
    lam_min = 1e-15 * max(hmax, 1e-300)
    nu = 2.0
    lam_indef = 0.0
    escapes = 0
    history = [f]
    zero_uv = np.zeros_like(uv_fixed)
    it = 0
    stop = Status.MAX_ITER
    if not np.isfinite(f):
        stop = Status.NON_FINITE_START
    while it < max_iter and stop == Status.MAX_ITER:
        check_cancelled()                            # SIGINT/SIGTERM: stop within one iteration
        if gnorm < tol and it == 0:
            # a start that is already stationary still gets the second-order test
            out = _escape_saddle(energy, x, f, H, solver, uv_fixed, zero_uv, hmax, step_limit)
            it += out["factorisations"]
            history.extend([f] * out["factorisations"])
            if out["x"] is None:
                stop = Status.CONVERGED
                break
            escapes += 1
            x = out["x"]
            f, g, H = energy.evaluate(energy.to_uv(x, uv_fixed), out=H)
            gnorm = float(np.linalg.norm(g))
            history[-1] = f
            continue
        it += 1
        accepted = False
        step = _step(energy, x, g, H, lam, solver, uv_fixed, zero_uv, step_limit)
        indefinite = step is None          # H + lambda I was not positive definite (or the step not finite)
        reason = "indefinite" if step is None else step.reason     # for the callback only
        if step is not None:
            n_eval += step.evaluations
            rho, delta = step.rho, step.delta
            if step.actual > 0 and (rho > 0 or step.backtracked):
                accepted = True
                x = step.x_new
                f, g, H = energy.evaluate(energy.to_uv(x, uv_fixed), out=H)
                gnorm = float(np.linalg.norm(g))
                lam = max(lam * max(MIN_SHRINK, 1.0 - (2.0 * rho - 1.0) ** 3), lam_min,
                          INDEF_MARGIN * lam_indef)
                lam_indef *= INDEF_DECAY
                nu = 2.0
                if np.linalg.norm(delta) <= 1e-15 * (1.0 + np.linalg.norm(x)):
                    stop = Status.STEP_TOO_SMALL
        if not accepted:
            if indefinite:
                # remember where H + lambda I stopped being positive definite, and jump well past it
                lam_indef = max(lam_indef, lam)
                lam *= INDEF_JUMP
            else:
                lam *= nu
                nu *= 2.0
            if lam > 1e30 * max(hmax, 1.0):
                stop = Status.DAMPING_DIVERGED
        history.append(f)
        if gnorm < tol:
            if escapes < MAX_ESCAPES:
                out = _escape_saddle(energy, x, f, H, solver, uv_fixed, zero_uv, hmax, step_limit)
                it += out["factorisations"]
                n_eval += out["evaluations"]
                history.extend([f] * out["factorisations"])
                if out["x"] is not None:
                    escapes += 1
                    x = out["x"]
                    f, g, H = energy.evaluate(energy.to_uv(x, uv_fixed), out=H)
                    gnorm = float(np.linalg.norm(g))
                    lam = max(lam, out["shift"])
                    nu = 2.0
                    history[-1] = f
                    continue
            stop = Status.CONVERGED
        if callback is not None and callback(dict(iteration=it, energy=f, grad_norm=gnorm,
                                                  damping=lam, accepted=accepted,
                                                  reason=reason)):
            stop = Status.CALLBACK if stop == Status.MAX_ITER else stop
            break
    return x, SolveResult(energy=float(f), grad_norm=gnorm, iterations=it, evaluations=n_eval,
                          converged=bool(gnorm < tol), history=np.asarray(history), status=stop,
                          solve_time_s=time.perf_counter() - t0,
                          extra=dict(linear_solver=solver.name, saddle_escapes=escapes))


@dataclass
class _Step:
    x_new: np.ndarray
    delta: np.ndarray
    actual: float
    rho: float
    backtracked: bool
    evaluations: int
    reason: str


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
