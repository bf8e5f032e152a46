"""Pictures of the sample scene: the atlas image (charts, seams, legend), the lit turntable preview and
the sweep plot, against goldens (tests/goldens/, regenerate with --uvbake-update-goldens); and the
geometry the atlas image draws (seams are exactly the chart-boundary edges)."""

import numpy as np
import pytest

from conftest import SAMPLE_SCENES

SIZE = 256


@pytest.fixture(scope="module")
def scene():
    from uvbake.atlas.pipeline import unwrap

    return unwrap(SAMPLE_SCENES / "scene.ply", texture_size_px=SIZE, bake="checker")


@pytest.fixture(scope="module")
def atlas(scene):
    from uvbake.render import atlas_image

    return atlas_image(scene, size_px=SIZE)


def test_atlas_image_golden(atlas, texture_regression):
    texture_regression.check(atlas, name="scene_atlas_image")


def test_atlas_image_draws_charts_seams_and_legend(scene, atlas):
    from uvbake.pictures import SEAM_RGB, seam_edges
    from uvbake.validate.report import BACKGROUND_RGB

    assert atlas.shape[1] == SIZE and atlas.shape[0] > SIZE and atlas.dtype == np.uint8
    square, legend = atlas[:SIZE], atlas[SIZE:]
    colours = {tuple(c) for c in square.reshape(-1, 3)} - {tuple(BACKGROUND_RGB), SEAM_RGB}
    assert len(colours) == len(scene.charts) == 8                     # one fill colour per chart
    # the midpoint of every seam segment is drawn dark, or a neighbour of its pixel is (segments are
    # sampled every half pixel, so a sample lies within 1/4 pixel of the midpoint)
    seg = seam_edges(scene.corner_uv)
    assert len(seg) > 0
    mid = seg.mean(axis=1)
    c = (mid[:, 0] * SIZE).astype(int)
    r = SIZE - 1 - (mid[:, 1] * SIZE).astype(int)
    dark = np.all(np.pad(square, ((1, 1), (1, 1), (0, 0)), constant_values=255) == SEAM_RGB, axis=2)
    near = np.zeros(len(seg), bool)
    for dr in (0, 1, 2):
        for dc in (0, 1, 2):
            near |= dark[np.clip(r + dr, 0, SIZE + 1), np.clip(c + dc, 0, SIZE + 1)]
    assert near.all(), f"{(~near).sum()} of {len(seg)} seam midpoints not drawn"
    # and seam pixels are few: lines, not fills (under 10 % of the square)
    assert 0 < np.mean(np.all(square == SEAM_RGB, axis=2)) < 0.1
    assert np.any(legend.max(axis=2) < 100) and np.mean(legend == 255) > 0.5   # text on white


def test_seam_edges_are_the_chart_boundaries():
    from uvbake.pictures import seam_edges

    # an n x n grid of quads in one chart: interior edges shared with equal UVs, 4 n boundary edges
    n = 4
    g = np.linspace(0.1, 0.9, n + 1)                                # grid lines 0.1, 0.3, 0.5, 0.7, 0.9
    uv = np.stack(np.meshgrid(g, g, indexing="xy"), axis=-1).reshape(-1, 2)
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="xy")
    a = (j * (n + 1) + i).ravel()
    F = np.concatenate([np.stack([a, a + 1, a + n + 2], 1), np.stack([a, a + n + 2, a + n + 1], 1)])
    assert len(seam_edges(uv[F])) == 4 * n
    # two charts: the right half moved by 0.02 in u; the cut along u = 0.5 is a seam on both sides
    corner = uv[F].copy()
    corner[corner[:, :, 0].mean(axis=1) > 0.5, :, 0] += 0.02
    seams = seam_edges(corner)
    left = np.all(np.isclose(seams[:, :, 0], 0.5), axis=1)
    right = np.all(np.isclose(seams[:, :, 0], 0.52), axis=1)
    assert len(seams) == 4 * n + 2 * n and left.sum() == right.sum() == n


def test_lit_turntable_preview_golden(scene, texture_regression):
    from uvbake.render import preview

    img = preview(scene, size_px=96, views="turntable:4", lighting="lit")
    assert img.shape == (96, 4 * 96 + 3 * 2, 3)
    texture_regression.check(img, name="scene_preview_lit_turntable")
    unlit = preview(scene, size_px=96, views="turntable:4")
    # shading only darkens the unlit texture values (no light brighter than the texture's own value)
    assert np.mean(img.astype(int)) < np.mean(unlit.astype(int))


def test_preview_rejects_unknown_views_and_lighting(scene):
    from uvbake.errors import InputError
    from uvbake.render import preview

    for kw, match in ((dict(views="turntable:0"), "turntable"), (dict(views=["top"]), "top"),
                      (dict(lighting="studio"), "lighting")):
        with pytest.raises(InputError, match=match):
            preview(scene, size_px=32, **kw)


@pytest.mark.slow
def test_sweep_plot_golden(tmp_path, texture_regression):
    pytest.importorskip("matplotlib")
    from uvbake.analysis.sensitivity import sweep
    from uvbake.io.load import load_mesh

    mesh = load_mesh(SAMPLE_SCENES / "scene.ply")
    result = sweep(mesh.V, mesh.F, [0.25, 0.5, 0.75], labels=mesh.face_labels, overlaps=False)
    d_area = [r.energy_area for r in result.records]
    d_angle = [r.energy_angle for r in result.records]
    # the trade-off the plot shows: more weight on area, less area distortion and more angle distortion
    assert d_area[0] > d_area[1] > d_area[2] and d_angle[0] < d_angle[1] < d_angle[2]
    path = tmp_path / "sweep.png"
    result.plot(path, title="scene.ply", dpi=60)
    texture_regression.check(path, name="scene_sweep_plot")
