"""Batch inputs, keys, options and the resume protocol (no Dask: the plain loop, client="local")."""

import json

import pytest
from batchkit import good_meshes

from uvbake.batch.inputs import collect, options_hash
from uvbake.batch.run import normalise_options
from uvbake.cli import main
from uvbake.errors import InputError

pytest.importorskip("pyarrow")


def test_folders_are_searched_recursively_skipping_hidden_and_the_output(tmp_path):
    root = tmp_path / "scans"
    good_meshes(root / "a", 2)
    good_meshes(root / "b" / "deep", 1)
    good_meshes(root / ".cache", 1)
    good_meshes(root / "out" / "assets" / "x", 1)          # a previous batch's output inside the input folder
    (root / "notes.txt").write_text("not a mesh")
    assets = collect([root], out_dir=root / "out")
    assert [a.id for a in assets] == ["a/good0", "a/good1", "b/deep/good0"]
    assert all(a.path.is_absolute() and a.timeout_s is None for a in assets)


def test_manifests_duplicates_and_name_clashes(tmp_path):
    (a,) = good_meshes(tmp_path / "one", 1)
    (b,) = good_meshes(tmp_path / "two", 1)                  # same file name, other folder
    (tmp_path / "list.txt").write_text("# assets\none/good0.ply\n\n  two/good0.ply  # the second\n")
    (tmp_path / "list.csv").write_text(f"path,timeout_s\n{a},2.5\n")
    assets = collect([tmp_path / "list.txt", tmp_path / "list.csv", a])
    assert len(assets) == 2                                 # the same file named three times is one asset
    ids = sorted(x.id for x in assets)
    assert ids[0].startswith("good0-") and ids[1].startswith("good0-") and ids[0] != ids[1]
    # the first mention wins: list.txt names it without a time limit
    assert {x.path: x.timeout_s for x in assets} == {a.resolve(): None, b.resolve(): None}
    assert collect([tmp_path / "list.csv"])[0].timeout_s == 2.5


@pytest.mark.parametrize("content, words", [
    ("file\none/good0.ply\n", "no 'path' column"),
    ("path,timeout_s\none/good0.ply,-1\n", "line 2: timeout_s '-1' must be a positive"),
    ("path\nmissing.ply\n", "line 2: missing.ply does not exist"),
])
def test_bad_manifests_name_the_line_and_the_fix(tmp_path, content, words):
    good_meshes(tmp_path / "one", 1)
    (tmp_path / "m.csv").write_text(content)
    with pytest.raises(InputError, match=words):
        collect([tmp_path / "m.csv"])


def test_bad_inputs(tmp_path):
    (tmp_path / "empty").mkdir()
    (tmp_path / "x.docx").write_text("")
    with pytest.raises(InputError, match="does not exist"):
        collect([tmp_path / "nope.ply"])
    with pytest.raises(InputError, match="holds no mesh"):
        collect([tmp_path / "empty"])
    with pytest.raises(InputError, match="neither a mesh"):
        collect([tmp_path / "x.docx"])


def test_option_keys_are_canonical():
    base = normalise_options()
    assert normalise_options(alpha=1 / 2, tol=1e-8, max_iter=1000.0) == base
    assert options_hash(normalise_options(alpha=0.5)) == options_hash(base)
    changed = [dict(alpha=0.3), dict(texture_size_px=512), dict(bake=None), dict(guarantee=False), dict(format="glb"),
               dict(preview_size_px=0), dict(seed=1), dict(texture_size_px=(1024, 512))]
    # a square given as (N, N) is the square N; a rectangle is [width, height] (JSON-ready)
    assert normalise_options(texture_size_px=(1024, 1024)) == base
    assert normalise_options(texture_size_px=(1024, 512))["unwrap"]["texture_size_px"] == [1024, 512]
    hashes = {options_hash(normalise_options(**o)) for o in changed}
    assert len(hashes) == len(changed) and options_hash(base) not in hashes
    for bad, words in [(dict(alpha=2), "alpha=2"), (dict(texture_size_px=8), "texture_size_px=8"),
                       (dict(bake="paint"), "bake='paint'"), (dict(format="fbx"), "format='fbx'"),
                       (dict(colour=1), "unknown option")]:
        with pytest.raises(InputError, match=words):
            normalise_options(**bad)


@pytest.mark.parametrize("args, words", [
    (["nope.ply"], "does not exist"),
    (["IN", "--alpha", "2"], "alpha=2.0 is outside"),
    (["IN", "--scheduler", "tcp://127.0.0.1:1", "--workers", "2"], "--workers sizes the local cluster"),
    (["IN", "--timeout-per-asset", "0"], "must be a positive number"),
])
def test_bad_arguments_exit_2_and_write_nothing(tmp_path, capsys, args, words):
    (src,) = good_meshes(tmp_path / "in", 1)
    out = tmp_path / "out"
    argv = ["batch", *[str(src) if a == "IN" else a for a in args], "-o", str(out)]
    assert main(argv) == 2
    assert words in capsys.readouterr().err
    assert not out.exists()
    with pytest.raises(SystemExit) as exc:                     # argparse's own errors: also 2
        main(["batch", str(src)])
    assert exc.value.code == 2


def test_an_interrupted_or_damaged_asset_is_never_trusted(tmp_path):
    from uvbake.batch import run

    (src,) = good_meshes(tmp_path / "in", 1)
    out = tmp_path / "out"
    opts = dict(client="local", bake=None, preview_size_px=0, texture_size_px=128)
    assert run([src], out, **opts).column("status").to_pylist() == ["done"]
    d = out / "assets" / "good0"
    obj = (d / "good0_uv.obj").read_bytes()
    marker = json.loads((d / "status.json").read_text())
    assert marker["key"].startswith(__import__("hashlib").sha256(src.read_bytes()).hexdigest())

    # a half-written output under a valid-looking marker (e.g. the disk filled up): redone, not trusted
    (d / "good0_uv.obj").write_bytes(obj[: len(obj) // 2])
    (d / ".staging-x1").mkdir()                              # and what an interrupted run leaves behind
    (d / ".staging-x1" / "good0_uv.obj").write_bytes(b"v 0 0")
    assert run([src], out, **opts).column("status").to_pylist() == ["done"]
    assert (d / "good0_uv.obj").read_bytes() == obj
    assert not list(d.glob(".staging-*"))
    # an interruption before the marker was written (files in place, no marker): redone
    (d / "status.json").unlink()
    assert run([src], out, **opts).column("status").to_pylist() == ["done"]
    assert run([src], out, **opts).column("status").to_pylist() == ["cached"]
    # other options are another key: redone
    assert run([src], out, **dict(opts, alpha=0.2)).column("status").to_pylist() == ["done"]


def test_the_zygote_is_single_threaded_when_it_forks(tmp_path):
    """fork() after the imports is only safe with no other thread alive in the zygote."""
    import os

    import psutil

    from uvbake.batch import run

    (src,) = good_meshes(tmp_path / "in", 1)
    assert run([src], tmp_path / "out", client="local", bake="checker", preview_size_px=32,
               texture_size_px=64).column("status").to_pylist() == ["done"]
    zygotes = [p for p in psutil.Process(os.getpid()).children()
               if "uvbake.batch.zygote" in " ".join(p.cmdline())]
    assert len(zygotes) == 1                              # one per thread that ran assets: this one
    assert zygotes[0].num_threads() == 1                  # after importing uvbake, Open3D, trimesh, CHOLMOD


def test_an_asset_whose_task_cannot_run_is_recorded_as_lost_and_the_rest_go_on(tmp_path):
    from uvbake.batch import exit_status, run

    good_meshes(tmp_path / "in", 2)
    out = tmp_path / "out"
    (out / "assets").mkdir(parents=True)
    (out / "assets" / "good0").write_text("a file where the asset's folder must go")
    table = run([tmp_path / "in"], out, client="local", bake=None, preview_size_px=0, texture_size_px=64)
    rows = {r["asset"]: r for r in table.to_pylist()}
    assert rows["good0"]["status"] == "lost" and rows["good0"]["error"].startswith("FileExistsError")
    assert rows["good1"]["status"] == "done" and exit_status(table) == 1
    assert (out / "summary.csv").read_text().count("\n") == 3          # header and both rows


def test_a_crashing_asset_is_recorded_with_its_signal(tmp_path):
    """A native crash (here: SIGSEGV sent to the asset's process) ends that asset only."""
    import signal
    import threading
    import time

    import psutil
    from batchkit import slow_mesh

    from uvbake.batch import run

    slow = slow_mesh(tmp_path / "in" / "slow.ply", n=250)
    good_meshes(tmp_path / "in", 1)
    out = tmp_path / "out"
    result = {}
    worker = threading.Thread(target=lambda: result.setdefault("table", run(
        [tmp_path / "in"], out, client="local", bake=None, preview_size_px=0, timeout_per_asset_s=60)))
    worker.start()
    crashed = False
    deadline = time.monotonic() + 60
    while not crashed and time.monotonic() < deadline and worker.is_alive():
        for p in psutil.process_iter(["cmdline"]):
            if "uvbake.batch.zygote" in " ".join(p.info["cmdline"] or []):
                try:
                    if any(str(out / "assets" / "slow") in f.path for f in p.open_files()):
                        p.send_signal(signal.SIGSEGV)
                        crashed = True
                except psutil.Error:
                    pass
        time.sleep(0.05)
    worker.join(120)
    assert crashed, f"never saw the process of {slow}"
    rows = {r["asset"]: r for r in result["table"].to_pylist()}
    assert rows["slow"]["status"] == "crashed" and "killed by SIGSEGV" in rows["slow"]["error"]
    assert rows["good0"]["status"] == "done"
