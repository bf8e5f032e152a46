"""Studies of a solve: backend cross-check, alpha sensitivity sweep, and the one definition of the
atlas metrics (texel share)."""

from uvbake._lazy import lazy_getattr

_SUBMODULES = ("crosscheck", "sensitivity", "metrics")
__getattr__ = lazy_getattr(__name__, {m: f"{__name__}.{m}" for m in _SUBMODULES})
__all__ = list(_SUBMODULES)
