"""Levenberg-Marquardt against nlopt's L-BFGS on the same F, side by side (issue 3).

    python bench/backends.py                                   # halftunnel, camelhead, beetle; alpha 0.1, 0.5
    python bench/backends.py --meshes halftunnel --alphas 0.5 --storage 5,10,20,30
    python bench/backends.py --budget 120 --strict-pd          # see below

For each mesh (all its charts, from ../shared/meshes) and alpha, both backends start from the same
lscm map and stop under the same rule (scale-free gradient norm < tol). Printed per backend:
iterations (LM: factorisations; L-BFGS: accepted iterates), F+gradient evaluations, wall time, F*,
the final gradient norm, the stop reason, whether the end point is a local minimum, and F*'s relative
difference to LM's. Each L-BFGS run is capped at ``--budget`` seconds (stopped through the callback,
reported as "time budget"), so the whole table takes a few minutes.

``--strict-pd`` runs LM with the linear-solver fix proposed in the issue-3 report: CHOLMOD's
simplicial LDL^T factorisation succeeds on indefinite matrices, so LM's "H + lambda I not positive
definite" branch never fires with CHOLMOD and LM can stop at saddle points. The flag patches
``CholmodSolver.factor`` in this process only (checking the signs of D); nothing is changed on disk.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
MESHES = REPO.parent / "shared" / "meshes"


def strict_pd_patch():
    from uvbake.flatten.solvers import linalg

    original = linalg.CholmodSolver.factor

    def factor(self, A, beta):
        original(self, A, beta)
        if np.any(self._factor.D() <= 0):
            raise linalg.NotPositiveDefinite("LDL^T with a non-positive pivot")

    linalg.CholmodSolver.factor = factor


def solve_mesh(path, alpha, backend, *, tol, max_iter, budget_s, storage=None):
    import uvbake
    import uvbake.flatten.solvers.lbfgs as lb
    from uvbake.analysis.crosscheck import is_local_minimum

    if storage is not None:
        lb.VECTOR_STORAGE = storage
    mesh = uvbake.load_mesh(path)
    charts = uvbake.split_charts(mesh.V, mesh.F, mesh.face_labels)
    row = dict(iterations=0, evaluations=0, time_s=0.0, energy=0.0, grad_norm=0.0, stops=set(), local_min=True)
    for c in charts:
        deadline = time.perf_counter() + budget_s
        hit = []

        def cb(d):
            if time.perf_counter() > deadline:
                hit.append(True)
                return True
            return False

        r = uvbake.parameterize(c.V, c.F, alpha=alpha, init="lscm", backend=backend, tol=tol,
                                max_iter=max_iter, callback=cb, name=c.name)
        row["iterations"] += r.iterations
        row["evaluations"] += r.n_evaluations
        row["time_s"] += r.time_s
        row["energy"] += r.energy
        row["grad_norm"] = max(row["grad_norm"], r.grad_norm)
        row["stops"].add("time budget" if hit else r.stop_reason)
        lm = is_local_minimum(c.V, c.F, r.uv, alpha)
        row["local_min"] = row["local_min"] and (lm is not False)
    row["charts"] = len(charts)
    return row


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--meshes", default="halftunnel,camelhead,beetle")
    p.add_argument("--alphas", default="0.1,0.5")
    p.add_argument("--tol", type=float, default=1e-8)
    p.add_argument("--budget", type=float, default=60.0, help="seconds per chart and L-BFGS run")
    p.add_argument("--lbfgs-max-iter", type=int, default=200000)
    p.add_argument("--storage", default=None, help="comma list of L-BFGS memories to compare (e.g. 5,10,20,30)")
    p.add_argument("--strict-pd", action="store_true", help="LM with the proposed CHOLMOD positive-definiteness check")
    args = p.parse_args(argv)
    if args.strict_pd:
        strict_pd_patch()
    storages = [None] if not args.storage else [int(s) for s in args.storage.split(",")]
    print(f"tol {args.tol:g}, lscm starts, L-BFGS budget {args.budget:g} s per chart"
          + (", LM with strict positive-definiteness check" if args.strict_pd else ""))
    hdr = ("| mesh | alpha | backend | iterations | evaluations | time (s) | F* | grad norm | stop | local min "
           "| F* rel. diff to LM |")
    print(hdr)
    print("|---|---:|---|---:|---:|---:|---:|---:|---|---|---:|")
    for name in args.meshes.split(","):
        path = MESHES / f"{name}.off"
        if not path.exists():
            print(f"| {name} | - | missing ({path}) |")
            continue
        for alpha in [float(a) for a in args.alphas.split(",")]:
            lm = solve_mesh(path, alpha, "lm", tol=args.tol, max_iter=1000, budget_s=args.budget)
            rows = [("lm", lm)]
            for m in storages:
                label = "lbfgs" if m is None else f"lbfgs m={m}"
                rows.append((label, solve_mesh(path, alpha, "lbfgs", tol=args.tol, max_iter=args.lbfgs_max_iter,
                                               budget_s=args.budget, storage=m)))
            for label, r in rows:
                rel = abs(r["energy"] - lm["energy"]) / max(abs(lm["energy"]), 1e-300)
                print(f"| {name} ({r['charts']} ch.) | {alpha:g} | {label} | {r['iterations']} | {r['evaluations']} "
                      f"| {r['time_s']:.2f} | {r['energy']:.10g} | {r['grad_norm']:.1e} | "
                      f"{', '.join(sorted(r['stops']))} | {'yes' if r['local_min'] else 'NO'} | "
                      f"{'-' if label == 'lm' else f'{rel:.1e}'} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
