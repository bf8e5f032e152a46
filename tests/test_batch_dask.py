"""uvbake batch on a real Dask cluster: `dask scheduler` and `dask worker` processes on 127.0.0.1."""

import contextlib
import json
import subprocess
import sys
import time

import psutil
import pytest
from batchkit import (
    batch_cli,
    cluster,
    corrupt_mesh,
    env,
    good_meshes,
    raising_mesh,
    slow_mesh,
    summary,
    write_ply,
)

from meshgen import plane

pytest.importorskip("distributed")
pytest.importorskip("pyarrow")

FAST = ["--bake", "none", "--preview-size", "0", "--texture-size", "128", "-q"]
FAST_OPTS = dict(bake=None, preview_size_px=0, texture_size_px=128)


@pytest.fixture(scope="module")
def dask_cluster(tmp_path_factory):
    with cluster(tmp_path_factory.mktemp("dask"), n_workers=2) as c:
        yield c


@pytest.fixture(scope="module")
def client(dask_cluster):
    from distributed import Client

    with Client(dask_cluster.address, timeout="30s") as c:
        yield c


def _children_of(out):
    """Processes still running an asset of the batch writing into ``out`` (their output goes to its staging)."""
    hits = []
    for p in psutil.process_iter(["cmdline"]):
        if "uvbake.batch.zygote" not in " ".join(p.info["cmdline"] or []):
            continue
        with contextlib.suppress(psutil.Error):
            if any(str(out) in f.path for f in p.open_files()):
                hits.append(p)
    return hits


def _mtimes(folder):
    return {p.name: p.stat().st_mtime_ns for p in folder.iterdir() if p.is_file()}


def test_bad_assets_are_recorded_the_rest_done_and_a_rerun_redoes_only_the_failed(tmp_path, dask_cluster, client):
    from uvbake.batch import run

    good = good_meshes(tmp_path / "in", 3)
    corrupt_mesh(tmp_path / "in" / "corrupt.ply")
    raising_mesh(tmp_path / "in" / "nan.ply")
    slow_mesh(tmp_path / "big" / "slow.ply")
    (tmp_path / "list.csv").write_text("path,timeout_s\nbig/slow.ply,1.0\n")
    out = tmp_path / "out"

    code, _, stderr = batch_cli(tmp_path / "in", tmp_path / "list.csv", "-o", out,
                                     "--scheduler", dask_cluster.address, *FAST[:-1])
    assert code == 1, stderr
    rows = summary(out)
    assert {a: r["status"] for a, r in rows.items()} == {
        "good0": "done", "good1": "done", "good2": "done", "corrupt": "failed", "nan": "failed", "slow": "timeout"}
    assert "cannot read as PLY" in rows["corrupt"]["error"]
    assert "NaN" in rows["nan"]["error"] and "vertices 3" in rows["nan"]["error"]
    assert "time limit of 1 s" in rows["slow"]["error"]
    for r in rows.values():                      # every error is one line, and the CLI printed it
        assert r["error"] is None or ("\n" not in r["error"] and r["error"] in stderr)
    # failures first in the summary, then the rest by name
    assert list(rows)[:3] == ["slow", "corrupt", "nan"]
    assert rows["slow"]["t_asset_s"] < 20       # stopped by the limit, not run to the end
    assert not _children_of(out), "a timed-out asset's process is still running"
    for p in good:
        d = out / "assets" / p.stem
        marker = json.loads((d / "status.json").read_text())
        assert marker["status"] == "ok" and set(marker["outputs"]) == {
            f"{p.stem}_uv.obj", f"{p.stem}_uv.mtl", f"{p.stem}_uv.png", "report.json", "atlas.png"}
        assert rows[p.stem]["charts"] >= 1 and rows[p.stem]["valid"] is True
        assert rows[p.stem]["worker"].startswith("tcp://127.0.0.1:")
        assert 0 < rows[p.stem]["packing"] <= 1
    assert not list(out.rglob(".staging-*"))
    before = {p.stem: _mtimes(out / "assets" / p.stem) for p in good}

    # rerun: no work for the done ones (the summary says cached, their files are untouched), the failed redone
    table = run([tmp_path / "in", tmp_path / "list.csv"], out, client=client, **FAST_OPTS)
    rows2 = {r["asset"]: r for r in table.to_pylist()}
    assert {a: rows2[a]["status"] for a in rows2} == {
        "good0": "cached", "good1": "cached", "good2": "cached", "corrupt": "failed", "nan": "failed", "slow": "timeout"}
    assert {p.stem: _mtimes(out / "assets" / p.stem) for p in good} == before
    assert summary(out) == rows2

    # a changed input is redone (its key is its bytes): repair the NaN mesh; the rest stays cached
    write_ply(tmp_path / "in" / "nan.ply", *plane(6, 5))
    (tmp_path / "list.csv").write_text("path\n")        # and drop the slow one from the manifest
    rows3 = {r["asset"]: r["status"] for r in run([tmp_path / "in"], out, client=client, **FAST_OPTS).to_pylist()}
    assert rows3 == {"good0": "cached", "good1": "cached", "good2": "cached", "corrupt": "failed", "nan": "done"}


def test_batch_outputs_are_byte_identical_to_the_single_asset_command(tmp_path, client):
    from uvbake.batch import run

    (src,) = good_meshes(tmp_path / "in", 1)
    table = run([src], tmp_path / "out", client=client, alpha=0.3, texture_size_px=256, gutter_px=3,
                preview_size_px=0)
    assert table.column("status").to_pylist() == ["done"]
    single = tmp_path / "single"
    single.mkdir()
    p = subprocess.run([sys.executable, "-m", "uvbake.cli", str(src), "-o", str(single / "good0_uv.obj"),
                        "--alpha", "0.3", "--texture-size", "256", "--gutter", "3", "--bake",
                        str(single / "checker.png"), "-q"], env=env(), capture_output=True, text=True, check=False)
    assert p.returncode == 0, p.stderr
    for name in ("good0_uv.obj", "good0_uv.mtl", "good0_uv.png"):
        assert (tmp_path / "out" / "assets" / "good0" / name).read_bytes() == (single / name).read_bytes(), name


def test_killing_a_worker_mid_batch_loses_no_asset(tmp_path):
    from distributed import Client

    paths = good_meshes(tmp_path / "in", 6)
    out = tmp_path / "out"
    with cluster(tmp_path / "dask", n_workers=2) as c, Client(c.address, timeout="30s") as watch:
        proc = subprocess.Popen([sys.executable, "-m", "uvbake.cli", "batch", str(tmp_path / "in"), "-o", str(out),
                                 "--scheduler", c.address, *FAST], env=env(), stdin=subprocess.DEVNULL,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            victim = next(a for a, w in watch.scheduler_info()["workers"].items() if w["name"] == "w0")
            deadline = time.monotonic() + 60
            running = []
            while time.monotonic() < deadline:   # wait until w0 is inside an asset and one asset is done
                done = list(out.glob("assets/*/status.json"))
                running = list(watch.processing().get(victim, ()))
                if done and running:
                    break
                time.sleep(0.05)
            assert running and len(done) < len(paths), "the batch ended before a worker could be killed"
            c.kill("w0")
            _, stderr = proc.communicate(timeout=120)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.communicate()
    assert proc.returncode == 0, stderr
    rows = summary(out)
    assert sorted(rows) == sorted(p.stem for p in paths)
    assert all(r["status"] == "done" for r in rows.values())
    # the asset w0 was running when it died was redone on the other worker
    killed = [a for a, r in rows.items() if any(str(k).endswith("-" + a) for k in running)]
    assert killed and all(rows[a]["worker"] != victim for a in killed)
    time.sleep(1.0)                  # the orphaned child notices its worker is gone within 0.5 s
    assert not _children_of(out)


def test_local_cluster_when_no_scheduler_is_given(tmp_path):
    (src,) = good_meshes(tmp_path / "in", 1)
    code, stdout, stderr = batch_cli(src, "-o", tmp_path / "out", "--workers", "1", *FAST[:-1])
    assert code == 0, stderr
    rows = summary(tmp_path / "out")
    assert rows["good0"]["status"] == "done" and rows["good0"]["worker"].startswith("tcp://")
    assert "1 assets: 1 done" in stdout
