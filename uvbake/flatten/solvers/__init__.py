"""Solver backends for one chart: trust-region Newton-CG (trust), Levenberg-Marquardt (lm), nlopt L-BFGS (lbfgs),
their linear algebra and the second-order certificate."""

from uvbake._lazy import lazy_getattr

_SUBMODULES = ("result", "trust", "lm", "lbfgs", "linalg", "certificate")
__getattr__ = lazy_getattr(__name__, {m: f"{__name__}.{m}" for m in _SUBMODULES})
__all__ = list(_SUBMODULES)
