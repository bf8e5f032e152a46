"""Outputs of the uvbake command (issue 15): every target checked before any work, all written
together or none, messages in the user's words, a failed validation writes only the report."""

import errno
import json
import os
import shutil
import time

import numpy as np
import pytest

from uvbake.cli import main
from uvbake.errors import InputError, OutputError
from uvbake.io.atomic import OutputSet

from conftest import SAMPLE_SCENES
from meshgen import grid


@pytest.fixture
def scene(tmp_path):
    dst = tmp_path / "scene.ply"
    shutil.copy(SAMPLE_SCENES / "scene.ply", dst)
    return dst


@pytest.fixture
def small(tmp_path):
    """A 6 x 6 curved sheet as OBJ: solves in well under a second."""
    st, F = grid(7, 7)
    V = np.column_stack([st, 0.2 * np.sin(3 * st[:, 0])])
    path = tmp_path / "sheet.obj"
    path.write_text("".join(f"v {x:.17g} {y:.17g} {z:.17g}\n" for x, y, z in V)
                    + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in F))
    return path


def _files(folder):
    return {p.name: p.read_bytes() for p in folder.iterdir() if p.is_file()}


def _refused_fast(args, capsys, folder, monkeypatch):
    """Run main; the refusal must come before any loading or solving."""
    def no_work(*a, **k):
        raise AssertionError("the run started before the outputs were checked")

    import uvbake.cli.unwrap as command

    monkeypatch.setattr(command, "unwrap", no_work)
    before = _files(folder)
    code = main([str(a) for a in args])
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert _files(folder) == before
    assert not [p for p in folder.iterdir() if p.name.endswith((".part", ".tmp"))]
    return err


def test_read_only_output_is_refused_before_any_work_unless_force(small, tmp_path, capsys, monkeypatch):
    tex = tmp_path / "checker.png"
    tex.write_bytes(b"keep me")
    tex.chmod(0o444)
    err = _refused_fast([small, "--bake", tex, "-q"], capsys, tmp_path, monkeypatch)
    assert f"--bake {tex} is read-only" in err and "--force" in err
    monkeypatch.undo()
    assert main([str(small), "--bake", str(tex), "-q", "--force"]) == 0
    assert tex.read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize("case", ["folder is a file", "target is a folder", "mtl is a folder", "missing folder",
                                  "json is the input"])
def test_bad_targets_are_refused_up_front_in_the_users_words(case, small, tmp_path, capsys, monkeypatch):
    (tmp_path / "afile").write_text("x")
    (tmp_path / "adir").mkdir()
    (tmp_path / "out.mtl").mkdir()
    args, expect = {
        "folder is a file": (["--json", tmp_path / "afile" / "r.json"], "afile is a file, not a folder"),
        "target is a folder": (["-o", tmp_path / "adir"], "must end in .obj"),
        "mtl is a folder": (["-o", tmp_path / "out.obj"], f"-o {tmp_path / 'out.mtl'} is a folder"),
        "missing folder": (["--bake", tmp_path / "nope" / "t.png"], "does not exist"),
        "json is the input": (["--json", small], "is the input"),
    }[case]
    err = _refused_fast([small, "-q", *args], capsys, tmp_path, monkeypatch)
    assert expect in err
    assert ".part" not in err and ".tmp" not in err


def test_a_full_disk_writes_nothing_and_says_so(small, tmp_path, capsys, monkeypatch):
    # the JSON report is the last file written; the disk is full by then: no output may appear
    real = OutputSet.write_bytes

    def full(self, final, data):
        if str(final).endswith(".json"):
            tmp = self.temp_path(final)
            with open(tmp, "wb") as f:
                f.write(data[:10])
            from uvbake.io.atomic import write_error
            raise write_error(final, OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(tmp)),
                              self.flags[final])
        return real(self, final, data)

    monkeypatch.setattr(OutputSet, "write_bytes", full)
    report = tmp_path / "r.json"
    before = _files(tmp_path)
    code = main([str(small), "-q", "--json", str(report), "--bake", str(tmp_path / "t.png")])
    err = capsys.readouterr().err
    assert code == 1
    assert f"cannot write --json {report}: no space left on device" in err
    assert "permission" not in err and ".part" not in err
    assert _files(tmp_path) == before                                # not even the OBJ or the PNG


def test_os_errors_name_the_users_path_not_the_temporary():
    from uvbake.io.atomic import write_error

    err = write_error("out/scene.png", OSError(errno.ENOSPC, "No space left on device", "out/.scene.png.x.part"),
                      "--bake")
    assert isinstance(err, OutputError) and isinstance(err, OSError)
    assert str(err) == "cannot write --bake out/scene.png: no space left on device; free some space or write " \
                       "to another disk"


def test_output_set_is_all_or_nothing(tmp_path):
    a, b = tmp_path / "a.txt", tmp_path / "b.txt"
    a.write_text("old a")
    with pytest.raises(RuntimeError), OutputSet([a, b]) as outs:
        outs.write_bytes(a, b"new a")
        raise RuntimeError("the second file could not be made")
    assert a.read_text() == "old a" and not b.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt"]
    with OutputSet([a, b]) as outs:
        outs.write_bytes(a, b"new a")
        outs.write_bytes(b, b"new b")
        assert outs.commit() == [a, b]
    assert a.read_text() == "new a" and b.read_text() == "new b"
    with pytest.raises(InputError, match="same file"):
        OutputSet([a, tmp_path / "." / "a.txt"])


def _invalid_atlas(monkeypatch):
    """The final validation fails (as it did on collapsed charts): the pipeline's last check."""
    from uvbake.validate import core

    real = core.validate

    def failing(uv, F=None, **kwargs):
        rep = real(uv, F, **kwargs)
        if np.asarray(uv).ndim == 3:                              # the atlas (per-corner UVs)
            rep.valid = False
            rep.flipped = np.array([0])
        return rep

    monkeypatch.setattr(core, "validate", failing)


def test_a_failed_validation_writes_only_the_report(small, tmp_path, capsys, monkeypatch):
    _invalid_atlas(monkeypatch)
    report = tmp_path / "r.json"
    code = main([str(small), "-q", "--json", str(report), "--bake", str(tmp_path / "t.png")])
    err = capsys.readouterr().err
    assert code == 1
    assert "not valid" in err and "wrote only the report" in err and "--keep-invalid" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.json", "sheet.obj"]
    rep = json.loads(report.read_text())
    assert rep["valid"] is False and rep["outputs"] == [str(report)]


def test_keep_invalid_writes_everything_and_says_so(small, tmp_path, capsys, monkeypatch):
    _invalid_atlas(monkeypatch)
    code = main([str(small), "-q", "--keep-invalid", "--bake", str(tmp_path / "t.png")])
    err = capsys.readouterr().err
    assert code == 1 and "written anyway: --keep-invalid" in err
    assert {"sheet_uv.obj", "sheet_uv.mtl", "sheet_uv.png", "t.png"} <= set(os.listdir(tmp_path))


@pytest.mark.parametrize("args, message", [
    (["--alpha", "abc"], "argument --alpha: 'abc' is not a number"),
    (["--alpha", "2"], "argument --alpha: 2 must be within [0.0, 1.0]"),
    (["--seed", "-1"], "argument --seed: -1 must be within"),
    (["--tol", "0"], "argument --tol: 0 must be above 0.0"),
    (["--max-iter", "abc"], "argument --max-iter: 'abc' is not a whole number"),
    (["--workers", "0"], "argument --workers: 0 must be at least 1"),
    (["--gutter", "200", "--texture-size", "256"], "--gutter 200 must be at most 32"),
    (["--bogus"], "unrecognized arguments: --bogus"),
])
def test_option_errors_are_one_line_naming_the_flag(args, message, small, tmp_path, capsys, monkeypatch):
    err = _refused_fast([small, *args], capsys, tmp_path, monkeypatch)
    assert message in err and "usage:" not in err


def test_a_folder_as_input_is_an_input_error(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["."]) == 2
    err = capsys.readouterr().err
    assert "MESH . is a folder" in err and "internal error" not in err


def test_the_check_is_done_before_the_solve_even_on_a_big_mesh(scene, tmp_path, capsys):
    # a read-only report target among good ones: refused in far less time than a solve takes
    report = tmp_path / "r.json"
    report.write_text("{}")
    report.chmod(0o444)
    t0 = time.perf_counter()
    assert main([str(scene), "-q", "--json", str(report)]) == 2
    assert time.perf_counter() - t0 < 2.0
    assert report.read_text() == "{}"
