"""Cross-check of the two backends (issue 3): agreement where they should agree, loud failure otherwise."""

import json

import numpy as np
import pytest

from uvbake.analysis.crosscheck import CrossCheckError, cross_check, cross_check_charts, uv_diameter
from uvbake.errors import SolverError
from uvbake.flatten.energy import DistortionEnergy
from uvbake.io.load import load_mesh
from uvbake.mesh.arrays import rigid_align
from uvbake.mesh.charts import split_charts

from conftest import SAMPLE_SCENES, shared_mesh

pytest.importorskip("nlopt")

RTOL_ENERGY, RTOL_UV = 1e-6, 1e-4


def _charts(path):
    m = load_mesh(path)
    return split_charts(m.V, m.F, m.face_labels)


def _assert_agree(res):
    assert res.agree, res.summary()
    assert res.energy_rel_diff <= RTOL_ENERGY and res.uv_max_diff_rel <= RTOL_UV
    assert res.converged_lm and res.converged_lbfgs
    # both end points are minima, not saddles: agreement is not an accident of two stalled solvers
    assert res.local_min_lm is not False and res.local_min_lbfgs is not False


def test_rigid_align_recovers_rotation_and_refuses_reflection():
    rng = np.random.default_rng(1)
    P = rng.normal(size=(50, 2))
    th = 2.5
    R = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    Q = P @ R.T + [3.0, -1.0]
    R_est, t, aligned = rigid_align(P, Q)
    assert np.allclose(R_est, R, atol=1e-12) and np.allclose(aligned, Q, atol=1e-12)
    assert np.linalg.det(R_est) == pytest.approx(1.0)
    mirrored = P * [1.0, -1.0]                          # a reflection is not a rigid motion of the plane
    _, _, al = rigid_align(mirrored, P)
    assert np.max(np.linalg.norm(al - P, axis=1)) > 0.5
    # diameter of a square's corners and centre: its diagonal
    assert uv_diameter(np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5]])) == pytest.approx(np.sqrt(2))


@pytest.mark.parametrize("scene", ["multi_component.ply", "scene.ply", "disk_holes.ply", "sphere_cap.ply"])
def test_sample_scenes_backends_agree(scene):
    charts = _charts(SAMPLE_SCENES / scene)
    for alpha in (0.1, 0.5):
        report = cross_check_charts(charts, alpha=alpha, init="lscm", rtol_energy=RTOL_ENERGY, rtol_uv=RTOL_UV)
        assert report.agree and len(report.results) == len(charts)
        for res in report.results:
            _assert_agree(res)
        d = json.loads(json.dumps(report.to_dict(), allow_nan=False))
        assert d["agree"] and len(d["charts"]) == len(charts)
        assert {"energy_lm", "energy_lbfgs", "energy_rel_diff", "uv_max_diff", "uv_max_diff_rel",
                "iterations_lm", "iterations_lbfgs", "time_lm_s", "time_lbfgs_s"} <= set(d["charts"][0])


@pytest.mark.meshes
def test_halftunnel_alpha_01_backends_agree():
    m = load_mesh(shared_mesh("halftunnel.off"))
    _assert_agree(cross_check(m.V, m.F, alpha=0.1, init="lscm"))


def _lm_saddle_bug():
    """True while LM's linear solver accepts indefinite matrices (CHOLMOD simplicial LDL^T)."""
    try:
        import scipy.sparse as sp

        from uvbake.flatten.solvers.linalg import NotPositiveDefinite, make_solver
    except ImportError:
        return False
    A = sp.csc_matrix(np.array([[1.0, 0.0], [0.0, -1.0]]))
    try:
        make_solver(A).factor(A, 0.0)
    except NotPositiveDefinite:
        return False
    return True


@pytest.mark.meshes
def test_halftunnel_alpha_05_backends_agree():
    m = load_mesh(shared_mesh("halftunnel.off"))
    res = cross_check(m.V, m.F, alpha=0.5, init="lscm", raise_on_disagree=False)
    if _lm_saddle_bug():
        # the cross-check caught it: LM stops at a saddle (F 102.72, two negative Hessian eigenvalues)
        # where L-BFGS goes on to the minimum (F 96.42); see the issue-3 report for the linalg fix
        assert not res.agree and res.local_min_lm is False and res.local_min_lbfgs is True
        assert res.energy_lbfgs < res.energy_lm
        pytest.xfail("LM ends at a saddle: CHOLMOD's LDL^T does not report indefinite matrices")
    _assert_agree(res)


def test_wrong_gradient_makes_the_cross_check_fail_loudly(monkeypatch):
    """A test double: L-BFGS's gradient (value_and_gradient; LM uses evaluate) is subtly wrong."""
    chart = _charts(SAMPLE_SCENES / "multi_component.ply")[1]
    V, F = chart.V, chart.F
    good = cross_check(V, F, alpha=0.5)
    _assert_agree(good)

    original = DistortionEnergy.value_and_gradient

    def wrong(self, uv):
        # a forgotten factor 2 in the area term's gradient: F is right, grad F is that of another
        # function, whose stationary points are elsewhere
        f, _ = original(self, uv)
        alpha = self.alpha
        try:
            self.alpha = 0.5 * alpha
            _, g = original(self, uv)
        finally:
            self.alpha = alpha
        return f, g

    monkeypatch.setattr(DistortionEnergy, "value_and_gradient", wrong)
    with pytest.raises(CrossCheckError) as exc:
        cross_check(V, F, alpha=0.5)
    assert isinstance(exc.value, SolverError) and "DISAGREE" in str(exc.value)
    (res,) = exc.value.results
    assert not res.agree
    assert res.energy_rel_diff > RTOL_ENERGY or res.uv_max_diff_rel > RTOL_UV
    # LM (F, gradient and Hessian from evaluate) is untouched by the double
    assert res.energy_lm == pytest.approx(good.energy_lm, rel=1e-12)
    # without raising, the same verdict comes back as data, and a whole-mesh check lists the chart
    assert not cross_check(V, F, alpha=0.5, raise_on_disagree=False).agree
    with pytest.raises(CrossCheckError, match="DISAGREE on 1 of 1"):
        cross_check_charts([(V, F)], alpha=0.5)
    # the form the CLI writes into its JSON report before exiting non-zero
    rep = cross_check_charts([(V, F)], alpha=0.5, raise_on_disagree=False)
    d = json.loads(json.dumps(rep, allow_nan=False))
    assert d["agree"] is False and "DISAGREE" in d["message"] and d["charts"][0]["agree"] is False


@pytest.mark.slow
@pytest.mark.meshes
@pytest.mark.parametrize("alpha", [0.1, 0.5])
def test_camelhead_backends_agree(alpha):
    m = load_mesh(shared_mesh("camelhead.off"))
    _assert_agree(cross_check(m.V, m.F, alpha=alpha, init="lscm"))
