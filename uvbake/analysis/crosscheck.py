"""Cross-check the two backends: Levenberg-Marquardt and nlopt's L-BFGS on the same F from the same start.

One energy module (:mod:`uvbake.flatten.energy`), two independent solvers: LM uses F, its gradient and
its Hessian (``DistortionEnergy.evaluate``), L-BFGS only F and the gradient
(``DistortionEnergy.value_and_gradient``). When both reach the same minimum, F* agrees to the
solvers' tolerance and the two maps agree up to a rigid motion of the plane (F is invariant under
translating and rotating the map, and neither solver fixes that gauge for alpha > 0). A wrong gradient
sends L-BFGS elsewhere (or stops its line search); a Hessian inconsistent with the gradient slows LM
but does not move its fixed point, so the cross-check is above all a check of the gradient and of
each solver's stopping point.

Per chart it reports F* of each backend, their relative difference, the largest distance between
the two UV maps after the best rigid alignment (2D Kabsch/Procrustes, rotation and translation, no
scaling, no reflection), that distance over the chart's UV diameter, iterations, evaluations and
time of each, and whether each end point is a local minimum (H + delta I positive definite, with
delta = 1e-6 max diag H; a saddle point has a clearly negative eigenvalue).

Disagreement is loud: :func:`cross_check` and :func:`cross_check_charts` raise
:class:`CrossCheckError` (carrying the results) unless called with ``raise_on_disagree=False``.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike

from uvbake.errors import InputError, SolverError
from uvbake.flatten.solvers.linalg import is_positive_definite
from uvbake.mesh.arrays import rigid_align, unit_scale

#: Second-order test: H + SADDLE_SHIFT * max(diag H) * I must be positive definite at a minimum
#: (the gauge directions give eigenvalues ~1e-14 max diag H, a real saddle -1e-2 and below).
SADDLE_SHIFT = 1e-6


class CrossCheckError(SolverError):
    """The two backends disagree; ``results`` holds every chart's :class:`CrossCheckResult`."""

    def __init__(self, message: str, results: Iterable[CrossCheckResult] = ()) -> None:
        super().__init__(message)
        self.results = list(results)


@dataclass
class CrossCheckResult:
    """Both backends on one chart, from the same start."""

    name: str
    alpha: float
    init: str
    vertices: int
    energy_lm: float
    energy_lbfgs: float
    energy_rel_diff: float
    uv_max_diff: float          # after the best rigid alignment, in the surface's length units
    uv_max_diff_rel: float      # over the chart's UV diameter (of the LM map)
    diameter: float
    iterations_lm: int
    iterations_lbfgs: int
    evaluations_lm: int
    evaluations_lbfgs: int
    time_lm_s: float
    time_lbfgs_s: float
    grad_norm_lm: float
    grad_norm_lbfgs: float
    converged_lm: bool
    converged_lbfgs: bool
    stop_reason_lm: str
    stop_reason_lbfgs: str
    local_min_lm: bool | None
    local_min_lbfgs: bool | None
    n_flipped_lm: int
    n_flipped_lbfgs: int
    rtol_energy: float
    rtol_uv: float
    agree: bool
    extra: dict = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        extra = d.pop("extra")
        d.update(extra)
        return {k: (float(v) if isinstance(v, np.floating) else v) for k, v in d.items()}

    def summary(self) -> str:
        """One line: the verdict and the numbers behind it."""
        verdict = "agree" if self.agree else "DISAGREE"
        s = (f"{self.name}: backends {verdict} at alpha={self.alpha:g}: F* lm={self.energy_lm:.10g} "
             f"lbfgs={self.energy_lbfgs:.10g} (rel diff {self.energy_rel_diff:.2e}, tol {self.rtol_energy:g}), "
             f"UV max diff {self.uv_max_diff_rel:.2e} of the diameter (tol {self.rtol_uv:g}); "
             f"lm {self.iterations_lm} it {self.time_lm_s:.2f} s [{self.stop_reason_lm}], "
             f"lbfgs {self.iterations_lbfgs} it {self.time_lbfgs_s:.2f} s [{self.stop_reason_lbfgs}]")
        for which, ok in (("lm", self.local_min_lm), ("lbfgs", self.local_min_lbfgs)):
            if ok is False:
                s += f"; the {which} end point is not a local minimum (negative curvature)"
        return s


def uv_diameter(uv: ArrayLike) -> float:
    """Largest distance between two UVs (over the convex hull's vertices)."""
    uv = np.asarray(uv, dtype=np.float64)
    try:
        from scipy.spatial import ConvexHull

        pts = uv[ConvexHull(uv).vertices]
    except Exception:          # degenerate (collinear) map: use all points
        pts = uv
    if len(pts) > 4000:
        pts = pts[:: len(pts) // 4000 + 1]
    d = pts[:, None, :] - pts[None, :, :]
    return float(np.sqrt(np.max(np.einsum("ijk,ijk->ij", d, d))))


def is_local_minimum(V: np.ndarray, F: np.ndarray, uv: np.ndarray, alpha: float) -> bool | None:
    """True when the Hessian of F at ``uv`` is positive semi-definite up to the gauge (see module doc).

    None at alpha = 0 (F is then a convex quadratic: every stationary point is a minimum).
    """
    if alpha == 0.0:
        return None
    from uvbake.flatten.energy import DistortionEnergy

    F = np.asarray(F, dtype=np.int64)
    Vn, unit = unit_scale(V, F)
    energy = DistortionEnergy(Vn, F, alpha=alpha)
    _, _, H = energy.evaluate(np.asarray(uv, dtype=np.float64) / unit)
    hmax = float(np.max(np.abs(H.data[energy.diagonal_slots])))
    return _positive_definite(H, SADDLE_SHIFT * hmax)


def _positive_definite(H, shift):
    """Whether H + shift I is positive definite (:func:`uvbake.flatten.solvers.linalg.is_positive_definite`)."""
    return is_positive_definite(H + shift * sp.identity(H.shape[0], format="csc"))


def cross_check(V: np.ndarray, F: np.ndarray, *, alpha: float = 0.5, init: str = "lscm", tol: float = 1e-8,
                max_iter: int = 1000, lbfgs_max_iter: int | None = None, seed: int = 0,
                rtol_energy: float = 1e-6, rtol_uv: float = 1e-4, raise_on_disagree: bool = True,
                second_order: bool = True, name: str = "chart 0") -> CrossCheckResult:
    """Solve one chart with both backends from the same start and compare the results.

    Parameters
    ----------
    V, F : one chart (a connected disk with holes)
    alpha, init, tol, seed : as in :func:`uvbake.parameterize`
    max_iter : int
        Levenberg-Marquardt's iteration cap.
    lbfgs_max_iter : int, optional
        L-BFGS's iteration cap (default 20 * max_iter: preconditioned L-BFGS needs tens to hundreds
        of iterations where LM needs tens).
    rtol_energy : float
        The backends agree on F* when |F_lm - F_lbfgs| <= rtol_energy * max(|F_lm|, |F_lbfgs|, 1e-12)...
    rtol_uv : float
        ... and the aligned maps differ by at most rtol_uv times the chart's UV diameter.
    raise_on_disagree : bool
        Raise :class:`CrossCheckError` on disagreement (default); False returns the result with
        ``agree=False``.
    second_order : bool
        Also test whether each end point is a local minimum (one sparse factorisation each).

    Returns
    -------
    CrossCheckResult
    """
    from uvbake import parameterize

    if not (rtol_energy > 0 and rtol_uv > 0):
        raise InputError(f"rtol_energy={rtol_energy!r} and rtol_uv={rtol_uv!r} must be positive tolerances")
    lbfgs_max_iter = 20 * int(max_iter) if lbfgs_max_iter is None else int(lbfgs_max_iter)
    common = dict(alpha=alpha, init=init, tol=tol, seed=seed, name=name)
    r_lm = parameterize(V, F, backend="lm", max_iter=max_iter, **common)
    r_lb = parameterize(V, F, backend="lbfgs", max_iter=lbfgs_max_iter, **common)

    e1, e2 = float(r_lm.energy), float(r_lb.energy)
    denom = max(abs(e1), abs(e2), 1e-12)
    rel = abs(e1 - e2) / denom if np.isfinite(e1) and np.isfinite(e2) else float("inf")
    if np.all(np.isfinite(r_lb.uv)) and np.all(np.isfinite(r_lm.uv)):
        _, _, aligned = rigid_align(r_lb.uv, r_lm.uv)
        uv_diff = float(np.max(np.linalg.norm(aligned - r_lm.uv, axis=1)))
    else:
        uv_diff = float("inf")
    diam = uv_diameter(r_lm.uv)
    uv_rel = uv_diff / diam if diam > 0 else float("inf")
    agree = bool(rel <= rtol_energy and uv_rel <= rtol_uv)
    lmin_lm = lmin_lb = None
    if second_order:
        lmin_lm = is_local_minimum(V, F, r_lm.uv, r_lm.alpha)
        lmin_lb = is_local_minimum(V, F, r_lb.uv, r_lb.alpha)
    res = CrossCheckResult(
        name=name, alpha=float(r_lm.alpha), init=init, vertices=int(len(V)),
        energy_lm=e1, energy_lbfgs=e2, energy_rel_diff=float(rel),
        uv_max_diff=uv_diff, uv_max_diff_rel=float(uv_rel), diameter=diam,
        iterations_lm=int(r_lm.iterations), iterations_lbfgs=int(r_lb.iterations),
        evaluations_lm=int(r_lm.n_evaluations), evaluations_lbfgs=int(r_lb.n_evaluations),
        time_lm_s=float(r_lm.time_s), time_lbfgs_s=float(r_lb.time_s),
        grad_norm_lm=float(r_lm.grad_norm), grad_norm_lbfgs=float(r_lb.grad_norm),
        converged_lm=bool(r_lm.converged), converged_lbfgs=bool(r_lb.converged),
        stop_reason_lm=r_lm.stop_reason, stop_reason_lbfgs=r_lb.stop_reason,
        local_min_lm=lmin_lm, local_min_lbfgs=lmin_lb,
        n_flipped_lm=int(r_lm.n_flipped), n_flipped_lbfgs=int(r_lb.n_flipped),
        rtol_energy=float(rtol_energy), rtol_uv=float(rtol_uv), agree=agree,
    )
    if not agree and raise_on_disagree:
        raise CrossCheckError(res.summary(), [res])
    return res


class CrossCheckReport(dict):
    """Cross-check of every chart of a mesh: a JSON-ready dict (``agree``, ``message``, ``charts``)
    that also carries the :class:`CrossCheckResult` objects as ``results``."""

    def __init__(self, results: Iterable[CrossCheckResult]) -> None:
        self.results = list(results)
        super().__init__(agree=all(r.agree for r in self.results), message=self.summary(),
                         charts=[r.to_dict() for r in self.results])

    @property
    def agree(self) -> bool:
        return all(r.agree for r in self.results)

    @property
    def disagreeing(self) -> list[CrossCheckResult]:
        return [r for r in self.results if not r.agree]

    def to_dict(self) -> dict[str, Any]:
        return dict(self)

    def summary(self) -> str:
        bad = self.disagreeing
        if not bad:
            return f"backends agree on all {len(self.results)} charts"
        return (f"backends DISAGREE on {len(bad)} of {len(self.results)} charts: "
                + " | ".join(r.summary() for r in bad))


def cross_check_charts(charts: Iterable[Any], results: Sequence[Any] | None = None, *,
                       raise_on_disagree: bool = True, progress: Callable[..., Any] | None = None,
                       **options: Any) -> CrossCheckReport:
    """:func:`cross_check` on every chart (``Chart`` objects or (V, F) pairs), one report.

    Parameters
    ----------
    charts : list of Chart or (V, F) pairs
    results : list of ParamResult, optional
        A run already made on these charts (e.g. the pipeline's). Both backends are still solved
        from the same start (the pipeline may have started a split chart from its parent's map);
        the given result's F and backend are recorded as ``energy_given`` / ``backend_given``.
    raise_on_disagree : bool
        Raise :class:`CrossCheckError` (after checking every chart, listing all that disagree).
        Pass False to get the report with ``agree=False`` instead (the CLI does, to write its JSON
        report before exiting non-zero).
    **options
        Passed to :func:`cross_check` (alpha, init, tol, max_iter, seed, rtol_energy, rtol_uv, ...).

    Returns
    -------
    CrossCheckReport (a dict: ``agree``, ``message``, ``charts``).
    """
    items = [(c.V, c.F, c.name) if hasattr(c, "V") else (c[0], c[1], f"chart {i}") for i, c in enumerate(charts)]
    if results is not None and len(results) != len(items):
        raise InputError(f"{len(results)} results for {len(items)} charts; pass one result per chart")
    out = []
    for i, (V, F, name) in enumerate(items):
        res = cross_check(V, F, raise_on_disagree=False, name=name, **options)
        if results is not None:
            res.extra.update(energy_given=float(results[i].energy), backend_given=str(results[i].backend))
        out.append(res)
        if progress:
            progress(i + 1, len(items), res)
    report = CrossCheckReport(out)
    if raise_on_disagree and not report.agree:
        raise CrossCheckError(report.summary(), out)
    return report
