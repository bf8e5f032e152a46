"""``parameterize``: flatten one chart by minimising the paper's F; ``parameterize_charts`` for many.

The solve runs on the chart scaled to unit mean edge length (F is invariant when mesh and map are
scaled together, and the gradient then has a scale-free norm: the paper's stopping rule made
independent of the model's units). The UVs are scaled back to the surface's own length units.

Gauge. F is invariant under translating and rotating the map, which LM's damping handles. At
alpha = 0 only the conformal term is left and its minimum is the collapsed map, so two boundary
vertices are pinned (as LSCM does) to fix translation, rotation and scale, and the converged map is
then scaled so its total UV area equals the surface's 3D area: the conformal map at the surface's
own scale. Its reported gradient norm is that of the pinned problem.
"""

from __future__ import annotations

import os
import time
from concurrent.futures import ThreadPoolExecutor, as_completed

import numpy as np

from uvbake.mesh.charts import check_chart
from uvbake.flatten.energy import DistortionEnergy, optimal_scale
from uvbake.errors import InputError
from uvbake.flatten.starts import INITS, farthest_boundary_pair, initial_map
from uvbake.flatten.solvers.result import ParamResult

BACKENDS = ("lm", "lbfgs")


def _check_options(alpha, init, backend, tol, max_iter):
    try:
        alpha = float(alpha)
    except (TypeError, ValueError):
        raise InputError(f"alpha={alpha!r} is not a number; pass a weight between 0 and 1") from None
    if not (0.0 <= alpha <= 1.0):
        raise InputError(f"alpha={alpha!r} is outside [0, 1]; pass a weight between 0 (angles only) and 1 (areas only)")
    if init not in INITS:
        raise InputError(f"init={init!r} is not one of {', '.join(repr(i) for i in INITS)}")
    if backend not in BACKENDS:
        raise InputError(f"backend={backend!r} is not one of {', '.join(repr(b) for b in BACKENDS)}")
    if not (np.isfinite(tol) and tol > 0):
        raise InputError(f"tol={tol!r} must be a positive number (the scale-free gradient norm to reach)")
    if int(max_iter) != max_iter or max_iter < 0:
        raise InputError(f"max_iter={max_iter!r} must be a non-negative integer")
    return alpha


CONTINUATION_ALPHA = 0.1


def _solve(backend, energy, x0, uv_fixed, tol, max_iter, linear_solver, callback):
    if backend == "lm":
        from uvbake.flatten.solvers.lm import levenberg_marquardt

        return levenberg_marquardt(energy, x0, uv_fixed=uv_fixed, tol=tol, max_iter=max_iter,
                                   linear_solver=linear_solver, callback=callback)
    from uvbake.flatten.solvers.lbfgs import lbfgs

    return lbfgs(energy, x0, uv_fixed=uv_fixed, tol=tol, max_iter=max_iter, callback=callback)


def parameterize(V, F, *, alpha=0.5, init="lscm", backend="lm", tol=1e-8, max_iter=1000, seed=0,
                 uv0=None, callback=None, linear_solver="auto", continuation=True, name="chart 0"):
    """Flatten one chart (a connected disk with holes) by minimising the paper's F.

    Parameters
    ----------
    V : (n,3) float array
    F : (m,3) int array
    alpha : float in [0, 1]
        Weight of area preservation; 1 - alpha weighs angle preservation.
    init : {"lscm", "tutte", "random"}
        Start map. "tutte" needs one boundary loop; "random" is seeded by ``seed``.
    backend : {"lm", "lbfgs"}
        Levenberg-Marquardt with the full Hessian, or nlopt's L-BFGS on the same F and gradient.
    tol : float
        Stop when the scale-free gradient norm is under ``tol``.
    max_iter : int
        Iteration cap (LM: factorisations, rejected steps included).
    seed : int
        Seed of the random start.
    uv0 : (n,2) float array, optional
        A start map of your own (overrides ``init``), in the surface's units.
    callback : callable, optional
        Called after each iteration with a dict (iteration, energy, grad_norm, ...); return True to stop.
    linear_solver : {"auto", "cholmod", "superlu"}
    continuation : bool
        When the start has flipped triangles (always so for ``init="random"``) and alpha > 0.1,
        solve at alpha = 0.1 first and continue from there (reported in ``extra["continuation"]``;
        iterations of both stages are counted). False runs the paper's plain LM from the start.

    Returns
    -------
    ParamResult
        ``uv (n,2)`` in the surface's length units, ``energy`` (the paper's F at uv), ``grad_norm``,
        ``iterations``, ``converged``, ``n_flipped``, ``history``, ``time_s``.
    """
    from threadpoolctl import threadpool_limits

    from uvbake.flatten.solvers.linalg import cholmod_available

    cholmod_available()          # load CHOLMOD's BLAS first, so the limit below reaches it too

    # One BLAS thread: numpy's and CHOLMOD's OpenBLAS pools otherwise fight over the cores
    # (camelhead, 11 LM iterations: 3.1 s with two threads each, 1.55 s with one); charts run
    # in parallel threads instead.
    with threadpool_limits(limits=1, user_api="blas"):
        return _parameterize(V, F, alpha=alpha, init=init, backend=backend, tol=tol, max_iter=max_iter,
                             seed=seed, uv0=uv0, callback=callback, linear_solver=linear_solver,
                             continuation=continuation, name=name)


def _parameterize(V, F, *, alpha, init, backend, tol, max_iter, seed, uv0, callback, linear_solver,
                  continuation, name):
    t0 = time.perf_counter()
    alpha = _check_options(alpha, init, backend, tol, max_iter)
    check_chart(V, F, name=name)
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    # unit mean edge length, centred: the scale-free frame of the stopping rule
    edges = V[F[:, [1, 2, 0]]] - V[F]
    unit = float(np.mean(np.linalg.norm(edges, axis=2)))
    Vn = (V - V.mean(axis=0)) / unit
    if uv0 is not None:
        uv0 = np.asarray(uv0, dtype=np.float64)
        if uv0.shape != (len(V), 2) or not np.all(np.isfinite(uv0)):
            raise InputError(f"{name}: uv0 has shape {uv0.shape} or non-finite values; pass finite (n,2) UVs")
        start = uv0 / unit
        init_name = "given"
    else:
        start = initial_map(Vn, F, init, seed=seed)
        init_name = init

    fixed = None
    if alpha == 0.0:
        p, q = farthest_boundary_pair(Vn, F)
        fixed = np.zeros(2 * len(V), bool)
        fixed[[2 * p, 2 * p + 1, 2 * q, 2 * q + 1]] = True
    energy = DistortionEnergy(Vn, F, alpha=alpha, fixed=fixed)
    # best uniform scale of the start (at alpha = 0: the scale of equal total area), so that the
    # pins of the alpha = 0 gauge sit at the surface's own scale
    start = start * optimal_scale(energy, start)
    if alpha == 0.0 and np.linalg.norm(start[p] - start[q]) == 0:
        start[q] += [np.linalg.norm(Vn[q] - Vn[p]), 0.0]
    f_init = energy.value(start)          # at the target alpha, before any continuation

    stages = []
    if continuation and alpha > CONTINUATION_ALPHA and np.any(energy.determinants(start) <= 0):
        # An invalid start (flipped triangles, e.g. init="random") first goes to the nearly convex
        # angle-dominated energy, then on to alpha: measured on developable patches from random
        # starts at alpha 0.5 / 0.9, direct solves stall in wound local minima (F per triangle up to
        # 0.1) while the continuation reaches the isometry (F per triangle < 1e-20).
        e_c = DistortionEnergy(Vn, F, alpha=CONTINUATION_ALPHA)
        x_c, info_c = _solve(backend, e_c, e_c.to_vector(start), start, tol, max_iter, linear_solver, callback)
        start = e_c.to_uv(x_c, start)
        start = start * optimal_scale(energy, start)
        stages.append(info_c)
    x, info = _solve(backend, energy, energy.to_vector(start), start, tol,
                     max(max_iter - sum(st["iterations"] for st in stages), 0), linear_solver, callback)
    if stages:
        info = dict(info)
        info["iterations"] += stages[0]["iterations"]
        info["evaluations"] = info.get("evaluations", 0) + stages[0].get("evaluations", 0)
        info["continuation"] = dict(alpha=CONTINUATION_ALPHA, iterations=stages[0]["iterations"],
                                    energy=float(stages[0]["energy"]),
                                    history=[float(h) for h in stages[0]["history"]])
    uvn = energy.to_uv(x, start)
    grad_norm = info["grad_norm"]
    if alpha == 0.0:
        # the pinned conformal map, scaled to the surface's own area. The pinned problem is linear,
        # so with the pins moved by the same scale its solution is the scaled map: a re-solve from
        # there only polishes the gradient, which the scaling multiplied by s.
        uvn = uvn * optimal_scale(energy, uvn)
        x, polish = _solve(backend, energy, energy.to_vector(uvn), uvn, tol, max_iter, linear_solver, None)
        uvn = energy.to_uv(x, uvn)
        grad_norm = polish["grad_norm"]
        info["iterations"] += polish["iterations"]
        info["history"] = np.concatenate([info["history"], polish["history"][1:]])
    det = energy.determinants(uvn)
    uv = uvn * unit
    return ParamResult(
        uv=uv,
        energy=float(DistortionEnergy.value(energy, uvn)),
        grad_norm=float(grad_norm),
        iterations=int(info["iterations"]),
        converged=bool(grad_norm < tol),
        n_flipped=int(np.count_nonzero(det <= 0)),
        history=np.asarray(info["history"]),
        time_s=time.perf_counter() - t0,
        alpha=alpha,
        init=init_name,
        backend=backend,
        energy_init=float(f_init),
        stop_reason=info["stop_reason"],
        n_evaluations=int(info.get("evaluations", 0)),
        extra={k: info[k] for k in ("linear_solver", "continuation") if k in info},
    )


def parameterize_charts(charts, *, workers=None, progress=None, starts=None, **options):
    """Parameterize several charts independently, in parallel threads.

    Parameters
    ----------
    charts : list of :class:`uvbake.mesh.charts.Chart` (or of (V, F) pairs)
    workers : int, optional
        Threads to use (default: the number of CPUs, at most the number of charts). The heavy work
        (sparse factorisations, numpy kernels) releases the GIL.
    progress : callable, optional
        Called as ``progress(done, total, result)`` after each chart finishes.
    starts : list of ((k,2) array or None), optional
        A start map per chart (``uv0`` of :func:`parameterize`); None keeps ``init``.
    **options
        Passed to :func:`parameterize` (alpha, init, backend, tol, max_iter, seed, ...).

    Returns
    -------
    list of ParamResult, in the order of ``charts``.
    """
    items = [(c.V, c.F, c.name) if hasattr(c, "V") else (c[0], c[1], f"chart {i}") for i, c in enumerate(charts)]
    if not items:
        return []
    _check_options(options.get("alpha", 0.5), options.get("init", "lscm"), options.get("backend", "lm"),
                   options.get("tol", 1e-8), options.get("max_iter", 1000))
    workers = workers or min(os.cpu_count() or 1, len(items))
    results = [None] * len(items)
    done = 0

    def run(i):
        V, F, name = items[i]
        uv0 = None if starts is None else starts[i]
        return i, parameterize(V, F, name=name, uv0=uv0, **options)

    if workers <= 1 or len(items) == 1:
        for i in range(len(items)):
            _, results[i] = run(i)
            done += 1
            if progress:
                progress(done, len(items), results[i])
        return results
    with ThreadPoolExecutor(max_workers=workers) as pool:
        # largest charts first so the pool stays busy
        order = sorted(range(len(items)), key=lambda i: -len(items[i][1]))
        for fut in as_completed([pool.submit(run, i) for i in order]):
            i, res = fut.result()
            results[i] = res
            done += 1
            if progress:
                progress(done, len(items), res)
    return results
