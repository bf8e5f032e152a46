"""pytest plugin: the ``texture_regression`` fixture compares images with golden PNGs.

Registered through the ``pytest11`` entry point ``uvbake = "pytest_uvbake.plugin"``, so installing
uvbake is enough::

    def test_atlas(texture_regression):
        result = uvbake.atlas.pipeline.unwrap("scene.ply", texture_size_px=256, bake="checker")
        texture_regression.check(result.image, name="scene_checker")   # tests/goldens/scene_checker.png

- Golden: ``<folder of the test file>/<uvbake_goldens_dir>/<name>.png`` (ini option, default
  ``goldens``; an absolute path is used as is).
- Pass when the jitter-tolerant mean absolute difference is at most ``mad_tol`` (0..255 levels) and the
  SSIM is at least ``ssim_min`` (see :mod:`pytest_uvbake.compare`). Defaults: ``DEFAULT_MAD_TOL``,
  ``DEFAULT_SSIM_MIN``, ``DEFAULT_JITTER_PX``; ini options ``uvbake_mad_tol``, ``uvbake_ssim_min``,
  ``uvbake_jitter_px`` change them for a project, keyword arguments for one check.
- On failure: ``<name>.actual.png`` and ``<name>.diff.png`` are written next to the test file (stale
  ones are removed when the check passes again) and the message gives both numbers and both paths.
- Missing golden: the test fails and says to run ``pytest --uvbake-update-goldens``.
- ``--uvbake-update-goldens``: goldens are (re)written instead of compared, the test passes and the
  terminal summary lists every golden written.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from .compare import Comparison, as_image, compare_images, diff_image

#: Default tolerances (MAD in 0..255 levels, mean over channels; SSIM tolerant to 1-pixel shifts).
#: Measured on the 256 x 256 vertex-colour atlas of sample_scenes/scene.ply (tests/test_render.py):
#: identical 0 / 1; +-1 level noise on every texel ~0.67 / ~0.99; one chart moved by 1 texel 0 / >= 0.9995;
#: moved by 8 texels 1.4-2.6 / 0.966-0.984; checker baked instead of colours 81 / 0.22.
DEFAULT_MAD_TOL = 1.0
DEFAULT_SSIM_MIN = 0.98
DEFAULT_JITTER_PX = 1

_NAME = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.\-]*(/[A-Za-z0-9_][A-Za-z0-9_.\-]*)*$")
_UPDATED = pytest.StashKey[list]()


def pytest_addoption(parser):
    group = parser.getgroup("uvbake", "uvbake texture regression")
    group.addoption("--uvbake-update-goldens", action="store_true", default=False,
                    help="write/overwrite the golden PNGs of texture_regression checks instead of comparing")
    parser.addini("uvbake_goldens_dir", "folder of golden PNGs, relative to each test file's folder "
                  "(default: goldens)", default="goldens")
    parser.addini("uvbake_mad_tol", f"default texture_regression mad_tol (default {DEFAULT_MAD_TOL})",
                  default=str(DEFAULT_MAD_TOL))
    parser.addini("uvbake_ssim_min", f"default texture_regression ssim_min (default {DEFAULT_SSIM_MIN})",
                  default=str(DEFAULT_SSIM_MIN))
    parser.addini("uvbake_jitter_px", f"default texture_regression jitter_px (default {DEFAULT_JITTER_PX})",
                  default=str(DEFAULT_JITTER_PX))


def pytest_configure(config):
    config.stash[_UPDATED] = []


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    updated = config.stash.get(_UPDATED, [])
    if updated:
        terminalreporter.section("uvbake goldens updated")
        for path in updated:
            terminalreporter.write_line(f"wrote {path}")
        terminalreporter.write_line(f"{len(updated)} golden image(s) written (--uvbake-update-goldens); "
                                    "review and commit them")


def _ini_float(config, name):
    raw = config.getini(name)
    try:
        return float(raw)
    except ValueError:
        raise pytest.UsageError(f"ini option {name} = {raw!r} is not a number") from None


class TextureRegression:
    """The ``texture_regression`` fixture's object; call :meth:`check`."""

    def __init__(self, request):
        self._request = request
        self._config = request.config
        self.test_dir = Path(request.path).parent
        goldens = Path(self._config.getini("uvbake_goldens_dir"))
        self.goldens_dir = goldens if goldens.is_absolute() else self.test_dir / goldens
        self.update = bool(self._config.getoption("uvbake_update_goldens"))
        self.mad_tol = _ini_float(self._config, "uvbake_mad_tol")
        self.ssim_min = _ini_float(self._config, "uvbake_ssim_min")
        self.jitter_px = int(_ini_float(self._config, "uvbake_jitter_px"))
        self._names = set()

    def golden_path(self, name: str) -> Path:
        return self.goldens_dir / f"{name}.png"

    def check(self, image_or_path, name: str | None = None, *, mad_tol: float | None = None,
              ssim_min: float | None = None, jitter_px: int | None = None) -> Comparison | None:
        """Compare an image (array, PIL image or PNG path) with the golden ``<name>.png``.

        Fails the test (``pytest.fail``) when the mean absolute difference exceeds ``mad_tol`` or the
        SSIM is under ``ssim_min``, when the sizes differ, or when the golden is missing. Returns the
        :class:`~pytest_uvbake.compare.Comparison` on success (``None`` when updating goldens).
        """
        name = self._check_name(name)
        mad_tol = self.mad_tol if mad_tol is None else float(mad_tol)
        ssim_min = self.ssim_min if ssim_min is None else float(ssim_min)
        jitter_px = self.jitter_px if jitter_px is None else jitter_px
        if not mad_tol >= 0 or not -1 <= ssim_min <= 1:
            raise ValueError(f"mad_tol={mad_tol} must be >= 0 and ssim_min={ssim_min} in [-1, 1]")
        actual = as_image(image_or_path)
        golden = self.golden_path(name)
        actual_out = self.test_dir / f"{name}.actual.png"
        diff_out = self.test_dir / f"{name}.diff.png"

        if self.update:
            _write_png(golden, actual)
            _remove(actual_out, diff_out)
            self._config.stash[_UPDATED].append(str(golden))
            self._request.node.user_properties.append(("uvbake_golden_written", str(golden)))
            return None

        if not golden.exists():
            _write_png(actual_out, actual)
            pytest.fail(f"texture_regression: golden {golden} does not exist; run pytest with "
                        f"--uvbake-update-goldens to create it (actual image written to {actual_out})",
                        pytrace=False)
        expected = as_image(golden)
        if expected.shape != actual.shape:
            _write_png(actual_out, actual)
            pytest.fail(f"texture_regression {name!r}: image is {_shape(actual)} but golden {golden} is "
                        f"{_shape(expected)}; actual written to {actual_out} (run with "
                        "--uvbake-update-goldens if the change is intended)", pytrace=False)
        cmp = compare_images(actual, expected, jitter_px=jitter_px)
        if cmp.mad <= mad_tol and cmp.ssim >= ssim_min:
            _remove(actual_out, diff_out)
            return cmp
        _write_png(actual_out, actual)
        _write_png(diff_out, diff_image(actual, expected, cmp.diff))
        why = []
        if cmp.mad > mad_tol:
            why.append(f"MAD {cmp.mad:.3f} > mad_tol {mad_tol:g}")
        if cmp.ssim < ssim_min:
            why.append(f"SSIM {cmp.ssim:.4f} < ssim_min {ssim_min:g}")
        pytest.fail(f"texture_regression {name!r} differs from {golden}: {' and '.join(why)} "
                    f"(MAD {cmp.mad:.3f}, SSIM {cmp.ssim:.4f}, max pixel difference {cmp.max_diff:.1f}, "
                    f"jitter_px {cmp.jitter_px}); actual: {actual_out}, diff: {diff_out}; run with "
                    "--uvbake-update-goldens if the change is intended", pytrace=False)

    def _check_name(self, name):
        if name is None:
            name = re.sub(r"[^A-Za-z0-9_.\-]+", "-", self._request.node.name).strip("-.") or "image"
        if not isinstance(name, str) or not _NAME.match(name) or ".." in name.split("/"):
            raise ValueError(f"texture_regression name {name!r}: use letters, digits, '_', '-', '.' and "
                             "'/' between folder names (no absolute paths, no '..')")
        if name in self._names:
            raise ValueError(f"texture_regression name {name!r} already checked in this test; "
                             "give each image its own name")
        self._names.add(name)
        return name


def _shape(img):
    return f"{img.shape[1]}x{img.shape[0]}x{img.shape[2]}"


def _write_png(path: Path, img: np.ndarray):
    """Write atomically (a temporary file in the same folder, then rename)."""
    from PIL import Image

    from uvbake.io.atomic import atomic_write

    path.parent.mkdir(parents=True, exist_ok=True)
    arr = img[:, :, 0] if img.shape[2] == 1 else img
    with atomic_write(path, "wb") as fh:
        Image.fromarray(arr).save(fh, format="PNG", optimize=False, compress_level=9)


def _remove(*paths):
    for p in paths:
        if p.exists():
            p.unlink()


@pytest.fixture
def texture_regression(request):
    """Compare images with golden PNGs: ``texture_regression.check(image, name, mad_tol=, ssim_min=)``."""
    return TextureRegression(request)
