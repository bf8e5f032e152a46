"""From a mesh to a textured atlas: the pipeline, charting, the guarantee, packing, baking."""

from uvbake._lazy import lazy_getattr

_SUBMODULES = ("pipeline", "charting", "guarantee", "pack", "maxrects", "distance", "bake")
__getattr__ = lazy_getattr(__name__, {m: f"{__name__}.{m}" for m in _SUBMODULES})
__all__ = list(_SUBMODULES)
