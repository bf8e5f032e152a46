"""``uvbake batch INPUTS... -o OUTDIR``: the command-line face of :func:`uvbake.batch.run`.

Exit status: 0 when every asset is done (or cached from an earlier run), 1 when some failed (the
summary and report.html say which), 2 for bad arguments.
"""

from __future__ import annotations

import argparse
import sys

from uvbake.batch.run import DEFAULT_TIMEOUT_S, OUTPUT_DEFAULTS, UNWRAP_DEFAULTS, exit_status
from uvbake.batch.run import run as run_batch
from uvbake.cli.common import ArgumentParser
from uvbake.cli.common import run as run_command
from uvbake.cli.unwrap import texture_size
from uvbake.errors import InputError
from uvbake.flatten.options import BACKENDS, INITS

DESCRIPTION = ("Unwrap many meshes on Dask: one task per asset, each with its own time limit; a failing,\n"
                    "crashing or timed-out asset is recorded and the rest go on. Rerunning into the same OUTDIR\n"
                    "skips assets already done with the same input bytes and options and redoes the others.\n"
                    "Writes OUTDIR/assets/<name>/ per asset, summary.parquet, summary.csv and report.html.")
EPILOG = ("examples:\n"
               "  uvbake batch scans/ -o out                             # a local Dask cluster, one process per core\n"
               "  uvbake batch list.csv -o out --scheduler tcp://host:8786 --timeout-per-asset 300\n"
               "inputs: mesh files, folders (searched recursively) and manifests (.txt: one path per line;\n"
               ".csv: a 'path' column and an optional 'timeout_s' column).")


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The arguments of ``uvbake batch INPUTS... -o OUTDIR``."""
    p.add_argument("inputs", nargs="+", metavar="INPUT", help="mesh files, folders or .txt/.csv manifests")
    p.add_argument("-o", "--output", required=True, metavar="OUTDIR", help="output folder (created if missing)")
    g = p.add_argument_group("execution")
    g.add_argument("--scheduler", metavar="ADDRESS",
                   help="a running Dask scheduler (tcp://host:8786); default: a local cluster")
    g.add_argument("--workers", type=int, metavar="N",
                   help="worker processes of the local cluster (default: the usable cores)")
    g.add_argument("--timeout-per-asset", type=float, default=DEFAULT_TIMEOUT_S, metavar="S",
                   help=f"stop an asset after S seconds and record it as timed out (default {DEFAULT_TIMEOUT_S:g})")
    g.add_argument("--retries", type=int, default=1, help="Dask retries of a task that raised (default 1)")
    g = p.add_argument_group("unwrap (as for 'uvbake MESH')")
    g.add_argument("--alpha", type=float, default=UNWRAP_DEFAULTS["alpha"], help="weight of area preservation in [0, 1]")
    g.add_argument("--init", default=UNWRAP_DEFAULTS["init"], choices=INITS, help="start map")
    g.add_argument("--backend", default=UNWRAP_DEFAULTS["backend"], choices=BACKENDS, help="solver")
    g.add_argument("--tol", type=float, default=UNWRAP_DEFAULTS["tol"], help="scale-free gradient norm to reach")
    g.add_argument("--max-iter", type=int, default=UNWRAP_DEFAULTS["max_iter"], help="iteration cap per chart")
    g.add_argument("--seed", type=int, default=UNWRAP_DEFAULTS["seed"], help="seed of --init random")
    g.add_argument("--no-auto-cut", action="store_true", help="refuse closed charts and charts with handles")
    g.add_argument("--no-repair", action="store_true", help="refuse non-manifold input")
    g.add_argument("--paper", action="store_true", help="the paper's formulation: no splitting, no continuation")
    g.add_argument("--texture-size", type=texture_size, default=None, metavar="PX|WxH",
                   help=f"texture side in texels, or WIDTHxHEIGHT (default {UNWRAP_DEFAULTS['texture_size_px']}; "
                        f"with --texel-density each texture grows to fit)")
    g.add_argument("--texel-density", type=float, default=None, metavar="PX_PER_UNIT",
                   help="fixed texels per world unit, the same for every asset of the batch (each texture "
                        "grows to fit, or with --texture-size an asset that cannot fit fails)")
    g.add_argument("--gutter", type=int, default=UNWRAP_DEFAULTS["gutter_px"], metavar="PX",
                   help=f"gap between charts in texels (default {UNWRAP_DEFAULTS['gutter_px']})")
    g.add_argument("--bake", default="checker", choices=["checker", "vertex-colors", "none"],
                   help="texture to bake into every atlas (default checker)")
    g = p.add_argument_group("outputs")
    g.add_argument("--format", default=OUTPUT_DEFAULTS["format"], choices=["obj", "glb"],
                   help="textured mesh format (default obj: .obj + .mtl + .png)")
    g.add_argument("--preview-size", type=int, default=OUTPUT_DEFAULTS["preview_size_px"], metavar="PX",
                   help=f"side of each preview view in the report, 0 for none (default {OUTPUT_DEFAULTS['preview_size_px']})")
    g.add_argument("--atlas-image", default=OUTPUT_DEFAULTS["atlas_image"], choices=["auto", "texture", "charts", "none"],
                   help="atlas thumbnail: the baked texture or the charts in colour (default auto)")
    g.add_argument("--no-html", action="store_true", help="no report.html")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar, no summary line")


def parser() -> argparse.ArgumentParser:
    p = ArgumentParser(prog="uvbake batch", description=DESCRIPTION, epilog=EPILOG,
                       formatter_class=argparse.RawDescriptionHelpFormatter, exit_on_usage_error=True)
    add_arguments(p)
    return p


def main(argv: list[str] | None = None) -> int:
    """Run ``uvbake batch``; the exit status (0 all done, 1 some failed, 2 bad input)."""
    p = parser()
    return run_command("uvbake batch", lambda: run(p.parse_args(sys.argv[1:] if argv is None else argv)))


def _texture_options(args: argparse.Namespace) -> dict:
    """--texture-size and --texel-density as batch options (a texture size left out: the default, or a
    growing atlas with --texel-density)."""
    out = {} if args.texture_size is None else {"texture_size_px": args.texture_size}
    if args.texel_density is not None:
        out["texel_density"] = args.texel_density
    return out


def run(args: argparse.Namespace) -> int:
    """``uvbake batch``: unwrap every input on Dask, write the summary; 1 when some asset failed."""
    if args.scheduler and args.workers is not None:
        raise InputError("--workers sizes the local cluster; with --scheduler start as many 'dask worker's as you "
                         "want instead (drop --workers)")
    table = run_batch(args.inputs, args.output, scheduler=args.scheduler, workers=args.workers,
                timeout_per_asset_s=args.timeout_per_asset, retries=args.retries, progress=not args.quiet,
                html=not args.no_html, alpha=args.alpha, init=args.init, backend=args.backend, tol=args.tol,
                max_iter=args.max_iter, seed=args.seed, auto_cut=not args.no_auto_cut, repair=not args.no_repair,
                guarantee=not args.paper, continuation=not args.paper, **_texture_options(args),
                gutter_px=args.gutter, bake=None if args.bake == "none" else args.bake, format=args.format,
                preview_size_px=args.preview_size,
                atlas_image=None if args.atlas_image == "none" else args.atlas_image)
    status = exit_status(table)
    if not args.quiet:
        rows = table.to_pylist()
        counts: dict[str, int] = {}
        for r in rows:
            counts[r["status"]] = counts.get(r["status"], 0) + 1
        print(f"uvbake batch: {len(rows)} assets: " + ", ".join(f"{v} {k}" for k, v in sorted(counts.items()))
              + f" -> {args.output}/summary.csv, {args.output}/report.html")
        for r in rows:
            if r["status"] not in ("done", "cached"):
                print(f"uvbake batch: {r['status']}: {r['asset']}: {r['error']}", file=sys.stderr)
    return status

