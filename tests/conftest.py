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
