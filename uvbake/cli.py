"""The ``uvbake`` command.

    uvbake MESH [--alpha A] [--init lscm|tutte|random] [--backend lm|lbfgs] [-o OUT.obj] [--json R.json]
    uvbake check MESH [...]     validate the UVs of a textured mesh (see ``uvbake check --help``)
    uvbake sweep MESH [...]     alpha sensitivity study (see ``uvbake sweep --help``)

Errors print one line and exit non-zero (2 for bad input, 1 for a failed solve, 3 for a bug), never a
traceback (set UVBAKE_DEBUG=1 to see one). Output files are written atomically and never replace the
input.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

SUBCOMMANDS = {"check": "uvbake.check", "sweep": "uvbake.sweep_cli"}


def _parser():
    p = argparse.ArgumentParser(
        prog="uvbake",
        description="Flatten every chart of a mesh with the weighted area/angle distortion minimiser "
                    "(Levenberg-Marquardt) and write the mesh with its UVs. Charts come from a per-face "
                    "segment label (PLY face property 'segment', 'label', ...) and connected components.",
        epilog="Other commands: 'uvbake check MESH' validates a textured mesh's UVs; "
               "'uvbake sweep MESH --alphas 0:1:0.1' studies the alpha sensitivity.",
    )
    p.add_argument("mesh", help="input mesh (PLY, OBJ, OFF, GLB/GLTF, STL)")
    p.add_argument("-o", "--output", help="output OBJ with UVs (default: MESH_uv.obj next to the input)")
    p.add_argument("--alpha", type=float, default=0.5,
                   help="weight of area preservation in [0, 1]; 1 - alpha weighs angles (default 0.5)")
    p.add_argument("--init", default="lscm", choices=["lscm", "tutte", "random"], help="start map (default lscm)")
    p.add_argument("--backend", default="lm", choices=["lm", "lbfgs"],
                   help="lm: Levenberg-Marquardt, full Hessian (default); lbfgs: nlopt L-BFGS")
    p.add_argument("--tol", type=float, default=1e-8, help="scale-free gradient norm to reach (default 1e-8)")
    p.add_argument("--max-iter", type=int, default=1000, help="iteration cap per chart (default 1000)")
    p.add_argument("--seed", type=int, default=0, help="seed of --init random (default 0)")
    p.add_argument("--no-continuation", action="store_true",
                   help="from an invalid start, run the paper's plain LM instead of going through alpha=0.1")
    p.add_argument("--workers", type=int, default=None, help="charts solved in parallel (default: CPU count)")
    p.add_argument("--json", metavar="REPORT", help="write a JSON report here")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar, no summary")
    return p


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        if argv and argv[0] in SUBCOMMANDS:
            import importlib

            return importlib.import_module(SUBCOMMANDS[argv[0]]).main(argv[1:])
        return _unwrap_command(_parser().parse_args(argv))
    except KeyboardInterrupt:
        print("uvbake: interrupted; no output was written", file=sys.stderr)
        return 130
    except Exception as exc:  # one line, no traceback, whatever went wrong
        from .errors import InputError, UvbakeError

        if os.environ.get("UVBAKE_DEBUG"):
            raise
        if isinstance(exc, InputError):
            print(f"uvbake: error: {exc}", file=sys.stderr)
            return 2
        if isinstance(exc, UvbakeError):
            print(f"uvbake: failed: {exc}", file=sys.stderr)
            return 1
        if isinstance(exc, OSError):
            print(f"uvbake: error: {exc.strerror or exc} ({exc.filename or ''}); check the path and permissions",
                  file=sys.stderr)
            return 2
        print(f"uvbake: internal error: {type(exc).__name__}: {exc} (rerun with UVBAKE_DEBUG=1 and report it)",
              file=sys.stderr)
        return 3


def output_path(mesh, output, *, suffix="_uv", ext=".obj"):
    """The output path: the one given, or MESH<suffix><ext> beside the input; never the input itself."""
    from .errors import InputError

    src = Path(mesh)
    out = Path(output) if output else src.with_name(src.stem + suffix + ext)
    if out.exists() and src.exists() and out.resolve() == src.resolve():
        raise InputError(f"output {out} is the input mesh; choose another output path with -o")
    if not out.parent.exists():
        raise InputError(f"output folder {out.parent} does not exist; create it or choose another path with -o")
    if out.exists() and out.is_dir():
        raise InputError(f"output {out} is a folder; give a file name with -o")
    return out


def _unwrap_command(args):
    import numpy as np

    from .charts import split_charts
    from .errors import InputError
    from .io import atomic_write, load_mesh, save_obj
    from .parameterization import _check_options, parameterize_charts

    t0 = time.perf_counter()
    _check_options(args.alpha, args.init, args.backend, args.tol, args.max_iter)
    if args.workers is not None and args.workers < 1:
        raise InputError(f"--workers {args.workers} must be at least 1")
    out = output_path(args.mesh, args.output)
    if out.suffix.lower() != ".obj":
        raise InputError(f"output {out} must end in .obj (textured GLB export comes with packing and baking)")
    report_path = output_path(args.mesh, args.json, suffix="_report", ext=".json") if args.json else None
    mesh = load_mesh(args.mesh)
    charts = split_charts(mesh.V, mesh.F, mesh.face_labels)

    bar = _progress(len(charts), quiet=args.quiet)

    def on_iteration(info):
        if bar is not None:
            bar.set_postfix_str(f"iter {info['iteration']}  |grad| {info['grad_norm']:.1e}", refresh=False)

    results = parameterize_charts(
        charts, workers=args.workers, progress=(lambda done, total, res: bar.update(1)) if bar else None,
        alpha=args.alpha, init=args.init, backend=args.backend, tol=args.tol, max_iter=args.max_iter,
        seed=args.seed, continuation=not args.no_continuation, callback=on_iteration)
    if bar is not None:
        bar.close()

    # per-corner UVs: each chart keeps its own UV vertices (seams split), charts side by side in u
    uv_parts, uv_faces = [], np.empty_like(mesh.F)
    offset_u, offset_i = 0.0, 0
    for chart, res in zip(charts, results):
        uv = res.uv - res.uv.min(axis=0)
        gap = 0.05 * float(np.ptp(uv, axis=0).max())
        uv_parts.append(uv + [offset_u, 0.0])
        uv_faces[chart.face_index] = chart.F + offset_i
        offset_u += float(uv[:, 0].max()) + gap
        offset_i += len(uv)
    save_obj(out, mesh.V, mesh.F, uv=np.vstack(uv_parts), uv_faces=uv_faces)

    report = {
        "input": str(args.mesh),
        "output": str(out),
        "vertices": int(len(mesh.V)),
        "triangles": int(len(mesh.F)),
        "options": {"alpha": args.alpha, "init": args.init, "backend": args.backend, "tol": args.tol,
                    "max_iter": args.max_iter, "seed": args.seed, "continuation": not args.no_continuation},
        "charts": [dict(name=c.name, label=c.label, triangles=int(len(c.F)), **r.to_dict())
                   for c, r in zip(charts, results)],
        "energy_total": float(sum(r.energy for r in results)),
        "n_flipped_total": int(sum(r.n_flipped for r in results)),
        "all_converged": bool(all(r.converged for r in results)),
        "time_s": time.perf_counter() - t0,
    }
    if report_path is not None:
        with atomic_write(report_path) as fh:
            json.dump(report, fh, indent=1)
    if not args.quiet:
        conv = sum(r.converged for r in results)
        print(f"uvbake: {len(charts)} chart(s), {len(mesh.F)} triangles, alpha {args.alpha}: "
              f"F* {report['energy_total']:.6g}, {conv}/{len(charts)} converged, "
              f"{report['n_flipped_total']} flipped, {report['time_s']:.2f} s -> {out}")
        for c, r in zip(charts, results):
            if not r.converged:
                print(f"uvbake: warning: {c.name} stopped before convergence ({r.stop_reason}, "
                      f"|grad| {r.grad_norm:.2e} after {r.iterations} iterations); raise --max-iter",
                      file=sys.stderr)
    return 0


def _progress(total, *, quiet):
    if quiet:
        return None
    from tqdm import tqdm

    # disable=None: shown on a terminal, silent when stderr is a pipe or a CI log
    return tqdm(total=total, unit="chart", desc="uvbake", disable=None, leave=False, file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
