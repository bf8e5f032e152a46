"""The pytest plugin, from the outside: inner pytest sessions (pytester) pass, fail and update goldens.

The images are a small synthetic atlas (checkered charts on black); the variants are a one-pixel jitter
(the whole image shifted by a pixel, plus +-1 level noise), a chart moved by 6 texels, and a chart whose
texture was swapped for stripes.
"""

import numpy as np
import pytest
import scipy.ndimage  # noqa: F401  (imported here: pytester's in-process runs must not import it first)

from pytest_uvbake.compare import compare_images, pixel_diff
from pytest_uvbake.plugin import DEFAULT_MAD_TOL, DEFAULT_SSIM_MIN

pytest_plugins = ["pytester"]

ATLAS = r'''
import numpy as np

CHARTS = [(8, 8, 56, 40), (8, 60, 40, 60), (72, 12, 48, 36), (72, 64, 50, 56)]   # y, x, h, w


def checker(h, w, sq=6, phase=0):
    yy, xx = np.mgrid[0:h, 0:w]
    on = ((yy + phase) // sq + (xx + phase) // sq) % 2 == 0
    img = np.where(on[:, :, None], np.array([230, 200, 60], np.uint8), np.array([40, 60, 160], np.uint8))
    return img.astype(np.uint8)


def atlas(variant="base"):
    img = np.zeros((128, 128, 3), np.uint8)
    for k, (y, x, h, w) in enumerate(CHARTS):
        tex = checker(h, w, phase=3 * k)
        if variant == "swapped" and k == 2:
            tex = np.zeros_like(tex)
            tex[::4] = 255                                   # stripes instead of the checker
        if variant == "moved" and k == 1:
            x += 6
        img[y:y + h, x:x + w] = tex
    if variant == "jitter":
        img = np.concatenate([img[:, :1], img[:, :-1]], axis=1)          # one pixel to the right
        rng = np.random.default_rng(1)
        img = np.clip(img.astype(int) + rng.integers(-1, 2, img.shape), 0, 255).astype(np.uint8)
    if variant == "bigger":
        img = np.zeros((130, 128, 3), np.uint8)
    return img
'''

INNER_TEST = r'''
import os
from atlas_images import atlas


def test_atlas(texture_regression):
    texture_regression.check(atlas(os.environ.get("ATLAS_VARIANT", "base")), name="atlas")
'''


@pytest.fixture(autouse=True)
def _only_our_plugin(monkeypatch):
    """Inner sessions load only uvbake's plugin (not every pytest11 plugin of this environment)."""
    monkeypatch.setenv("PYTEST_DISABLE_PLUGIN_AUTOLOAD", "1")


def _run(pytester, *args):
    return pytester.runpytest_inprocess("-p", "pytest_uvbake.plugin", "-p", "no:cacheprovider", *args)


@pytest.fixture
def inner(pytester, monkeypatch):
    pytester.makepyfile(atlas_images=ATLAS, test_inner=INNER_TEST)
    monkeypatch.setenv("ATLAS_VARIANT", "base")

    def run(variant="base", *args):
        monkeypatch.setenv("ATLAS_VARIANT", variant)
        return _run(pytester, *args)
    run.path = pytester.path
    return run


def test_registered_as_pytest11_entry_point(request):
    from importlib.metadata import entry_points

    eps = {ep.name: ep.value for ep in entry_points(group="pytest11")}
    assert eps.get("uvbake") == "pytest_uvbake.plugin"
    assert request.config.pluginmanager.hasplugin("uvbake")          # loaded in this very session
    assert "texture_regression" in request.fixturenames or request.getfixturevalue("texture_regression")


def _atlas(variant):
    scope = {}
    exec(ATLAS, scope)
    return scope["atlas"](variant)


def test_update_then_identical_passes(inner):
    r = inner("base", "--uvbake-update-goldens")
    r.assert_outcomes(passed=1)
    golden = inner.path / "goldens" / "atlas.png"
    assert golden.exists()
    r.stdout.fnmatch_lines(["*uvbake goldens updated*", f"wrote {golden}", "*1 golden image(s) written*"])
    r = inner("base")
    r.assert_outcomes(passed=1)
    assert not (inner.path / "atlas.actual.png").exists()


def test_missing_golden_fails_and_says_how_to_create_it(inner):
    r = inner("base")
    r.assert_outcomes(failed=1)
    r.stdout.fnmatch_lines(["*golden*atlas.png does not exist; run pytest with --uvbake-update-goldens*"])
    assert (inner.path / "atlas.actual.png").exists()


def test_one_pixel_jitter_passes(inner):
    inner("base", "--uvbake-update-goldens").assert_outcomes(passed=1)
    inner("jitter").assert_outcomes(passed=1)


@pytest.mark.parametrize("variant", ["moved", "swapped"])
def test_real_change_fails_and_writes_actual_and_diff(inner, variant):
    from PIL import Image

    inner("base", "--uvbake-update-goldens").assert_outcomes(passed=1)
    r = inner(variant)
    r.assert_outcomes(failed=1)
    r.stdout.fnmatch_lines(["*texture_regression 'atlas' differs from*atlas.png: *SSIM*actual: *atlas.actual.png, "
                            "diff: *atlas.diff.png*--uvbake-update-goldens*"])
    actual, diff = inner.path / "atlas.actual.png", inner.path / "atlas.diff.png"
    assert np.array_equal(np.asarray(Image.open(actual)), _atlas(variant))
    d = np.asarray(Image.open(diff))
    assert d.shape == (128, 128, 3) and (d[:, :, 0] > 200).any()          # differences in red
    # the golden is untouched; accepting the change makes the same test pass and cleans up
    assert np.array_equal(np.asarray(Image.open(inner.path / "goldens" / "atlas.png")), _atlas("base"))
    inner(variant, "--uvbake-update-goldens").assert_outcomes(passed=1)
    assert not actual.exists() and not diff.exists()
    inner(variant).assert_outcomes(passed=1)


def test_size_change_fails(inner):
    inner("base", "--uvbake-update-goldens").assert_outcomes(passed=1)
    r = inner("bigger")
    r.assert_outcomes(failed=1)
    r.stdout.fnmatch_lines(["*image is 128x130x3 but golden*is 128x128x3*"])


def test_ini_goldens_dir_and_per_check_tolerance(pytester, monkeypatch):
    pytester.makeini("[pytest]\nuvbake_goldens_dir = ref/images\n")
    pytester.makepyfile(atlas_images=ATLAS, test_inner=r'''
import os
from atlas_images import atlas

def test_loose(texture_regression):
    texture_regression.check(atlas(os.environ["ATLAS_VARIANT"]), name="sub/atlas", mad_tol=50, ssim_min=0.5)
''')
    monkeypatch.setenv("ATLAS_VARIANT", "base")
    _run(pytester, "--uvbake-update-goldens").assert_outcomes(passed=1)
    assert (pytester.path / "ref" / "images" / "sub" / "atlas.png").exists()
    monkeypatch.setenv("ATLAS_VARIANT", "moved")
    _run(pytester).assert_outcomes(passed=1)         # loosened on purpose


def test_bad_name_is_an_error(pytester):
    pytester.makepyfile(test_inner=r'''
import numpy as np, pytest

def test_names(texture_regression):
    img = np.zeros((8, 8, 3), np.uint8)
    for bad in ["../escape", "/abs", "a b"]:
        with pytest.raises(ValueError, match="texture_regression name"):
            texture_regression.check(img, name=bad)
''')
    _run(pytester).assert_outcomes(passed=1)


# ---------------------------------------------------------------------------------------------------
# the measures themselves (numbers quoted in the plugin's docstring and the report)


def test_measures_separate_noise_from_changes():
    base = _atlas("base")
    same = compare_images(base, base.copy())
    assert same.mad == 0 and same.ssim == pytest.approx(1.0)
    jitter = compare_images(_atlas("jitter"), base)
    assert jitter.mad < 0.7 * DEFAULT_MAD_TOL and jitter.ssim > DEFAULT_SSIM_MIN + 0.01
    for variant in ("moved", "swapped"):
        c = compare_images(_atlas(variant), base)
        assert c.mad > 2 * DEFAULT_MAD_TOL or c.ssim < DEFAULT_SSIM_MIN - 0.03, (variant, c.to_dict())


def test_jitter_px_zero_is_plain_mad():
    rng = np.random.default_rng(0)
    a = rng.integers(0, 256, (20, 30, 3)).astype(np.uint8)
    b = rng.integers(0, 256, (20, 30, 3)).astype(np.uint8)
    assert compare_images(a, b, jitter_px=0).mad == pytest.approx(np.abs(a.astype(float) - b).mean(), rel=1e-6)
    # tolerant difference is symmetric and never larger than the plain one
    d1, d0 = pixel_diff(a, b, 1), pixel_diff(a, b, 0)
    assert np.array_equal(d1, pixel_diff(b, a, 1)) and np.all(d1 <= d0)


def test_an_extra_feature_is_not_hidden_by_jitter():
    base = np.zeros((32, 32, 3), np.uint8)
    spot = base.copy()
    spot[10:13, 10:13] = 255                 # a 3x3 feature that the golden does not have
    d = pixel_diff(spot, base, 1)
    assert d[11, 11] == 255
