"""``parameterize``: flatten one chart by minimising the paper's F; ``parameterize_charts`` for many.

The solve runs on the chart scaled to unit mean edge length (F is invariant when mesh and map are
scaled together, and the gradient then has a scale-free norm: the paper's stopping rule made
independent of the model's units). The UVs are scaled back to the surface's own length units.

Gauge. F is invariant under translating and rotating the map, which LM's damping handles. At
alpha = 0 only the conformal term is left and its minimum is the collapsed map, so two boundary
vertices are pinned (as LSCM does) to fix translation, rotation and scale, and the converged map is
then scaled so its total UV area equals the surface's 3D area: the conformal map at the surface's
own scale. Its reported gradient norm is that of the pinned problem.

Running many charts. :func:`solve_chart` is a plain function of (chart, options, start) that pickles,
so any ``concurrent.futures.Executor`` runs it: :func:`parameterize_charts` uses threads by default
(the sparse factorisations and numpy kernels release the GIL). BLAS is limited to one thread per
worker (numpy's and CHOLMOD's OpenBLAS pools otherwise fight over the cores): in the calling process
once around the whole map, and in worker processes by the executor's initializer
:func:`limit_blas_threads`.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import time
from collections.abc import Callable, Sequence
from concurrent.futures import Executor, ThreadPoolExecutor, as_completed
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

from uvbake.cancel import check_cancelled
from uvbake.errors import InputError
from uvbake.flatten.energy import DistortionEnergy, optimal_scale, scaled_start
from uvbake.flatten.holes import chart_energy, with_hole_fans
from uvbake.flatten.joint import joint_groups, solve_joint
from uvbake.flatten.options import CONTINUATION_ALPHA, DEFAULTS, SolveOptions, _whole
from uvbake.flatten.pinches import pinches_end_to_end, welded
from uvbake.flatten.solvers.certificate import certify
from uvbake.flatten.solvers.lbfgs import lbfgs
from uvbake.flatten.solvers.linalg import cholmod_available, make_solver, one_blas_thread
from uvbake.flatten.solvers.lm import levenberg_marquardt
from uvbake.flatten.solvers.result import ParamResult, SolveResult, Status, minimum_flag
from uvbake.flatten.solvers.trust import trust_region
from uvbake.flatten.starts import farthest_boundary_pair, initial_map
from uvbake.mesh.arrays import signed_areas, unique_sorted, unit_scale
from uvbake.mesh.charts import Chart, check_chart

#: alphas of the continuation stages of an invalid start (measured: docs/decisions/solver.md)
CONTINUATION_SCHEDULE: tuple[float, ...] = (CONTINUATION_ALPHA,)

__all__ = ["parameterize", "parameterize_charts", "solve_chart", "limit_blas_threads", "SolveOptions"]

Callback = Callable[[dict[str, Any]], Any]
Progress = Callable[[int, int, ParamResult], Any]


def limit_blas_threads() -> None:
    """Executor initializer for worker processes: one BLAS thread for the worker's whole life.

    ``ProcessPoolExecutor(initializer=limit_blas_threads)``. Not for threads: BLAS pools are
    process-wide, so :func:`parameterize_charts` limits them once around the map instead.
    """
    cholmod_available()          # load CHOLMOD's BLAS first, so the limit reaches it too
    threadpool_limits(limits=1, user_api="blas")


def _run_backend(energy: DistortionEnergy, start: np.ndarray, options: SolveOptions, max_iter: int,
                 callback: Callback | None, solver: Any = None) -> tuple[np.ndarray, SolveResult]:
    """One backend run from ``start``; ``solver`` (the chart's, for the Hessian's pattern) is reused."""
    x0 = energy.to_vector(start)
    if options.backend == "lbfgs":
        return lbfgs(energy, x0, uv_fixed=start, tol=options.tol, max_iter=max_iter, callback=callback)
    step_limit = None
    if options.injective and np.all(energy.determinants(start) > 0):
        from uvbake.atlas.guarantee import determinant_step_limit

        step_limit = determinant_step_limit(energy, start)
    common = dict(uv_fixed=start, tol=options.tol, max_iter=max_iter, linear_solver=options.linear_solver,
                  callback=callback, step_limit=step_limit, solver=solver)
    if options.step == "trust":
        return trust_region(energy, x0, certificate=options.certificate, **common)
    return levenberg_marquardt(energy, x0, **common)


def _chart_arrays(chart: Chart | Sequence[Any], index: int = 0) -> tuple[np.ndarray, np.ndarray, str]:
    if isinstance(chart, Chart) or hasattr(chart, "V"):
        c: Any = chart
        return c.V, c.F, c.name
    name = chart[2] if len(chart) > 2 else f"chart {index}"
    return chart[0], chart[1], name


def solve_chart(chart: Chart | Sequence[Any], options: SolveOptions = DEFAULTS, start: np.ndarray | None = None,
                callback: Callback | None = None, checked: bool = False) -> ParamResult:
    """Flatten one chart: the work unit any executor runs (a picklable function of picklable data).

    Parameters
    ----------
    chart : :class:`uvbake.mesh.charts.Chart`, or (V, F) or (V, F, name)
    options : SolveOptions
    start : (n,2) float array, optional
        A start map of your own (overrides ``options.init``), in the surface's units.
    callback : callable, optional
        As in :func:`parameterize`.
    checked : bool
        The chart is known to be a disk with holes (:func:`uvbake.mesh.charts.check_chart` passed,
        as for the pipeline's charts): skip the check.

    Does not touch BLAS thread limits (see :func:`limit_blas_threads`).
    """
    t0 = time.perf_counter()
    check_cancelled()
    V, F, name = _chart_arrays(chart)
    if not checked:
        check_chart(V, F, name=name)
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    Vn, unit = unit_scale(V, F)
    alpha = options.alpha
    uv_start, init_name = _start_map(Vn, F, unit, start, options, name)

    m = len(F)
    energy, uv_start = _energy_and_start(Vn, F, uv_start, options)
    f_init = chart_energy(energy, uv_start, m)          # at the target alpha, before any continuation
    # one symbolic analysis per chart: the continuation's energy has the same pattern (no pins
    # when alpha > 0.1), and the certificate factors the same Hessian
    solver = make_solver(energy.empty_matrix(), method=options.linear_solver) if options.backend == "lm" else None

    uv_start, stage = _continuation(energy, uv_start, options, callback, solver)
    spent = stage.iterations if stage is not None else 0
    x, info = _run_backend(energy, uv_start, options, max(options.max_iter - spent, 0), callback, solver)
    iterations = info.iterations + spent
    evaluations = info.evaluations + (stage.evaluations if stage is not None else 0)
    history = info.history
    uvn = energy.to_uv(x, uv_start)
    if alpha == 0.0:
        # the pinned conformal map, scaled to the surface's own area. The pinned problem is linear,
        # so with the pins moved by the same scale its solution is the scaled map: a re-solve from
        # there only polishes the gradient, which the scaling multiplied by s.
        uvn = uvn * optimal_scale(energy, uvn)
        x, info = _run_backend(energy, uvn, options, options.max_iter, None, solver)
        uvn = energy.to_uv(x, uvn)
        iterations += info.iterations
        history = np.concatenate([history, info.history[1:]])
    grad_norm = info.grad_norm
    extra: dict[str, Any] = {}
    if "linear_solver" in info.extra:
        extra["linear_solver"] = info.extra["linear_solver"]
    if options.injective:
        extra["injective"] = bool(options.backend == "lm" and stage is None)
    if stage is not None:
        extra["continuation"] = dict(alpha=CONTINUATION_ALPHA, iterations=stage.iterations,
                                     energy=float(stage.energy), history=[float(h) for h in stage.history])
    det = energy.determinants(uvn)[:m]
    floor = info.status == Status.AT_FLOOR    # F at its floor 0: a global minimum to FLOOR_TOL, nothing to certify
    converged = bool(grad_norm < options.tol or floor)
    cert = info.extra.get("certificate")      # the trust region's own second-order test, at uvn
    if cert is None and options.certificate and not floor:
        cert = certify(energy, uvn, linear_solver=options.linear_solver, solver=solver)
    n = len(V)                                # the chart's own vertices (hole fans dropped)
    flip_free = _flip_free_uv(energy, info, det, uv_start, unit)
    return ParamResult(
        uv=uvn[:n] * unit,
        energy=chart_energy(energy, uvn, m),
        grad_norm=float(grad_norm),
        iterations=int(iterations),
        converged=converged,
        n_flipped=int(np.count_nonzero(det <= 0)),
        history=np.asarray(history),
        time_s=time.perf_counter() - t0,
        alpha=alpha,
        init=init_name,
        backend=options.backend,
        energy_init=float(f_init),
        stop_reason=info.message,
        n_evaluations=int(evaluations),
        extra=extra,
        status=info.status,
        lambda_min=cert.lambda_min if cert else float("nan"),
        is_local_minimum=minimum_flag(info.status, converged, cert),
        flip_free_uv=None if flip_free is None else flip_free[:n],
    )


def _energy_and_start(Vn: np.ndarray, F: np.ndarray, uv_start: np.ndarray,
                      options: SolveOptions) -> tuple[DistortionEnergy, np.ndarray]:
    """The chart's energy (two boundary vertices pinned at alpha = 0; holes filled with fans after the
    chart's own vertices and triangles with ``fill_holes``) and the start at its best uniform scale."""
    fixed = None
    if options.alpha == 0.0:
        p, q = farthest_boundary_pair(Vn, F)
        fixed = np.zeros(2 * len(Vn), bool)
        fixed[[2 * p, 2 * p + 1, 2 * q, 2 * q + 1]] = True
    weights = None
    if options.fill_holes and fixed is None and np.all(signed_areas(uv_start, F) > 0):
        Vn, F, weights, uv_start = with_hole_fans(Vn, F, uv_start)
    energy = DistortionEnergy(Vn, F, alpha=options.alpha, fixed=fixed, weights=weights)
    # best uniform scale of the start (at alpha = 0: the scale of equal total area), so that the
    # pins of the alpha = 0 gauge sit at the surface's own scale
    uv_start = scaled_start(uv_start, optimal_scale(energy, uv_start))
    if options.alpha == 0.0 and np.linalg.norm(uv_start[p] - uv_start[q]) == 0:
        uv_start[q] += [np.linalg.norm(Vn[q] - Vn[p]), 0.0]
    return energy, uv_start


def _flip_free_uv(energy: DistortionEnergy, info: SolveResult, det: np.ndarray, uv_start: np.ndarray,
                  unit: float) -> np.ndarray | None:
    """The backend's last flip-free iterate in chart units, when the result has flips (for a resumed,
    step-bounded solve); None otherwise, and at alpha 0, whose second run restarts from the scaled map."""
    x = info.extra.get("flip_free_x")
    if x is None or not np.any(det <= 0) or energy.alpha == 0.0:
        return None
    return energy.to_uv(x, uv_start) * unit


def _start_map(Vn: np.ndarray, F: np.ndarray, unit: float, start: np.ndarray | None, options: SolveOptions,
               name: str) -> tuple[np.ndarray, str]:
    """The start map in the solver's unit frame, and its name for the report."""
    if start is None:
        return initial_map(Vn, F, options.init, seed=options.seed), options.init
    start = np.asarray(start, dtype=np.float64)
    if start.shape != (len(Vn), 2) or not np.all(np.isfinite(start)):
        raise InputError(f"{name}: uv0 has shape {start.shape} or non-finite values; pass finite (n,2) UVs")
    return start / unit, "given"


def _continuation(energy: DistortionEnergy, start: np.ndarray,
                  options: SolveOptions, callback: Callback | None,
                  solver: Any = None) -> tuple[np.ndarray, SolveResult | None]:
    """An invalid start (flipped triangles, e.g. init="random") first goes to the nearly convex
    angle-dominated energy, then on to alpha (docs/decisions/continuation.md); with more than one
    stage in CONTINUATION_SCHEDULE, through each alpha below the target in turn."""
    stages = [a for a in CONTINUATION_SCHEDULE if a < options.alpha]
    if not (options.continuation and stages and np.any(energy.determinants(start) <= 0)):
        return start, None
    # the stages only have to reach the basin: no second-order test there
    opts = options.replace(certificate=False)
    total: SolveResult | None = None
    for a in stages:
        e_c = energy.with_alpha(a)
        spent = total.iterations if total is not None else 0
        x_c, info = _run_backend(e_c, start, opts, max(options.max_iter - spent, 0), callback, solver)
        start = e_c.to_uv(x_c, start)
        if total is not None:
            info.iterations += total.iterations
            info.evaluations += total.evaluations
            info.history = np.concatenate([total.history, info.history[1:]])
        total = info
    return start * optimal_scale(energy, start), total


def parameterize(V: np.ndarray, F: np.ndarray, *, alpha: float = DEFAULTS.alpha, init: str = DEFAULTS.init,
                 backend: str = DEFAULTS.backend, step: str = DEFAULTS.step, tol: float = DEFAULTS.tol, max_iter: int = DEFAULTS.max_iter,
                 seed: int = DEFAULTS.seed, uv0: np.ndarray | None = None, callback: Callback | None = None,
                 linear_solver: str = DEFAULTS.linear_solver, continuation: bool = DEFAULTS.continuation,
                 injective: bool = DEFAULTS.injective, certificate: bool = DEFAULTS.certificate,
                 fill_holes: bool = DEFAULTS.fill_holes, name: str = "chart 0") -> ParamResult:
    """Flatten one chart (a connected disk with holes) by minimising the paper's F.

    Parameters
    ----------
    V : (n,3) float array
    F : (m,3) int array
    alpha : float in [0, 1]
        Weight of area preservation; 1 - alpha weighs angle preservation.
    init : {"lscm", "tutte", "random", "isomap", "laplacian"}
        Start map. "tutte" needs one boundary loop; "random" is seeded by ``seed``; "isomap" and
        "laplacian" are the paper's Fig. 6 starts (:mod:`uvbake.flatten.starts`).
    backend : {"lm", "lbfgs"}
        The second-order solver with the full Hessian, or nlopt's L-BFGS on the same F and gradient.
    step : {"trust", "damped"}
        The "lm" backend's step: a trust-region Newton-CG step (default) or the paper's
        Levenberg-Marquardt damping (see :class:`~uvbake.flatten.options.SolveOptions`).
    tol : float
        Stop when the scale-free gradient norm is under ``tol``.
    max_iter : int
        Iteration cap (factorisations and trial steps, rejected ones included).
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
    injective : bool
        See :class:`uvbake.flatten.options.SolveOptions`: no determinant reaches zero during the LM.
    certificate : bool
        Compute the second-order certificate (``lambda_min``, ``is_local_minimum``): the smallest
        Hessian eigenvalue off the rigid-motion gauge, by shift-invert Lanczos
        (:mod:`uvbake.flatten.solvers.certificate`). False leaves them NaN / None.
    fill_holes : bool
        Solve with each hole filled by a lightly weighted fan of triangles (:mod:`uvbake.flatten.holes`),
        so a hole's border cannot fold over itself; the result holds the chart's own vertices only.

    Returns
    -------
    ParamResult
        ``uv (n,2)`` in the surface's length units, ``energy`` (the paper's F at uv), ``grad_norm``,
        ``iterations``, ``converged``, ``n_flipped``, ``history``, ``time_s``, ``status``.
    """
    options = SolveOptions(alpha=alpha, init=init, backend=backend, step=step, tol=tol, max_iter=max_iter, seed=seed,
                           linear_solver=linear_solver, continuation=continuation, injective=injective,
                           certificate=certificate, fill_holes=fill_holes)
    if callback is not None and not callable(callback):
        raise InputError(f"callback={callback!r} is not callable; pass a function or None")
    with one_blas_thread("blas"):
        return solve_chart((V, F, name), options, uv0, callback)


def parameterize_charts(charts: Sequence[Chart | Sequence[Any]], *, workers: int | None = None,
                        progress: Progress | None = None, starts: Sequence[np.ndarray | None] | None = None,
                        executor: Executor | None = None, options: SolveOptions | None = None,
                        callback: Callback | None = None, checked: bool = False,
                        pinch_keys: Sequence[np.ndarray | None] | None = None,
                        **option_values: Any) -> list[ParamResult]:
    """Parameterize several charts independently, in parallel.

    Parameters
    ----------
    charts : list of :class:`uvbake.mesh.charts.Chart` (or of (V, F) pairs)
    workers : int, optional
        Threads of the default executor (default: the number of CPUs, at most the number of charts).
        Without ``workers``, the default executor runs only when two charts or more have
        POOL_MIN_FACES triangles; else the charts are solved in turn in this thread (threads would
        only contend for the GIL).
    progress : callable, optional
        Called as ``progress(done, total, result)`` after each chart finishes.
    starts : list of ((k,2) array or None), optional
        A start map per chart (``uv0`` of :func:`parameterize`); None keeps ``init``.
    executor : concurrent.futures.Executor, optional
        Runs :func:`solve_chart` per chart (default: a thread pool of ``workers`` threads). For a
        ``ProcessPoolExecutor`` pass ``initializer=limit_blas_threads``, and no ``callback``.
    options : SolveOptions, optional
        The solve options; or give them as keywords (alpha, init, backend, tol, max_iter, seed, ...).
    callback : callable, optional
        Passed to every solve (see :func:`parameterize`).
    checked : bool
        Every chart already passed :func:`uvbake.mesh.charts.check_chart` (see :func:`solve_chart`).
    pinch_keys : list of ((k,) int array or None), optional
        Per chart, its vertices' pinch keys (:mod:`uvbake.flatten.pinches`: equal non-negative keys
        for copies of one input vertex a repair split): each pinch is solved as one vertex, and its
        copies get its UV.

    Returns
    -------
    list of ParamResult, in the order of ``charts`` (whatever order they finish in).
    """
    if options is None:
        options = SolveOptions(**option_values)
    elif option_values:
        options = options.replace(**option_values)
    items = [_chart_arrays(c, i) for i, c in enumerate(charts)]
    items, starts, backs = _weld_pinches(items, starts, pinch_keys)
    if workers is not None and (not _whole(workers) or workers < 1):
        raise InputError(f"workers={workers!r} must be a positive integer (threads solving charts)")
    chosen = workers is not None
    workers = int(workers or min(os.cpu_count() or 1, max(len(items), 1)))
    results: list[ParamResult | None] = [None] * len(items)
    done = 0

    def finish(i: int, res: ParamResult) -> None:
        nonlocal done
        results[i] = res
        done += 1
        if progress:
            progress(done, len(items), res)

    jobs = _jobs(items, options, starts, checked)
    # BLAS pools are process-wide: limit them once here, around every solve of this process
    # camelhead, 11 LM iterations: 3.1 s with two BLAS threads each, 1.55 s with one
    with one_blas_thread("blas"):
        if executor is None and (workers <= 1 or len(jobs) <= 1 or (not chosen and _few_large(items))):
            for job in sorted(jobs):
                for i, res in zip(job, _solve_job(items, job, options, starts, callback, checked)):
                    finish(i, res)
        else:
            # largest jobs first so the pool stays busy
            jobs.sort(key=lambda job: -sum(len(items[i][1]) for i in job))
            _run_pool([(job, (items, job, options, starts, callback, checked)) for job in jobs], executor, workers,
                      finish)
    return _unwelded([r for r in results if r is not None], backs)


def _weld_pinches(items: list[tuple[np.ndarray, np.ndarray, str]], starts: Sequence[np.ndarray | None] | None,
                  keys: Sequence[np.ndarray | None] | None
                  ) -> tuple[list[tuple[np.ndarray, np.ndarray, str]], Sequence | None, dict[int, np.ndarray]]:
    """(items, starts, backs): the charts with each pinch welded (:mod:`uvbake.flatten.pinches`; found
    for all charts at once, laid end to end), their starts on the kept vertices, and {chart: each
    original vertex's index among its kept ones} for the charts that changed (``keys`` None: none)."""
    if keys is None:
        return items, starts, {}
    if len(keys) != len(items):
        raise InputError(f"pinch_keys has {len(keys)} entries for {len(items)} charts; pass one per chart (or None)")
    nv = [len(V) for V, _, _ in items]
    rep, off = pinches_end_to_end(list(keys), [F for _, F, _ in items], nv)
    if rep is None:
        return items, starts, {}
    items, starts = list(items), None if starts is None else list(starts)
    backs: dict[int, np.ndarray] = {}
    moved = np.flatnonzero(rep != np.arange(len(rep)))
    for i in unique_sorted(np.searchsorted(off, moved, side="right") - 1):     # one per chart with a pinch
        Vi, Fi, name = items[i]
        kept, Fw, backs[int(i)] = welded(np.asarray(Fi, dtype=np.int64), rep[off[i]:off[i] + nv[i]] - off[i])
        items[i] = (np.asarray(Vi, dtype=np.float64)[kept], Fw, name)
        if starts is not None and starts[i] is not None:
            starts[i] = np.asarray(starts[i])[kept]
    return items, starts, backs


def _unwelded(results: list[ParamResult], backs: dict[int, np.ndarray]) -> list[ParamResult]:
    """``results`` with those of charts solved with their pinches welded (``backs``, see
    :func:`_weld_pinches`) on the charts' own vertices."""
    out = list(results)
    for i, back in backs.items():                   # one per chart with a pinch
        ff = out[i].flip_free_uv
        out[i] = dataclasses.replace(out[i], uv=out[i].uv[back], flip_free_uv=None if ff is None else ff[back])
    return out


def _jobs(items: list[tuple[np.ndarray, np.ndarray, str]], options: SolveOptions,
          starts: Sequence[np.ndarray | None] | None, checked: bool) -> list[list[int]]:
    """The solves to run, each a list of chart indices: a chart alone, or small charts solved together
    (:mod:`uvbake.flatten.joint`; only charts known to be disks, ``checked``)."""
    groups = joint_groups(items, options, starts) if checked else []
    grouped = {i for g in groups for i in g}
    return [[i] for i in range(len(items)) if i not in grouped] + groups


def _solve_job(items: list[tuple[np.ndarray, np.ndarray, str]], job: list[int], options: SolveOptions,
               starts: Sequence[np.ndarray | None] | None, callback: Callback | None,
               checked: bool) -> list[ParamResult]:
    """The results of one job: a chart alone (:func:`solve_chart`) or a batch solved together."""
    if len(job) == 1:
        i = job[0]
        return [solve_chart(items[i], options, None if starts is None else starts[i], callback, checked)]
    assert starts is not None
    together = solve_joint([items[i] for i in job], options, [np.asarray(starts[i]) for i in job], callback)
    if together is not None:
        return together
    return [solve_chart(items[i], options, starts[i], callback, checked) for i in job]


#: Charts of at least this many triangles keep a solving thread busy outside the GIL (sparse
#: factorisations, large array operations); smaller ones mostly hold it.
POOL_MIN_FACES = 5000


def _few_large(items: list[tuple[np.ndarray, np.ndarray, str]]) -> bool:
    """Whether fewer than two charts are large enough for the default thread pool to pay: threads on
    small charts contend for the GIL and cost CPU and wall time (cow's 30 charts: 2.3 s CPU and 2.1 s
    wall against 2.0 and 2.0 s solved in turn; 200 small spheres 6.6 / 6.3 s against 5.8 / 5.8 s;
    camelhead's 19, the largest 4,336 triangles: 5.9 s CPU against 5.2-5.6 s, wall level). Results
    are the same either way: each chart's solve is independent and deterministic."""
    return sum(len(F) >= POOL_MIN_FACES for _, F, _ in items) < 2


def _run_pool(jobs: list[tuple[list[int], tuple[Any, ...]]], executor: Executor | None, workers: int,
              finish: Callable[[int, ParamResult], None]) -> None:
    """:func:`_solve_job` of every job on ``executor`` (default a pool of ``workers`` threads)."""
    with contextlib.ExitStack() as stack:
        pool = executor or stack.enter_context(ThreadPoolExecutor(max_workers=workers))
        futures = {pool.submit(_solve_job, *args): job for job, args in jobs}
        try:
            for fut in as_completed(futures):
                for i, res in zip(futures[fut], fut.result()):
                    finish(i, res)
        except BaseException:
            # a chart failed or the run was stopped (a callback raised, Ctrl-C): charts not
            # yet started are dropped instead of solved before the error reaches the caller
            for fut in futures:
                fut.cancel()
            raise
