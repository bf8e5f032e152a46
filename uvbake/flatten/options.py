"""``SolveOptions``: the options of one chart solve, validated once, with their defaults in one place.

The CLI, :func:`uvbake.unwrap`, :func:`uvbake.parameterize` and :func:`uvbake.parameterize_charts`
take their defaults from :data:`DEFAULTS` and build one ``SolveOptions``; the solvers trust it.
Importing it imports neither numpy nor scipy, so the command line builds its parser (``uvbake --help``)
from these defaults without loading the numerical stack.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import sys
from dataclasses import dataclass
from typing import Any

from uvbake.errors import InputError

#: start maps (:func:`uvbake.flatten.starts.initial_map`)
INITS = ("lscm", "tutte", "random", "isomap", "laplacian")
BACKENDS = ("lm", "lbfgs")
#: sparse factorisations (:func:`uvbake.flatten.solvers.linalg.make_solver`)
LINEAR_SOLVERS = ("auto", "cholmod", "superlu")
#: steps of the second-order backend: the trust-region Newton-CG step, or Levenberg-Marquardt's damped step
STEPS = ("trust", "damped")

#: alpha of the continuation stage for invalid starts (see :func:`uvbake.flatten.solve.solve_chart`)
CONTINUATION_ALPHA = 0.1


def _numpy_scalars() -> tuple[tuple[type, ...], tuple[type, ...]]:
    """numpy's (floating, integer) scalar types once numpy is loaded; none before, when no value can
    be one (so this module need not import numpy)."""
    np = sys.modules.get("numpy")
    return ((np.floating,), (np.integer,)) if np is not None else ((), ())


def _whole(x: Any) -> bool:
    """An integer, or a float with an integer value (as read from CSV or JSON); never a bool or a str."""
    if isinstance(x, bool):
        return False
    floating, integer = _numpy_scalars()
    is_float = isinstance(x, (float, *floating))
    if is_float:
        return bool(math.isfinite(x) and float(x).is_integer())
    return isinstance(x, (int, *integer))


def _choices(values: tuple[str, ...]) -> str:
    return ", ".join(repr(v) for v in values)


@dataclass(frozen=True)
class SolveOptions:
    """How to flatten a chart. Invalid values raise :class:`uvbake.InputError` at construction.

    Attributes
    ----------
    alpha : float in [0, 1]
        Weight of area preservation; 1 - alpha weighs angle preservation.
    init : {"lscm", "tutte", "random", "isomap", "laplacian"}
        Start map ("random" is seeded by ``seed``).
    backend : {"lm", "lbfgs"}
        The second-order solver with the full Hessian, or nlopt's L-BFGS on the same F and gradient.
    step : {"trust", "damped"}
        The "lm" backend's step: "trust" (default) a trust-region Newton step by truncated CG
        preconditioned by the per-triangle PSD projection of the Hessian
        (:mod:`uvbake.flatten.solvers.trust`); "damped" the paper's Levenberg-Marquardt damping
        (:mod:`uvbake.flatten.solvers.lm`). Same F, same stopping rule; docs/decisions/solver.md.
    tol : float > 0
        Stop when the scale-free gradient norm is under ``tol``.
    max_iter : int >= 0
        Iteration cap (LM: factorisations, rejected steps included).
    seed : int
        Seed of the random start.
    linear_solver : {"auto", "cholmod", "superlu"}
    injective : bool
        LM only: from a start with every det A > 0, shorten each step so no determinant reaches zero
        (:func:`uvbake.atlas.guarantee.determinant_step_limit`); ignored for starts with flips.
    continuation : bool
        Solve invalid starts at alpha = 0.1 first (see :func:`uvbake.parameterize`).
    certificate : bool
        Compute the second-order certificate (``lambda_min``, ``is_local_minimum`` of the result).
    fill_holes : bool
        Solve with each hole filled by a lightly weighted fan of triangles, so its border cannot fold
        over itself (:mod:`uvbake.flatten.holes`; alpha > 0, from a start with nothing flipped). The
        atlas pipeline's default; off for the paper's plain F.
    """

    alpha: float = 0.5
    init: str = "lscm"
    backend: str = "lm"
    step: str = "trust"
    tol: float = 1e-8
    max_iter: int = 1000
    seed: int = 0
    linear_solver: str = "auto"
    continuation: bool = True
    injective: bool = False
    certificate: bool = True
    fill_holes: bool = False

    def __post_init__(self) -> None:
        try:
            alpha = float(self.alpha)
        except (TypeError, ValueError, OverflowError):
            raise InputError(f"alpha={self.alpha!r} is not a number; pass a weight between 0 and 1") from None
        if not (0.0 <= alpha <= 1.0):
            raise InputError(f"alpha={self.alpha!r} is outside [0, 1]; pass a weight between 0 (angles only) "
                             "and 1 (areas only)")
        object.__setattr__(self, "alpha", alpha)
        if self.init not in INITS:
            raise InputError(f"init={self.init!r} is not one of {_choices(INITS)}")
        if self.backend not in BACKENDS:
            raise InputError(f"backend={self.backend!r} is not one of {_choices(BACKENDS)}")
        if self.step not in STEPS:
            raise InputError(f"step={self.step!r} is not one of {_choices(STEPS)}")
        if not (isinstance(self.tol, numbers.Real) and not isinstance(self.tol, bool) and self.tol > 0
                and math.isfinite(float(min(self.tol, 1e300)))):    # min: ints too large for a float
            raise InputError(f"tol={self.tol!r} must be a positive number (the scale-free gradient norm to reach)")
        if not _whole(self.max_iter) or self.max_iter < 0:
            raise InputError(f"max_iter={self.max_iter!r} must be a non-negative integer")
        object.__setattr__(self, "max_iter", int(self.max_iter))
        if not _whole(self.seed) or not 0 <= self.seed < 2**32:
            raise InputError(f"seed={self.seed!r} must be an integer from 0 to 2**32 - 1 (the random start's seed)")
        object.__setattr__(self, "seed", int(self.seed))
        if self.linear_solver not in LINEAR_SOLVERS:
            raise InputError(f"linear_solver={self.linear_solver!r} is not one of {_choices(LINEAR_SOLVERS)}")

    def replace(self, **changes: Any) -> SolveOptions:
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    def report(self) -> dict[str, Any]:
        """The options as the JSON report lists them."""
        return dict(alpha=self.alpha, init=self.init, backend=self.backend, step=self.step, tol=self.tol,
                    max_iter=self.max_iter, seed=self.seed, continuation=self.continuation)


#: The defaults, for signatures and the CLI: ``alpha=DEFAULTS.alpha``.
DEFAULTS = SolveOptions()
