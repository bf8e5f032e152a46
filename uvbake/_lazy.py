"""Lazy attribute access for packages: submodules and re-exported names import on first use."""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any


def lazy_getattr(package: str, names: Mapping[str, str]) -> Callable[[str], Any]:
    """A module ``__getattr__`` resolving ``names[attr]`` ("module" or "module:attribute") on first use.

    Keeps ``import uvbake`` cheap (no scipy or open3d until used) while ``uvbake.render`` and
    ``uvbake.atlas.pipeline`` work without an explicit import.
    """

    def __getattr__(name: str) -> Any:
        if name not in names:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        module, _, attr = names[name].partition(":")
        mod = importlib.import_module(module)
        return getattr(mod, attr) if attr else mod

    return __getattr__
