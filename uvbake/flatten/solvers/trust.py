"""Trust-region Newton on the distortion energy: Steihaug-Toint truncated CG on the true Hessian,
preconditioned by the Cholesky factor of the per-triangle PSD projection of that Hessian.

Each iteration factors H+ + mu I once (H+ is H with every triangle's block projected onto the PSD
cone, :meth:`DistortionEnergy.projected_hessian`, so the factorisation never fails and none is wasted),
then runs preconditioned CG on the true model m(p) = g.p + p.H p / 2 inside the trust region
||p||_M <= Delta (M = H+ + mu I): CG stops at the boundary on negative curvature (the indefinite area
term is followed, not damped away), at the boundary when the iterate leaves the region, or when the
residual is below eta ||g|| with the forcing term eta = min(ETA_MAX, sqrt(||g||)) (superlinear
convergence). Where H is positive semidefinite per triangle H+ = H and CG ends after one step: the
Newton step. Nocedal & Wright, Numerical Optimization, 2nd ed., Alg. 4.1 and 7.2; Steihaug (1983).
The gain ratio uses the term-by-term change of F (DistortionEnergy.change), as LM does.
Measurements: docs/decisions/solver.md.
"""

from __future__ import annotations

import time

import numpy as np

from uvbake.cancel import check_cancelled
from uvbake.flatten.solvers.linalg import NotPositiveDefinite, make_solver
from uvbake.flatten.solvers.result import SolveResult, Status

ETA_MAX = 0.1          # loosest relative CG residual (far from the minimum)
MAX_CG = 50            # CG iterations per outer iteration
SHIFT = 1e-8           # mu = SHIFT * max diag H: the preconditioner's regularisation (gauge directions)
SHRINK, GROW = 0.25, 2.0
BACKTRACK = 4          # halvings of a failed trial step before the radius shrinks
ACCEPT = 1e-4          # accept a step when actual / predicted decrease exceeds it


def _boundary(zMz, zMd, dMd, delta):
    """tau >= 0 with ||z + tau d||_M = delta."""
    disc = zMd * zMd + dMd * (delta * delta - zMz)
    return (-zMd + np.sqrt(max(disc, 0.0))) / dMd


def steihaug(H, g, msolve, delta, eta, max_cg=MAX_CG):
    """Approximately minimise g.p + p.H p / 2 over ||p||_M <= delta by preconditioned CG.

    Returns (p, on_boundary, cg_iterations, negative_curvature)."""
    z = np.zeros_like(g)
    r = g.copy()
    y = msolve(r)
    d = -y
    ry = float(r @ y)
    zMz, zMd, dMd = 0.0, 0.0, ry
    gnorm = float(np.linalg.norm(g))
    for j in range(1, max_cg + 1):
        Hd = H @ d
        dHd = float(d @ Hd)
        if dHd <= 0:
            return z + _boundary(zMz, zMd, dMd, delta) * d, True, j, True
        a = ry / dHd
        zMz_new = zMz + 2.0 * a * zMd + a * a * dMd
        if zMz_new >= delta * delta:
            return z + _boundary(zMz, zMd, dMd, delta) * d, True, j, False
        z = z + a * d
        zMz = zMz_new
        r = r + a * Hd
        if np.linalg.norm(r) <= eta * gnorm:
            return z, False, j, False
        y = msolve(r)
        ry_new = float(r @ y)
        beta = ry_new / ry
        ry = ry_new
        zMd = beta * (zMd + a * dMd)
        dMd = ry + beta * beta * dMd
        d = -y + beta * d
    return z, False, max_cg, False


def trust_region(energy, x0, *, uv_fixed, tol=1e-8, max_iter=500, linear_solver="auto", callback=None,
                 step_limit=None, solver=None):
    """Minimise ``energy`` from the free unknowns ``x0``; the arguments and result of
    :func:`uvbake.flatten.solvers.lm.levenberg_marquardt` (iterations are factorisations)."""
    t0 = time.perf_counter()
    x = np.array(x0, dtype=np.float64)
    H = energy.empty_matrix()
    Hp = energy.empty_matrix()
    f, g, H = energy.evaluate(energy.to_uv(x, uv_fixed), out=H)
    solver = solver or make_solver(H, method=linear_solver)
    diag = energy.diagonal_slots
    hmax = float(np.max(np.abs(H.data[diag]))) if len(diag) else 1.0
    mu = SHIFT * max(hmax, 1e-300)
    gnorm = float(np.linalg.norm(g))
    delta = None
    history = [f]
    zero_uv = np.zeros_like(uv_fixed)
    it, n_eval, n_cg = 0, 1, 0
    stop = Status.MAX_ITER if np.isfinite(f) else Status.NON_FINITE_START
    fresh = True                                   # H+ must be refactored (x moved)
    while it < max_iter and stop == Status.MAX_ITER:
        check_cancelled()
        if gnorm < tol:
            stop = Status.CONVERGED
            break
        if fresh:
            energy.projected_hessian(energy.to_uv(x, uv_fixed), H, out=Hp)
            try:
                solver.factor(Hp, mu)
            except NotPositiveDefinite:            # rounding on a nearly singular H+: more shift
                mu *= 100.0
                it += 1
                continue
            it += 1
            fresh = False
        if delta is None:                          # first radius: the full preconditioned Newton step
            p0 = solver.solve(g)
            delta = float(np.sqrt(max(g @ p0, 0.0))) or 1.0
        eta = min(ETA_MAX, np.sqrt(gnorm))

        def pHp_m(v):
            return float(v @ (Hp @ v)) + mu * float(v @ v)

        p, boundary, j, _ = steihaug(H, g, solver.solve, delta, eta)
        n_cg += j
        if step_limit is not None:
            p = p * step_limit(x, p)
        uv = energy.to_uv(x, uv_fixed)
        gp, pHp = float(g @ p), float(p @ (H @ p))
        t, rho, actual = 1.0, -1.0, 0.0
        for _ in range(BACKTRACK + 1):
            # the trial step t p, halved (Armijo on the model's decrease) while it fails
            pred = -(t * gp + 0.5 * t * t * pHp)
            actual = -energy.change(uv, energy.to_uv(t * p, zero_uv))
            n_eval += 1
            rho = actual / pred if pred > 0 else -1.0
            if (rho > ACCEPT and actual > 0) or not BACKTRACK:
                break
            t *= 0.5
        accepted = bool(rho > ACCEPT and actual > 0)
        if t < 1.0 and accepted:
            delta = t * float(np.sqrt(pHp_m(p)))
        elif rho < 0.25:
            delta *= SHRINK
        elif rho > 0.75 and boundary:
            delta *= GROW
        p = t * p
        x_new = x + p
        if accepted:
            x = x_new
            f, g, H = energy.evaluate(energy.to_uv(x, uv_fixed), out=H)
            gnorm = float(np.linalg.norm(g))
            fresh = True
            if np.linalg.norm(p) <= 1e-15 * (1.0 + np.linalg.norm(x)):
                stop = Status.STEP_TOO_SMALL
        elif delta < 1e-15 * (1.0 + np.linalg.norm(x)):
            stop = Status.STEP_TOO_SMALL
        else:
            # a rejected step keeps the factorisation: the next try costs CG only, counted as an iteration
            it += 1
        history.append(f)
        if callback is not None and callback(dict(iteration=it, energy=f, grad_norm=gnorm, damping=delta,
                                                  accepted=accepted, reason=f"gain {rho:.3g} cg {j} bnd {boundary}")):
            stop = Status.CALLBACK if stop == Status.MAX_ITER else stop
            break
    if gnorm < tol:
        stop = Status.CONVERGED
    return x, SolveResult(energy=float(f), grad_norm=gnorm, iterations=it, evaluations=n_eval,
                          converged=bool(gnorm < tol), history=np.asarray(history), status=stop,
                          solve_time_s=time.perf_counter() - t0,
                          extra=dict(linear_solver=solver.name, cg_iterations=n_cg))
