"""Mesh arrays and their structure: checks, topology, charts, repair, cutting into disks."""

from uvbake._lazy import lazy_getattr

_SUBMODULES = ("arrays", "topology", "charts", "repair", "cut")
__getattr__ = lazy_getattr(__name__, {m: f"{__name__}.{m}" for m in _SUBMODULES})
__all__ = list(_SUBMODULES)
