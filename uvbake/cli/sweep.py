"""``uvbake sweep MESH --alphas 0:1:0.1 [--plot out.png] [--csv out.csv] [--json out.json]``.

Solves every chart of the mesh at every alpha and reports F*(alpha) (summed over charts: charts are
independent, so the mesh's optimum is the sum of theirs), iterations, flips, overlaps and the relative
sensitivity S = (alpha / F*) dF*/dalpha (paper section 3.6, Eq. 10). A table goes to stdout; the plot,
CSV and JSON are written atomically. Exit codes: :mod:`uvbake.cli.common`.
"""

from __future__ import annotations

import argparse
import math
import os
import sys

from uvbake.cli.common import ArgumentParser
from uvbake.cli.common import run as run_command
from uvbake.errors import InputError
from uvbake.flatten.options import BACKENDS, DEFAULTS, INITS

DESCRIPTION = "alpha sensitivity study: solve every alpha, report F*(alpha) and S(alpha) (Eq. 10)."


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The arguments of ``uvbake sweep MESH ...``."""
    p.add_argument("mesh", help="mesh file (PLY, OBJ, OFF, GLB, STL); charts from face labels and connectivity")
    p.add_argument("--alphas", default="0:1:0.1",
                   help="start:stop:step (stop included) or a comma list, values in [0, 1] (default 0:1:0.1)")
    p.add_argument("--init", default=DEFAULTS.init, choices=INITS,
                   help=f"start map of every chart (default {DEFAULTS.init})")
    p.add_argument("--backend", default=DEFAULTS.backend, choices=BACKENDS,
                   help="lm: full-Hessian Newton, trust-region steps (default); lbfgs: nlopt L-BFGS")
    p.add_argument("--warm-start", action="store_true",
                   help="start each alpha from the previous alpha's solution (reported per alpha)")
    p.add_argument("--tol", type=float, default=DEFAULTS.tol,
                   help=f"scale-free gradient norm to reach (default {DEFAULTS.tol:g})")
    p.add_argument("--max-iter", type=int, default=DEFAULTS.max_iter,
                   help=f"iteration cap per chart and alpha (default {DEFAULTS.max_iter})")
    p.add_argument("--seed", type=int, default=DEFAULTS.seed, help=f"seed of --init random (default {DEFAULTS.seed})")
    p.add_argument("--no-overlaps", action="store_true", help="skip the overlap count (faster)")
    p.add_argument("--plot", metavar="PNG", help="write the plot here: F per iteration, F*(alpha), area and angle "
                                                 "distortion against alpha, sensitivity")
    p.add_argument("--csv", metavar="CSV", help="write the numbers as CSV")
    p.add_argument("--json", metavar="JSON", help="write the numbers (and histories) as JSON")
    p.add_argument("--recommend", action="store_true",
                   help="recommend an alpha: the least combined angle + area distortion among those whose "
                        "maps have the fewest flips and overlaps (printed, and in --json)")
    p.add_argument("-q", "--quiet", action="store_true", help="no table on stdout")


def main(argv: list[str] | None = None) -> int:
    """Run ``uvbake sweep``; return the exit status (0 done, 2 bad input)."""
    parser = ArgumentParser(prog="uvbake sweep", description=DESCRIPTION)
    add_arguments(parser)
    return run_command("uvbake sweep", lambda: run(parser.parse_args(argv)))


def run(args: argparse.Namespace) -> int:
    """``uvbake sweep``: solve every alpha, print the table, write the files asked for."""
    from uvbake.analysis.sensitivity import parse_alphas, recommend_alpha, require_matplotlib, sweep
    from uvbake.io.load import load_mesh

    alphas = parse_alphas(args.alphas)
    if args.max_iter < 0:
        raise InputError(f"--max-iter {args.max_iter} must be a non-negative integer")
    if not (math.isfinite(args.tol) and args.tol > 0):
        raise InputError(f"--tol {args.tol} must be a positive number")
    for opt in ("plot", "csv", "json"):
        path = getattr(args, opt)
        if path:
            folder = os.path.dirname(os.path.abspath(path))
            if not os.path.isdir(folder):
                raise InputError(f"--{opt} {path}: folder {folder} does not exist; create it or pick another path")
    if args.plot:
        require_matplotlib()              # before a long sweep, not after
    mesh = load_mesh(args.mesh)

    def progress(done, total, rec):
        if not args.quiet:
            print(f"  alpha={rec.alpha:<6g} F*={rec.energy:<14.8g} iterations={rec.iterations:<5d} "
                  f"flips={rec.n_flipped:<4d} overlaps={'-' if rec.overlaps is None else rec.overlaps:<4} "
                  f"{'converged' if rec.converged else ','.join(rec.stop_reasons)} ({done}/{total})",
                  file=sys.stderr, flush=True)

    res = sweep(mesh.V, mesh.F, alphas, labels=mesh.face_labels, init=args.init, warm_start=args.warm_start,
                backend=args.backend, tol=args.tol, max_iter=args.max_iter, seed=args.seed,
                overlaps=not args.no_overlaps, progress=progress)
    if not args.quiet:
        print(f"{'alpha':>6} {'F*':>14} {'S':>9} {'S_env':>9} {'iter':>5} {'flips':>5} {'overl':>5} {'UVarea':>7}")
        for r, s, se in zip(res.records, res.sensitivity, res.sensitivity_envelope):
            ov = "-" if r.overlaps is None else str(r.overlaps)
            print(f"{r.alpha:6.3g} {r.energy:14.8g} {s:9.4f} {se:9.4f} {r.iterations:5d} {r.n_flipped:5d} "
                  f"{ov:>5} {r.uv_area_ratio:7.3f}")
        for note in res.notes:
            print(f"note: {note}")
    if args.recommend:
        rec = recommend_alpha(res)
        print(f"recommended: {rec['reason']}")
    title = f"{args.mesh}: {res.n_charts} chart(s), init {args.init}" + (", warm start" if args.warm_start else "")
    if args.csv:
        res.save_csv(args.csv)
    if args.json:
        res.save_json(args.json)
    if args.plot:
        res.plot(args.plot, title=title)
    return 0

