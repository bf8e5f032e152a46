"""alpha sweeps and the relative sensitivity S = (alpha / F*) dF*/dalpha (paper section 3.6, Eq. 10)."""

import csv
import json

import numpy as np
import pytest

import uvbake
from uvbake.analysis.sensitivity import finite_difference, parse_alphas, relative_sensitivity, sweep
from uvbake.cli.sweep import main
from uvbake.errors import InputError
from uvbake.io.load import load_mesh

from conftest import SAMPLE_SCENES


def cylinder_patch(nu=14, nv=8, angle=1.6):
    """A piece of a unit cylinder: developable (an isometry to the plane exists), curved in 3D."""
    t = np.linspace(0.0, angle, nu)
    z = np.linspace(0.0, 1.0, nv)
    T, Z = np.meshgrid(t, z, indexing="ij")
    V = np.column_stack([np.cos(T).ravel(), np.sin(T).ravel(), Z.ravel()])
    idx = np.arange(nu * nv).reshape(nu, nv)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    F = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])]).astype(np.int64)
    return V, F


@pytest.fixture(scope="module")
def cap():
    m = load_mesh(SAMPLE_SCENES / "sphere_cap.ply")
    return m.V, m.F


# -- the numerics, exactly -------------------------------------------------------------------------

def test_finite_difference_is_exact_on_parabolas_on_uneven_grids():
    x = np.array([0.0, 0.1, 0.25, 0.3, 0.6, 1.0])
    y = 3 * x ** 2 - 2 * x + 1
    assert np.allclose(finite_difference(x, y), 6 * x - 2, atol=1e-12)      # ends included
    assert np.allclose(finite_difference(x[:2], y[:2]), (y[1] - y[0]) / 0.1)
    assert np.isnan(finite_difference(x[:1], y[:1])).all()


def test_relative_sensitivity_end_points_and_zero_energy():
    a = np.array([0.0, 0.5, 1.0])
    S = relative_sensitivity(a, [2.0, 4.0, 0.0], [1.0, 2.0, -3.0], n_triangles=10)
    assert S[0] == 0.0                      # the alpha factor of Eq. 10
    assert S[1] == pytest.approx(0.5 / 4.0 * 2.0)
    assert np.isnan(S[2])                   # F* = 0: relative sensitivity undefined, not invented


def test_parse_alphas():
    a = parse_alphas("0:1:0.1")
    assert len(a) == 11 and a[0] == 0.0 and a[-1] == 1.0 and np.allclose(np.diff(a), 0.1)
    assert list(parse_alphas("0.5, 0.1,0.5")) == [0.1, 0.5]
    for bad in ("0:1.5:0.5", "-0.1,0.2", "a:b:c", "0:1", "1:0:0.1", "0:1:0", "", "nan"):
        with pytest.raises(InputError):
            parse_alphas(bad)


# -- the mathematics on meshes ---------------------------------------------------------------------

def test_developable_patch_has_zero_optimum_for_every_alpha():
    V, F = cylinder_patch()
    res = sweep(V, F, [0.0, 0.25, 0.5, 0.75, 1.0])
    for r in res.records:
        assert r.converged and r.energy < 1e-12 * len(F), (r.alpha, r.energy)
        assert r.n_flipped == 0 and r.overlaps in (0, None)
        assert r.uv_area_ratio == pytest.approx(1.0, rel=1e-6)        # an isometry keeps area
    # F* == 0 everywhere: S is undefined (NaN) except at alpha = 0 where the alpha factor gives 0
    assert res.sensitivity[0] == 0.0 and np.isnan(res.sensitivity[1:]).all()


def test_curved_chart_energy_is_continuous_and_S_matches_independent_solves(cap):
    V, F = cap
    alphas = np.round(np.arange(0.2, 0.61, 0.05), 10)
    res = sweep(V, F, alphas, overlaps=False)
    E = res.energies
    assert all(r.converged for r in res.records)
    assert np.all(E > 1.0)
    # continuity: each step of F* is what the envelope slope predicts, up to O(h^2)
    h = np.diff(alphas)
    predicted = 0.5 * (res.dF_dalpha_envelope[1:] + res.dF_dalpha_envelope[:-1]) * h
    assert np.allclose(np.diff(E), predicted, rtol=2e-3, atol=1e-3)
    # concave F* (a minimum of functions affine in alpha) with F*(0+) >= 0 gives S <= 1
    assert np.all(res.sensitivity <= 1.0 + 1e-6)
    # an independent central difference of separately solved problems at three alphas
    delta = 1e-3
    for alpha in (0.2, 0.4, 0.6):
        Fp = uvbake.parameterize(V, F, alpha=alpha + delta).energy
        Fm = uvbake.parameterize(V, F, alpha=alpha - delta).energy
        F0 = res.energies[np.argmin(abs(alphas - alpha))]
        S_ind = alpha / F0 * (Fp - Fm) / (2 * delta)
        i = int(np.argmin(abs(alphas - alpha)))
        # the sweep's S (grid step 0.05, one-sided at 0.2 and 0.6) agrees to its truncation error...
        assert res.sensitivity[i] == pytest.approx(S_ind, rel=5e-3, abs=1e-3)
        # ...and the envelope theorem's value to the small step's
        assert res.sensitivity_envelope[i] == pytest.approx(S_ind, rel=1e-4, abs=1e-5)


def test_warm_start_reaches_the_same_optima_and_says_so(cap):
    V, F = cap
    cold = sweep(V, F, [0.3, 0.4, 0.5], overlaps=False)
    warm = sweep(V, F, [0.3, 0.4, 0.5], warm_start=True, overlaps=False)
    assert [r.started_from for r in cold.records] == ["lscm"] * 3
    assert [r.started_from for r in warm.records] == ["lscm", "alpha=0.3", "alpha=0.4"]
    assert any("warm start" in n for n in warm.notes)
    assert np.allclose(warm.energies, cold.energies, rtol=1e-9)
    assert np.allclose(warm.sensitivity, cold.sensitivity, rtol=1e-6)


def test_several_charts_sum_and_outputs(tmp_path):
    m = load_mesh(SAMPLE_SCENES / "multi_component.ply")
    alphas = [0.0, 0.5, 1.0]
    res = sweep(m.V, m.F, alphas)
    assert res.n_charts == 4
    per_chart = sum(uvbake.parameterize(c.V, c.F, alpha=0.5).energy for c in uvbake.split_charts(m.V, m.F))
    assert res.records[1].energy == pytest.approx(per_chart, rel=1e-12)
    h = res.records[1].history
    assert h[-1] == pytest.approx(res.records[1].energy, rel=1e-9) and h[0] >= h[-1]
    assert res.sensitivity[0] == 0.0 and any("alpha=0" in n for n in res.notes)
    res.save_csv(tmp_path / "s.csv")
    res.save_json(tmp_path / "s.json")
    res.plot(tmp_path / "s.png")
    rows = list(csv.DictReader((tmp_path / "s.csv").read_text().splitlines()))
    assert [float(r["alpha"]) for r in rows] == alphas
    assert float(rows[1]["energy"]) == pytest.approx(res.records[1].energy, rel=1e-15)
    d = json.loads((tmp_path / "s.json").read_text())
    assert d["records"][1]["sensitivity"] == pytest.approx(res.sensitivity[1])
    assert len(d["records"][1]["history"]) == len(h)
    assert (tmp_path / "s.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.csv", "s.json", "s.png"]   # no temp files left
    with pytest.raises(InputError):
        res.save_csv(tmp_path / "missing" / "s.csv")


# -- the command -----------------------------------------------------------------------------------

def test_sweep_command_writes_numbers_and_plot(tmp_path, capsys):
    out = tmp_path / "plot.png"
    rc = main([str(SAMPLE_SCENES / "multi_component.ply"), "--alphas", "0.2:0.6:0.2", "--plot", str(out),
               "--csv", str(tmp_path / "n.csv"), "--json", str(tmp_path / "n.json"), "--warm-start"])
    assert rc == 0
    assert out.read_bytes()[:4] == b"\x89PNG"
    d = json.loads((tmp_path / "n.json").read_text())
    assert d["warm_start"] and [r["alpha"] for r in d["records"]] == [0.2, 0.4, 0.6]
    assert d["records"][1]["started_from"] == "alpha=0.2"
    assert "alpha" in capsys.readouterr().out


@pytest.mark.parametrize("args, words", [
    (["--alphas", "0:2:0.5"], "outside [0, 1]"),
    (["--alphas", "x"], "start:stop:step"),
    (["--plot", "/nonexistent-folder/p.png"], "does not exist"),
])
def test_sweep_command_errors_are_one_line(args, words, capsys, tmp_path):
    assert main([str(SAMPLE_SCENES / "multi_component.ply"), *args]) == 2
    err = capsys.readouterr().err
    assert words in err and err.count("\n") == 1 and "Traceback" not in err
    assert main([str(tmp_path / "nope.ply")]) == 2


def _record(alpha, d_area, d_angle, flips=0, overlaps=0, area_ratio=1.0):
    from uvbake.analysis.sensitivity import AlphaRecord

    return AlphaRecord(alpha=alpha, energy=alpha * d_area + (1 - alpha) * d_angle, energy_area=d_area,
                       energy_angle=d_angle, iterations=1, evaluations=1, n_flipped=flips, overlaps=overlaps,
                       converged=True, grad_norm=0.0, uv_area_ratio=area_ratio, stop_reasons=["converged"],
                       started_from="lscm", history=np.zeros(1), time_s=0.0)


def _result(records):
    from uvbake.analysis.sensitivity import SweepResult

    z = np.zeros(len(records))
    return SweepResult(records=records, sensitivity=z, dF_dalpha=z, dF_dalpha_envelope=z,
                       sensitivity_envelope=z, init="lscm", warm_start=False, backend="lm", n_charts=1)


def test_recommend_alpha_prefers_valid_maps_then_least_combined_distortion():
    from uvbake.analysis.sensitivity import recommend_alpha

    # distortions relative to the largest (area 8, angle 10): combined 0+1, 0.25+0.5, 0.5+0.2, 1+0.1
    recs = [_record(0.0, 0.0, 10.0), _record(0.3, 2.0, 5.0), _record(0.6, 4.0, 2.0, flips=3),
            _record(0.9, 8.0, 1.0)]
    rec = recommend_alpha(_result(recs))
    # 0.6 distorts least (0.7) but flips; among the valid ones 0.3 (0.75) beats 0.9 (1.1) and 0 (1.0)
    assert rec["alpha"] == 0.3 and rec["invalid"] == 0
    assert rec["combined"] == pytest.approx(0.75, abs=1e-12)
    assert "alpha 0.6 distorts less" in rec["reason"] and "3 flipped" in rec["reason"]
    # with every map invalid, the fewest invalid triangles win; a collapsed map is never chosen
    recs = [_record(0.0, 0.0, 10.0, overlaps=5), _record(0.5, 1.0, 1.0, flips=2, area_ratio=1e-6),
            _record(0.9, 8.0, 1.0, flips=1)]
    rec = recommend_alpha(_result(recs))
    assert rec["alpha"] == 0.9 and rec["invalid"] == 1 and "not considered" in rec["reason"]
