"""Trust-region Newton on the distortion energy: Steihaug-Toint truncated CG on the true Hessian,
preconditioned by the Cholesky factor of the per-triangle PSD projection of that Hessian.

Each iteration factors M = H+ + mu I once (H+ is H with every triangle's block projected onto the PSD
cone, :meth:`DistortionEnergy.projected_hessian`, so the factorisation does not fail and none is
wasted), then runs preconditioned CG on the true model m(p) = g.p + p.H p / 2 inside the trust region
||p||_M <= Delta: CG stops at the boundary on negative curvature (the indefinite area term is
followed, not damped away), at the boundary when the iterate leaves the region, or when the residual
is below eta ||g|| with the forcing term eta = min(ETA_MAX, sqrt(||g||)) (superlinear convergence).
Where every triangle's block is positive semidefinite H+ = H and CG ends after one step: the Newton
step. A trial step that fails the gain test is halved along its direction (at most BACKTRACK times,
evaluations only) before the radius shrinks. Nocedal & Wright, Numerical Optimization, 2nd ed.,
Alg. 4.1 and 7.2; Steihaug (1983); Nocedal & Yuan (1998) for backtracking inside a trust region.

Iterations: factorisations plus trial steps that reuse a factorisation after a rejection, plus the
factorisations of the second-order test. At a stationary point the certificate
(:func:`~uvbake.flatten.solvers.certificate.certify`, on the same symbolic analysis) is the
second-order test: a negative lambda_min is a saddle, left along its eigenvector. Measurements and
the routes compared: docs/decisions/solver.md.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from uvbake.cancel import check_cancelled
from uvbake.flatten.solvers.certificate import certify
from uvbake.flatten.solvers.linalg import NotPositiveDefinite, make_solver
from uvbake.flatten.solvers.result import SolveResult, Status, final_status, floor_reached, stalled

if TYPE_CHECKING:
    from uvbake.flatten.energy import DistortionEnergy

ETA_MAX = 0.1          # loosest relative CG residual (far from the minimum)
MAX_CG = 50            # CG iterations per trial step
SHIFT = 1e-8           # mu = SHIFT * max diag H: regularises M on the gauge directions
SPREAD = 1e5           # ... max diag H taken at most SPREAD * its median (_diagonal_scale)
SHRINK, GROW = 0.25, 2.0
BACKTRACK = 4          # halvings of a failed trial step before the radius shrinks
ACCEPT = 1e-4          # a step is taken when actual / predicted decrease exceeds it
MAX_ESCAPES = 20       # saddle escapes per solve
NEWTON_FIRST = False   # after a full interior step with a good gain, try the true H + mu I first (measured: not adopted)
REUSE_CG = 10          # keep M for the next step after a Newton-like step that took <= REUSE_CG CG iterations
MODEL = "true"         # the model's Hessian: "true" H, or "projected" H+ (measured: projected Newton)
UNSHIFT_PINNED = True  # pinned (alpha = 0): drop mu once CG runs out against it (a chart of slivers)


def _diagonal_scale(d):
    """The scale of H's diagonal ``d`` that the shift mu is taken against: its largest entry, but at most
    SPREAD times its median. A sliver's entries grow like 1/area, so a reconstructed surface's few
    slivers can make the largest entry many orders above the rest; mu then swamps the other triangles'
    curvature in the preconditioner and CG stops at MAX_CG on every step (measured in
    docs/decisions/atlas.md, ninth session)."""
    if not len(d):
        return 1.0
    return max(min(float(d.max()), SPREAD * float(np.median(d))), 1e-300)


def _boundary(zMz, zMd, dMd, delta):
    """tau >= 0 with ||z + tau d||_M = delta."""
    disc = zMd * zMd + dMd * (delta * delta - zMz)
    return (-zMd + np.sqrt(max(disc, 0.0))) / dMd


def steihaug(H: Any, g: np.ndarray, msolve: Callable[[np.ndarray], np.ndarray], delta: float, eta: float,
             max_cg: int = MAX_CG) -> tuple[np.ndarray, bool, int]:
    """Approximately minimise g.p + p.H p / 2 over ||p||_M <= delta by CG preconditioned with M
    (``msolve(r) = M^-1 r``); the M-norms of the iterates are updated by the recurrences of Conn,
    Gould and Toint (Trust-Region Methods, 2000, sec. 7.5).

    Returns (p, on_boundary, cg_iterations)."""
    z = np.zeros_like(g)
    r = g.copy()
    y = msolve(r)
    d = -y
    ry = float(r @ y)
    zMz, zMd, dMd = 0.0, 0.0, ry
    stop = eta * float(np.linalg.norm(g))
    for j in range(1, max_cg + 1):
        Hd = H @ d
        dHd = float(d @ Hd)
        a = ry / dHd if dHd > 0 else np.inf
        zMz_new = zMz + 2.0 * a * zMd + a * a * dMd
        if dHd <= 0 or zMz_new >= delta * delta:      # negative curvature, or leaving the region
            return z + _boundary(zMz, zMd, dMd, delta) * d, True, j
        z = z + a * d
        zMz = zMz_new
        r = r + a * Hd
        if np.linalg.norm(r) <= stop:
            return z, False, j
        y = msolve(r)
        ry_new = float(r @ y)
        beta = ry_new / ry
        ry = ry_new
        zMd = beta * (zMd + a * dMd)
        dMd = ry + beta * beta * dMd
        d = -y + beta * d
    return z, False, max_cg


class _State:
    """The iterate, what is known at it, the factorisation of M there, and the counters."""

    def __init__(self, energy, x, uv_fixed, solver, linear_solver, step_limit):
        self.energy, self.uv_fixed, self.step_limit = energy, uv_fixed, step_limit
        self.zero_uv = np.zeros_like(uv_fixed)
        self.H = energy.empty_matrix()
        self.Hp = energy.empty_matrix()
        self.it, self.n_eval, self.n_cg, self.escapes = 0, 0, 0, 0
        self.history, self.cert = [], None
        self.flip_free = None                      # the last iterate with every det > 0 (unbounded steps)
        self.move(x)
        self.history.append(self.f)
        self.solver = solver or make_solver(self.H, method=linear_solver)
        self.pinned = bool(energy.fixed.any())
        self.newton, self.reuse, self.M = False, False, self.Hp
        self.mu_floor = SHIFT * _diagonal_scale(np.abs(self.H.data[energy.diagonal_slots]))
        self.mu, self.shift_needed = self.mu_floor, False

    def move(self, x):
        self.x = x
        self.uv = self.energy.to_uv(x, self.uv_fixed)
        self.f, self.g, _ = self.energy.evaluate(self.uv, out=self.H)
        self.floor = self.energy.at_floor          # F at its floor 0: a global minimum to FLOOR_TOL
        self.n_eval += 1
        if self.step_limit is None and self.energy.min_det > 0:   # det A of this evaluation
            self.flip_free = x
        self.gnorm = float(np.linalg.norm(self.g))
        self.factored = False                      # M must be factored at the new iterate
        self.cert = None

    def factor(self):
        """Factor M here (one iteration): H + mu I when the last step looked like Newton's (near the
        minimum, where H is positive definite but many triangles' blocks are not, so H+ != H), else
        H+ + mu I. False when the factorisation failed (H indefinite: H+ next; H+ nearly singular
        in rounding: mu raised)."""
        self.it += 1
        if self.newton:
            self.newton = False
            try:
                self.solver.factor(self.H, self.mu)
                self.M, self.factored = self.H, True
                return True
            except NotPositiveDefinite:
                self.history.append(self.f)
                return False
        self.energy.projected_hessian(self.uv, self.H, out=self.Hp)
        try:
            self.solver.factor(self.Hp, self.mu)
        except NotPositiveDefinite:                # rounding on a nearly singular H+: more shift
            self.shift_needed = self.shift_needed or self.mu == 0.0
            self.mu = max(self.mu * 100.0, self.mu_floor)
            self.history.append(self.f)
            return False
        self.M, self.factored = self.Hp, True
        return True

    def advance(self, step, delta):
        """Take ``step`` (zero when the trial failed); the status: MAX_ITER to go on."""
        x_old = self.x
        if np.any(step):
            self.move(self.x + step)
            self.factored = self.reuse             # M of the previous iterate as the preconditioner
        self.history.append(self.f)
        moved = float(np.linalg.norm(self.x - x_old))
        small = 1e-15 * (1.0 + np.linalg.norm(self.x))
        if (moved > 0 and moved <= small) or (moved == 0 and delta < small):
            return Status.STEP_TOO_SMALL
        return Status.MAX_ITER

    def msolve(self, r):
        """M^-1 r without its translation part when nothing is pinned: H is exactly singular along
        the two translations, where M's tiny shift would otherwise amplify r's rounding."""
        y = self.solver.solve(r)
        if not self.pinned:
            y = self.energy.center(y)
        return y

    @property
    def model(self):
        return self.Hp if MODEL == "projected" else self.H

    def after_trial(self, delta, t, rho, boundary, p, cg):
        """The new trust radius; whether to try the true H next (NEWTON_FIRST) or to keep the
        factorisation for the next step (REUSE_CG)."""
        good = t == 1.0 and not boundary and rho > 0.75
        self.newton = NEWTON_FIRST and good
        self.reuse = good and cg <= REUSE_CG
        radius = _radius(delta, t, rho, boundary, self.m_norm(p) if 0 < t < 1 else 0.0)
        if UNSHIFT_PINNED and cg >= MAX_CG and self.pinned and not self.shift_needed:
            # pinned (alpha = 0) there is no gauge to regularise, and CG ran out against the shift: on a
            # chart of slivers mu swamps the low modes (docs/decisions/solver.md); H+ alone from now on
            self.mu = 0.0
        return radius

    def m_norm(self, p):
        return float(np.sqrt(p @ (self.M @ p) + self.mu * (p @ p)))

    def second_order(self):
        """The certificate here; True when it found a saddle and moved off it."""
        self.cert = certify(self.energy, self.uv, H=self.H, solver=self.solver)
        self.it += self.cert.factorisations
        self.history.extend([self.f] * self.cert.factorisations)
        self.factored = False
        x_new = None if self.cert.is_local_minimum else _escape(self, self.cert, self.step_limit, self.zero_uv)
        if x_new is None:
            return False
        self.escapes += 1
        self.move(x_new)
        self.history[-1] = self.f
        return True


def _step(state, delta, step_limit):
    """(step, whether it ends on the trust region's boundary, CG iterations); the step None when it is
    not finite. A step cut short by the determinant bound ends inside the region, so it never grows the
    radius (grown at every such step, a solve pressed against folds overflows it)."""
    p, boundary, j = steihaug(state.model, state.g, state.msolve, delta, min(ETA_MAX, np.sqrt(state.gnorm)))
    state.n_cg += j
    if step_limit is not None:
        lim = step_limit(state.x, p)
        p, boundary = p * lim, boundary and lim >= 1.0
    return (p if np.all(np.isfinite(p)) else None), boundary, j


def _radius(delta, t, rho, boundary, m_norm):
    """The trust radius after a trial step (``t`` the fraction of the step taken, 0 if none)."""
    if 0 < t < 1.0:                                # backtracked: the radius of the step taken
        return t * m_norm
    if rho < 0.25:
        return delta * SHRINK
    if rho > 0.75 and boundary:
        return delta * GROW
    return delta


def _trial(state, p, zero_uv):
    """The largest of p, p/2, ..., p/2^BACKTRACK that passes the gain test, as
    (t, rho, evaluations); t = 0 when none does."""
    gp, pHp = float(state.g @ p), float(p @ (state.model @ p))
    t, rho = 1.0, -1.0
    for k in range(BACKTRACK + 1):
        pred = -(t * gp + 0.5 * t * t * pHp)
        actual = -state.energy.change(state.uv, state.energy.to_uv(t * p, zero_uv))
        rho = actual / pred if pred > 0 else -1.0
        if rho > ACCEPT and actual > 0:
            return t, rho, k + 1
        t *= 0.5
    return 0.0, rho, BACKTRACK + 1


def _escape(state, cert, step_limit, zero_uv):
    """A point lower than ``state`` along the certificate's negative-curvature eigenvector, or None."""
    v = cert.vector
    if v is None:
        return None
    for t in (1.0, 0.5, 0.25, 0.125, 0.0625, 0.03125):
        for sign in (1.0, -1.0):
            step = sign * t * v
            if step_limit is not None and step_limit(state.x, step) < 1.0:
                continue
            if state.energy.change(state.uv, state.energy.to_uv(step, zero_uv)) < 0:
                return state.x + step
    return None


def trust_region(energy: DistortionEnergy, x0: np.ndarray, *, uv_fixed: np.ndarray, tol: float = 1e-8,
                 max_iter: int = 500, linear_solver: str = "auto",
                 callback: Callable[[dict[str, Any]], Any] | None = None,
                 step_limit: Callable[[np.ndarray, np.ndarray], float] | None = None, solver: Any = None,
                 certificate: bool = True) -> tuple[np.ndarray, SolveResult]:
    """Minimise ``energy`` (a :class:`uvbake.flatten.energy.DistortionEnergy`) from the free unknowns ``x0``.

    The arguments and result of :func:`uvbake.flatten.solvers.lm.levenberg_marquardt`, and:

    solver : optional
        A solver of :func:`~uvbake.flatten.solvers.linalg.make_solver` for the Hessian's pattern
        (its symbolic analysis is reused; the caller may reuse it afterwards).
    certificate : bool
        Run the second-order test at the stationary point (and leave saddles); its
        :class:`~uvbake.flatten.solvers.certificate.Certificate` is ``extra["certificate"]``.

    ``extra`` also holds the CG iterations and the saddle escapes.
    """
    t0 = time.perf_counter()
    s = _State(energy, np.array(x0, dtype=np.float64), uv_fixed, solver, linear_solver, step_limit)
    delta = None
    stop = Status.MAX_ITER if np.isfinite(s.f) else Status.NON_FINITE_START
    while s.it < max_iter and stop == Status.MAX_ITER:
        check_cancelled()                          # SIGINT/SIGTERM: stop within one iteration
        if floor_reached(s.floor, energy.alpha, s.gnorm, tol):
            stop = Status.AT_FLOOR
            break
        if s.gnorm < tol:
            if certificate and s.escapes < MAX_ESCAPES and s.second_order():
                continue
            stop = Status.CONVERGED
            break
        if s.factored:
            s.it += 1                              # a new trial step on the same factorisation
        elif not s.factor():
            continue
        if delta is None:                          # first radius: the preconditioned steepest descent's
            delta = float(np.sqrt(max(s.g @ s.msolve(s.g), 0.0))) or 1.0
        p, boundary, j = _step(s, delta, step_limit)
        if p is None:                              # the model or its solve broke down: stop, keep x
            stop = Status.DAMPING_DIVERGED
            break
        t, rho, k = _trial(s, p, s.zero_uv)
        s.n_eval += k
        delta = s.after_trial(delta, t, rho, boundary, p, j)
        stop = s.advance(t * p, delta)
        if stop == Status.MAX_ITER and stalled(s.history):
            stop = Status.ROUNDOFF_LIMITED
        if callback is not None and callback(dict(iteration=s.it, energy=s.f, grad_norm=s.gnorm, damping=delta,
                                                  accepted=t > 0, reason=f"gain {rho:.3g}, {j} CG")):
            stop = Status.CALLBACK if stop == Status.MAX_ITER else stop
    stop, reached = final_status(stop, s.gnorm, tol, floor_reached(s.floor, energy.alpha, s.gnorm, tol))
    return s.x, SolveResult(energy=float(s.f), grad_norm=s.gnorm, iterations=s.it, evaluations=s.n_eval,
                            converged=reached, history=np.asarray(s.history), status=stop,
                            solve_time_s=time.perf_counter() - t0,
                            extra=dict(linear_solver=s.solver.name, cg_iterations=s.n_cg, saddle_escapes=s.escapes,
                                       certificate=s.cert, flip_free_x=s.flip_free))
