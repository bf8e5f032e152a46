"""Many small charts solved as one problem.

F is a sum over triangles, so the F of several charts taken together is the sum of their Fs: its
gradient and Hessian are the charts' side by side (block diagonal), its minimisers are the charts'
minimisers, and its gradient norm is under ``tol`` only when every chart's is. Solving small charts
together pays the per-solve costs once (building the energy and the Hessian's pattern, the symbolic
analysis, each iteration's numpy and CHOLMOD calls) instead of once per chart: 200 charts of 40
triangles each took 5.6 ms apiece alone, mostly that overhead.

Each chart keeps its own frame (unit mean edge length, :func:`uvbake.mesh.arrays.unit_scale`), its
start's optimal scale, and its own translation and rotation gauge (``DistortionEnergy(parts=)``).
The trust region then runs on the sum: one trust radius, so a batch takes about as many iterations
as its slowest chart, and a per-iteration callback is called once per iteration of the batch (its
dict is the batch's; returning True stops the batch). What a chart reports of its own: UVs, energy,
gradient norm, flips and energy at the start; what it shares with its batch (``extra["joint"]``):
iterations, history, the stop reason and the second-order certificate (lambda_min is the least of
the batch's charts', so a lower bound of the chart's own).

Which charts join (:func:`joint_groups`): the trust region's step (``step="trust"``, ``backend="lm"``)
at alpha > 0 (at alpha 0 each chart pins two vertices and is rescaled after), from a given start with
every triangle positively oriented (no continuation stage), and of at most JOINT_MAX_FACES triangles
(with ``fill_holes``, charts without holes: a chart with holes is solved alone with its fans);
consecutive such charts fill a batch up to JOINT_FACES triangles.
Batches depend on the charts' order and sizes only, never on the machine.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from uvbake.cancel import check_cancelled
from uvbake.flatten.energy import DistortionEnergy, optimal_scales, scaled_start
from uvbake.flatten.holes import holes
from uvbake.flatten.options import SolveOptions
from uvbake.flatten.solvers.certificate import certify
from uvbake.flatten.solvers.linalg import make_solver
from uvbake.flatten.solvers.result import ParamResult, Status, minimum_flag
from uvbake.mesh.arrays import signed_areas, unit_scale

#: Charts of at most this many triangles may be solved together.
JOINT_MAX_FACES = 1000
#: A batch is closed once it holds this many triangles.
JOINT_FACES = 8000
#: Batches of fewer charts are solved chart by chart (nothing to share).
JOINT_MIN_CHARTS = 2

Item = tuple[np.ndarray, np.ndarray, str]


def joint_groups(items: Sequence[Item], options: SolveOptions,
                 starts: Sequence[np.ndarray | None] | None) -> list[list[int]]:
    """Batches of chart indices to solve together (each of JOINT_MIN_CHARTS charts or more, in the
    charts' order); the charts in none are solved one by one."""
    if (starts is None or options.alpha <= 0.0 or options.backend != "lm"
            or options.step != "trust"):
        return []
    groups: list[list[int]] = []
    cur: list[int] = []
    size = 0
    for i, ((_, F, _), s) in enumerate(zip(items, starts)):       # one iteration per chart
        if not _joins(F, s) or (options.fill_holes and holes(F) > 0):      # holes get fans: alone
            continue
        cur.append(i)
        size += len(F)
        if size >= JOINT_FACES:
            groups.append(cur)
            cur, size = [], 0
    groups.append(cur)
    return [g for g in groups if len(g) >= JOINT_MIN_CHARTS]


def _joins(F: np.ndarray, start: np.ndarray | None) -> bool:
    """Whether a chart may join a batch: small, and a finite start with every triangle positive."""
    if start is None or len(F) > JOINT_MAX_FACES or len(F) == 0:
        return False
    s = np.asarray(start, dtype=np.float64)
    return bool(s.ndim == 2 and s.shape[1] == 2 and np.all(np.isfinite(s))
                and np.all(signed_areas(s, np.asarray(F, dtype=np.int64)) > 0))


def solve_joint(items: Sequence[Item], options: SolveOptions, starts: Sequence[np.ndarray],
                callback: Any = None) -> list[ParamResult] | None:
    """The charts ``items`` ((V, F, name) each, disks with holes) solved together from ``starts``
    (see the module's docstring): one ParamResult per chart, in order; None when F is not finite at
    the start for some chart (a degenerate triangle): the caller then solves them one by one."""
    from uvbake.flatten.solve import _flip_free_uv, _run_backend

    t0 = time.perf_counter()
    check_cancelled()
    frames = [unit_scale(V, F) for V, F, _ in items]                 # one iteration per chart
    nv = np.array([len(V) for V, _, _ in items])
    nf = np.array([len(F) for _, F, _ in items])
    first = np.concatenate([[0], np.cumsum(nv)[:-1]])
    ffirst = np.concatenate([[0], np.cumsum(nf)])
    units = np.array([u for _, u in frames])
    vpart = np.repeat(np.arange(len(items)), nv)
    fpart = np.repeat(np.arange(len(items)), nf)
    V = np.concatenate([Vn for Vn, _ in frames])
    F = np.concatenate([np.asarray(f, dtype=np.int64) + o for (_, f, _), o in zip(items, first)])
    energy = DistortionEnergy(V, F, alpha=options.alpha, parts=vpart)
    uv0 = np.concatenate([np.asarray(s, dtype=np.float64) for s in starts]) / units[vpart][:, None]
    uv0 = scaled_start(uv0, optimal_scales(energy, uv0, fpart), vpart)
    f_init = _part_energies(energy, uv0, fpart, len(items))
    if not np.all(np.isfinite(f_init)) or not np.all(np.isfinite(uv0)):
        return None                               # one chart's non-finite F would stall the whole batch
    solver = make_solver(energy.empty_matrix(), method=options.linear_solver)
    x, info = _run_backend(energy, uv0, options, options.max_iter, callback, solver)
    uvn = energy.to_uv(x, uv0)
    g = energy.gradient(uvn).reshape(-1, 2)
    gnorm = np.sqrt(np.bincount(vpart, weights=(g * g).sum(axis=1), minlength=len(items)))
    f = _part_energies(energy, uvn, fpart, len(items))
    det = energy.determinants(uvn)
    flipped = np.bincount(fpart, weights=det <= 0, minlength=len(items)).astype(np.int64)
    floor = info.status == Status.AT_FLOOR        # F at its floor 0: a global minimum to FLOOR_TOL, nothing to certify
    reached = (gnorm < options.tol) | floor
    cert = info.extra.get("certificate")
    if cert is None and options.certificate and not floor:
        cert = certify(energy, uvn, linear_solver=options.linear_solver, solver=solver)
    share = time.perf_counter() - t0
    joint = dict(charts=len(items), triangles=int(nf.sum()), iterations=int(info.iterations))
    extra: dict[str, Any] = dict(linear_solver=info.extra.get("linear_solver"), joint=joint)
    if options.injective:
        extra["injective"] = True                 # no continuation stage: the step bound held throughout
    out = []
    for k, (_, _, name) in enumerate(items):                          # one iteration per chart
        v = slice(first[k], first[k] + nv[k])
        fk = slice(int(ffirst[k]), int(ffirst[k + 1]))
        ff = _flip_free_uv(energy, info, det[fk], uv0, 1.0)
        out.append(ParamResult(
            uv=uvn[v] * units[k], energy=float(f[k]), grad_norm=float(gnorm[k]), iterations=int(info.iterations),
            converged=bool(reached[k]), n_flipped=int(flipped[k]), history=np.asarray(info.history),
            time_s=share * nf[k] / nf.sum(), alpha=options.alpha, init="given", backend=options.backend,
            energy_init=float(f_init[k]), stop_reason=info.message, n_evaluations=int(info.evaluations),
            extra=dict(extra),
            status=info.status, lambda_min=cert.lambda_min if cert else float("nan"),
            is_local_minimum=minimum_flag(info.status, bool(reached[k]), cert),
            flip_free_uv=None if ff is None else ff[v] * units[k]))
    return out


def _part_energies(energy: DistortionEnergy, uv: np.ndarray, fpart: np.ndarray, k: int) -> np.ndarray:
    """Each part's F at ``uv``."""
    d_area, d_angle = energy.per_triangle(uv)
    per = energy.w * (energy.alpha * d_area + (1.0 - energy.alpha) * d_angle)
    return np.bincount(fpart, weights=per, minlength=k)
