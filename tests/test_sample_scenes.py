"""The shipped sample scenes: topology, quality and byte-exact regeneration.

Topology is recomputed here from the faces alone (numpy + scipy.sparse.csgraph), independent of the
checks inside make_scenes.py.
"""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from uvbake.io.load import load_mesh

SAMPLE_SCENES = Path(__file__).resolve().parents[1] / "sample_scenes"
SCENE_FILES = ["disk_holes.ply", "sphere_cap.ply", "scene.ply", "multi_component.ply"]


def _component_labels(n, edges):
    graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    return connected_components(graph, directed=False)[1]


def surface_stats(F):
    """Components, boundary loops, V - E + F and genus of the vertices F uses; asserts manifold."""
    used, F = np.unique(F, return_inverse=True)
    F = F.reshape(-1, 3)
    n = len(used)
    half = np.vstack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    edges, counts = np.unique(np.sort(half, axis=1), axis=0, return_counts=True)
    assert counts.max() <= 2, "an edge has more than two faces"
    assert len(np.unique(half, axis=0)) == len(half), "faces are not consistently oriented"
    boundary = edges[counts == 1]
    boundary_degree = np.bincount(boundary.ravel(), minlength=n)
    assert set(np.unique(boundary_degree)) <= {0, 2}, "the boundary touches itself at a vertex"
    labels = _component_labels(n, edges)
    n_comp = labels.max() + 1
    on_boundary = boundary_degree > 0
    loop_labels = _component_labels(n, boundary)
    n_loops = len(np.unique(loop_labels[on_boundary]))
    chi = n - len(edges) + len(F)
    genus = (2 * n_comp - n_loops - chi) // 2
    return {"components": int(n_comp), "loops": int(n_loops), "chi": int(chi), "genus": int(genus)}


def component_face_sets(F):
    half = np.vstack([F[:, [0, 1]], F[:, [1, 2]]])
    labels = _component_labels(F.max() + 1, half)
    return [F[labels[F[:, 0]] == k] for k in np.unique(labels[F[:, 0]])]


def min_angle_deg(V, F):
    T = V[F]
    smallest = np.inf
    for k in range(3):
        u = T[:, (k + 1) % 3] - T[:, k]
        w = T[:, (k + 2) % 3] - T[:, k]
        cos = np.sum(u * w, 1) / np.linalg.norm(u, axis=1) / np.linalg.norm(w, axis=1)
        smallest = min(smallest, np.degrees(np.arccos(np.clip(cos, -1, 1))).min())
    return smallest


@pytest.fixture(scope="module", params=SCENE_FILES)
def scene_file(request):
    return SAMPLE_SCENES / request.param


def test_scene_is_small_clean_and_well_shaped(scene_file):
    assert scene_file.stat().st_size < 1_000_000
    mesh = load_mesh(scene_file)
    assert mesh.source == str(scene_file)
    assert 1000 <= len(mesh.F) <= 10000
    assert np.isfinite(mesh.V).all()
    assert np.array_equal(np.unique(mesh.F), np.arange(len(mesh.V))), "unreferenced vertices"
    assert min_angle_deg(mesh.V, mesh.F) > 20.0
    surface_stats(mesh.F)  # manifold, oriented, no pinched boundary vertex


def test_disk_holes_is_one_disk_with_three_holes():
    mesh = load_mesh(SAMPLE_SCENES / "disk_holes.ply")
    assert surface_stats(mesh.F) == {"components": 1, "loops": 4, "chi": -2, "genus": 0}
    assert mesh.face_labels is None and mesh.vertex_colors is None
    assert np.linalg.norm(mesh.V[:, :2], axis=1).max() == pytest.approx(1.0, abs=1e-6)
    assert np.ptp(mesh.V[:, 2]) > 0.2  # curved, not flat


def test_sphere_cap_lies_on_the_unit_sphere_and_faces_outward():
    mesh = load_mesh(SAMPLE_SCENES / "sphere_cap.ply")
    assert surface_stats(mesh.F) == {"components": 1, "loops": 3, "chi": -1, "genus": 0}
    np.testing.assert_allclose(np.linalg.norm(mesh.V, axis=1), 1.0, atol=1e-6)
    assert mesh.V[:, 2].min() == pytest.approx(-0.3, abs=1e-6)
    T = mesh.V[mesh.F]
    normals = np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0])
    assert np.all(np.sum(normals * T.mean(axis=1), axis=1) > 0)


def test_scene_has_eight_labelled_disk_charts_of_varied_size_and_colours():
    mesh = load_mesh(SAMPLE_SCENES / "scene.ply")
    assert surface_stats(mesh.F) == {"components": 1, "loops": 4, "chi": -2, "genus": 0}
    assert np.array_equal(np.unique(mesh.face_labels), np.arange(8))
    loops, areas = [], []
    T = mesh.V[mesh.F]
    face_area = 0.5 * np.linalg.norm(np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]), axis=1)
    for k in range(8):
        stats = surface_stats(mesh.F[mesh.face_labels == k])
        assert stats["components"] == 1 and stats["genus"] == 0, f"chart {k}: {stats}"
        assert stats["chi"] == 2 - stats["loops"]
        loops.append(stats["loops"])
        areas.append(face_area[mesh.face_labels == k].sum())
    assert loops == [3, 1, 1, 1, 1, 2, 1, 1]  # chart 0 has two holes, chart 5 one
    assert max(areas) > 4 * min(areas)        # a few large charts and several small ones
    c = mesh.vertex_colors
    assert c.shape == mesh.V.shape and c.min() >= 0 and c.max() <= 1
    assert len(np.unique(np.round(c * 255), axis=0)) > 500  # a gradient, not a flat tint


def test_multi_component_has_four_disk_patches():
    mesh = load_mesh(SAMPLE_SCENES / "multi_component.ply")
    assert mesh.face_labels is None
    parts = component_face_sets(mesh.F)
    stats = [surface_stats(f) for f in parts]
    assert [s["components"] for s in stats] == [1, 1, 1, 1]
    assert [s["genus"] for s in stats] == [0, 0, 0, 0]
    assert sorted(s["loops"] for s in stats) == [1, 1, 1, 2]


def test_make_scenes_reproduces_the_shipped_files_byte_for_byte(tmp_path):
    script = SAMPLE_SCENES / "make_scenes.py"
    subprocess.run([sys.executable, str(script), "--out", str(tmp_path)], check=True,
                   capture_output=True, text=True)
    for name in [*SCENE_FILES, "README.md"]:
        shipped = (SAMPLE_SCENES / name).read_bytes()
        assert (tmp_path / name).read_bytes() == shipped, f"{name} differs from the shipped file"
