"""The chart-solve machinery: SolveOptions, the shared result and status, executors, BLAS limits, PD tests."""

import dataclasses
import multiprocessing
import pickle
import sys
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor

import numpy as np
import pytest
import scipy.sparse as sp
from threadpoolctl import threadpool_info, threadpool_limits

from uvbake.errors import InputError
from uvbake.flatten.options import DEFAULTS, SolveOptions
from uvbake.flatten.solve import limit_blas_threads, parameterize, parameterize_charts, solve_chart
from uvbake.flatten.solvers.linalg import cholmod_available, is_positive_definite
from uvbake.flatten.solvers.result import MESSAGES, Status

from meshgen import bumpy_disk, cone, plane


def _charts():
    return [bumpy_disk(10), plane(7, 6), cone(10, 4), bumpy_disk(8, seed=3)]


def _blas_threads():
    return sorted((d["filepath"], d["num_threads"]) for d in threadpool_info() if d["user_api"] == "blas")


# ---- options -----------------------------------------------------------------------------------

def test_options_are_frozen_and_validated_once_with_the_parameter_names():
    o = SolveOptions(alpha=1)
    assert o.alpha == 1.0 and isinstance(o.alpha, float)
    with pytest.raises(dataclasses.FrozenInstanceError):
        o.alpha = 0.3
    for bad, word in [(dict(alpha=1.5), "alpha"), (dict(alpha="x"), "alpha"), (dict(init="lsqm"), "init"),
                      (dict(backend="newton"), "backend"), (dict(tol=0.0), "tol"), (dict(max_iter=2.5), "max_iter"),
                      (dict(linear_solver="mkl"), "linear_solver")]:
        with pytest.raises(InputError, match=word):
            SolveOptions(**bad)
    with pytest.raises(InputError, match="alpha"):
        o.replace(alpha=-0.1)
    # one set of defaults: parameterize's signature takes them from DEFAULTS
    import inspect

    sig = inspect.signature(parameterize).parameters
    for f in dataclasses.fields(SolveOptions):
        assert sig[f.name].default == getattr(DEFAULTS, f.name)


# ---- status ------------------------------------------------------------------------------------

@pytest.mark.parametrize("backend", ["lm", "lbfgs"])
def test_both_backends_report_a_status_and_its_message(backend):
    V, F = bumpy_disk(10)
    r = parameterize(V, F, alpha=0.5, backend=backend)
    assert r.converged and r.status == Status.CONVERGED and r.stop_reason == MESSAGES[Status.CONVERGED]
    r = parameterize(V, F, alpha=0.9, init="random", max_iter=3, continuation=False, backend=backend)
    assert not r.converged and r.status == Status.MAX_ITER and r.stop_reason == "max_iter"


# ---- executors and BLAS threads ------------------------------------------------------------------

def test_blas_thread_limits_are_restored_after_parameterize_charts():
    cholmod_available()          # CHOLMOD's BLAS loaded before the count, as the solves load it
    with threadpool_limits(limits=2, user_api="blas"):
        before = _blas_threads()
        assert before and all(n == 2 for _, n in before)
        for _ in range(2):
            parameterize_charts(_charts(), workers=3, alpha=0.5)
            assert _blas_threads() == before
        parameterize(*bumpy_disk(8), alpha=0.5)
        assert _blas_threads() == before


def test_solve_chart_pickles_and_any_executor_gives_the_same_bytes():
    charts = _charts()
    options = SolveOptions(alpha=0.5)
    assert pickle.loads(pickle.dumps(solve_chart)) is solve_chart
    serial = parameterize_charts(charts, workers=1, options=options)
    with ThreadPoolExecutor(max_workers=2) as pool:
        threads = parameterize_charts(charts, executor=pool, options=options)
    ctx = multiprocessing.get_context("spawn")   # fork after threads can deadlock
    with ProcessPoolExecutor(max_workers=2, mp_context=ctx, initializer=limit_blas_threads) as pool:
        procs = parameterize_charts(charts, executor=pool, options=options)
    for a, b, c in zip(serial, threads, procs):
        assert a.converged
        # same input and options, one BLAS thread everywhere: identical bits whatever runs the solve
        assert np.array_equal(a.uv, b.uv) and np.array_equal(a.uv, c.uv)
        assert a.iterations == b.iterations == c.iterations


# ---- positive-definite test ------------------------------------------------------------------------

def _methods():
    return ["superlu"] + (["cholmod", "cholmod-supernodal"] if cholmod_available() else [])


@pytest.mark.parametrize("method", _methods())
def test_indefinite_matrices_are_rejected_by_superlu_as_by_cholmod(method, monkeypatch):
    if method == "cholmod-supernodal":               # the L L^T that charts of SUPERNODAL_FROM unknowns get
        import uvbake.flatten.solvers.linalg as linalg

        monkeypatch.setattr(linalg, "SUPERNODAL_FROM", 1)
        assert linalg.cholmod_mode(2) == "supernodal"
        method = "cholmod"
    rng = np.random.default_rng(0)
    n = 12
    B = rng.standard_normal((n, n))
    pd = B @ B.T + n * np.eye(n)                      # positive definite
    swap = np.array([[0.0, 1.0], [1.0, 0.0]])          # zero diagonal, eigenvalues +-1: SuperLU must pivot
    cases = [
        (pd, True),
        (np.block([[pd, np.zeros((n, 2))], [np.zeros((2, n)), swap]]), False),
        (np.array([[1.0, 2.0], [2.0, 1.0]]), False),   # positive diagonal, eigenvalues 3 and -1
        (pd - (np.linalg.eigvalsh(pd)[0] - 1e-3) * np.eye(n), True),    # smallest eigenvalue 1e-3
        (pd - (np.linalg.eigvalsh(pd)[0] + 1.0) * np.eye(n), False),    # smallest eigenvalue -1
    ]
    for M, expected in cases:
        assert (np.linalg.eigvalsh(M)[0] > 0) == expected    # the reference verdict
        assert is_positive_definite(sp.csc_matrix(M), method=method) == expected
    broken = pd.copy()
    broken[3, 3] = np.nan                             # a supernodal L L^T does not stop at a NaN pivot
    assert not is_positive_definite(sp.csc_matrix(broken), method=method)


def test_the_default_thread_pool_runs_only_for_two_large_charts_or_more(monkeypatch):
    import uvbake.flatten.solve as solve

    charts = [bumpy_disk(n=8, seed=s) for s in range(3)]                   # 98 triangles each
    pools = []

    class Counting(ThreadPoolExecutor):
        def __init__(self, *a, **k):
            pools.append(k.get("max_workers"))
            super().__init__(*a, **k)

    monkeypatch.setattr(solve, "ThreadPoolExecutor", Counting)
    monkeypatch.setattr(solve.os, "cpu_count", lambda: 2)
    serial = solve.parameterize_charts(charts, alpha=0.5)                 # small charts: solved in turn
    assert pools == []
    asked = solve.parameterize_charts(charts, workers=2, alpha=0.5)       # threads asked for: threads
    assert pools == [2]
    monkeypatch.setattr(solve, "POOL_MIN_FACES", len(charts[0][1]))      # now every chart counts as large
    pooled = solve.parameterize_charts(charts, alpha=0.5)
    assert pools == [2, 2]
    for a, b, c in zip(serial, asked, pooled):                             # the same results either way
        assert np.array_equal(a.uv, b.uv) and np.array_equal(a.uv, c.uv) and a.iterations == c.iterations


# ---- small charts solved together ------------------------------------------------------------------

def _small_charts_with_starts():
    from uvbake.atlas.conformal import lscm

    charts = [bumpy_disk(n=6, seed=s) for s in range(3)] + [cone(nu=10, nv=4), plane(nu=7, nv=6)]
    charts[1] = (charts[1][0] * 7.0, charts[1][1])                          # another unit: its own frame
    return charts, [lscm(V, F) for V, F in charts]


def _singular_values(V, F, uv):
    from uvbake.flatten.energy import jacobians, triangle_frames

    _, Q, _ = triangle_frames(np.asarray(V, float), np.asarray(F))
    return np.linalg.svd(jacobians(Q, np.asarray(F), uv), compute_uv=False)


def test_small_charts_solved_together_reach_each_charts_own_minimum(monkeypatch):
    """F is a sum over triangles: the batch's minimiser is every chart's own (up to each chart's own
    rotation and translation), its gradient norm bounds each chart's, and its certificate's lambda_min
    is the least of the charts'."""
    import uvbake.flatten.energy as energy_module
    from uvbake.flatten import joint

    charts, starts = _small_charts_with_starts()
    options = SolveOptions(alpha=0.5)
    # the plane alone is developable: its conformal start is an isometry, F at its floor 0 (no certificate)
    flat = solve_chart(charts[4], options, starts[4], checked=True)
    assert flat.status == Status.AT_FLOOR and flat.is_local_minimum and np.isnan(flat.lambda_min)
    assert flat.grad_norm < options.tol                      # below alpha 1 the gradient test still decides
    assert flat.energy <= len(charts[4][1]) * energy_module.FLOOR_TOL ** 2
    monkeypatch.setattr(energy_module, "FLOOR_TOL", 0.0)     # every chart certified, to compare the lambdas
    assert joint.joint_groups([(V, F, "c") for V, F in charts], options, starts) == [[0, 1, 2, 3, 4]]
    together = joint.solve_joint([(V, F, f"c{i}") for i, (V, F) in enumerate(charts)], options, starts)
    alone = [solve_chart((V, F), options, s, checked=True) for (V, F), s in zip(charts, starts)]
    for (V, F), t, a in zip(charts, together, alone):
        assert t.converged and a.converged and t.grad_norm < options.tol and t.n_flipped == 0
        assert t.extra["joint"]["charts"] == 5
        assert t.energy == pytest.approx(a.energy, rel=1e-9, abs=1e-12)
        assert t.energy_init == pytest.approx(a.energy_init, rel=1e-9)
        # the same map up to a rigid motion: the Jacobians' singular values agree
        assert np.allclose(_singular_values(V, F, t.uv), _singular_values(V, F, a.uv), rtol=1e-6, atol=1e-8)
        assert t.is_local_minimum and t.lambda_min <= a.lambda_min * (1 + 1e-6) + 1e-12
    assert together[0].lambda_min == pytest.approx(min(a.lambda_min for a in alone), rel=1e-5)


def test_a_batch_small_enough_for_the_dense_certificate_sets_each_charts_gauge_aside(monkeypatch):
    import uvbake.flatten.energy as energy_module
    from uvbake.atlas.conformal import lscm
    from uvbake.flatten import joint

    monkeypatch.setattr(energy_module, "FLOOR_TOL", 0.0)     # flat charts: certified, not stopped at F's floor
    charts = [plane(nu=3, nv=3, seed=s) for s in range(3)]                    # 9 vertices each: 54 unknowns
    starts = [lscm(V, F) for V, F in charts]
    options = SolveOptions(alpha=0.7)
    together = joint.solve_joint([(V, F, "c") for V, F in charts], options, starts)
    alone = [solve_chart((V, F), options, s, checked=True) for (V, F), s in zip(charts, starts)]
    # 9 gauge directions set aside (3 per chart), not 3: the least eigenvalue is a chart's, not a zero
    assert together[0].lambda_min == pytest.approx(min(a.lambda_min for a in alone), rel=1e-6)
    assert together[0].lambda_min > 1e-6 and all(t.is_local_minimum for t in together)


def test_only_small_charts_with_valid_starts_and_a_positive_alpha_are_batched(monkeypatch):
    from uvbake.flatten import joint

    charts, starts = _small_charts_with_starts()
    items = [(V, F, "c") for V, F in charts]
    flipped = starts[2] * [1.0, -1.0]                                        # a mirrored start: every triangle flipped
    opts = SolveOptions(alpha=0.5)
    assert joint.joint_groups(items, opts, starts[:2] + [flipped] + starts[3:]) == [[0, 1, 3, 4]]
    assert joint.joint_groups(items, SolveOptions(alpha=0.0), starts) == []           # pinned gauge per chart
    assert joint.joint_groups(items, SolveOptions(alpha=0.5, step="damped"), starts) == []
    assert joint.joint_groups(items, opts, None) == []
    monkeypatch.setattr(joint, "JOINT_MAX_FACES", 59)                     # the plane's 60 triangles: alone
    monkeypatch.setattr(joint, "JOINT_FACES", 100)                         # a batch closes at 100 triangles
    assert [len(F) for _, F in charts] == [50, 50, 50, 54, 60]
    assert joint.joint_groups(items, opts, starts) == [[0, 1], [2, 3]]
    monkeypatch.setattr(joint, "JOINT_FACES", 150)                         # the last batch of one chart: alone
    assert joint.joint_groups(items, opts, starts) == [[0, 1, 2]]


def test_batched_charts_give_the_same_bytes_serially_and_on_threads():
    charts, starts = _small_charts_with_starts()
    serial = parameterize_charts(charts, starts=starts, workers=1, checked=True, alpha=0.5)
    threads = parameterize_charts(charts, starts=starts, workers=2, checked=True, alpha=0.5)
    assert all("joint" in r.extra for r in serial)
    for a, b in zip(serial, threads):
        assert np.array_equal(a.uv, b.uv) and a.iterations == b.iterations


def test_a_batch_with_a_degenerate_triangle_is_solved_chart_by_chart(monkeypatch):
    """A chart whose F is not finite at its start (a triangle of zero 3D area) must not stall the
    charts batched with it: the batch falls back to one solve per chart, with the same results."""
    import uvbake.flatten.solve as solve

    charts, starts = _small_charts_with_starts()
    V, F = charts[4]
    V = V.copy()
    V[F[0, 2]] = 0.5 * (V[F[0, 0]] + V[F[0, 1]])                          # triangle 0 collapses onto its edge
    charts[4] = (V, F)
    alone = []
    monkeypatch.setattr(solve, "solve_chart", lambda *a, **k: alone.append(1) or solve_chart(*a, **k))
    got = solve.parameterize_charts(charts, starts=starts, workers=1, checked=True, alpha=0.5)
    assert len(alone) == 5                                                 # the batch fell back
    for (Vc, Fc), s, r in zip(charts[:4], starts[:4], got[:4]):
        ref = solve_chart((Vc, Fc), SolveOptions(alpha=0.5), s, checked=True)
        assert np.array_equal(r.uv, ref.uv) and "joint" not in r.extra


def test_one_blas_thread_limits_every_blas_and_rescans_only_after_an_import():
    import sys
    import types

    from uvbake.flatten.solvers import linalg

    cholmod_available()
    with threadpool_limits(limits=2, user_api="blas"):
        before = _blas_threads()
        with linalg.one_blas_thread("blas"):
            inside = _blas_threads()          # a fresh scan: every BLAS loaded, not only the cached ones
        assert [p for p, _ in inside] == [p for p, _ in before] and all(n == 1 for _, n in inside)
        assert _blas_threads() == before
        made = linalg._POOLS
        with linalg.one_blas_thread("blas"):
            pass
        assert linalg._POOLS is made          # no import since: the scan is reused
        sys.modules["_uvbake_probe"] = types.ModuleType("_uvbake_probe")
        try:
            with linalg.one_blas_thread("blas"):
                assert all(n == 1 for _, n in _blas_threads())
            assert linalg._POOLS is not made  # an import since: scanned again
        finally:
            del sys.modules["_uvbake_probe"]
        assert _blas_threads() == before


_OMP_PROBE = """
import os, sys
import numpy as np, scipy.sparse as sp
from uvbake.flatten.solvers.linalg import CholmodSolver, cholmod_available
assert cholmod_available()
k = 160                                   # a grid's 2 x 25,600 unknowns, factored supernodal
idx = np.arange(k * k).reshape(k, k)
i = np.concatenate([idx[:, :-1].ravel(), idx[:-1, :].ravel()])
j = np.concatenate([idx[:, 1:].ravel(), idx[1:, :].ravel()])
A = sp.coo_matrix((np.ones(len(i)), (i, j)), shape=(k * k, k * k))
A = A + A.T
A = sp.kron(sp.identity(2), sp.diags(np.asarray(A.sum(1)).ravel() + 1.0) - A).tocsc()
before = len(os.listdir("/proc/self/task"))
s = CholmodSolver(A)
s.factor(A, 0.0)
print(len(os.listdir("/proc/self/task")) - before, os.environ.get("OMP_THREAD_LIMIT"))
"""


@pytest.mark.skipif(not cholmod_available() or not sys.platform.startswith("linux"),
                    reason="needs scikit-sparse, and /proc for the thread count")
@pytest.mark.parametrize("user_limit", [None, "3"])
def test_cholmod_factors_without_an_openmp_team_and_leaves_the_environment_alone(user_limit):
    """CHOLMOD 3's supernodal loops ask for a team of 4 OpenMP threads, past OMP_NUM_THREADS and
    threadpoolctl; on two cores that doubled a factorisation's CPU. Its runtime is loaded with a thread
    limit of 1, unless the user set one, and the environment is left as the user had it."""
    import os
    import subprocess

    env = {k: v for k, v in os.environ.items() if k != "OMP_THREAD_LIMIT"}
    if user_limit is not None:
        env["OMP_THREAD_LIMIT"] = user_limit
    out = subprocess.run([sys.executable, "-c", _OMP_PROBE], env=env, capture_output=True, text=True, check=True)
    new_threads, seen = out.stdout.split()
    assert seen == str(user_limit)                      # "None" when the user had not set it
    if user_limit is None:
        assert new_threads == "0"
