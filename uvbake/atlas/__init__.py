"""From flattened charts to a textured atlas: the pipeline, packing, baking."""

from uvbake._lazy import lazy_getattr

_SUBMODULES = ("pipeline", "pack", "maxrects", "distance", "bake")
__getattr__ = lazy_getattr(__name__, {m: f"{__name__}.{m}" for m in _SUBMODULES})
__all__ = list(_SUBMODULES)
