"""uvbake: texture atlases you can trust.

Flattens each chart of a mesh by minimising the weighted area/angle distortion of Mejia, Acosta and
Ruiz-Salguero (Engineering Computations 34(6), 2017) with Levenberg-Marquardt, and checks the result.

    >>> import uvbake
    >>> result = uvbake.parameterize(V, F, alpha=0.5)          # doctest: +SKIP
    >>> result.uv, result.energy, result.n_flipped             # doctest: +SKIP
"""

from uvbake._lazy import lazy_getattr
from uvbake.errors import ChartError, InputError, SolverError, UvbakeError

__version__ = "0.1.0"

# Public names resolve lazily so `import uvbake` stays cheap (no scipy/open3d until used).
_LAZY = {
    "parameterize": "uvbake.flatten.solve:parameterize",
    "parameterize_charts": "uvbake.flatten.solve:parameterize_charts",
    "ParamResult": "uvbake.flatten.solvers.result:ParamResult",
    "load_mesh": "uvbake.io.load:load_mesh",
    "split_charts": "uvbake.mesh.charts:split_charts",
    # the package uvbake.validate is callable: uvbake.validate(uv, F) runs uvbake.validate.validate
    "validate": "uvbake.validate",
    "unwrap": "uvbake.atlas.pipeline:unwrap",
    "UnwrapResult": "uvbake.atlas.pipeline:UnwrapResult",
    "repair": "uvbake.mesh.repair:repair",
    "pack_charts": "uvbake.atlas.pack:pack_charts",
}
# subpackages and modules, reachable as attributes after `import uvbake`
_SUBMODULES = {
    "mesh": "uvbake.mesh",
    "flatten": "uvbake.flatten",
    "atlas": "uvbake.atlas",
    "io": "uvbake.io",
    "analysis": "uvbake.analysis",
    "cli": "uvbake.cli",
    "render": "uvbake.render",
    "errors": "uvbake.errors",
    "crosscheck": "uvbake.analysis.crosscheck",
    "sensitivity": "uvbake.analysis.sensitivity",
}

__getattr__ = lazy_getattr(__name__, {**_LAZY, **_SUBMODULES})


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY) | set(_SUBMODULES))


__all__ = ["UvbakeError", "InputError", "ChartError", "SolverError", *_LAZY, *_SUBMODULES]
