"""alpha sweeps: F*(alpha), convergence per alpha and the relative sensitivity (paper section 3.6).

For a mesh (one or several charts) and a list of weights alpha, :func:`sweep` solves every alpha and
records the optimum F*(alpha), iterations, flips and overlaps, and the relative sensitivity of the
paper's Eq. 10,

    S(alpha) = (alpha / F*) dF*/dalpha,

with dF*/dalpha by finite differences over the alphas given (second-order three-point formulas on a
possibly uneven grid: central inside, one-sided at the two ends). An independent value comes from
the envelope theorem: at a minimum U*(alpha) the gradient in U vanishes, so

    dF*/dalpha = sum_t (D_area - D_angle)  evaluated at U*(alpha),

recorded as ``dF_dalpha_envelope`` / ``sensitivity_envelope``. The two agree where F* is smooth in
alpha (the same local minimum is followed); where they differ the solver has jumped between minima.

Several charts. Charts are independent, so F* of the mesh is the sum of the charts' F* (and so is
its derivative, and D_area - D_angle); iterations, flips and overlaps are summed too. The history
plotted for an alpha is the mesh's F after k iterations of every chart's solver (a chart that has
stopped contributes its final F).

Properties worth knowing when reading the plot:

* F*(alpha) = min_U [alpha A(U) + (1 - alpha) C(U)] is a minimum of functions affine in alpha, hence
  concave (for the global minimum); with F*(0+) >= 0 that gives S <= 1.
* At alpha = 0 only the conformal term is left and its infimum is the collapsed map; uvbake then
  returns the pinned conformal map at the surface's own scale (see :mod:`uvbake.flatten.solve`),
  so F*(0) is *not* the limit of F*(alpha) as alpha -> 0+. S(0) = 0 by the alpha factor of Eq. 10;
  the derivative reported at alpha = 0 is the one-sided difference, flagged in ``notes``.
* For small alpha > 0 the optimum can be the collapsed map (all UVs nearly equal, F* = alpha * m):
  ``uv_area_ratio`` (total UV area over 3D area) makes that visible, and the plot marks it.

Warm starts (``warm_start=True``) solve the alphas in increasing order, each from the previous
alpha's solution; the record of each alpha says where it started (``started_from``).
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from uvbake.errors import InputError
from uvbake.flatten.energy import DistortionEnergy
from uvbake.flatten.solve import parameterize
from uvbake.io.atomic import atomic_write_bytes
from uvbake.mesh.arrays import signed_areas, triangle_areas
from uvbake.mesh.charts import split_charts
from uvbake.validate.core import validate

#: F* under this (times the number of triangles) is zero to rounding: S is then undefined (NaN).
ZERO_ENERGY = 1e-12
#: A map whose total UV area is under this fraction of the 3D area counts as collapsed.
COLLAPSED_AREA = 1e-3


@dataclass
class AlphaRecord:
    """One alpha of a sweep (sums over charts)."""

    alpha: float
    energy: float
    energy_area: float           # sum_t D_area at the optimum
    energy_angle: float          # sum_t D_angle at the optimum
    iterations: int
    evaluations: int
    n_flipped: int
    overlaps: int | None         # overlapping triangle pairs within charts (None: validator unavailable)
    converged: bool
    grad_norm: float             # largest over charts
    uv_area_ratio: float         # total |UV area| over total 3D area
    stop_reasons: list
    started_from: str            # "lscm" / "tutte" / "random" or "alpha=<previous>"
    history: np.ndarray
    time_s: float

    def to_dict(self, *, with_history: bool = True) -> dict[str, Any]:
        d = {k: getattr(self, k) for k in ("alpha", "energy", "energy_area", "energy_angle", "iterations",
                                           "evaluations", "n_flipped", "overlaps", "converged",
                                           "grad_norm", "uv_area_ratio", "stop_reasons", "started_from",
                                           "time_s")}
        d = {k: (float(v) if isinstance(v, (float, np.floating)) else v) for k, v in d.items()}
        d["collapsed"] = bool(self.uv_area_ratio < COLLAPSED_AREA)
        if with_history:
            d["history"] = [float(h) for h in self.history]
        return d


@dataclass
class SweepResult:
    """F*(alpha) and S(alpha) of a sweep; see the module docstring for the definitions."""

    records: list
    sensitivity: np.ndarray              # S by finite differences of F*(alpha)
    dF_dalpha: np.ndarray                # finite-difference derivative
    dF_dalpha_envelope: np.ndarray       # sum (D_area - D_angle) at each optimum
    sensitivity_envelope: np.ndarray
    init: str
    warm_start: bool
    backend: str
    n_charts: int
    notes: list = field(default_factory=list)
    recommendation: dict | None = None     # set by recommend_alpha (``uvbake sweep --recommend``)

    @property
    def alphas(self) -> np.ndarray:
        return np.array([r.alpha for r in self.records])

    @property
    def energies(self) -> np.ndarray:
        return np.array([r.energy for r in self.records])

    def to_dict(self) -> dict[str, Any]:
        return {
            "init": self.init,
            "warm_start": self.warm_start,
            "backend": self.backend,
            "charts": self.n_charts,
            "notes": list(self.notes),
            **({"recommendation": self.recommendation} if self.recommendation else {}),
            "alphas": [float(a) for a in self.alphas],
            "records": [
                dict(r.to_dict(), sensitivity=_num(s), dF_dalpha=_num(d), dF_dalpha_envelope=_num(de),
                     sensitivity_envelope=_num(se))
                for r, s, d, de, se in zip(self.records, self.sensitivity, self.dF_dalpha,
                                           self.dF_dalpha_envelope, self.sensitivity_envelope)
            ],
        }

    def save_json(self, path: str | os.PathLike[str]) -> None:
        text = json.dumps(_clean(self.to_dict()), indent=2, allow_nan=False)
        atomic_write_bytes(path, (text + "\n").encode())

    CSV_COLUMNS = ("alpha", "energy", "sensitivity", "dF_dalpha", "sensitivity_envelope", "dF_dalpha_envelope",
                   "energy_area", "energy_angle", "iterations", "evaluations", "n_flipped", "overlaps",
                   "converged", "grad_norm", "uv_area_ratio", "collapsed", "started_from", "time_s")

    def save_csv(self, path: str | os.PathLike[str]) -> None:
        lines = [",".join(self.CSV_COLUMNS)]
        for row in self.to_dict()["records"]:
            cells = []
            for c in self.CSV_COLUMNS:
                v = row[c]
                cells.append("" if v is None else (repr(float(v)) if isinstance(v, float) else str(v)))
            lines.append(",".join(cells))
        atomic_write_bytes(path, ("\n".join(lines) + "\n").encode())

    def plot(self, path: str | os.PathLike[str], *, title: str | None = None, dpi: int = 120) -> None:
        """Write a PNG: F per iteration for every alpha (log scale) and F*, S against alpha."""
        require_matplotlib()
        import matplotlib

        matplotlib.use("Agg", force=False)
        from matplotlib.figure import Figure

        fig = Figure(figsize=(11, 8), layout="constrained")          # 2 x 2: readable at README width
        (ax1, ax2), (ax4, ax3) = fig.subplots(2, 2)
        cmap = matplotlib.colormaps["viridis"]
        alphas = self.alphas
        span = (alphas.max() - alphas.min()) or 1.0
        for r in self.records:
            h = np.maximum(np.asarray(r.history, dtype=float), 1e-300)
            ax1.semilogy(np.arange(len(h)), h, color=cmap((r.alpha - alphas.min()) / span),
                         label=f"{r.alpha:g}", lw=1.2)
        ax1.set_xlabel("iteration")
        ax1.set_ylabel("F")
        ax1.set_title("F per iteration")
        ax1.legend(title="alpha", fontsize="small", ncol=2)
        E = self.energies
        ax2.plot(alphas, E, "o-", color="C0")
        col = np.array([r.uv_area_ratio < COLLAPSED_AREA for r in self.records])
        if col.any():
            ax2.plot(alphas[col], E[col], "x", color="red", ms=10, label="collapsed map")
            ax2.legend(fontsize="small")
        flips = np.array([r.n_flipped for r in self.records])
        if flips.any():
            for a, e, nf in zip(alphas, E, flips):
                if nf:
                    ax2.annotate(f"{nf} flips", (a, e), fontsize="x-small", xytext=(3, 3),
                                 textcoords="offset points")
        ax2.set_xlabel("alpha")
        ax2.set_ylabel("F*")
        ax2.set_title("optimum F*(alpha)")
        ax3.axhline(0.0, color="0.7", lw=0.8)
        ax3.plot(alphas, self.sensitivity, "o-", label="finite differences (Eq. 10)")
        ax3.plot(alphas, self.sensitivity_envelope, "s--", ms=4, mfc="none",
                 label="envelope: sum(D_area - D_angle)")
        ax3.set_xlabel("alpha")
        ax3.set_ylabel("S = (alpha / F*) dF*/dalpha")
        ax3.set_title("relative sensitivity")
        ax3.legend(fontsize="small")
        d_area, d_angle = distortions(self)
        ax4.plot(alphas, d_area, "o-", label="area: sum (det A - 1)^2 / max")
        ax4.plot(alphas, d_angle, "s-", label="angle: sum D_angle / max")
        ax4.plot(alphas, d_area + d_angle, "k.--", label="combined")
        if self.recommendation:
            ax4.axvline(self.recommendation["alpha"], color="C3", lw=1.0, label="recommended")
        ax4.set_xlabel("alpha (weight of area)")
        ax4.set_title("area vs angle distortion (each / its largest)")
        ax4.legend(fontsize="small")
        for ax in (ax2, ax3, ax4):
            ax.grid(True, color="0.9", lw=0.6)
        if title:
            fig.suptitle(title)
        import io

        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=dpi)
        atomic_write_bytes(path, buf.getvalue())


def distortions(result: SweepResult) -> tuple[np.ndarray, np.ndarray]:
    """Area and angle distortion per alpha (sums of D_area and D_angle over the triangles at each
    optimum), each divided by its largest value over the sweep so the two are comparable."""
    da = np.array([r.energy_area for r in result.records], dtype=float)
    dg = np.array([r.energy_angle for r in result.records], dtype=float)
    return da / max(da.max(), 1e-300), dg / max(dg.max(), 1e-300)


def recommend_alpha(result: SweepResult) -> dict[str, Any]:
    """The alpha to use, and why: among the alphas whose per-chart maps have the fewest flipped
    triangles plus overlapping pairs (each of those is what makes the atlas stage add a chart; zero
    means the atlas validates with no extra chart) and are not collapsed, the one with the least
    combined distortion (area + angle, each relative to its largest over the sweep).
    Stored in ``result.recommendation`` and returned: dict(alpha, reason, combined, invalid)."""
    recs = result.records
    d_area, d_angle = distortions(result)
    combined = d_area + d_angle
    invalid = np.array([r.n_flipped + (r.overlaps or 0) for r in recs])
    ok = np.array([r.uv_area_ratio >= COLLAPSED_AREA and r.converged for r in recs])
    if not ok.any():
        ok[:] = True
    fewest = invalid[ok].min()
    cand = np.flatnonzero(ok & (invalid == fewest))
    k = int(cand[np.argmin(combined[cand])])
    best_all = int(np.flatnonzero(ok)[np.argmin(combined[ok])])
    a = recs[k].alpha
    why = (f"alpha {a:g}: its combined distortion {combined[k]:.3f} (area {d_area[k]:.3f} + angle "
           f"{d_angle[k]:.3f}, each relative to its largest over the {len(recs)} alphas) is the least among "
           f"the alphas whose maps have {'no' if fewest == 0 else f'the fewest ({fewest})'} flipped triangles "
           f"or overlapping pairs, so the atlas needs "
           f"{'no extra chart' if fewest == 0 else 'the fewest extra charts'}")
    if best_all != k:
        why += (f"; alpha {recs[best_all].alpha:g} distorts less ({combined[best_all]:.3f}) but has "
                f"{invalid[best_all]} flipped or overlapping triangles, each of which costs a chart split")
    excluded = [r.alpha for r, o in zip(recs, ok) if not o]
    if excluded:
        why += "; not considered (collapsed or not converged): " + ", ".join(f"{x:g}" for x in excluded)
    result.recommendation = dict(alpha=float(a), reason=why + ".", combined=float(combined[k]),
                                 invalid=int(fewest))
    return result.recommendation


def require_matplotlib() -> None:
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise InputError("plotting needs matplotlib, which is not installed: pip install 'uvbake[plot]' "
                         "(or leave out --plot)") from None


def parse_alphas(text: str) -> np.ndarray:
    """``"0:1:0.1"`` (start:stop:step, stop included) or ``"0.1,0.5,0.9"`` -> sorted unique floats in [0, 1]."""
    text = str(text).strip()
    try:
        if ":" in text:
            parts = [float(p) for p in text.split(":")]
            if len(parts) != 3:
                raise ValueError
            a, b, step = parts
            if not (step > 0) or b < a:
                raise InputError(f"--alphas {text!r}: need start <= stop and a positive step, e.g. 0:1:0.1")
            n = int(np.floor((b - a) / step + 1e-9)) + 1
            if n > 10001:
                raise InputError(f"--alphas {text!r} gives {n} values; use a larger step")
            vals = [round(a + i * step, 12) for i in range(n)]
        else:
            vals = [float(p) for p in text.split(",") if p.strip()]
    except InputError:
        raise
    except ValueError:
        raise InputError(f"--alphas {text!r} is not start:stop:step or a comma list of numbers, "
                         "e.g. 0:1:0.1 or 0.1,0.5,0.9") from None
    return check_alphas(vals)


def check_alphas(alphas: ArrayLike) -> np.ndarray:
    a = np.asarray(alphas, dtype=np.float64).ravel()
    if a.size == 0:
        raise InputError("no alpha given; pass at least one weight in [0, 1], e.g. 0:1:0.1")
    if not np.all(np.isfinite(a)) or np.any(a < 0) or np.any(a > 1):
        bad = [float(x) for x in a if not (0 <= x <= 1)]
        raise InputError(f"alpha values {bad} are outside [0, 1]; every weight must be between 0 and 1")
    return np.unique(a)


def finite_difference(x: ArrayLike, y: ArrayLike) -> np.ndarray:
    """dy/dx on an increasing, possibly uneven grid: three-point formulas, second order.

    Inside: the central formula with unequal spacings h1 = x_i - x_{i-1}, h2 = x_{i+1} - x_i,
    y' = [h1^2 y_{i+1} - h2^2 y_{i-1} + (h2^2 - h1^2) y_i] / (h1 h2 (h1 + h2)).
    Ends: the one-sided three-point formula (the derivative of the parabola through the first, or
    last, three points at the end point); with two points, the slope of the chord. One point: NaN.
    """
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    n = len(x)
    d = np.full(n, np.nan)
    if n < 2:
        return d
    if n == 2:
        d[:] = (y[1] - y[0]) / (x[1] - x[0])
        return d
    h1 = x[1:-1] - x[:-2]
    h2 = x[2:] - x[1:-1]
    d[1:-1] = (h1 ** 2 * y[2:] - h2 ** 2 * y[:-2] + (h2 ** 2 - h1 ** 2) * y[1:-1]) / (h1 * h2 * (h1 + h2))
    d[0] = _parabola_slope(x[:3], y[:3], x[0])
    d[-1] = _parabola_slope(x[-3:], y[-3:], x[-1])
    return d


def _parabola_slope(x, y, at):
    # derivative of the Lagrange interpolant through three points
    x0, x1, x2 = x
    y0, y1, y2 = y
    return (y0 * (2 * at - x1 - x2) / ((x0 - x1) * (x0 - x2))
            + y1 * (2 * at - x0 - x2) / ((x1 - x0) * (x1 - x2))
            + y2 * (2 * at - x0 - x1) / ((x2 - x0) * (x2 - x1)))


def relative_sensitivity(alphas: ArrayLike, energies: ArrayLike, derivative: ArrayLike,
                         n_triangles: int = 1) -> np.ndarray:
    """S = alpha / F* * dF*/dalpha, 0 at alpha = 0, NaN where F* is zero to rounding."""
    a = np.asarray(alphas, dtype=np.float64)
    E = np.asarray(energies, dtype=np.float64)
    d = np.asarray(derivative, dtype=np.float64)
    S = np.full(len(a), np.nan)
    ok = np.abs(E) > ZERO_ENERGY * max(n_triangles, 1)
    S[ok] = a[ok] / E[ok] * d[ok]
    S[a == 0] = 0.0
    return S


def sweep(V: ArrayLike, F: ArrayLike, alphas: ArrayLike, *, labels: ArrayLike | None = None, init: str = "lscm",
          warm_start: bool = False, backend: str = "lm", tol: float = 1e-8, max_iter: int = 1000, seed: int = 0,
          overlaps: bool = True, progress: Callable[[int, int, AlphaRecord], None] | None = None) -> SweepResult:
    """Solve the mesh for every alpha and compute the relative sensitivity S(alpha).

    Parameters
    ----------
    V : (n,3) float array
    F : (m,3) int array
        A mesh of one or several charts (split by ``labels`` and edge connectivity).
    alphas : sequence of floats in [0, 1]
        Sorted and de-duplicated before solving.
    labels : (m,) int array, optional
        Per-face segment labels (see :func:`uvbake.mesh.charts.split_charts`).
    init : {"lscm", "tutte", "random", "isomap", "laplacian"}
        Start of every solve (of the first one with ``warm_start``).
    warm_start : bool
        Start each alpha from the previous alpha's solution (reported per record in ``started_from``).
    backend, tol, max_iter, seed : as in :func:`uvbake.parameterize`
    overlaps : bool
        Count overlapping triangle pairs with :func:`uvbake.validate.validate` (None when off or the
        validator is not importable).
    progress : callable, optional
        ``progress(done, total, record)`` after each alpha.

    Returns
    -------
    SweepResult
    """
    alphas = check_alphas(alphas)
    charts = split_charts(V, F, labels)
    notes: list[str] = []
    counter = _OverlapCounter(overlaps, notes)
    area3d = [float(np.sum(triangle_areas(c.V, c.F))) for c in charts]
    m_total = int(sum(len(c.F) for c in charts))
    prev: list[np.ndarray | None] = [None] * len(charts)
    prev_alpha = None
    records = []
    for k, alpha in enumerate(alphas):
        t0 = time.perf_counter()
        results = []
        for ci, c in enumerate(charts):
            uv0 = prev[ci] if (warm_start and prev[ci] is not None) else None
            results.append(parameterize(c.V, c.F, alpha=float(alpha), init=init, backend=backend, tol=tol,
                                        max_iter=max_iter, seed=seed, uv0=uv0, name=c.name))
        started = f"alpha={prev_alpha:g}" if warm_start and prev_alpha is not None else init
        rec = _record(float(alpha), charts, results, counter, sum(area3d), started, t0)
        records.append(rec)
        prev = [r.uv for r in results]
        prev_alpha = float(alpha)
        if progress:
            progress(k + 1, len(alphas), rec)

    a = np.array([r.alpha for r in records])
    E = np.array([r.energy for r in records])
    dF = finite_difference(a, E)
    dF_env = np.array([r.energy_area - r.energy_angle for r in records])
    notes += _sweep_notes(a, records, warm_start)
    return SweepResult(
        records=records,
        sensitivity=relative_sensitivity(a, E, dF, m_total),
        dF_dalpha=dF,
        dF_dalpha_envelope=dF_env,
        sensitivity_envelope=relative_sensitivity(a, E, dF_env, m_total),
        init=init, warm_start=bool(warm_start), backend=backend, n_charts=len(charts), notes=notes,
    )


def _record(alpha, charts, results, counter, area3d, started_from, t0):
    d_area, d_angle, uv_area, n_over = _split_energy(charts, results, alpha, counter)
    return AlphaRecord(
        alpha=alpha,
        energy=float(sum(r.energy for r in results)),
        energy_area=d_area, energy_angle=d_angle,
        iterations=int(sum(r.iterations for r in results)),
        evaluations=int(sum(r.n_evaluations for r in results)),
        n_flipped=int(sum(r.n_flipped for r in results)),
        overlaps=n_over,
        converged=bool(all(r.converged for r in results)),
        grad_norm=float(max(r.grad_norm for r in results)),
        uv_area_ratio=uv_area / area3d if area3d > 0 else float("nan"),
        stop_reasons=sorted({r.stop_reason for r in results}),
        started_from=started_from,
        history=_sum_histories([r.history for r in results]),
        time_s=time.perf_counter() - t0,
    )


class _OverlapCounter:
    """Overlapping triangle pairs per chart; turns itself off (with a note) when the validator fails."""

    def __init__(self, enabled, notes):
        self.notes = notes
        self.validate = validate if enabled else None

    def count(self, alpha, chart, uv):
        if self.validate is None:
            return None
        try:
            return int(len(self.validate(uv, chart.F).overlap_pairs))
        except Exception as exc:      # a validator failure must not lose the sweep
            self.notes.append(f"alpha={alpha:g} {chart.name}: overlap check failed ({type(exc).__name__}: {exc})")
            self.validate = None
            return None


def _split_energy(charts, results, alpha, counter):
    """F* split into its area and angle terms, the total UV area, and the overlap count (None: unknown)."""
    d_area = d_angle = 0.0
    uv_area = 0.0
    n_over = 0 if counter.validate is not None else None
    for c, r in zip(charts, results):
        e = DistortionEnergy(c.V, c.F, alpha=alpha)
        da, dg = e.per_triangle(r.uv)
        d_area += float(da.sum())
        d_angle += float(dg.sum())
        uv_area += float(np.sum(np.abs(signed_areas(r.uv, c.F))))
        if n_over is not None:
            n = counter.count(alpha, c, r.uv)
            n_over = None if n is None else n_over + n
    return d_area, d_angle, uv_area, n_over


def _sweep_notes(a, records, warm_start):
    notes = []
    if len(a) >= 2 and a[0] == 0.0:
        notes.append("alpha=0 is solved in uvbake's gauge (pinned conformal map at the surface's scale), "
                     "which is not the limit of F*(alpha) as alpha->0+ (the collapsed map): S(0)=0 by "
                     "Eq. 10's alpha factor, and the differences next to alpha=0 include that jump")
    collapsed = [r.alpha for r in records if r.uv_area_ratio < COLLAPSED_AREA]
    if collapsed:
        notes.append(f"collapsed maps (UV area < {COLLAPSED_AREA:g} of the 3D area) at alpha = "
                     + ", ".join(f"{x:g}" for x in collapsed))
    if not all(r.converged for r in records):
        notes.append("not converged at alpha = " + ", ".join(f"{r.alpha:g}" for r in records if not r.converged))
    if warm_start:
        notes.append("warm start: each alpha started from the previous alpha's solution")
    return notes


def _sum_histories(histories):
    n = max(len(h) for h in histories)
    total = np.zeros(n)
    for h in histories:
        h = np.asarray(h, dtype=np.float64)
        total[: len(h)] += h
        total[len(h):] += h[-1]
    return total


def _clean(obj):
    """JSON-safe copy: non-finite floats become None, numpy scalars Python numbers."""
    if isinstance(obj, dict):
        return {k: _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return _num(obj)
    return obj


def _num(v):
    if v is None:
        return None
    v = float(v)
    return v if np.isfinite(v) else None
