"""Lint, types and size limits of the package, as CI runs them (ruff, mypy, radon; configured in pyproject)."""

import importlib.util
import subprocess
import sys

import pytest

from conftest import REPO

MAX_MODULE_LINES = 600
MAX_COMPLEXITY = 20


def _tool(name):
    if importlib.util.find_spec(name) is None:
        pytest.skip(f"{name} is not installed (pip install -e '.[test]')")


def _run(*args):
    return subprocess.run([sys.executable, "-m", *args], cwd=REPO, capture_output=True, text=True, timeout=600)


def test_ruff_is_clean():
    _tool("ruff")
    proc = _run("ruff", "check", "--no-cache", ".")
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_mypy_is_clean():
    _tool("mypy")
    proc = _run("mypy", "uvbake")
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_no_module_is_longer_than_600_lines():
    long = {str(p.relative_to(REPO)): n for p in (REPO / "uvbake").rglob("*.py")
            if (n := len(p.read_text().splitlines())) > MAX_MODULE_LINES}
    assert not long
