"""The README's examples run here, so they cannot rot."""

import json
import re
import shlex

from conftest import REPO, run_readme_example

README = (REPO / "README.md").read_text()


def test_python_example_runs(tmp_path, monkeypatch):
    scope = run_readme_example("import uvbake\n", tmp_path, monkeypatch)
    assert scope["result"].converged and len(scope["results"]) == len(scope["charts"]) >= 2
    assert scope["atlas"].report["valid"] and scope["atlas"].image.shape == (512, 512, 3)
    assert (tmp_path / "scene_uv.glb").stat().st_size > 0
    assert scope["report"].valid == (scope["result"].n_flipped == 0)


def test_quick_start_commands(tmp_path, monkeypatch):
    from uvbake.cli import main

    quick = re.search(r"## Quick start.*?```sh\n(.*?)```", README, re.S).group(1).strip().splitlines()
    install, run = quick[0].split(" && ")
    assert install == "./install.sh" and (REPO / "install.sh").exists()
    assert quick[1] == "python3 -m pytest -q"
    ci = (REPO / ".ci" / "run").read_text()
    # CI runs the same test command with the pinned versions, then with the newest releases
    assert "bash install.sh" in ci and "\n" + quick[1] + " || status=$?\n" in ci
    assert '"$venv/bin/python" -m pytest -q || latest=$?' in ci and "constraints" not in ci.split("venv=")[1].split("pytest")[0]
    args = shlex.split(run)
    assert args[0] == "uvbake"
    (tmp_path / "sample_scenes").symlink_to(REPO / "sample_scenes")
    monkeypatch.chdir(tmp_path)
    assert main(args[1:]) == 0
    report = json.loads((tmp_path / "scene_report.json").read_text())
    assert report["all_converged"] and report["valid"] and len(report["charts"]) >= 2
    for name in ("scene_uv.obj", "scene_uv.mtl", "scene_uv.png", "checker.png"):
        assert (tmp_path / name).stat().st_size > 0
