"""The benchmark metrics of bench/metrics.py on maps whose answers are known."""

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

_PATH = Path(__file__).resolve().parent.parent / "bench" / "metrics.py"
_spec = importlib.util.spec_from_file_location("bench_metrics", _PATH)
metrics = importlib.util.module_from_spec(_spec)
sys.modules.setdefault("bench_metrics", metrics)       # dataclasses look their module up there
_spec.loader.exec_module(metrics)


def grid(nx=6, ny=4, z=None):
    """A flat (or lifted) nx x ny vertex grid on [0, nx-1] x [0, ny-1], consistently oriented."""
    x, y = np.meshgrid(np.arange(nx, dtype=float), np.arange(ny, dtype=float), indexing="xy")
    V = np.stack([x.ravel(), y.ravel(), np.zeros(x.size) if z is None else z(x, y).ravel()], axis=1)
    F = []
    for j in range(ny - 1):
        for i in range(nx - 1):
            a = j * nx + i
            F += [[a, a + 1, a + nx + 1], [a, a + nx + 1, a + nx]]
    return V, np.array(F, dtype=np.int64)


def rotation(theta):
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


def test_isometry_has_unit_singular_values():
    V, F = grid(z=lambda x, y: 0.0 * x)
    # a rigid motion in 3D, then drop z: an isometry of the flat grid
    uv = V[:, :2] @ rotation(0.7).T + [3.0, -2.0]
    R3 = np.array([[1, 0, 0], [0, np.cos(0.4), -np.sin(0.4)], [0, np.sin(0.4), np.cos(0.4)]])
    s1, s2, det, area = metrics.singular_values(V @ R3.T, F, uv)
    assert np.allclose(s1, 1) and np.allclose(s2, 1) and np.all(det > 0)
    assert np.isclose(area.sum(), 15.0)
    d = metrics.distortion(V, F, uv)
    assert np.isclose(d["angle_mean"], 1) and np.isclose(d["angle_max"], 1) and d["area"] < 1e-12


def test_uniform_scale_is_free_after_the_best_global_scale():
    V, F = grid()
    for mode in ("median", "mean"):
        d = metrics.distortion(V, F, 37.0 * V[:, :2], area_scale=mode)
        assert np.isclose(d["angle_mean"], 1) and d["area"] < 1e-12
        assert np.isclose(d["scale"], 1 / 37.0)


def test_shear_gives_the_analytic_ratio():
    V, F = grid()
    k = 0.8
    uv = V[:, :2] @ np.array([[1.0, k], [0.0, 1.0]]).T
    # singular values of [[1,k],[0,1]]: sqrt of the eigenvalues of [[1,k],[k,1+k^2]]
    ev = np.linalg.eigvalsh(np.array([[1.0, k], [k, 1 + k * k]]))
    ratio = np.sqrt(ev[1] / ev[0])
    d = metrics.distortion(V, F, uv)
    assert np.isclose(d["angle_mean"], ratio) and np.isclose(d["angle_max"], ratio)
    assert d["area"] < 1e-12                               # a shear keeps area


def test_non_uniform_scale_area_distortion_is_the_median_deviation():
    # half the triangles (by area) scaled by 2 in area, half unchanged: median of log det is log 1,
    # so the L1-optimal scale leaves half the area at |log 2|
    V, F = grid(nx=5, ny=3)
    uv = V[:, :2].copy()
    uv[:, 0] = np.where(V[:, 0] > 2, 2 + 2 * (V[:, 0] - 2), V[:, 0])
    d = metrics.distortion(V, F, uv)
    assert np.isclose(d["area"], 0.5 * np.log(2))
    assert metrics.distortion(V, F, uv, area_scale="mean")["area"] >= d["area"] - 1e-12


def test_mirrored_chart_has_no_flips_and_same_distortion():
    V, F = grid()
    uv = V[:, :2] * [-1.0, 1.0]
    assert len(metrics.flipped(F, uv)) == 0
    s1, s2, det, _ = metrics.singular_values(V, F, uv)
    assert np.all(det < 0) and np.allclose(s1, 1) and np.allclose(s2, 1)
    m = metrics.measure(V, F, uv)
    assert m.n_flipped == 0 and m.n_charts == 1 and np.isclose(m.angle_mean, 1)


def test_one_flipped_triangle_counts_one():
    V, F = grid(nx=5, ny=5)
    uv = V[:, :2].copy()
    uv[12] = [2.0, 2.0]                                    # centre vertex: fine
    # a corner vertex pulled across its triangle's opposite edge flips exactly that triangle
    uv[0] = [1.5, 1.5]                                     # vertex 0 is in one triangle only: (0, 1, 6)
    assert set(np.flatnonzero(np.any(F == 0, axis=1))) == {0, 1}
    flips = metrics.flipped(F, uv)
    s = metrics.signed_areas(uv, F)
    assert list(flips) == list(np.flatnonzero(s <= 0))
    assert len(flips) >= 1
    # a clean single flip: reflect one isolated triangle of a per-corner map (its own chart would be
    # mirrored, so keep it glued: move one vertex of a boundary triangle through the opposite edge)
    V2 = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], float)
    F2 = np.array([[0, 1, 3], [0, 3, 2]])
    uv2 = V2[:, :2].copy()
    uv2[2] = [0.8, 0.4]                                    # beyond the diagonal 0-3: (0,3,2) flips
    assert list(metrics.flipped(F2, uv2)) == [1]
    assert metrics.measure(V2, F2, uv2).n_flipped == 1


def test_seam_length_of_a_grid_cut_in_two_equals_the_cut():
    V, F = grid(nx=6, ny=4)                                # 5 x 3 squares
    C = V[:, :2][F].copy()                                 # per-corner UVs
    left = np.all(V[F][:, :, 0] <= 2.0, axis=1)            # faces left of x = 2
    C[~left] += [10.0, 0.0]                                # right half moved away: cut along x = 2
    assert np.isclose(metrics.seam_length(V, F, C), 3.0)  # the cut line x = 2, y in [0, 3]
    m = metrics.measure(V, F, C)
    assert m.n_charts == 2 and m.n_flipped == 0 and np.isclose(m.angle_mean, 1)
    # uncut per-vertex map: no seam, one chart; a 3D boundary never counts
    assert metrics.seam_length(V, F, V[:, :2]) == 0.0
    assert metrics.measure(V, F, V[:, :2]).n_charts == 1


def test_seam_length_counts_a_split_vertex_only_on_edges_that_disagree():
    V, F = grid(nx=3, ny=3)
    C = V[:, :2][F].copy()
    # move the centre vertex (4) in the corners of the two faces of square (0,0) only
    sq = [0, 1]
    for f in sq:
        C[f][F[f] == 4] += [0.0, 0.01]
    # the cut edges are those with one side in sq and one outside that contain vertex 4:
    # edge 1-4 (faces 0 and 3) and edge 3-4 (faces 1 and 4)
    assert np.isclose(metrics.seam_length(V, F, C), 2.0)


def test_per_corner_and_per_vertex_agree_and_packing():
    V, F = grid(z=lambda x, y: 0.1 * np.sin(x) * np.cos(y))
    uv = V[:, :2] / 5.0
    a = metrics.distortion(V, F, uv)
    b = metrics.distortion(V, F, uv[F])
    assert a == b
    assert np.isclose(metrics.packing_efficiency(uv, F), 15.0 / 25.0)


def test_collapsed_triangles_are_counted_not_averaged():
    V, F = grid(nx=3, ny=2)
    uv = V[:, :2].copy()
    C = uv[F].copy()
    C[0] = [[0, 0], [1, 0], [2, 0]]                        # a collapsed triangle in a per-corner map
    d = metrics.distortion(V, F, C)
    assert d["n_collapsed"] == 1 and np.isfinite(d["angle_mean"]) and np.isclose(d["angle_mean"], 1)


def test_weighted_median():
    assert metrics.weighted_median([3.0, 1.0, 2.0], [1, 1, 1]) == 2.0
    assert metrics.weighted_median([0.0, 10.0], [3, 1]) == 0.0


def test_bad_area_scale_is_refused():
    V, F = grid()
    with pytest.raises(ValueError):
        metrics.distortion(V, F, V[:, :2], area_scale="max")


def test_uniformly_scaled_map_gives_every_triangle_its_fair_share():
    V, F = grid(z=lambda x, y: 0.0 * x)
    for scale in (1e-3, 1.0, 250.0):
        uv = scale * (V[:, :2] @ rotation(0.3).T) + [5.0, 7.0]
        s = metrics.texel_share(V, F, uv[F])
        # rtol 1e-9: at scale 1e-3 the offset of 7 costs ~log10(7e3) digits of the UV differences
        assert np.allclose(s, 1.0, rtol=1e-9, atol=0)
        summary = metrics.texel_summary(V, F, uv[F])
        assert np.isclose(summary["min_texel_share"], 1.0, rtol=1e-9)
        assert summary["area_below_quarter"] == 0.0 and summary["area_below_sixteenth"] == 0.0


def test_halving_one_of_two_equal_triangles_gives_the_analytic_shares():
    # two right triangles of area 1/2 each; in UV the first keeps area 1/2, the second gets 1/4
    V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    F = np.array([[0, 1, 2], [0, 2, 3]])
    C = V[:, :2][F].copy()
    C[1] = [[0, 0], [1, 1], [0, 0.5]]                      # second triangle: area 1/4 (flat shear)
    # UV total 3/4: shares (1/2 / 3/4) / (1/2) = 4/3 and (1/4 / 3/4) / (1/2) = 2/3
    s = metrics.texel_share(V, F, C)
    assert np.allclose(s, [4 / 3, 2 / 3], rtol=1e-12)
    assert metrics.area_below(V, F, s, 0.7) == 0.5        # half the surface under 0.7 of fair
    assert metrics.area_below(V, F, s, 0.5) == 0.0


def test_starved_triangle_is_found_and_its_area_counted():
    V, F = grid(nx=5, ny=5)                                # 32 triangles of area 1/2, total 16
    C = V[:, :2][F].copy()
    C[7] = C[7].mean(axis=0) + 0.01 * (C[7] - C[7].mean(axis=0))   # shrunk 100x in length
    s = metrics.texel_share(V, F, C)
    # UV total 16 - 1/2 + 1/2e-4; share of the shrunk one (0.5e-4 / total) / (0.5 / 16)
    total = 16 - 0.5 + 0.5e-4
    assert np.isclose(s[7], (0.5e-4 / total) / (0.5 / 16), rtol=1e-12)
    assert np.allclose(np.delete(s, 7), (0.5 / total) / (0.5 / 16), rtol=1e-12)
    summary = metrics.texel_summary(V, F, C)
    assert np.isclose(summary["min_texel_share"], s[7], rtol=1e-12)
    assert np.isclose(summary["area_below_sixteenth"], 0.5 / 16, rtol=1e-12)
    assert np.isclose(summary["area_below_quarter"], 0.5 / 16, rtol=1e-12)


def test_texel_share_ignores_zero_area_faces_and_mirroring():
    V, F = grid(nx=3, ny=2)
    V = np.vstack([V, [[0.5, 0.0, 0.0]]])                  # on edge (0,1): a zero-area face
    F = np.vstack([F, [[0, 1, len(V) - 1]]])
    uv = V[:, :2] * [-2.0, 2.0]                            # mirrored, scaled: still fair
    s = metrics.texel_share(V, F, uv[F])
    assert s[-1] == 1.0 and np.allclose(s[:-1], 1.0, rtol=1e-12)   # zero 3D area: needs no texels
    assert np.isclose(metrics.texel_summary(V, F, uv[F])["min_texel_share"], 1.0, rtol=1e-12)


def test_peers_measure_undoes_a_per_axis_normalised_atlas():
    """bench/peers.py measures xatlas-style UVs (u / width, v / height) in texel units."""
    spec = importlib.util.spec_from_file_location("bench_peers", _PATH.parent / "peers.py")
    peers = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(peers)
    V, F = grid(nx=5, ny=3)                                # a 4 x 2 rectangle, area 8
    width, height = 200, 100
    texel = 20.0 * V[:, :2] + [10.0, 5.0]                  # 80 x 40 texels, an isometry up to scale
    C = (texel / [width, height])[F]                       # normalised per axis: anisotropic in [0,1]^2
    rec = peers.measure(V, F, C, width, height)
    assert np.isclose(rec["min_texel_share"], 1.0, rtol=1e-12) and rec["area_below_quarter"] == 0.0
    assert np.isclose(rec["angle"], 1.0, rtol=1e-12) and rec["area"] < 1e-12
    assert np.isclose(rec["packing"], 80 * 40 / (width * height), rtol=1e-12)
    assert rec["charts"] == 1 and rec["seam"] == 0.0 and rec["flipped"] == 0 and rec["overlaps"] == 0


def test_distortions_of_many_charts_at_once_are_each_charts_own():
    """The report measures every chart in one pass (charts laid end to end, sums accumulated per
    chart); each chart's numbers must be chart_distortion's to rounding (1e-12 relative), for charts
    with collapsed triangles and a chart with no measurable triangle alike."""
    from uvbake.analysis.metrics import chart_distortion, chart_distortions

    rng = np.random.default_rng(5)
    Vs, Fs, uvs = [], [], []
    for k in range(7):
        V, F = grid(nx=3 + k, ny=2 + k % 3, z=lambda x, y: 0.1 * k * np.sin(x) * y)
        uv = V[:, :2] @ rotation(k) * (1 + k) + rng.normal(0, 0.05, (len(V), 2))
        if k == 2:
            uv[F[0, 2]] = 0.5 * (uv[F[0, 0]] + uv[F[0, 1]])          # one collapsed triangle
        if k == 4:
            uv[:] = 0.0                                             # every triangle collapsed (J = 0 exactly)
        Vs.append(V)
        Fs.append(F)
        uvs.append(uv)
    together = chart_distortions(Vs, Fs, uvs)
    assert len(together) == len(Fs)
    for V, F, uv, d in zip(Vs, Fs, uvs, together):
        alone = chart_distortion(V, F, uv)
        assert alone.keys() == d.keys()
        for key, a in alone.items():
            if np.isinf(a):
                assert d[key] == a
            else:
                assert d[key] == pytest.approx(a, rel=1e-12, abs=0)
    assert np.isinf(together[4]["angle_distortion_mean"]) and np.isfinite(together[2]["angle_distortion_mean"])


def test_singular_values_in_closed_form_are_the_svds():
    # metrics.singular_values takes a 2 x 2 Jacobian's singular values in closed form; they must be
    # LAPACK's to rounding on random maps of every scale, mirrored ones, a collapsed and a zero map
    from uvbake.flatten.energy import jacobians, triangle_frames

    V, F = grid(nx=7, ny=5, z=lambda x, y: 0.3 * np.sin(x) * np.cos(y))
    _, Q, _ = triangle_frames(V, F)
    rng = np.random.default_rng(4)
    for scale in (1e-9, 1.0, 1e9):
        uv = rng.normal(size=(len(V), 2)) * scale
        uv[F[0]] = [[0, 0], [1, 1], [2, 2]]                     # one collapsed triangle (rank 1)
        uv[F[-1]] = 0.0                                          # one zero map (F[-1] shares no vertex of F[0])
        s1, s2, det, _ = metrics.singular_values(V, F, uv)
        ref = np.linalg.svd(jacobians(Q, F, uv), compute_uv=False)
        assert np.all(s1 >= s2) and np.all(s2 >= 0)
        assert np.allclose(s1, ref[:, 0], rtol=1e-13, atol=0)
        assert np.allclose(s2, ref[:, 1], rtol=0, atol=1e-13 * ref[:, 0].max())
        assert s2[0] <= 1e-13 * s1[0] and s1[-1] == 0 and s2[-1] == 0
        assert np.allclose(s1 * s2, np.abs(det), rtol=1e-12, atol=0)
