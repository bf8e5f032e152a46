"""The README's examples run here, so they cannot rot."""

import json
import re
import shlex

from conftest import REPO

README = (REPO / "README.md").read_text()


def test_python_example_runs(monkeypatch):
    block = re.search(r"```python\n(.*?)```", README, re.S).group(1)
    monkeypatch.chdir(REPO)
    scope = {}
    exec(compile(block, "README.md", "exec"), scope)
    assert scope["result"].converged and len(scope["results"]) == 5
    assert scope["report"].valid == (scope["result"].n_flipped == 0)


def test_quick_start_commands(tmp_path, monkeypatch):
    from uvbake.cli import main

    quick = re.search(r"## Quick start.*?```sh\n(.*?)```", README, re.S).group(1).strip().splitlines()
    install, run = quick[0].split(" && ")
    assert install == "./install.sh" and (REPO / "install.sh").exists()
    assert quick[1] == "python3 -m pytest -q"
    ci = (REPO / ".ci" / "run").read_text()
    assert "bash install.sh" in ci and "\n" + quick[1] + "\n" in ci   # CI runs the same test command
    args = shlex.split(run)
    assert args[0] == "uvbake"
    (tmp_path / "sample_scenes").symlink_to(REPO / "sample_scenes")
    monkeypatch.chdir(tmp_path)
    assert main(args[1:]) == 0
    report = json.loads((tmp_path / "scene_report.json").read_text())
    assert report["all_converged"] and len(report["charts"]) == 5
    assert (tmp_path / "scene_uv.obj").stat().st_size > 0
