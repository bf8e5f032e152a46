"""Flattening one chart: the distortion energy, start maps, options, the solve and its solvers."""

from uvbake._lazy import lazy_getattr

_SUBMODULES = ("energy", "starts", "solve", "solvers")
__getattr__ = lazy_getattr(__name__, {m: f"{__name__}.{m}" for m in _SUBMODULES})
__all__ = list(_SUBMODULES)
