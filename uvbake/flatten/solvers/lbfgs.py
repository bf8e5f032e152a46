"""nlopt's L-BFGS (LD_LBFGS) on the distortion energy: the cross-check backend.

Same F, same analytic gradient (:class:`uvbake.flatten.energy.DistortionEnergy`), same stopping rule as
Levenberg-Marquardt (the Euclidean norm of the gradient over the free unknowns under ``tol``, the
problem being normalised to unit mean edge length), same result record.

nlopt has no gradient-norm stopping rule, so the objective checks the norm itself and raises
``nlopt.ForcedStop`` once it is under ``tol``. nlopt's own tests (ftol, xtol) are switched off; the
best point ever evaluated is kept and returned, whatever way the run ends.

What counts as an iteration. nlopt does not report its iterations. An *iteration* here is an
evaluation that improves on the best F seen so far: that is an accepted iterate of L-BFGS's line
search (a trial point of the line search that is not better is not an iteration, but it is an
evaluation). ``history`` holds F at x0 and then after every iteration, ``max_iter`` caps iterations,
and the callback is called once per iteration. ``evaluations`` counts every F+gradient evaluation.

Preconditioning. Plain L-BFGS needs thousands of iterations here (the Hessian's conditioning follows
the mesh), and nlopt's LD_LBFGS takes no preconditioner, so nlopt runs in the variables y of
x = x_ref + T y with T T^T = (H(x_ref) + mu I)^-1, H the Hessian of F (sparse Cholesky, once per
refresh); its objective is F(x_ref + T y) and its gradient T^T grad F. This is only a change of
coordinates: F, grad F, the stopping rule and the history stay in x, so a cross-check against LM still
tests F and its gradient. The preconditioner is rebuilt at the best point every ``refresh_every``
iterations.

Precision near the optimum. A line search compares values of F; once F's decrease per step falls
below F's rounding error (about 1e-16 |F|, i.e. 1e-13 on a chart with F ~ 1e3) the search cannot tell
better from worse. So the objective handed to nlopt is F(x) - F(x_ref), computed term by term
(:meth:`DistortionEnergy.change`, accurate to the rounding error of the *difference*, not of F).
When nlopt stops on its own short of the tolerance (round-off, its generic failure, or "success" from
its built-in gradient test, see :data:`SCALE`), L-BFGS is restarted from the best point (the memory
is lost; at most ``restarts`` times, and only while restarts still lower the gradient norm). Stop
reasons are reported as they happened: ``stop_reason`` is the final one, ``nlopt_results`` lists
every nlopt run's end.

Measurements behind the constants: docs/decisions/lbfgs.md (bench/backends.py).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike

from uvbake.cancel import check_cancelled, is_cancelled
from uvbake.errors import InputError
from uvbake.flatten.solvers.linalg import (
    NotPositiveDefinite,
    cholesky_lower,
    cholmod_available,
)
from uvbake.flatten.solvers.result import MESSAGES, SolveResult, Status

if TYPE_CHECKING:
    from uvbake.flatten.energy import DistortionEnergy

#: L-BFGS memory (stored correction pairs); docs/decisions/lbfgs.md
VECTOR_STORAGE = 20

#: Default change of variables (see :func:`_preconditioner`).
PRECONDITION = "cholesky"


#: nlopt sees SCALE * (F - F_ref): a larger scale moves Luksan's built-in gradient test (max |g_i| <= 1e-8)
#: out of the way of ours; raised SCALE_STEP-fold up to SCALE_MAX on each early "success" (docs/decisions/lbfgs.md)
SCALE = 1.0
SCALE_STEP = 1e3
SCALE_MAX = 1e12

#: Iterations per nlopt run before the preconditioner is rebuilt at the best point (docs/decisions/lbfgs.md)
REFRESH_EVERY = 50


#: nlopt's evaluation cap is a C int: a larger max_iter (a user's "no limit") is capped here.
NLOPT_MAX_EVAL = 2**31 - 1


def lbfgs(energy: DistortionEnergy, x0: ArrayLike, *, uv_fixed: ArrayLike, tol: float = 1e-8, max_iter: int = 1000,
          callback: Callable[[dict[str, Any]], bool | None] | None = None, vector_storage: int | None = None,
          max_eval: int | None = None, restarts: int = 50, precondition: str | None = None,
          refresh_every: int | None = None) -> tuple[np.ndarray, SolveResult]:
    """Minimise ``energy`` (a :class:`uvbake.flatten.energy.DistortionEnergy`) with nlopt's LD_LBFGS.

    Parameters
    ----------
    energy : DistortionEnergy
    x0 : (k,) float array
        Free unknowns of the start map.
    uv_fixed : (n,2) float array
        Per-vertex UVs supplying the values of fixed unknowns.
    tol : float
        Stop when ||grad F|| < tol (the same rule as Levenberg-Marquardt).
    max_iter : int
        Cap on iterations (evaluations that improved on the best F; see the module docstring).
    callback : callable, optional
        Called after every iteration with a dict (iteration, energy, grad_norm, evaluations);
        returning True stops the solve.
    vector_storage : int, optional
        L-BFGS memory (default :data:`VECTOR_STORAGE`).
    max_eval : int, optional
        Cap on F+gradient evaluations (default 20 * max_iter + 100).
    restarts : int
        Restarts allowed after nlopt stops on its own (round-off, failure, its own "success")
        before the tolerance.
    refresh_every : int, optional
        Iterations of one nlopt run before it is restarted with the preconditioner rebuilt at the
        best point (default :data:`REFRESH_EVERY`; 0 never refreshes).
    precondition : {"cholesky", "jacobi", "none"}, optional
        Change of variables x = x_ref + T y handed to nlopt (see :func:`_preconditioner`); default
        :data:`PRECONDITION`. F, the gradient, the stopping rule and the history stay in x.

    Returns
    -------
    x : (k,) float array
        The best point evaluated.
    result : SolveResult
        ``extra`` holds restarts, nlopt_results (every nlopt run's end, in words), preconditioner and
        preconditioner_builds.
    """
    import nlopt

    t0 = time.perf_counter()
    x0 = np.array(x0, dtype=np.float64)
    uv_fixed = np.asarray(uv_fixed, dtype=np.float64)
    zero_uv = np.zeros_like(uv_fixed)
    k = len(x0)
    m = int(VECTOR_STORAGE if vector_storage is None else vector_storage)
    max_eval = int(20 * max_iter + 100 if max_eval is None else max_eval)

    f0, g0 = energy.value_and_gradient(energy.to_uv(x0, uv_fixed))
    st = dict(x=x0.copy(), f=float(f0), g=float(np.linalg.norm(g0)), it=0, ev=1, stop=None)
    history = [st["f"]]
    early = _stop_before_start(st, tol, max_iter, k)
    if early is not None:
        return x0, _info(st, history, early, tol, [], 0, t0)

    kind = PRECONDITION if precondition is None else precondition
    refresh = REFRESH_EVERY if refresh_every is None else int(refresh_every)
    pc = dict(zip(("T", "Tt", "name"), _preconditioner(energy, x0, uv_fixed, kind)), scale=SCALE, builds=1)

    def run(x_ref):
        """One nlopt run from the best point; F is measured relative to F(x_ref), x = x_ref + T y."""
        uv_ref = energy.to_uv(x_ref, uv_fixed)
        f_ref = st["f"]
        best_rel = [0.0]                      # best F - f_ref seen in this run (x_ref itself is 0)
        T, Tt, scale = pc["T"], pc["Tt"], pc["scale"]
        it_start = st["it"]

        def objective(y, grad):
            x = x_ref + T(y)
            if is_cancelled():                       # SIGINT/SIGTERM: raised after nlopt returns
                st["stop"] = Status.CALLBACK         # never reported: check_cancelled raises
                raise nlopt.ForcedStop
            if st["ev"] >= max_eval:
                st["stop"] = Status.MAX_EVAL
                raise nlopt.ForcedStop
            uv = energy.to_uv(x, uv_fixed)
            f_abs, g = energy.value_and_gradient(uv)
            st["ev"] += 1
            rel = energy.change(uv_ref, energy.to_uv(x - x_ref, zero_uv))
            if grad.size:
                grad[:] = Tt(g) * scale
            if not (np.isfinite(f_abs) and np.all(np.isfinite(g))):
                return float("inf")
            if rel < best_rel[0]:
                best_rel[0] = rel
                gn = float(np.linalg.norm(g))
                st.update(x=np.array(x, dtype=np.float64), f=f_ref + rel, g=gn)
                st["it"] += 1
                history.append(st["f"])
                if gn < tol:
                    st["stop"] = Status.CONVERGED
                    raise nlopt.ForcedStop
                if callback is not None and callback(dict(iteration=st["it"], energy=st["f"],
                                                          grad_norm=gn, evaluations=st["ev"])):
                    st["stop"] = Status.CALLBACK
                    raise nlopt.ForcedStop
                if st["it"] >= max_iter:
                    st["stop"] = Status.MAX_ITER
                    raise nlopt.ForcedStop
                if refresh and st["it"] - it_start >= refresh:
                    st["refresh"] = True
                    raise nlopt.ForcedStop
            return float(rel) * scale

        opt = nlopt.opt(nlopt.LD_LBFGS, k)
        opt.set_min_objective(objective)
        opt.set_vector_storage(m)
        opt.set_ftol_rel(0.0)
        opt.set_ftol_abs(0.0)
        opt.set_xtol_rel(0.0)
        opt.set_xtol_abs(0.0)
        opt.set_maxeval(min(max(1, max_eval - st["ev"] + 1), NLOPT_MAX_EVAL))
        st.pop("refresh", None)
        try:
            opt.optimize(np.zeros(k))
            code = opt.last_optimize_result()
            status = {nlopt.SUCCESS: Status.NLOPT_SUCCESS, nlopt.STOPVAL_REACHED: Status.NLOPT_STOPVAL,
                      nlopt.FTOL_REACHED: Status.NLOPT_FTOL, nlopt.XTOL_REACHED: Status.NLOPT_XTOL,
                      nlopt.MAXEVAL_REACHED: Status.MAX_EVAL, nlopt.MAXTIME_REACHED: Status.NLOPT_MAXTIME}.get(
                          code, Status.NLOPT_OTHER)
            return status, (f"nlopt result {code}" if status == Status.NLOPT_OTHER else MESSAGES[status])
        except Exception as exc:
            # our own stops raise nlopt.ForcedStop from the objective; depending on the build, nlopt
            # hands it back as ForcedStop or as its generic runtime_error, so the flags decide
            if st.pop("refresh", False):
                return Status.REFRESH, MESSAGES[Status.REFRESH]
            if st["stop"] is not None:
                return st["stop"], MESSAGES[st["stop"]]
            if isinstance(exc, nlopt.RoundoffLimited):
                return Status.ROUNDOFF_LIMITED, MESSAGES[Status.ROUNDOFF_LIMITED]
            if isinstance(exc, nlopt.ForcedStop):
                return Status.FORCED_STOP, MESSAGES[Status.FORCED_STOP]
            detail = f"{type(exc).__name__}{': ' + str(exc) if str(exc) else ''}"
            return Status.NLOPT_FAILURE, f"nlopt failure ({detail})"

    reasons = []                           # (Status, message) of every nlopt run
    n_restart = 0
    while True:
        g_before = st["g"]
        reason = run(st["x"].copy())
        check_cancelled()
        reasons.append(reason)
        if st["stop"] is not None or reason[0] == Status.MAX_EVAL:
            break
        if reason[0] == Status.REFRESH:
            # planned: rebuild the preconditioner at the best point and go on (not a restart)
            if kind != "none":
                pc.update(zip(("T", "Tt", "name"), _preconditioner(energy, st["x"], uv_fixed, kind)))
                pc["builds"] += 1
            continue
        # nlopt stopped on its own short of the tolerance: restart from the best point while that
        # still helps; its "success" is its own gradient test, pushed away by a larger scale
        if reason[0] == Status.NLOPT_SUCCESS and pc["scale"] < SCALE_MAX:
            pc["scale"] = min(pc["scale"] * SCALE_STEP, SCALE_MAX)
        elif st["g"] >= 0.9 * g_before:
            break
        if n_restart >= restarts:
            break
        n_restart += 1
    stop = (st["stop"], MESSAGES[st["stop"]]) if st["stop"] is not None else reasons[-1]
    ends = [message for status, message in reasons if status != Status.REFRESH]
    return st["x"], _info(st, history, stop, tol, ends, n_restart, t0, pc["name"], pc["builds"])


def _stop_before_start(st, tol, max_iter, k):
    """Why no nlopt run is needed at the start (None: run)."""
    if not np.isfinite(st["f"]):
        return Status.NON_FINITE_START
    if st["g"] < tol:
        return Status.CONVERGED
    if max_iter == 0 or k == 0:
        return Status.MAX_ITER
    return None


def _preconditioner(energy, x0, uv_fixed, kind):
    """Maps y -> T y and g -> T^T g for the change of variables x = x_ref + T y, with T T^T ~ H^-1.

    "cholesky": M = H(x0) + mu I (F's Hessian at the start, mu raised tenfold from 1e-6 max diag H
    until M is positive definite), factored once, P M P^T = L L^T, T = P^T L^-T. The Hessian only
    shapes the path: the end point is where F's gradient vanishes, so the cross-check against LM
    still tests F and its gradient independently of LM's Newton steps. Needs scikit-sparse
    (CHOLMOD); without it, "jacobi" is used.
    "jacobi": T = diag(H(x0))^-1/2 (mesh-size grading only).
    "none": T = I.
    """
    if kind not in ("cholesky", "jacobi", "none"):
        raise InputError(f"precondition={kind!r} is not one of 'cholesky', 'jacobi', 'none'")
    if kind == "none" or len(x0) == 0:
        return (lambda y: y), (lambda g: g), "none"
    _, _, H = energy.evaluate(energy.to_uv(x0, uv_fixed))
    d = np.abs(H.diagonal())
    dmax = float(d.max()) if d.size and np.isfinite(d).all() else 0.0
    if not dmax > 0:
        return (lambda y: y), (lambda g: g), "none"
    if kind == "cholesky":
        if not cholmod_available():
            kind = "jacobi"
        else:
            eye = sp.identity(H.shape[0], format="csc")
            mu = 1e-6 * dmax
            for _ in range(12):
                try:
                    fac = cholesky_lower((H + mu * eye).tocsc())
                except NotPositiveDefinite:
                    mu *= 10.0
                    continue

                def T(y, fac=fac):
                    return fac.apply_Pt(fac.solve_Lt(y, use_LDLt_decomposition=False))

                def Tt(g, fac=fac):
                    return fac.solve_L(fac.apply_P(g), use_LDLt_decomposition=False)

                return T, Tt, f"cholesky (mu {mu / dmax:.0e} max diag)"
            kind = "jacobi"
    s = 1.0 / np.sqrt(np.maximum(d, 1e-12 * dmax))
    return (lambda y: s * y), (lambda g: s * g), "jacobi"


def _info(st, history, stop, tol, ends, n_restart, t0, pc_name="none", builds=0):
    status, message = (stop, MESSAGES[stop]) if isinstance(stop, Status) else stop
    return SolveResult(energy=float(st["f"]), grad_norm=float(st["g"]), iterations=int(st["it"]),
                       evaluations=int(st["ev"]), converged=bool(st["g"] < tol),
                       history=np.asarray(history, dtype=np.float64), status=status, message=message,
                       solve_time_s=time.perf_counter() - t0,
                       extra=dict(preconditioner=pc_name, preconditioner_builds=int(builds),
                                  restarts=int(n_restart), nlopt_results=list(ends)))
