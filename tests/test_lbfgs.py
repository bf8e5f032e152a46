"""nlopt L-BFGS backend: the same stopping rule, result record and callback protocol as LM."""

import numpy as np
import pytest

import uvbake
from uvbake.flatten.energy import DistortionEnergy, optimal_scale
from uvbake.flatten.solvers.lbfgs import lbfgs
from uvbake.flatten.solvers.lm import levenberg_marquardt
from uvbake.flatten.starts import initial_map

pytest.importorskip("nlopt")


def dome(n=12, height=0.35):
    """A curved open height-field patch over [0,1]^2 (a disk), unit-ish mean edge length after scaling."""
    s = np.linspace(0.0, 1.0, n)
    X, Y = np.meshgrid(s, s, indexing="ij")
    Z = height * np.sin(np.pi * X) * np.sin(np.pi * Y)
    V = np.column_stack([X.ravel(), Y.ravel(), Z.ravel()]) * (n - 1)
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    F = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])]).astype(np.int64)
    return V, F


def problem(alpha=0.5):
    V, F = dome()
    V = V - V.mean(axis=0)
    energy = DistortionEnergy(V, F, alpha=alpha)
    start = initial_map(V, F, "lscm")
    start = start * optimal_scale(energy, start)
    return energy, start


def test_reaches_the_gradient_tolerance_and_reports_honestly():
    energy, start = problem(0.5)
    x0 = energy.to_vector(start)
    x, info = lbfgs(energy, x0, uv_fixed=start, tol=1e-9, max_iter=5000)
    assert all(hasattr(info, k) for k in ("energy", "grad_norm", "iterations", "converged", "history", "stop_reason",
                                          "evaluations"))
    f, g = energy.value_and_gradient(energy.to_uv(x, start))
    # the record describes the returned point, under the same rule as LM
    assert info.converged and info.stop_reason == "converged"
    assert np.linalg.norm(g) < 1e-9
    assert info.grad_norm == pytest.approx(np.linalg.norm(g), rel=1e-12)
    assert info.energy == pytest.approx(f, rel=1e-12)
    h = info.history
    assert h[0] == pytest.approx(energy.value(start), rel=1e-14)
    assert len(h) == info.iterations + 1
    assert np.all(np.diff(h) <= 1e-12 * h[0])          # only improvements count as iterations
    assert info.evaluations >= info.iterations + 1


def test_same_minimum_as_levenberg_marquardt():
    energy, start = problem(0.5)
    x0 = energy.to_vector(start)
    x_lm, i_lm = levenberg_marquardt(energy, x0, uv_fixed=start, tol=1e-10)
    x_lb, i_lb = lbfgs(energy, x0, uv_fixed=start, tol=1e-9, max_iter=5000)
    assert i_lm.converged and i_lb.converged
    assert i_lb.energy == pytest.approx(i_lm.energy, rel=1e-10)
    # F is invariant to rigid motions only; after removing them the maps coincide
    from uvbake.mesh.arrays import rigid_align

    uv_lm, uv_lb = energy.to_uv(x_lm, start), energy.to_uv(x_lb, start)
    _, _, al = rigid_align(uv_lb, uv_lm)
    assert np.max(np.abs(al - uv_lm)) < 1e-6 * np.ptp(uv_lm)


def test_callback_protocol_and_stop():
    energy, start = problem(0.5)
    seen = []

    def cb(d):
        seen.append(d)
        return d["iteration"] >= 5

    x, info = lbfgs(energy, energy.to_vector(start), uv_fixed=start, tol=1e-12, callback=cb)
    assert info.stop_reason == "stopped by callback" and info.iterations == 5
    assert [d["iteration"] for d in seen] == [1, 2, 3, 4, 5]
    assert all({"iteration", "energy", "grad_norm"} <= set(d) for d in seen)
    assert [d["energy"] for d in seen] == pytest.approx(list(info.history[1:]))


def test_iteration_cap_returns_best_point():
    energy, start = problem(0.8)
    x, info = lbfgs(energy, energy.to_vector(start), uv_fixed=start, tol=1e-14, max_iter=7)
    assert info.iterations == 7 and info.stop_reason == "max_iter" and not info.converged
    f = energy.value(energy.to_uv(x, start))
    assert f == pytest.approx(info.history.min(), rel=1e-12)
    assert f < info.history[0]


def test_converged_start_and_non_finite_start():
    energy, start = problem(0.5)
    x0 = energy.to_vector(start)
    x, _ = levenberg_marquardt(energy, x0, uv_fixed=start, tol=1e-11)
    x1, info = lbfgs(energy, x, uv_fixed=start, tol=1e-8)
    assert info.iterations == 0 and info.stop_reason == "converged" and np.array_equal(x1, x)
    bad = x0.copy()
    bad[3] = np.nan
    _, info = lbfgs(energy, bad, uv_fixed=start)
    assert info.stop_reason == "non-finite start" and not info.converged


def test_parameterize_backend_lbfgs_record_and_pinned_alpha0():
    V, F = dome()
    for alpha in (0.0, 0.3):
        r_lm = uvbake.parameterize(V, F, alpha=alpha, backend="lm")
        r_lb = uvbake.parameterize(V, F, alpha=alpha, backend="lbfgs", max_iter=20000)
        assert r_lb.backend == "lbfgs" and r_lb.converged and r_lb.grad_norm < 1e-8
        assert r_lb.n_evaluations > r_lb.iterations > 0
        # ||g|| < 1e-8 bounds F's error by about ||g||^2 / (smallest curvature): 1e-8 relative here
        assert r_lb.energy == pytest.approx(r_lm.energy, rel=1e-7)
        if alpha == 0.0:
            # two pinned vertices fix the gauge: the convex conformal problem has one solution
            assert np.max(np.abs(r_lb.uv - r_lm.uv)) < 1e-5 * np.ptp(r_lm.uv)


@pytest.mark.parametrize("kind", ["cholesky", "jacobi", "none"])
def test_preconditioners_change_the_path_not_the_minimum(kind):
    energy, start = problem(0.5)
    x0 = energy.to_vector(start)
    x_lm, i_lm = levenberg_marquardt(energy, x0, uv_fixed=start, tol=1e-10)
    x, info = lbfgs(energy, x0, uv_fixed=start, tol=1e-9, max_iter=20000, precondition=kind)
    assert info.converged and info.extra["preconditioner"].startswith(kind)
    assert info.energy == pytest.approx(i_lm.energy, rel=1e-10)


def test_bad_preconditioner_name():
    energy, start = problem(0.5)
    with pytest.raises(uvbake.InputError, match="precondition"):
        lbfgs(energy, energy.to_vector(start), uv_fixed=start, precondition="ilu")
