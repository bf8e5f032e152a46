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


# TEMPORARY: functions other branches are reducing right now; the coordinator empties this set when
# they are merged. Nothing may be added to it.
_BEING_REDUCED = {
    "uvbake/atlas/charting.py::make_charts",
    "uvbake/atlas/guarantee.py::solve_valid",
    "uvbake/atlas/pipeline.py::_unwrap",
    "uvbake/flatten/solvers/lm.py::levenberg_marquardt",
    "uvbake/flatten/solve.py::parameterize_charts",
}


def test_no_function_is_more_complex_than_20():
    _tool("radon")
    from radon.complexity import cc_visit

    blocks = {}   # "path::function" or "path::Class.method" -> cyclomatic complexity, as `radon cc` counts it
    for p in sorted((REPO / "uvbake").rglob("*.py")):
        for b in cc_visit(p.read_text()):
            name = f"{b.classname}.{b.name}" if getattr(b, "classname", None) else b.name
            blocks[f"{p.relative_to(REPO).as_posix()}::{name}"] = b.complexity
    assert _BEING_REDUCED <= blocks.keys(), _BEING_REDUCED - blocks.keys()
    complex_ = {k: c for k, c in blocks.items() if c > MAX_COMPLEXITY and k not in _BEING_REDUCED}
    assert not complex_, complex_
