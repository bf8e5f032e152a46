"""The record every parameterization backend returns."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class ParamResult:
    """One chart's parameterization.

    Attributes
    ----------
    uv : (n,2) float array
        Per-vertex UVs in the surface's own length units.
    energy : float
        The paper's F (unweighted sum over triangles) at ``uv``.
    grad_norm : float
        Euclidean norm of grad F, with mesh and map scaled to unit mean edge length (scale-free).
    iterations : int
        Solver iterations (for LM: factorisations, rejected steps included).
    converged : bool
        True when grad_norm fell under the tolerance.
    n_flipped : int
        Triangles whose Jacobian determinant is <= 0 (flipped or collapsed).
    history : (k,) float array
        F after each iteration at the target alpha, starting with the F of the map it started from
        (after a continuation stage, whose own history is in ``extra["continuation"]``).
    time_s : float
        Wall time of init plus solve.
    """

    uv: np.ndarray
    energy: float
    grad_norm: float
    iterations: int
    converged: bool
    n_flipped: int
    history: np.ndarray
    time_s: float
    alpha: float = 0.5
    init: str = "lscm"
    backend: str = "lm"
    energy_init: float = float("nan")
    stop_reason: str = ""
    n_evaluations: int = 0
    extra: dict = field(default_factory=dict)

    def to_dict(self, *, with_uv=False):
        """JSON-ready summary (UVs left out unless asked)."""
        d = {
            "alpha": self.alpha,
            "init": self.init,
            "backend": self.backend,
            "vertices": int(len(self.uv)),
            "energy": float(self.energy),
            "energy_init": float(self.energy_init),
            "grad_norm": float(self.grad_norm),
            "iterations": int(self.iterations),
            "evaluations": int(self.n_evaluations),
            "converged": bool(self.converged),
            "stop_reason": self.stop_reason,
            "n_flipped": int(self.n_flipped),
            "time_s": float(self.time_s),
            "history": [float(h) for h in self.history],
        }
        d.update(self.extra)
        if with_uv:
            d["uv"] = np.asarray(self.uv).tolist()
        return d
