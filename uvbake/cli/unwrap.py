"""``uvbake [unwrap] MESH``: unwrap a mesh into a textured atlas (the default command).

    uvbake MESH [--alpha A] [--bake checker.png] [-o OUT.obj|OUT.glb] [--json R.json] [...]
    uvbake unwrap MESH [...]    the same; needed only for a mesh file named like a command

Output files are written atomically and never replace the input. Exit codes: :mod:`uvbake.cli.common`.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from uvbake.analysis.crosscheck import cross_check_charts
from uvbake.atlas.pipeline import check_texture, unwrap
from uvbake.atlas.shapepack import mip_gutter_px
from uvbake.cli.progress import Progress
from uvbake.errors import InputError
from uvbake.flatten.options import BACKENDS, DEFAULTS
from uvbake.flatten.starts import INITS
from uvbake.io.atomic import atomic_write
from uvbake.io.export import save_png
from uvbake.pictures import atlas_image
from uvbake.render import LIGHTING, preview, view_directions

DESCRIPTION = (
    "Unwrap a mesh into a texture atlas: flatten every chart with the weighted area/angle\n"
    "distortion minimiser (Levenberg-Marquardt), split charts until no triangle is flipped\n"
    "or overlapping, pack them, bake a texture and write the textured mesh and a report.\n"
    "Charts come from a per-face segment label (PLY face property 'segment', 'label', ...)\n"
    "and connected components."
)

EPILOG = (
    "examples:\n"
    "  uvbake scene.ply --alpha 0.5 --bake checker.png\n"
    "  uvbake scan.ply -o scan.glb --bake colors.png --texture-size 2048 --json report.json\n"
    "other commands: 'uvbake check MESH' validates a textured mesh's UVs; "
    "'uvbake sweep MESH --alphas 0:1:0.1' studies the alpha sensitivity; "
    "'uvbake batch INPUTS... -o OUTDIR' unwraps many meshes on Dask; "
    "'uvbake unwrap MESH' unwraps a mesh file named like a command."
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The arguments of ``uvbake [unwrap] MESH ...``."""
    from uvbake import __version__

    p.add_argument("--version", action="version", version=f"uvbake {__version__}",
                   help="print the version and exit")
    p.add_argument("mesh", help="input mesh (PLY, OBJ, OFF, GLB/GLTF, STL)")
    p.add_argument("-o", "--output", help="textured mesh to write, .obj (with .mtl and .png) or .glb "
                                          "(default: MESH_uv.obj next to the input)")
    g = p.add_argument_group("flattening")
    g.add_argument("--alpha", type=float, default=DEFAULTS.alpha,
                   help=f"weight of area preservation in [0, 1]; 1 - alpha weighs angles (default {DEFAULTS.alpha})")
    g.add_argument("--init", default=DEFAULTS.init, choices=INITS, help=f"start map (default {DEFAULTS.init})")
    g.add_argument("--backend", default=DEFAULTS.backend, choices=BACKENDS,
                   help="lm: Levenberg-Marquardt, full Hessian (default); lbfgs: nlopt L-BFGS")
    g.add_argument("--cross-check", action="store_true",
                   help="also solve every chart with the other backend and fail if they disagree")
    g.add_argument("--tol", type=float, default=DEFAULTS.tol,
                   help=f"scale-free gradient norm to reach (default {DEFAULTS.tol:g})")
    g.add_argument("--max-iter", type=int, default=DEFAULTS.max_iter,
                   help=f"iteration cap per chart (default {DEFAULTS.max_iter})")
    g.add_argument("--seed", type=int, default=DEFAULTS.seed, help=f"seed of --init random (default {DEFAULTS.seed})")
    g.add_argument("--workers", type=int, default=None, help="charts solved in parallel (default: CPU count)")
    g = p.add_argument_group("guarantees")
    g.add_argument("--no-auto-cut", action="store_true",
                   help="refuse closed charts and charts with handles instead of cutting them into disks")
    g.add_argument("--no-repair", action="store_true",
                   help="refuse non-manifold input instead of repairing it (bowties, specks, duplicates)")
    g.add_argument("--paper", action="store_true",
                   help="the paper's formulation as is: charts from labels and disk cuts only, no distortion "
                        "budget, no injective solve (flips, overlaps and starved triangles are reported, not "
                        "removed) and no continuation from invalid starts")
    g.add_argument("--max-stretch", type=float, default=None, metavar="S",
                   help="distortion budget: every triangle keeps at least 1/S of its chart's texel density "
                        "(charts are cut before solving so they can; default 4)")
    g.add_argument("--max-charts", type=int, default=None, metavar="N",
                   help="chart budget: stop cutting for the distortion budget at N charts (the guarantee's "
                        "splits may still add some)")
    g.add_argument("--weld", action="store_true",
                   help="weld coincident boundary vertices (default: only for triangle soups; a mesh's own "
                        "cuts stay cuts)")
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
    g.add_argument("--keep-vertex-colors", action="store_true",
                   help="also write the vertex colours into the mesh file (viewers multiply them with the "
                        "texture, so a colour bake shows its colours twice); default: the texture alone")
    g = p.add_argument_group("pictures")
    g.add_argument("--preview", metavar="PNG", help="render the textured mesh (the checker when nothing is baked) "
                                                    "into this PNG, views side by side (Open3D offscreen, headless)")
    g.add_argument("--preview-size", type=int, default=256, metavar="PX",
                   help="side of each preview view in pixels, 32 to 2048 (default 256)")
    g.add_argument("--preview-views", default="front,back,angle", metavar="VIEWS",
                   help="comma-separated views from front, back, angle, or turntable:N for N views around "
                        "the vertical axis (default front,back,angle)")
    g.add_argument("--preview-lighting", choices=LIGHTING, default="unlit",
                   help="unlit: the texture's own colours (default); lit: shaded by a sun light, to see the shape")
    g.add_argument("--atlas-image", metavar="PNG",
                   help="draw the atlas into this PNG: charts in colour, seams as lines, and a legend with the "
                        "chart count, packing and worst distortion")
    g.add_argument("--atlas-image-size", type=int, default=512, metavar="PX",
                   help="side of the atlas picture in pixels, 16 to 4096 (default 512)")
    p.add_argument("--json", metavar="REPORT", help="write the JSON report here")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar, no summary")


def output_path(mesh: str, output: str | None, *, suffix: str = "_uv", ext: str = ".obj") -> Path:
    """The output path: the one given, or MESH<suffix><ext> beside the input; never the input itself."""
    src = Path(mesh)
    out = Path(output) if output else src.with_name(src.stem + suffix + ext)
    if out.exists() and src.exists() and out.resolve() == src.resolve():
        raise InputError(f"output {out} is the input mesh; choose another output path with -o")
    if not out.parent.exists():
        raise InputError(f"output folder {out.parent} does not exist; create it or choose another path with -o")
    if out.exists() and out.is_dir():
        raise InputError(f"output {out} is a folder; give a file name with -o")
    return out


@dataclass
class _Outputs:
    mesh: Path
    report: Path | None
    bake: Path | None
    bake_mode: str | None
    preview: Path | None
    atlas: Path | None


def _bake_output(args: argparse.Namespace) -> tuple[Path | None, str | None]:
    if args.bake or args.bake_mode:
        bake_path = output_path(args.mesh, args.bake, suffix="_texture", ext=".png")
        if bake_path.suffix.lower() != ".png":
            raise InputError(f"--bake {bake_path} must end in .png")
        name = bake_path.stem.lower()
        return bake_path, args.bake_mode or ("vertex-colors" if ("color" in name or "colour" in name) else "checker")
    if args.preview:
        return None, "checker"                    # a preview of an untextured atlas shows the checker
    return None, None


def _check_atlas_args(args: argparse.Namespace) -> None:
    if args.texture_size is None and args.texel_density is None:
        args.texture_size = 1024
    if args.texel_density is not None and not args.texel_density > 0:      # also NaN
        raise InputError(f"--texel-density {args.texel_density} must be a positive number of texels per unit")
    if args.mip_levels is not None:
        if not 1 <= args.mip_levels <= 8:
            raise InputError(f"--mip-levels {args.mip_levels} must be from 1 to 8")
        need = mip_gutter_px(args.mip_levels)
        if args.gutter is not None and args.gutter < need:
            raise InputError(f"--gutter {args.gutter} is less than the {need} texels --mip-levels "
                             f"{args.mip_levels} needs; leave --gutter out or raise it")
    check_texture(args.texture_size, args.gutter, args.texel_density)


def _outputs(args: argparse.Namespace) -> _Outputs:
    """Every output path, checked before any work: right suffixes, distinct, never the input."""
    if args.workers is not None and args.workers < 1:
        raise InputError(f"--workers {args.workers} must be at least 1")
    _check_atlas_args(args)
    out = output_path(args.mesh, args.output)
    if out.suffix.lower() not in (".obj", ".glb"):
        raise InputError(f"output {out} must end in .obj or .glb")
    report_path = output_path(args.mesh, args.json, suffix="_report", ext=".json") if args.json else None
    bake_path, mode = _bake_output(args)
    preview_path, atlas_path = _picture_outputs(args)
    outputs = [out] + ([out.with_suffix(".mtl"), out.with_suffix(".png")] if out.suffix.lower() == ".obj" else [])
    outputs += [p for p in (report_path, bake_path, preview_path, atlas_path) if p is not None]
    if len({p.resolve() for p in outputs}) < len(outputs):
        raise InputError(f"two outputs share one path ({', '.join(str(p) for p in outputs)}); "
                         "give -o, --json and --bake different names")
    if Path(args.mesh).exists() and Path(args.mesh).resolve() in {p.resolve() for p in outputs}:
        raise InputError(f"an output would replace the input {args.mesh}; choose other output names")
    return _Outputs(out, report_path, bake_path, mode, preview_path, atlas_path)


def _picture_outputs(args: argparse.Namespace) -> tuple[Path | None, Path | None]:
    """--preview and --atlas-image paths and options, checked before the solve."""
    preview_path = output_path(args.mesh, args.preview, suffix="_preview", ext=".png") if args.preview else None
    atlas_path = output_path(args.mesh, args.atlas_image, suffix="_atlas", ext=".png") if args.atlas_image else None
    for flag, path in (("--preview", preview_path), ("--atlas-image", atlas_path)):
        if path is not None and path.suffix.lower() != ".png":
            raise InputError(f"{flag} {path} must end in .png")
    if preview_path is not None:
        view_directions([v.strip() for v in args.preview_views.split(",")])
        if not 32 <= args.preview_size <= 2048:
            raise InputError(f"--preview-size {args.preview_size} must be from 32 to 2048 pixels")
    if atlas_path is not None and not 16 <= args.atlas_image_size <= 4096:
        raise InputError(f"--atlas-image-size {args.atlas_image_size} must be from 16 to 4096 pixels")
    return preview_path, atlas_path


def _solve(args: argparse.Namespace, mode: str | None) -> Any:
    bar = Progress(quiet=args.quiet)
    result = unwrap(args.mesh, alpha=args.alpha, init=args.init, backend=args.backend, tol=args.tol,
                    max_iter=args.max_iter, seed=args.seed, texture_size_px=args.texture_size,
                    gutter_px=args.gutter, texel_density=args.texel_density, mip_levels=args.mip_levels,
                    bake=mode, auto_cut=not args.no_auto_cut, repair=not args.no_repair,
                    guarantee=not args.paper, continuation=not args.paper, workers=args.workers,
                    max_stretch=args.max_stretch, max_charts=args.max_charts, weld=True if args.weld else None,
                    progress=bar.stage, callback=bar.iteration)
    if args.cross_check:
        result.report["cross_check"] = cross_check_charts(result.charts, result.results, alpha=args.alpha,
                                                          init=args.init, tol=args.tol, max_iter=args.max_iter,
                                                          seed=args.seed, raise_on_disagree=False)
    bar.close()
    return result


def _write(result: Any, paths: _Outputs, args: argparse.Namespace, t0: float) -> list[Path]:
    written = list(result.save(paths.mesh, keep_vertex_colors=args.keep_vertex_colors))
    if paths.bake is not None:
        save_png(paths.bake, result.image)
        written.append(paths.bake)
    if paths.preview is not None:
        preview(result, path=paths.preview, size_px=args.preview_size, lighting=args.preview_lighting,
                views=[v.strip() for v in args.preview_views.split(",")])
        written.append(paths.preview)
    if paths.atlas is not None:
        save_png(paths.atlas, atlas_image(result, size_px=args.atlas_image_size))
        written.append(paths.atlas)
    result.report["outputs"] = [str(p) for p in written] + ([str(paths.report)] if paths.report else [])
    result.report["timings"]["cli_total_s"] = time.perf_counter() - t0
    if paths.report is not None:
        with atomic_write(paths.report) as fh:
            json.dump(result.report, fh, indent=1)
    return written


def _summary(rep: dict[str, Any], alpha: float, written: list[Path]) -> None:
    atlas = rep["atlas"]
    print(f"uvbake: {rep['triangles']} triangles -> {rep['charts_final']} chart(s) "
          f"({rep['charts_input']} before cuts and splits), alpha {alpha}; "
          f"atlas {'valid' if rep['valid'] else 'NOT valid'}, packing {100 * atlas.get('efficiency', 0):.1f}% "
          f"of {atlas['texture_size_px']} px at {atlas.get('texel_density', 0):.4g} px/unit, "
          f"{rep['timings']['cli_total_s']:.2f} s -> {', '.join(str(p) for p in written)}")
    print(f"uvbake: {certificate_summary(rep['charts'])}")
    for w in (rep.get("repair") or {}).get("warnings", []):
        print(f"uvbake: warning: {w}", file=sys.stderr)
    for c in rep["charts"]:
        if not c["converged"]:
            print(f"uvbake: warning: {c['name']} stopped before convergence ({c['stop_reason']}, "
                  f"|grad| {c['grad_norm']:.2e} after {c['iterations']} iterations); raise --max-iter",
                  file=sys.stderr)


def certificate_summary(charts: list[dict[str, Any]]) -> str:
    """One line from the per-chart certificates of the JSON report: 'local minimum: yes, lambda_min = ...'
    (the smallest over charts)."""
    lams = [c["lambda_min"] for c in charts if c.get("is_local_minimum") is not None]
    if not lams:
        return "local minimum: not certified"
    bad = sum(1 for c in charts if c.get("is_local_minimum") is False)
    word = "yes" if bad == 0 else f"no ({bad} of {len(charts)} charts not a certified minimum)"
    return f"local minimum: {word}, lambda_min = {min(lams):.3g}"


def run(args: argparse.Namespace) -> int:
    """``uvbake [unwrap] MESH ...``: unwrap, bake, write; the exit status (1 when the atlas is not valid)."""
    t0 = time.perf_counter()
    paths = _outputs(args)
    result = _solve(args, paths.bake_mode)
    written = _write(result, paths, args, t0)
    rep = result.report
    if not args.quiet:
        _summary(rep, args.alpha, written)
    if args.cross_check and not rep["cross_check"]["agree"]:
        print(f"uvbake: failed: the backends disagree: {rep['cross_check']['message']}", file=sys.stderr)
        return 1
    if not rep["valid"] and not args.paper:
        print("uvbake: failed: the atlas still has flipped or overlapping triangles (see the report)",
              file=sys.stderr)
        return 1
    return 0
