"""Solver backends for one chart: Levenberg-Marquardt (lm), nlopt L-BFGS (lbfgs), their linear algebra."""

from uvbake._lazy import lazy_getattr

_SUBMODULES = ("result", "lm", "lbfgs", "linalg")
__getattr__ = lazy_getattr(__name__, {m: f"{__name__}.{m}" for m in _SUBMODULES})
__all__ = list(_SUBMODULES)
