"""The energy's mathematics: frames, Jacobians, gradient and Hessian against finite differences."""

import numpy as np
import pytest
import scipy.sparse as sp

from uvbake.flatten.energy import DistortionEnergy, jacobians, optimal_scale, triangle_frames

from meshgen import bumpy_disk, plane


def random_mesh(rng, n=9, m=10):
    V = rng.normal(size=(n, 3))
    F = np.array([rng.choice(n, 3, replace=False) for _ in range(m)])
    return V, F


def test_frames_are_isometric_and_right_handed():
    rng = np.random.default_rng(1)
    V, F = random_mesh(rng)
    R, Q, area = triangle_frames(V, F)
    X = V[F]
    # pairwise corner distances survive the flattening
    for i, j in [(0, 1), (1, 2), (2, 0)]:
        np.testing.assert_allclose(np.linalg.norm(R[:, :, i] - R[:, :, j], axis=1),
                                   np.linalg.norm(X[:, i] - X[:, j], axis=1), rtol=1e-12)
    # corners keep their counter-clockwise order about the normal: positive 2D signed area
    e1, e2 = R[:, :, 1] - R[:, :, 0], R[:, :, 2] - R[:, :, 0]
    np.testing.assert_allclose(0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]), area, rtol=1e-12)
    np.testing.assert_allclose(np.einsum("mik,mkj->mij", R, Q), np.broadcast_to(np.eye(2), (len(F), 2, 2)),
                               atol=1e-12)
    np.testing.assert_allclose(R.sum(axis=2), 0, atol=1e-12)


def test_identity_map_of_a_planar_mesh_has_zero_energy_and_unit_jacobians():
    st_V, F = plane(jitter=0.3)
    # flatten the tilted plane back isometrically: its own 2D coordinates
    _, Q, _ = triangle_frames(st_V, F)
    e1 = st_V[1] - st_V[0]
    e1 /= np.linalg.norm(e1)
    n = np.cross(st_V[F[0, 1]] - st_V[F[0, 0]], st_V[F[0, 2]] - st_V[F[0, 0]])
    n /= np.linalg.norm(n)
    e2 = np.cross(n, e1)
    uv = np.column_stack([st_V @ e1, st_V @ e2])
    A = jacobians(Q, F, uv)
    sv = np.linalg.svd(A, compute_uv=False)
    np.testing.assert_allclose(sv, 1.0, atol=1e-12)
    assert np.all(np.linalg.det(A) > 0)
    for alpha in (0.0, 0.3, 1.0):
        assert DistortionEnergy(st_V, F, alpha=alpha).value(uv) < 1e-24
    # a mirrored map is orientation-reversing: det = -1, area term 4 per triangle
    mirrored = uv * [1, -1]
    d_area, d_angle = DistortionEnergy(st_V, F, alpha=1.0).per_triangle(mirrored)
    np.testing.assert_allclose(d_area, 4.0, rtol=1e-12)
    np.testing.assert_allclose(d_angle, 4.0, rtol=1e-12)   # (1+1)^2 + 0


def test_energy_matches_its_definition_per_triangle():
    rng = np.random.default_rng(2)
    V, F = random_mesh(rng)
    uv = rng.normal(size=(len(V), 2))
    _, Q, _ = triangle_frames(V, F)
    A = jacobians(Q, F, uv)
    det = np.linalg.det(A)
    d_angle = (A[:, 0, 0] - A[:, 1, 1]) ** 2 + (A[:, 0, 1] + A[:, 1, 0]) ** 2
    for alpha in (0.0, 0.25, 1.0):
        expected = np.sum(alpha * (det - 1) ** 2 + (1 - alpha) * d_angle)
        assert DistortionEnergy(V, F, alpha=alpha).value(uv) == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("alpha", [0.0, 0.1, 0.5, 0.9, 1.0])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_gradient_and_hessian_match_central_differences(alpha, seed):
    rng = np.random.default_rng(seed)
    V, F = random_mesh(rng, n=8, m=9)
    uv = rng.normal(size=(len(V), 2))
    E = DistortionEnergy(V, F, alpha=alpha)
    f, g, H = E.evaluate(uv)
    x = uv.ravel()
    h = 1e-6
    eye = np.eye(len(x))
    g_fd = np.array([(E.value((x + h * e).reshape(-1, 2)) - E.value((x - h * e).reshape(-1, 2))) / (2 * h)
                     for e in eye])
    H_fd = np.array([(E.gradient((x + h * e).reshape(-1, 2)) - E.gradient((x - h * e).reshape(-1, 2))) / (2 * h)
                     for e in eye])
    assert np.linalg.norm(g - g_fd) <= 1e-6 * np.linalg.norm(g_fd)
    Hd = H.toarray()
    assert np.linalg.norm(Hd - H_fd) <= 1e-6 * np.linalg.norm(H_fd)
    np.testing.assert_array_equal(Hd, Hd.T)
    assert f == pytest.approx(E.value(uv), rel=1e-14)


def test_area_hessian_is_indefinite_where_triangles_shrink():
    rng = np.random.default_rng(3)
    V, F = random_mesh(rng, n=3, m=1)
    F = np.array([[0, 1, 2]])
    # a map that shrinks the triangle: det < 1, the (det - 1) Hess(det) term is indefinite
    R, _, _ = triangle_frames(V, F)
    uv = 0.3 * R[0].T
    _, _, H = DistortionEnergy(V, F, alpha=1.0).evaluate(uv)
    assert np.linalg.eigvalsh(H.toarray()).min() < -1e-8


def test_fixed_unknowns_give_the_free_block():
    V, F = bumpy_disk(6)
    rng = np.random.default_rng(4)
    uv = rng.normal(size=(len(V), 2))
    fixed = np.zeros(2 * len(V), bool)
    fixed[[0, 1, 10, 11]] = True
    full = DistortionEnergy(V, F, alpha=0.4)
    part = DistortionEnergy(V, F, alpha=0.4, fixed=fixed)
    f1, g1, H1 = full.evaluate(uv)
    f2, g2, H2 = part.evaluate(uv)
    assert f1 == pytest.approx(f2)
    np.testing.assert_allclose(g2, g1[~fixed], rtol=1e-13)
    np.testing.assert_allclose(H2.toarray(), H1.toarray()[np.ix_(~fixed, ~fixed)], rtol=1e-13)
    assert sp.isspmatrix_csc(H2)


def test_pattern_is_fixed_and_refilled_in_place():
    V, F = bumpy_disk(6)
    E = DistortionEnergy(V, F, alpha=0.5)
    rng = np.random.default_rng(5)
    H = E.empty_matrix()
    ptr, idx = H.indptr.copy(), H.indices.copy()
    _, _, H_a = E.evaluate(rng.normal(size=(len(V), 2)), out=H)
    assert H_a is H
    np.testing.assert_array_equal(H.indptr, ptr)
    np.testing.assert_array_equal(H.indices, idx)
    # the pattern is the vertex adjacency, two unknowns per vertex: nnz = 4 (n + 2 edges)
    n_edges = len({tuple(sorted(e)) for f in F for e in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0]))})
    assert H.nnz == 4 * (len(V) + 2 * n_edges)


def test_the_free_patterns_fast_build_is_the_general_one():
    # with no fixed unknown the pattern is built from vertex pairs (9 keys a triangle, not 36): the same
    # arrays, entry for entry, as the general build, also with a repeated vertex, a vertex no triangle
    # uses, a lone triangle and several parts (closed torus, cut cylinder)
    from meshgen import cut_cylinder, torus

    cases = [bumpy_disk(6), cut_cylinder(), torus()]
    V, F = plane()
    F = F.copy()
    F[3] = [F[3, 0], F[3, 0], F[3, 2]]                              # a triangle repeating a vertex
    cases += [(V, F), (np.vstack([V, [[9.0, 9.0, 9.0]]]), F), (V[:3], np.array([[0, 1, 2]]))]
    Vt, Ft = torus()
    Vd, Fd = bumpy_disk(4)
    cases.append((np.vstack([Vd, Vt]), np.vstack([Fd, Ft + len(Vd)])))
    names = ["_hslot_full", "_hslot", "_hkeep", "_indices", "_indptr", "_diag", "_gkeep", "_gslot"]
    for V, F in cases:
        fast = DistortionEnergy(V, F, alpha=0.5)
        general = DistortionEnergy(V, F, alpha=0.5)
        general._build_pattern_general()
        for name in names:
            a, b = getattr(fast, name), getattr(general, name)
            assert a.dtype == b.dtype and np.array_equal(a, b), name
        assert fast._nnz == general._nnz and fast._all_free and general._all_free


def test_change_is_accurate_where_the_difference_of_values_is_not():
    V, F = bumpy_disk(10)
    rng = np.random.default_rng(6)
    uv = 1e3 * rng.normal(size=(len(V), 2))          # F ~ 1e12 or more
    duv = 1e-12 * rng.normal(size=(len(V), 2))
    E = DistortionEnergy(V, F, alpha=0.5)
    exact = float(E.gradient(uv) @ duv.ravel())      # second-order terms are ~1e-12 relative here
    assert E.change(uv, duv) == pytest.approx(exact, rel=1e-6)
    naive = E.value(uv + duv) - E.value(uv)
    assert abs(naive - exact) > 1e-2 * abs(exact)    # the naive difference has lost it


def test_optimal_scale_minimises_along_the_ray():
    V, F = bumpy_disk(8)
    rng = np.random.default_rng(7)
    uv = rng.normal(size=(len(V), 2)) * 0.01 + V[:, :2]
    for alpha in (0.2, 0.7):
        E = DistortionEnergy(V, F, alpha=alpha)
        s = optimal_scale(E, uv)
        fs = E.value(s * uv)
        assert fs <= E.value(1.001 * s * uv) and fs <= E.value(0.999 * s * uv)


def test_alpha_outside_unit_interval_is_refused():
    V, F = plane()
    for bad in (-0.1, 1.5, float("nan")):
        with pytest.raises(ValueError, match="alpha"):
            DistortionEnergy(V, F, alpha=bad)
