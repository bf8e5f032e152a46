"""Preview renders, and the project's texture regression on the sample scenes (goldens in tests/goldens/).

CI runs these with the ``texture_regression`` fixture of uvbake's own pytest plugin. A deliberate
regression (a chart moved in the atlas, a texture swapped, a texture flipped upside down: the classic
v-origin bug) is shown to fail against the same goldens, and harmless noise (a chart moved by one
texel, +-1 level on every texel) is shown to pass, both with the plugin's default tolerances.
Regenerate the goldens with ``python3 -m pytest tests/test_render.py --uvbake-update-goldens``.
"""

from pathlib import Path

import numpy as np
import pytest

from pytest_uvbake.compare import as_image, compare_images
from pytest_uvbake.plugin import DEFAULT_MAD_TOL, DEFAULT_SSIM_MIN

from conftest import SAMPLE_SCENES

SIZE = 256          # texture side of the goldens
VIEW = 160          # side of each preview view
GOLDENS = Path(__file__).parent / "goldens"


def _golden(name, request):
    path = GOLDENS / f"{name}.png"
    if request.config.getoption("uvbake_update_goldens"):
        pytest.skip("goldens are being regenerated")
    assert path.exists(), f"{path} missing; run pytest with --uvbake-update-goldens"
    return as_image(path)


def _passes(image, golden):
    c = compare_images(image, golden)
    return c.mad <= DEFAULT_MAD_TOL and c.ssim >= DEFAULT_SSIM_MIN, c


@pytest.fixture(scope="module")
def scene():
    from uvbake.atlas.pipeline import unwrap

    return unwrap(SAMPLE_SCENES / "scene.ply", texture_size_px=SIZE, bake="vertex-colors")


@pytest.fixture(scope="module")
def scene_checker(scene):
    from uvbake.atlas.bake import bake_checker

    return bake_checker(scene.V, scene.F, scene.corner_uv, texture_size_px=SIZE,
                        texel_size_world=scene.report["atlas"]["texel_size_world"])


@pytest.fixture(scope="module")
def scene_preview(scene, scene_checker):
    from uvbake.render import preview

    return preview(scene.V, scene.F, scene.corner_uv, scene_checker, size_px=VIEW)


# --------------------------------------------------------------------------------------------------
# goldens (CI texture regression)


def test_scene_vertex_colors_golden(scene, texture_regression):
    assert scene.report["valid"] and scene.image.shape == (SIZE, SIZE, 3)
    texture_regression.check(scene.image, name="scene_colors_256")


def test_scene_checker_golden(scene_checker, texture_regression):
    texture_regression.check(scene_checker, name="scene_checker_256")


def test_scene_preview_golden(scene_preview, texture_regression):
    assert scene_preview.shape == (VIEW, 3 * VIEW + 4, 3)
    texture_regression.check(scene_preview, name="scene_preview")


def test_multi_component_golden(texture_regression):
    from uvbake.atlas.pipeline import unwrap

    r = unwrap(SAMPLE_SCENES / "multi_component.ply", texture_size_px=SIZE, bake="checker")
    assert r.report["valid"]
    texture_regression.check(r.image, name="multi_component_checker_256")


# --------------------------------------------------------------------------------------------------
# the tolerances: harmless noise passes, a real change fails (same goldens, default tolerances)


def _moved(scene, chart, texels):
    """Vertex-colour texture rebaked with one chart translated by ``texels`` in u (inward)."""
    from uvbake.atlas.bake import bake_vertex_colors

    cuv = scene.corner_uv.copy()
    sel = scene.chart_ids == chart
    step = texels / SIZE
    if cuv[sel][..., 0].max() + step > 1.0:
        step = -step
    cuv[sel, :, 0] += step
    return bake_vertex_colors(scene.V, scene.F, cuv, scene.vertex_colors, texture_size_px=SIZE)


def test_chart_moved_by_one_texel_passes_by_eight_fails(scene, request):
    golden = _golden("scene_colors_256", request)
    for k in range(len(scene.charts)):
        ok, c = _passes(_moved(scene, k, 1), golden)
        assert ok and c.mad < 0.5 * DEFAULT_MAD_TOL, (k, c.to_dict())
        ok, c = _passes(_moved(scene, k, 8), golden)
        assert not ok, (k, c.to_dict())


def test_texel_noise_passes(scene, request):
    golden = _golden("scene_colors_256", request)
    rng = np.random.default_rng(0)
    noisy = np.clip(scene.image.astype(int) + rng.integers(-1, 2, scene.image.shape), 0, 255).astype(np.uint8)
    ok, c = _passes(noisy, golden)
    assert ok, c.to_dict()


def test_swapped_texture_fails(scene_checker, request):
    ok, c = _passes(scene_checker, _golden("scene_colors_256", request))
    assert not ok and c.mad > 20 * DEFAULT_MAD_TOL, c.to_dict()


def test_preview_is_deterministic_and_catches_a_flipped_texture(scene, scene_checker, scene_preview, request):
    from uvbake.render import preview

    again = preview(scene.V, scene.F, scene.corner_uv, scene_checker, size_px=VIEW)
    assert np.array_equal(again, scene_preview)                         # same inputs, same bytes
    golden = _golden("scene_preview", request)
    assert _passes(scene_preview, golden)[0]
    flipped = preview(scene.V, scene.F, scene.corner_uv, scene_checker[::-1], size_px=VIEW)
    ok, c = _passes(flipped, golden)
    assert not ok, c.to_dict()


# --------------------------------------------------------------------------------------------------
# the renderer itself


def test_renderer_uv_convention_and_colours(tmp_path):
    """Open3D's renderer samples texture_uvs with v up (row 0 at v = 1); colours come out as baked."""
    from uvbake.render import preview

    V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    F = np.array([[0, 1, 2], [0, 2, 3]])
    corner_uv = V[:, :2][F]                                     # u = x, v = y
    tex = np.zeros((64, 64, 3), np.uint8)
    tex[:32] = (200, 40, 40)                                    # image top: red
    tex[32:] = (40, 40, 200)                                    # image bottom: blue
    tex[:, :16] = (40, 160, 40)                                 # image left: green
    img = preview(V, F, corner_uv, tex, size_px=96, views=["front"], background=(255, 255, 255),
                  path=tmp_path / "quad.png")
    assert img.shape == (96, 96, 3) and np.array_equal(as_image(tmp_path / "quad.png"), img)
    ys, xs = np.nonzero(np.any(img != 255, axis=2))
    y0, y1, x0, x1 = ys.min(), ys.max(), xs.min(), xs.max()

    def at(fy, fx):
        return img[int(y0 + fy * (y1 - y0)), int(x0 + fx * (x1 - x0))].astype(int)

    assert np.abs(at(0.25, 0.7) - (200, 40, 40)).max() <= 4          # top of the quad (v = 1): red
    assert np.abs(at(0.75, 0.7) - (40, 40, 200)).max() <= 4          # bottom: blue
    assert np.abs(at(0.5, 0.1) - (40, 160, 40)).max() <= 4           # left (u = 0): green


def test_preview_input_errors(monkeypatch):
    from uvbake.errors import InputError
    from uvbake.render import RenderError, preview

    V = np.eye(3)
    F = np.array([[0, 1, 2]])
    uv = np.zeros((1, 3, 2))
    with pytest.raises(InputError, match="views"):
        preview(V, F, uv, views=["top"])
    with pytest.raises(InputError, match="corner_uv"):
        preview(V, F, np.zeros((2, 3, 2)))
    with pytest.raises(InputError, match="size_px"):
        preview(V, F, uv, size_px=8)
    import uvbake.render as render

    monkeypatch.setattr(render.sys, "executable", "/bin/false")
    with pytest.raises(RenderError, match="libvulkan1 and mesa-vulkan-drivers"):
        preview(V, F, uv)


def test_preview_writes_png(tmp_path, scene, scene_checker, scene_preview):
    from uvbake.render import save_png

    out = save_png(tmp_path / "preview.png", scene_preview)
    assert np.array_equal(as_image(out), scene_preview)
