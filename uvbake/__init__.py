"""uvbake: texture atlases you can trust.

Flattens each chart of a mesh by minimising the weighted area/angle distortion of Mejia, Acosta and
Ruiz-Salguero (Engineering Computations 34(6), 2017) with Levenberg-Marquardt, and checks the result.

    >>> import uvbake
    >>> result = uvbake.parameterize(V, F, alpha=0.5)          # doctest: +SKIP
    >>> result.uv, result.energy, result.n_flipped             # doctest: +SKIP
"""

from .errors import ChartError, InputError, SolverError, UvbakeError

__version__ = "0.1.0"

# Public names resolve lazily so `import uvbake` stays cheap (no scipy/open3d until used).
_LAZY = {
    "parameterize": ("uvbake.parameterization", "parameterize"),
    "parameterize_charts": ("uvbake.parameterization", "parameterize_charts"),
    "ParamResult": ("uvbake.solvers.result", "ParamResult"),
    "load_mesh": ("uvbake.io", "load_mesh"),
    "split_charts": ("uvbake.charts", "split_charts"),
    "validate": ("uvbake.validation", "validate"),
    "unwrap": ("uvbake.pipeline", "unwrap"),
    "UnwrapResult": ("uvbake.pipeline", "UnwrapResult"),
    "repair": ("uvbake.repair", "repair"),
    "pack_charts": ("uvbake.pack", "pack_charts"),
}


def __getattr__(name):
    if name in _LAZY:
        import importlib

        module, attr = _LAZY[name]
        return getattr(importlib.import_module(module), attr)
    raise AttributeError(f"module 'uvbake' has no attribute {name!r}")


__all__ = ["UvbakeError", "InputError", "ChartError", "SolverError", *_LAZY]
