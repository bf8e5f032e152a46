"""The command layer: subcommands by argparse, the default unwrap, one error-to-exit-code map."""

import shutil

import pytest

from uvbake.cli import main
from uvbake.cli.common import EXIT_BAD_INPUT, EXIT_BUG, EXIT_FAILED, EXIT_INTERRUPTED, exit_code
from uvbake.errors import ChartError, InputError, SolverError

from conftest import REPO


def test_unwrap_names_the_command_so_a_mesh_path_may_be_check(tmp_path, monkeypatch, capsys):
    (tmp_path / "check").write_text("not a mesh")
    monkeypatch.chdir(tmp_path)
    # `uvbake unwrap check` reads the file `check` as a mesh (here a bad one: the loader says so)
    assert main(["unwrap", "check"]) == EXIT_BAD_INPUT
    assert capsys.readouterr().err.startswith("uvbake: error: check: unknown mesh format")
    shutil.copy(REPO / "sample_scenes" / "multi_component.ply", tmp_path / "m.ply")
    assert main(["unwrap", "m.ply", "-o", "out.obj", "-q", "--texture-size", "128"]) == 0
    # without `unwrap`, `check` is the subcommand: it validates the atlas just written
    assert main(["check", "out.obj", "--resolution", "128"]) == 0
    assert "valid" in capsys.readouterr().out


def test_default_command_and_subcommand_errors_share_one_map(tmp_path, capsys):
    assert main([str(tmp_path / "missing.ply")]) == EXIT_BAD_INPUT
    assert main(["check", str(tmp_path / "missing.obj")]) == EXIT_BAD_INPUT
    assert main(["sweep", str(tmp_path / "missing.ply")]) == EXIT_BAD_INPUT
    assert main(["check", "a.obj", "--frobnicate"]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 4 and err[0].startswith("uvbake: error:")
    assert err[1].startswith("uvbake check: error:") and err[2].startswith("uvbake sweep: error:")
    assert "unrecognized arguments" in err[3]


@pytest.mark.parametrize("exc, code", [
    (InputError("x"), EXIT_BAD_INPUT), (FileNotFoundError(2, "No such file", "a.ply"), EXIT_BAD_INPUT),
    (ChartError("x"), EXIT_BAD_INPUT), (SolverError("x"), EXIT_FAILED), (KeyboardInterrupt(), EXIT_INTERRUPTED),
    (ZeroDivisionError("x"), EXIT_BUG),
])
def test_exit_codes_follow_exception_classes(exc, code):
    assert exit_code(exc)[0] == code
