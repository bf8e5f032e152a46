"""Studies of a solve: backend cross-check, alpha sensitivity sweep."""

from uvbake._lazy import lazy_getattr

_SUBMODULES = ("crosscheck", "sensitivity")
__getattr__ = lazy_getattr(__name__, {m: f"{__name__}.{m}" for m in _SUBMODULES})
__all__ = list(_SUBMODULES)
