"""The ``uvbake`` command.

    uvbake MESH [--alpha A] [--bake checker.png] [-o OUT.obj|OUT.glb] [--json R.json] [...]
    uvbake check MESH [...]     validate the UVs of a textured mesh (see ``uvbake check --help``)
    uvbake sweep MESH [...]     alpha sensitivity study (see ``uvbake sweep --help``)
    uvbake batch INPUTS... -o OUTDIR   many meshes on Dask (see ``uvbake batch --help``)

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

SUBCOMMANDS = {"check": "uvbake.cli.check", "sweep": "uvbake.cli.sweep", "batch": "uvbake.cli.batch"}


def _parser():
    p = argparse.ArgumentParser(
        prog="uvbake",
        description="Unwrap a mesh into a texture atlas: flatten every chart with the weighted area/angle\n"
                    "distortion minimiser (Levenberg-Marquardt), split charts until no triangle is flipped\n"
                    "or overlapping, pack them, bake a texture and write the textured mesh and a report.\n"
                    "Charts come from a per-face segment label (PLY face property 'segment', 'label', ...)\n"
                    "and connected components.",
        epilog="examples:\n"
               "  uvbake scene.ply --alpha 0.5 --bake checker.png\n"
               "  uvbake scan.ply -o scan.glb --bake colors.png --texture-size 2048 --json report.json\n"
               "other commands: 'uvbake check MESH' validates a textured mesh's UVs; "
               "'uvbake sweep MESH --alphas 0:1:0.1' studies the alpha sensitivity; "
               "'uvbake batch INPUTS... -o OUTDIR' unwraps many meshes on Dask.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("mesh", help="input mesh (PLY, OBJ, OFF, GLB/GLTF, STL)")
    p.add_argument("-o", "--output", help="textured mesh to write, .obj (with .mtl and .png) or .glb "
                                          "(default: MESH_uv.obj next to the input)")
    g = p.add_argument_group("flattening")
    g.add_argument("--alpha", type=float, default=0.5,
                   help="weight of area preservation in [0, 1]; 1 - alpha weighs angles (default 0.5)")
    g.add_argument("--init", default="lscm", choices=["lscm", "tutte", "random"], help="start map (default lscm)")
    g.add_argument("--backend", default="lm", choices=["lm", "lbfgs"],
                   help="lm: Levenberg-Marquardt, full Hessian (default); lbfgs: nlopt L-BFGS")
    g.add_argument("--cross-check", action="store_true",
                   help="also solve every chart with the other backend and fail if they disagree")
    g.add_argument("--tol", type=float, default=1e-8, help="scale-free gradient norm to reach (default 1e-8)")
    g.add_argument("--max-iter", type=int, default=1000, help="iteration cap per chart (default 1000)")
    g.add_argument("--seed", type=int, default=0, help="seed of --init random (default 0)")
    g.add_argument("--workers", type=int, default=None, help="charts solved in parallel (default: CPU count)")
    g = p.add_argument_group("guarantees")
    g.add_argument("--no-auto-cut", action="store_true",
                   help="refuse closed charts and charts with handles instead of cutting them into disks")
    g.add_argument("--no-repair", action="store_true",
                   help="refuse non-manifold input instead of repairing it (bowties, specks, duplicates)")
    g.add_argument("--paper", action="store_true",
                   help="the paper's formulation as is: no chart splitting (flips and overlaps are reported, "
                        "not removed) and no continuation from invalid starts")
    g = p.add_argument_group("atlas and texture")
    g.add_argument("--texture-size", type=int, default=None, metavar="PX",
                   help="texture side in texels (default 1024; with --texel-density the texture grows to fit)")
    g.add_argument("--gutter", type=int, default=None, metavar="PX",
                   help="gap between charts in texels (default 4, or what --mip-levels needs)")
    g.add_argument("--texel-density", type=float, default=None, metavar="PX_PER_UNIT",
                   help="fixed texels per world unit, the same across assets (the texture grows to fit, or with "
                        "--texture-size the command says it cannot fit)")
    g.add_argument("--mip-levels", type=int, default=None, metavar="N",
                   help="keep charts from bleeding into each other under bilinear filtering of the first N mip "
                        "levels (the baked gutters are dilated): gutter 6, 10, 19, 36 texels for N = 1..4")
    g.add_argument("--bake", metavar="PNG", help="bake a texture to this PNG: a checkerboard, or the vertex "
                                                 "colours when the name contains 'color'/'colour'")
    g.add_argument("--bake-mode", choices=["checker", "vertex-colors"], help="what --bake bakes (overrides the name)")
    g.add_argument("--preview", metavar="PNG", help="render the textured mesh from the front, the back and an angle "
                                                    "into this PNG (Open3D offscreen, headless)")
    p.add_argument("--json", metavar="REPORT", help="write the JSON report here")
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
        from uvbake.errors import InputError, UvbakeError

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
    from uvbake.errors import InputError

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
    from uvbake.atlas.pipeline import _check_texture, unwrap
    from uvbake.errors import InputError

    t0 = time.perf_counter()
    if args.workers is not None and args.workers < 1:
        raise InputError(f"--workers {args.workers} must be at least 1")
    if args.texture_size is None and args.texel_density is None:
        args.texture_size = 1024
    if args.texel_density is not None and not args.texel_density > 0:      # also NaN
        raise InputError(f"--texel-density {args.texel_density} must be a positive number of texels per unit")
    if args.mip_levels is not None:
        from uvbake.atlas.shapepack import mip_gutter_px

        if not 1 <= args.mip_levels <= 8:
            raise InputError(f"--mip-levels {args.mip_levels} must be from 1 to 8")
        need = mip_gutter_px(args.mip_levels)
        if args.gutter is not None and args.gutter < need:
            raise InputError(f"--gutter {args.gutter} is less than the {need} texels --mip-levels "
                             f"{args.mip_levels} needs; leave --gutter out or raise it")
    _check_texture(args.texture_size, args.gutter, args.texel_density)
    out = output_path(args.mesh, args.output)
    if out.suffix.lower() not in (".obj", ".glb"):
        raise InputError(f"output {out} must end in .obj or .glb")
    report_path = output_path(args.mesh, args.json, suffix="_report", ext=".json") if args.json else None
    bake_path, mode = None, None
    if args.bake or args.bake_mode:
        bake_path = output_path(args.mesh, args.bake, suffix="_texture", ext=".png")
        if bake_path.suffix.lower() != ".png":
            raise InputError(f"--bake {bake_path} must end in .png")
        name = bake_path.stem.lower()
        mode = args.bake_mode or ("vertex-colors" if ("color" in name or "colour" in name) else "checker")
    elif args.preview:
        mode = "checker"                    # a preview of an untextured atlas shows the checker
    preview_path = output_path(args.mesh, args.preview, suffix="_preview", ext=".png") if args.preview else None
    outputs = [out] + ([out.with_suffix(".mtl"), out.with_suffix(".png")] if out.suffix.lower() == ".obj" else [])
    outputs += [p for p in (report_path, bake_path, preview_path) if p is not None]
    if len({p.resolve() for p in outputs}) < len(outputs):
        raise InputError(f"two outputs share one path ({', '.join(str(p) for p in outputs)}); "
                         "give -o, --json and --bake different names")
    if Path(args.mesh).exists() and Path(args.mesh).resolve() in {p.resolve() for p in outputs}:
        raise InputError(f"an output would replace the input {args.mesh}; choose other output names")

    bar = _progress(quiet=args.quiet)

    def on_stage(stage, done, total):
        if bar is not None:
            bar.set_description_str(f"uvbake {stage}", refresh=False)
            if stage == "solve":
                bar.total = total
                bar.n = done
            bar.refresh()

    def on_iteration(info):
        if bar is not None:
            bar.set_postfix_str(f"iter {info['iteration']} |grad| {info['grad_norm']:.1e}", refresh=False)

    result = unwrap(args.mesh, alpha=args.alpha, init=args.init, backend=args.backend, tol=args.tol,
                    max_iter=args.max_iter, seed=args.seed, texture_size_px=args.texture_size,
                    gutter_px=args.gutter, texel_density=args.texel_density, mip_levels=args.mip_levels,
                    bake=mode, auto_cut=not args.no_auto_cut, repair=not args.no_repair,
                    guarantee=not args.paper, continuation=not args.paper, workers=args.workers,
                    progress=on_stage, callback=on_iteration)
    if args.cross_check:
        from uvbake.analysis.crosscheck import cross_check_charts

        result.report["cross_check"] = cross_check_charts(result.charts, result.results, alpha=args.alpha,
                                                          init=args.init, tol=args.tol, max_iter=args.max_iter,
                                                          seed=args.seed, raise_on_disagree=False)
    if bar is not None:
        bar.close()
    written = result.save(out)
    if bake_path is not None:
        from uvbake.io.export import save_png

        save_png(bake_path, result.image)
        written = list(written) + [bake_path]
    if preview_path is not None:
        from uvbake.render import preview

        preview(result, path=preview_path)
        written = list(written) + [preview_path]
    result.report["outputs"] = [str(p) for p in written] + ([str(report_path)] if report_path else [])
    result.report["timings"]["cli_total_s"] = time.perf_counter() - t0
    if report_path is not None:
        from uvbake.io.atomic import atomic_write

        with atomic_write(report_path) as fh:
            json.dump(result.report, fh, indent=1)
    rep = result.report
    if not args.quiet:
        atlas = rep["atlas"]
        print(f"uvbake: {rep['triangles']} triangles -> {rep['charts_final']} chart(s) "
              f"({rep['charts_input']} before cuts and splits), alpha {args.alpha}; "
              f"atlas {'valid' if rep['valid'] else 'NOT valid'}, packing {100 * atlas.get('efficiency', 0):.1f}% "
              f"of {atlas['texture_size_px']} px at {atlas.get('texel_density', 0):.4g} px/unit, "
              f"{rep['timings']['cli_total_s']:.2f} s -> {', '.join(str(p) for p in written)}")
        for w in (rep.get("repair") or {}).get("warnings", []):
            print(f"uvbake: warning: {w}", file=sys.stderr)
        for c in rep["charts"]:
            if not c["converged"]:
                print(f"uvbake: warning: {c['name']} stopped before convergence ({c['stop_reason']}, "
                      f"|grad| {c['grad_norm']:.2e} after {c['iterations']} iterations); raise --max-iter",
                      file=sys.stderr)
    if args.cross_check and not rep["cross_check"]["agree"]:
        print(f"uvbake: failed: the backends disagree: {rep['cross_check']['message']}", file=sys.stderr)
        return 1
    if not rep["valid"] and not args.paper:
        print("uvbake: failed: the atlas still has flipped or overlapping triangles (see the report)",
              file=sys.stderr)
        return 1
    return 0


def _progress(*, quiet):
    if quiet:
        return None
    from tqdm import tqdm

    # disable=None: shown on a terminal, silent when stderr is a pipe or a CI log
    return tqdm(total=1, unit="chart", desc="uvbake", disable=None, leave=False, file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
