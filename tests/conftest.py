"""Shared fixtures: the research meshes beside the checkout (skipped cleanly when absent)."""

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED_MESHES = REPO.parent / "shared" / "meshes"
SAMPLE_SCENES = REPO / "sample_scenes"


def shared_mesh(name):
    """Path of ../shared/meshes/<name>, or skip the test when the folder is not there."""
    path = SHARED_MESHES / name
    if not path.exists():
        pytest.skip(f"{path} not present (research meshes are not shipped with uvbake)")
    return path


@pytest.fixture
def shared_meshes():
    if not SHARED_MESHES.is_dir():
        pytest.skip(f"{SHARED_MESHES} not present")
    return SHARED_MESHES


def run_readme_example(containing, tmp_path, monkeypatch):
    """Run the README's first ```python block that contains ``containing``, in a scratch folder that
    sees sample_scenes/, and return its variables (the README's examples cannot rot)."""
    import re

    readme = (REPO / "README.md").read_text()
    blocks = [b for b in re.findall(r"```python\n(.*?)```", readme, re.S) if containing in b]
    assert blocks, f"README.md lost its example with {containing!r}"
    (tmp_path / "sample_scenes").symlink_to(SAMPLE_SCENES)
    monkeypatch.chdir(tmp_path)
    scope = {}
    exec(compile(blocks[0], "README.md", "exec"), scope)
    return scope
