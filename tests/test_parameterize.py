"""The LM parameterizer: developable patches flatten exactly, curved ones converge, options are checked."""

import numpy as np
import pytest

import uvbake
from uvbake import parameterize, parameterize_charts
from uvbake.flatten.energy import DistortionEnergy, jacobians, triangle_frames
from uvbake.flatten.starts import lscm, random_map, tutte

from conftest import shared_mesh
from meshgen import bumpy_disk, cone, cut_cylinder, plane

DEVELOPABLE = {"plane": plane, "cut_cylinder": cut_cylinder, "cone": cone}


def singular_values(V, F, uv):
    _, Q, _ = triangle_frames(V, F)
    return np.linalg.svd(jacobians(Q, F, uv), compute_uv=False)


@pytest.mark.parametrize("init", ["lscm", "random"])
@pytest.mark.parametrize("alpha", [0.1, 0.5, 0.9])
@pytest.mark.parametrize("surface", sorted(DEVELOPABLE))
def test_developable_patches_flatten_isometrically(surface, alpha, init):
    V, F = DEVELOPABLE[surface]()
    r = parameterize(V, F, alpha=alpha, init=init, seed=3)
    assert r.converged and r.grad_norm < 1e-8
    assert r.energy / len(F) < 1e-10
    np.testing.assert_allclose(singular_values(V, F, r.uv), 1.0, atol=1e-6)
    assert r.n_flipped == 0
    # UVs are in the surface's own units: edge lengths are preserved
    e3 = np.linalg.norm(V[F[:, 1]] - V[F[:, 0]], axis=1)
    e2 = np.linalg.norm(r.uv[F[:, 1]] - r.uv[F[:, 0]], axis=1)
    np.testing.assert_allclose(e2, e3, rtol=1e-6)


def test_history_never_increases_on_accepted_steps():
    V, F = bumpy_disk(16)
    seen = []
    r = parameterize(V, F, alpha=0.7, init="lscm", callback=lambda d: seen.append(d))
    assert r.converged
    assert len(r.history) == r.iterations + 1
    h = np.asarray(r.history)
    assert np.all(np.diff(h) <= 1e-12 * np.abs(h[:-1]))      # rounding of the recorded totals only
    accepted = [d for d in seen if d["accepted"]]
    assert accepted and all(b["energy"] <= a["energy"] * (1 + 1e-12) for a, b in zip(accepted, accepted[1:]))
    assert r.energy == pytest.approx(DistortionEnergy(V, F, alpha=0.7).value(r.uv), rel=1e-12)
    assert r.energy < r.energy_init


def test_random_start_without_continuation_runs_the_papers_plain_lm():
    V, F = bumpy_disk(12)
    plain = parameterize(V, F, alpha=0.5, init="random", seed=1, continuation=False)
    cont = parameterize(V, F, alpha=0.5, init="random", seed=1)
    assert "continuation" not in plain.extra and cont.extra["continuation"]["alpha"] == 0.1
    # accepted LM steps never raise F; the recorded totals may differ by rounding (another CPU's
    # summation order), so a rise of 1e-12 of F is allowed
    for h in (np.asarray(plain.history), np.asarray(cont.history)):
        assert np.all(np.diff(h) <= 1e-12 * np.abs(h[:-1]))
    assert cont.energy <= plain.energy * (1 + 1e-9)


def test_curved_chart_reaches_the_same_minimum_from_every_start():
    V, F = bumpy_disk(14)
    energies = [parameterize(V, F, alpha=0.5, init=i, seed=s).energy
                for i, s in [("lscm", 0), ("tutte", 0), ("random", 0), ("random", 1)]]
    assert max(energies) - min(energies) < 1e-9 * max(energies)
    assert min(energies) > 1e-3          # not developable: distortion is unavoidable


def test_alpha_zero_is_the_conformal_map_at_the_surfaces_own_scale():
    V, F = bumpy_disk(14)
    r = parameterize(V, F, alpha=0.0)
    area3d = 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1).sum()
    e = r.uv[F[:, 1:]] - r.uv[F[:, :1]]
    area_uv = 0.5 * (e[:, 0, 0] * e[:, 1, 1] - e[:, 0, 1] * e[:, 1, 0]).sum()
    assert area_uv == pytest.approx(area3d, rel=1e-12)
    assert r.converged
    # not collapsed, and a minimum of the angle term up to scale: scaling it changes F only by s^2
    assert np.ptp(r.uv, axis=0).min() > 0.1 * np.ptp(V, axis=0).max()
    E = DistortionEnergy(V, F, alpha=0.0)
    assert E.value(1.1 * r.uv) == pytest.approx(1.21 * r.energy, rel=1e-9)
    # from a random start it lands on the same map up to a rigid motion: same energy
    r2 = parameterize(V, F, alpha=0.0, init="random", seed=5)
    assert r2.energy == pytest.approx(r.energy, rel=1e-6)


def test_initial_maps():
    V, F = bumpy_disk(10)
    for uv in (lscm(V, F), tutte(V, F)):
        _, Q, _ = triangle_frames(V, F)
        assert np.all(np.linalg.det(jacobians(Q, F, uv)) > 0)         # valid starts on this disk
    a, b = random_map(V, F, seed=1), random_map(V, F, seed=1)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, random_map(V, F, seed=2))
    # Tutte puts the boundary on a circle whose circumference is the boundary's length
    from uvbake.mesh.topology import topology

    bnd = np.unique(topology(F).boundary_edges)
    rad = np.linalg.norm(tutte(V, F)[bnd], axis=1)
    np.testing.assert_allclose(rad, rad[0], rtol=1e-12)


def test_tutte_refuses_charts_with_holes():
    V, F = bumpy_disk(8)
    keep = ~(F == 27).any(axis=1)                # remove an interior vertex's star: a hole
    chart = uvbake.split_charts(V, F[keep])[0]   # drops the now unused vertex
    with pytest.raises(uvbake.InputError, match="one boundary loop"):
        parameterize(chart.V, chart.F, init="tutte")


@pytest.mark.parametrize("kwargs, match", [
    (dict(alpha=1.5), "alpha"), (dict(alpha=-0.01), "alpha"), (dict(alpha="x"), "alpha"),
    (dict(init="harmonic"), "init"), (dict(backend="newton"), "backend"),
    (dict(tol=0), "tol"), (dict(max_iter=-1), "max_iter"), (dict(linear_solver="magic"), "linear_solver"),
])
def test_bad_options_name_the_option(kwargs, match):
    V, F = plane()
    with pytest.raises(uvbake.InputError, match=match):
        parameterize(V, F, **kwargs)


def test_superlu_fallback_gives_the_same_answer():
    V, F = bumpy_disk(12)
    a = parameterize(V, F, alpha=0.5, linear_solver="superlu")
    b = parameterize(V, F, alpha=0.5, linear_solver="auto")
    assert a.converged and b.converged
    assert a.energy == pytest.approx(b.energy, rel=1e-9)
    assert a.extra["linear_solver"] == "superlu"


def test_iteration_cap_and_callback_stop():
    V, F = bumpy_disk(12)
    r = parameterize(V, F, alpha=0.9, init="random", max_iter=3, continuation=False)
    assert r.iterations == 3 and not r.converged and r.stop_reason == "max_iter"
    r = parameterize(V, F, alpha=0.9, callback=lambda d: d["iteration"] >= 2)
    assert r.iterations == 2 and r.stop_reason == "stopped by callback"


def test_charts_in_parallel_match_serial():
    charts = [bumpy_disk(10, seed=s) for s in range(3)]
    progress = []
    par = parameterize_charts(charts, alpha=0.5, workers=2, progress=lambda d, t, r: progress.append(d))
    ser = parameterize_charts(charts, alpha=0.5, workers=1)
    assert sorted(progress) == [1, 2, 3]
    for a, b in zip(par, ser):
        np.testing.assert_allclose(a.uv, b.uv, rtol=1e-12, atol=1e-12)


@pytest.mark.meshes
def test_halftunnel_converges_from_lscm_and_random():
    from uvbake.io.load import load_mesh

    m = load_mesh(shared_mesh("halftunnel.off"))
    for init in ("lscm", "random"):
        r = parameterize(m.V, m.F, alpha=0.5, init=init)
        assert r.converged, r.stop_reason
        assert r.iterations <= 400


@pytest.mark.parametrize("continuation", [False, True])
def test_lm_escapes_a_saddle_and_ends_at_a_local_minimum(continuation):
    # the collapsed map (all UVs equal) is stationary for every alpha > 0: grad det = 0 there, and
    # the Hessian -2 alpha Hess(det) is indefinite. Plain first-order stopping would accept it.
    V, F = plane()
    E = DistortionEnergy(V, F, alpha=0.5)
    assert np.linalg.norm(E.gradient(np.zeros((len(V), 2)))) == 0
    r = parameterize(V, F, alpha=0.5, uv0=np.zeros((len(V), 2)), continuation=continuation)
    assert r.converged and r.energy / len(F) < 1e-10
    np.testing.assert_allclose(singular_values(V, F, r.uv), 1.0, atol=1e-6)


@pytest.mark.meshes
def test_halftunnel_alpha_05_ends_at_a_minimum_not_a_saddle():
    # found by the L-BFGS cross-check: with an L D L^T factorisation that accepted indefinite
    # matrices, LM stopped at a saddle with F 102.72 and two negative Hessian eigenvalues
    from uvbake.analysis.crosscheck import is_local_minimum
    from uvbake.io.load import load_mesh

    m = load_mesh(shared_mesh("halftunnel.off"))
    r = parameterize(m.V, m.F, alpha=0.5)
    assert r.converged and r.energy == pytest.approx(96.42475801, rel=1e-8)
    assert is_local_minimum(m.V, m.F, r.uv, alpha=0.5)


# ---------------------------------------------------------------------------------------- issue 15


@pytest.mark.parametrize("option, value", [
    ("tol", "1e-8"), ("tol", None), ("tol", float("nan")), ("max_iter", "abc"), ("max_iter", 2.5),
    ("seed", -1), ("seed", "1"), ("alpha", "x"), ("init", 3), ("backend", None),
    ("linear_solver", "umfpack"), ("callback", 5),
])
def test_every_option_is_checked_up_front_naming_the_parameter(option, value):
    V, F = plane()
    with pytest.raises(uvbake.InputError, match=f"^{option}="):
        parameterize(V, F, **{option: value})


def test_workers_is_checked_naming_the_parameter():
    V, F = plane()
    with pytest.raises(uvbake.InputError, match="^workers="):
        parameterize_charts([(V, F)], workers=0)


@pytest.mark.parametrize("scale", [2.0 ** 996, 2.0 ** -1000, 1e300, 1e-300])
def test_any_finite_scale_gives_the_same_map(scale):
    # F is scale-free: the map of a scaled chart is the scaled map, without overflow or underflow
    V, F = plane()
    ref = parameterize(V, F, alpha=0.5)
    with np.errstate(all="raise"):
        r = parameterize(V * scale, F, alpha=0.5)
    assert r.converged and r.n_flipped == 0
    assert abs(r.energy - ref.energy) <= 1e-9 + 1e-6 * ref.energy
    rel = np.abs(r.uv / scale - ref.uv).max() / np.abs(ref.uv).max()
    assert rel < 1e-6


@pytest.mark.parametrize("factor", ["simplicial", "supernodal", "superlu"])
def test_the_chartings_one_shot_lscm_is_the_starts_lscm(factor, monkeypatch):
    # uvbake.atlas.conformal.lscm assembles the conformal energy straight into the free unknowns as one
    # complex Hermitian system (u-v coupling on boundary edges only); it must give the solver-built
    # real LSCM's map, on a disk and on a cut cylinder (its cut is boundary on both sides), with either
    # of CHOLMOD's factorisations (supernodal: what charts of SUPERNODAL_FROM unknowns or more get) and
    # with SuperLU (no CHOLMOD installed)
    import uvbake.flatten.solvers.linalg as linalg
    from uvbake.atlas.conformal import lscm as one_shot

    if factor == "supernodal":
        if not linalg.cholmod_available():
            pytest.skip("needs scikit-sparse (the cholmod extra)")
        monkeypatch.setattr(linalg, "SUPERNODAL_FROM", 1)
    if factor == "superlu":
        monkeypatch.setattr(linalg, "cholmod_available", lambda: False)
    for V, F in (bumpy_disk(n=8, seed=3), cut_cylinder()):
        a, b = lscm(V, F), one_shot(V, F)
        assert np.allclose(a, b, rtol=0, atol=1e-9 * np.ptp(a))
