"""The batch's HTML report, loaded from disk in headless Chromium (Debian's `chromium`)."""

import shutil
import subprocess

import numpy as np
import pytest
from batchkit import corrupt_mesh, good_meshes

pytest.importorskip("pyarrow")
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync"]


def _chromium(tmp_path, *args):
    p = subprocess.run([CHROMIUM, *FLAGS, f"--user-data-dir={tmp_path / 'profile'}", *args],
                       capture_output=True, text=True, timeout=60, stdin=subprocess.DEVNULL, check=False)
    assert p.returncode == 0, p.stderr[-2000:]
    return p.stdout


@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed (install.sh installs it)")
def test_report_renders_every_asset_and_sorts_in_a_real_browser(tmp_path):
    from PIL import Image

    from uvbake.batch import run
    from uvbake.batch.report import selftest_result

    good_meshes(tmp_path / "in", 3)
    corrupt_mesh(tmp_path / "in" / "corrupt.ply")
    out = tmp_path / "out"
    # the plain loop (client="local"): the report does not depend on the executor
    rows = run([tmp_path / "in"], out, client="local", preview_size_px=48, texture_size_px=128).to_pylist()
    good = [r for r in rows if r["status"] == "done"]
    assert len(good) == 3 and [r["asset"] for r in rows if r["status"] == "failed"] == ["corrupt"]

    url = (out / "report.html").as_uri() + "?selftest=1"
    result = selftest_result(_chromium(tmp_path, "--virtual-time-budget=10000", "--dump-dom", url))
    # every asset has its row, failures on top
    assert result["initial"] == ["corrupt", "good0", "good1", "good2"]
    # every preview and atlas image decoded (two per good asset, none for the failed one)
    assert result["images_total"] == 2 * len(good) and result["images_ok"] == result["images_total"], result
    # clicking "charts" sorts ascending, again descending; the failed asset (no charts) sorts last, then first
    by_charts = sorted(good, key=lambda r: (r["charts"], rows.index(r)))
    assert result["charts_asc"] == [r["asset"] for r in by_charts] + ["corrupt"]
    assert result["charts_desc"][0] == "corrupt"
    charts_desc = [next(r["charts"] for r in good if r["asset"] == a) for a in result["charts_desc"][1:]]
    assert charts_desc == sorted(charts_desc, reverse=True)
    assert result["shown_after_filter"] == 0                    # the filter hides rows that do not match

    shot = tmp_path / "report.png"                              # kept as the test's artifact
    _chromium(tmp_path, "--window-size=1200,600", f"--screenshot={shot}", (out / "report.html").as_uri())
    img = np.asarray(Image.open(shot).convert("RGB"), dtype=np.float64)
    assert img.shape == (600, 1200, 3)
    assert img.std() > 20                                      # a page with content, not a blank one
