"""Isomap and Laplacian-eigenmap starts, and the second-order certificate (issue 16)."""

import numpy as np
import pytest

import uvbake
from uvbake.flatten.energy import DistortionEnergy
from uvbake.flatten.solvers.certificate import certify, gauge_basis
from uvbake.flatten.starts import isomap, laplacian_eigenmap

from meshgen import bumpy_disk


@pytest.mark.parametrize("start", [isomap, laplacian_eigenmap])
def test_embedding_starts_are_oriented_and_unflipped_on_a_curved_disk(start):
    V, F = bumpy_disk()
    uv = start(V, F)
    det = DistortionEnergy(V, F, alpha=0.5).determinants(uv)
    assert uv.shape == (len(V), 2) and np.all(np.isfinite(uv))
    # a gently curved disk embeds without folds, and the orientation rule makes det > 0
    assert np.all(det > 0)


def test_four_starts_reach_the_same_minimum():
    V, F = bumpy_disk()
    res = {init: uvbake.parameterize(V, F, alpha=0.5, init=init) for init in
           ("lscm", "isomap", "laplacian", "random")}
    ref = res["lscm"].energy
    for init, r in res.items():
        assert r.converged and r.is_local_minimum, init
        assert abs(r.energy - ref) <= 1e-9 * ref, (init, r.energy, ref)
        assert r.lambda_min > 0
    assert "local minimum: yes, lambda_min = " in res["random"].certificate_line()


def _dense_lambda_min(energy, uv):
    _, _, H = energy.evaluate(uv)
    N = gauge_basis(energy, uv)
    # an orthonormal basis of the complement of the gauge, and H restricted to it
    q, _ = np.linalg.qr(np.hstack([N, np.eye(H.shape[0])]))
    C = q[:, N.shape[1]:]
    return np.linalg.eigvalsh(C.T @ H.toarray() @ C).min()


@pytest.mark.parametrize("path", ["lanczos", "dense"])
def test_certificate_matches_dense_eigenvalues_at_a_minimum(path, monkeypatch):
    import uvbake.flatten.solvers.certificate as certificate

    V, F = bumpy_disk(n=8)                           # 128 unknowns: the dense path unless told otherwise
    r = uvbake.parameterize(V, F, alpha=0.5)
    unit = np.mean(np.linalg.norm(V[F[:, [1, 2, 0]]] - V[F], axis=2))
    E = DistortionEnergy((V - V.mean(axis=0)) / unit, F, alpha=0.5)
    uv = r.uv / unit
    assert 2 * len(V) <= certificate.DENSE_MAX
    if path == "lanczos":
        monkeypatch.setattr(certificate, "DENSE_MAX", 12)
    cert = certify(E, uv)
    assert cert.factorisations == (0 if path == "dense" else 1)
    dense = _dense_lambda_min(E, uv)
    assert cert.gauge_dim == 3
    assert cert.lambda_min > 0 and cert.is_local_minimum
    # Lanczos to 1e-10 relative against LAPACK; the gauge residual at a converged map is ~1e-9
    assert cert.lambda_min == pytest.approx(dense, rel=1e-6)
    assert r.lambda_min == pytest.approx(cert.lambda_min, rel=1e-6)


def test_certificate_negative_at_a_constructed_saddle(monkeypatch):
    # The collapsed map uv = 0 is stationary (grad det and the angle term both vanish there), and
    # along any conformal direction the area term's curvature -2 alpha Hess(det) is negative: a saddle.
    V, F = bumpy_disk(n=8)
    E = DistortionEnergy(V, F, alpha=0.9)
    uv = np.zeros((len(V), 2))
    assert np.linalg.norm(E.gradient(uv)) == 0.0
    import uvbake.flatten.solvers.certificate as certificate

    cert = certify(E, uv)
    monkeypatch.setattr(certificate, "DENSE_MAX", 12)    # and by Lanczos
    assert certify(E, uv).lambda_min == pytest.approx(cert.lambda_min, rel=1e-6)
    assert cert.lambda_min < 0 and not cert.is_local_minimum
    assert cert.lambda_min == pytest.approx(_dense_lambda_min(E, uv), rel=1e-6)


def test_pinned_alpha_zero_has_no_gauge_and_is_certified():
    V, F = bumpy_disk(n=8)
    r = uvbake.parameterize(V, F, alpha=0.0)
    assert r.is_local_minimum and r.lambda_min > 0


def test_iterations_from_random_and_lscm_starts_stay_low():
    # loose regression bound (measured 7 from lscm and 25 from random on this mesh)
    V, F = bumpy_disk()
    assert uvbake.parameterize(V, F, alpha=0.5, init="lscm").iterations <= 20
    assert uvbake.parameterize(V, F, alpha=0.5, init="random").iterations <= 60


def test_a_certificate_past_its_lanczos_cap_says_not_checked_and_is_the_same_every_run(monkeypatch):
    # the cap is a work count (restarts), never a time: past it lambda_min is NaN and the chart's
    # verdict None ("not checked"), not a guess; within it the eigenvalue is the dense one
    import uvbake.flatten.solvers.certificate as certificate

    V, F = bumpy_disk(n=8)
    r = uvbake.parameterize(V, F, alpha=0.5)
    unit = np.mean(np.linalg.norm(V[F[:, [1, 2, 0]]] - V[F], axis=2))
    E = DistortionEnergy((V - V.mean(axis=0)) / unit, F, alpha=0.5)
    uv = r.uv / unit
    monkeypatch.setattr(certificate, "DENSE_MAX", 12)
    seen = []
    real = certificate.spla.eigsh

    def counted(op, **kw):
        seen.append(kw["maxiter"])
        return real(op, **kw)

    monkeypatch.setattr(certificate.spla, "eigsh", counted)
    assert certify(E, uv).lambda_min == pytest.approx(_dense_lambda_min(E, uv), rel=1e-6)
    assert seen == [certificate.LANCZOS_RESTARTS]
    monkeypatch.setattr(certificate, "LANCZOS_TOL", 1e-300)      # unreachable: every restart is spent
    monkeypatch.setattr(certificate, "LANCZOS_RESTARTS", 2)
    a, b = certify(E, uv), certify(E, uv)
    assert np.isnan(a.lambda_min) and a.is_local_minimum is None and a.vector is None
    assert np.isnan(b.lambda_min) and b.is_local_minimum is None
    # a map that is not finite (a solve that broke down) is not checked rather than failing the run
    bad = uv.copy()
    bad[3] = np.nan
    c = certify(E, bad)
    assert np.isnan(c.lambda_min) and c.is_local_minimum is None and c.vector is None


def test_a_chart_without_a_certificate_reports_null_not_nan():
    # a program reading the JSON report needs standard JSON: no NaN where no lambda_min was found
    import json

    V, F = bumpy_disk(n=6)
    r = uvbake.parameterize(V, F, alpha=0.5)
    assert json.loads(json.dumps(r.to_dict()))["lambda_min"] == pytest.approx(r.lambda_min, rel=1e-12)
    r.lambda_min, r.is_local_minimum = float("nan"), None
    d = r.to_dict()
    assert d["lambda_min"] is None and d["is_local_minimum"] is None
    json.loads(json.dumps(d), parse_constant=lambda c: pytest.fail(f"{c} in the report"))
