"""``uvbake [unwrap] MESH``: unwrap a mesh into a textured atlas (the default command).

    uvbake MESH [--alpha A] [--bake checker.png] [-o OUT.obj|OUT.glb] [--json R.json] [...]
    uvbake unwrap MESH [...]    the same; needed only for a mesh file named like a command

Every output is checked before any work, written to a temporary file beside it, and all are renamed
into place together at the end, or none (:class:`uvbake.io.atomic.OutputSet`); a run whose atlas fails
validation writes only its report unless ``--keep-invalid``. Exit codes: :mod:`uvbake.cli.common`.

The parser is built from light modules only (option defaults and choices); the pipeline, numpy and
scipy are imported by the functions that run it, so ``uvbake --help`` answers at once.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from uvbake.cli.progress import Progress
from uvbake.errors import InputError
from uvbake.flatten.options import BACKENDS, DEFAULTS, INITS
from uvbake.io.atomic import OutputSet
from uvbake.views import LIGHTING

DESCRIPTION = (
    "Unwrap a mesh into a texture atlas: cut it into charts under a distortion budget\n"
    "(--max-stretch) before solving, flatten every chart by minimising the weighted\n"
    "area/angle distortion (second-order, full Hessian), prove that no triangle is flipped or\n"
    "overlapping, pack the charts, bake a texture and write the textured mesh and a report.\n"
    "Charts come from a per-face segment label (PLY face property 'segment', 'label', ...;\n"
    "an OBJ file's materials), connected components and the distortion budget."
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


def _typed(kind: type, lo: float | None = None, hi: float | None = None, *, open_lo: bool = False) -> Any:
    """An argparse type: a number of ``kind`` within [lo, hi] (lo excluded with ``open_lo``), so that a
    bad value is a one-line error naming the flag, before any work."""
    def parse(text: str) -> Any:
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"{text!r} is not {'a whole number' if kind is int else 'a number'}") from None
        low = lo is not None and (value <= lo if open_lo else value < lo)
        if value != value or value in (float("inf"), float("-inf")) or low or (hi is not None and value > hi):
            bound = f"{'above' if open_lo else 'at least'} {lo}" if hi is None else f"within [{lo}, {hi}]"
            raise argparse.ArgumentTypeError(f"{text} must be {bound}")
        return value
    parse.__name__ = kind.__name__
    return parse


def texture_size(text: str) -> int | tuple[int, int]:
    """argparse type of --texture-size: ``PX`` (a square texture) or ``WxH``, each 16..16384 texels."""
    parts = text.lower().split("x")
    side = _typed(int, 16, 16384)
    if len(parts) == 1:
        return side(parts[0])
    if len(parts) != 2:
        raise argparse.ArgumentTypeError(f"{text!r} is not PX or WIDTHxHEIGHT (e.g. 1024 or 2048x1024)")
    W, H = side(parts[0]), side(parts[1])
    return W if W == H else (W, H)


texture_size.__name__ = "size"


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The arguments of ``uvbake [unwrap] MESH ...``."""
    from uvbake import __version__

    p.add_argument("--version", action="version", version=f"uvbake {__version__}",
                   help="print the version and exit")
    p.add_argument("mesh", help="input mesh (PLY, OBJ, OFF, GLB/GLTF, STL)")
    p.add_argument("-o", "--output", help="textured mesh to write, .obj (with .mtl and .png) or .glb "
                                          "(default: MESH_uv.obj next to the input)")
    g = p.add_argument_group("flattening")
    g.add_argument("--alpha", type=_typed(float, 0.0, 1.0), default=DEFAULTS.alpha,
                   help=f"weight of area preservation in [0, 1]; 1 - alpha weighs angles (default {DEFAULTS.alpha})")
    g.add_argument("--init", default=DEFAULTS.init, choices=INITS, help=f"start map (default {DEFAULTS.init})")
    g.add_argument("--backend", default=DEFAULTS.backend, choices=BACKENDS,
                   help="lm: full-Hessian Newton, trust-region steps (default; the paper's "
                        "Levenberg-Marquardt damping is step='damped' in Python); lbfgs: nlopt L-BFGS")
    g.add_argument("--cross-check", action="store_true",
                   help="also solve every chart with the other backend and fail if they disagree")
    g.add_argument("--tol", type=_typed(float, 0.0, open_lo=True), default=DEFAULTS.tol,
                   help=f"scale-free gradient norm to reach (default {DEFAULTS.tol:g})")
    g.add_argument("--max-iter", type=_typed(int, 0), default=DEFAULTS.max_iter,
                   help=f"iteration cap per chart (default {DEFAULTS.max_iter})")
    g.add_argument("--seed", type=_typed(int, 0, 2**32 - 1), default=DEFAULTS.seed, help=f"seed of --init random (default {DEFAULTS.seed})")
    g.add_argument("--workers", type=_typed(int, 1), default=None, help="charts solved in parallel (default: the CPU count when two charts or more "
                   "have 5000+ triangles, else one at a time)")
    g = p.add_argument_group("guarantees")
    g.add_argument("--no-auto-cut", action="store_true",
                   help="refuse closed charts and charts with handles instead of cutting them into disks")
    g.add_argument("--no-repair", action="store_true",
                   help="refuse non-manifold input instead of repairing it (bowties, specks, duplicates)")
    g.add_argument("--no-pack-splits", action="store_true",
                   help="never cut a large chart in two to pack the atlas denser (fewer seams)")
    g.add_argument("--paper", action="store_true",
                   help="the paper's formulation as is: charts from labels and disk cuts only, no distortion "
                        "budget, no injective solve (flips, overlaps and starved triangles are reported, not "
                        "removed) and no continuation from invalid starts")
    g.add_argument("--max-stretch", type=_typed(float, 1.0, open_lo=True), default=None, metavar="S",
                   help="distortion budget: every triangle keeps at least 1/S of its chart's texel density "
                        "(charts are cut before solving so they can; 1/S^2 after the solve) and its "
                        "angle distortion sigma1/sigma2 stays at most S^2; default 4")
    g.add_argument("--max-charts", type=_typed(int, 1), default=None, metavar="N",
                   help="chart budget: stop cutting for the distortion budget at N charts (charts whose "
                        "conformal map collapses triangles are still cut, and the guarantee's splits may add some)")
    g.add_argument("--ignore-materials", action="store_true",
                   help="let charts span OBJ materials (default: faces under two or more 'usemtl' materials "
                        "are labelled by material, so no chart spans two)")
    g.add_argument("--weld", action="store_true",
                   help="weld coincident boundary vertices (default: only for triangle soups; a mesh's own "
                        "cuts stay cuts)")
    g = p.add_argument_group("atlas and texture")
    g.add_argument("--texture-size", type=texture_size, default=None, metavar="PX|WxH",
                   help="texture side in texels, or WIDTHxHEIGHT for a rectangular texture (default 1024; with "
                        "--texel-density the texture grows to fit)")
    g.add_argument("--gutter", type=_typed(int, 0), default=None, metavar="PX",
                   help="gap between charts in texels (default 4, or what --mip-levels needs)")
    g.add_argument("--texel-density", type=_typed(float, 0.0, open_lo=True), default=None, metavar="PX_PER_UNIT",
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
    p.add_argument("--force", action="store_true", help="replace read-only output files")
    p.add_argument("--keep-invalid", action="store_true",
                   help="write the outputs even when the atlas fails validation (by default only the report)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar, no summary")


def output_path(mesh: str, output: str | None, *, suffix: str = "_uv", ext: str = ".obj") -> Path:
    """The output path: the one given, or MESH<suffix><ext> beside the input (checked by OutputSet)."""
    src = Path(mesh)
    return Path(output) if output else src.with_name(src.stem + suffix + ext)


def _check_input(mesh: str) -> None:
    path = Path(mesh)
    if not path.exists():
        raise InputError(f"MESH {mesh}: file not found; check the path")
    if path.is_dir():
        raise InputError(f"MESH {mesh} is a folder, not a mesh file; pass the path of a mesh file")


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
    from uvbake.atlas.pipeline import check_texture
    from uvbake.atlas.shapepack import mip_gutter_px
    if args.texture_size is None and args.texel_density is None:
        args.texture_size = 1024
    if args.mip_levels is not None:
        if not 1 <= args.mip_levels <= 8:
            raise InputError(f"--mip-levels {args.mip_levels} must be from 1 to 8")
        need = mip_gutter_px(args.mip_levels)
        if args.gutter is not None and args.gutter < need:
            raise InputError(f"--gutter {args.gutter} is less than the {need} texels --mip-levels "
                             f"{args.mip_levels} needs; leave --gutter out or raise it")
        if args.gutter is None and args.texture_size is not None:
            _check_mip_room(args, need)
    if args.gutter is not None and args.texture_size is not None:
        short = min(args.texture_size) if isinstance(args.texture_size, tuple) else args.texture_size
        if args.gutter > short // 8:
            from uvbake.atlas.pipeline import size_text

            side = "'s shorter side" if isinstance(args.texture_size, tuple) else ""
            raise InputError(f"--gutter {args.gutter} must be at most {short // 8} "
                             f"(an eighth of --texture-size {size_text(args.texture_size)}{side})")
    check_texture(args.texture_size, args.gutter, args.texel_density)


def _check_mip_room(args: argparse.Namespace, need: int) -> None:
    """The gutter --mip-levels derives held to an eighth of --texture-size, as --gutter is."""
    from uvbake.atlas.pipeline import mip_levels_within, mip_room, size_text

    short = min(args.texture_size) if isinstance(args.texture_size, tuple) else args.texture_size
    if need > short // 8:
        most = mip_levels_within(short // 8)
        side = "'s shorter side" if isinstance(args.texture_size, tuple) else ""
        fewer = f"use --mip-levels {most} or fewer, or" if most else "use"
        raise InputError(f"--mip-levels {args.mip_levels} needs a {need}-texel gutter, more than {short // 8} (an "
                         f"eighth of --texture-size {size_text(args.texture_size)}{side}); {fewer} a "
                         f"--texture-size of at least {mip_room(args.mip_levels, need)}")


def _outputs(args: argparse.Namespace) -> _Outputs:
    """Every output path, with the right suffix (the targets themselves are checked by OutputSet)."""
    _check_input(args.mesh)
    _check_atlas_args(args)
    out = output_path(args.mesh, args.output)
    if out.exists() and Path(args.mesh).exists() and out.samefile(args.mesh):
        raise InputError(f"output -o {out} is the input; choose another output path")
    if out.suffix.lower() not in (".obj", ".glb"):
        raise InputError(f"-o {out} must end in .obj or .glb")
    report_path = output_path(args.mesh, args.json, suffix="_report", ext=".json") if args.json else None
    bake_path, mode = _bake_output(args)
    preview_path, atlas_path = _picture_outputs(args)
    return _Outputs(out, report_path, bake_path, mode, preview_path, atlas_path)


def _picture_outputs(args: argparse.Namespace) -> tuple[Path | None, Path | None]:
    """--preview and --atlas-image paths and options, checked before the solve."""
    from uvbake.render import view_directions
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


def _targets(paths: _Outputs) -> list[tuple[str, Path]]:
    """Every file the run may write, with the flag that named it (for messages)."""
    from uvbake.io.export import textured_paths
    targets = [("-o", p) for p in textured_paths(paths.mesh)]
    targets += [(flag, p) for flag, p in (("--json", paths.report), ("--bake", paths.bake),
                                          ("--preview", paths.preview), ("--atlas-image", paths.atlas))
                if p is not None]
    return targets


def unwrap(source: Any, **options: Any) -> Any:
    """:func:`uvbake.unwrap`, imported when a run starts (the parser stays light); the one call a run makes."""
    from uvbake.atlas.pipeline import unwrap as pipeline_unwrap

    return pipeline_unwrap(source, **options)


def _solve(args: argparse.Namespace, mode: str | None) -> Any:
    from uvbake.analysis.crosscheck import cross_check_charts

    bar = Progress(quiet=args.quiet)
    result = unwrap(args.mesh, alpha=args.alpha, init=args.init, backend=args.backend, tol=args.tol,
                    max_iter=args.max_iter, seed=args.seed, texture_size_px=args.texture_size,
                    gutter_px=args.gutter, texel_density=args.texel_density, mip_levels=args.mip_levels,
                    bake=mode, auto_cut=not args.no_auto_cut, repair=not args.no_repair,
                    guarantee=not args.paper, continuation=not args.paper, workers=args.workers,
                    max_stretch=args.max_stretch, max_charts=args.max_charts, weld=True if args.weld else None,
                    pack_splits=not args.no_pack_splits, materials=not args.ignore_materials,
                    progress=bar.stage, callback=bar.iteration)
    if args.cross_check:
        result.report["cross_check"] = cross_check_charts(result.charts, result.results, alpha=args.alpha,
                                                          init=args.init, tol=args.tol, max_iter=args.max_iter,
                                                          seed=args.seed, raise_on_disagree=False)
    bar.close()
    return result


def _stage_outputs(result: Any, paths: _Outputs, args: argparse.Namespace, outs: OutputSet) -> list[Path]:
    """Write the textured mesh, the baked texture and the preview to their temporary files."""
    from uvbake.atlas.pipeline import _blank, atlas_size
    from uvbake.io.export import png_bytes, textured_files
    from uvbake.pictures import atlas_image
    from uvbake.render import preview

    image = result.image if result.image is not None else _blank(atlas_size(result.report))
    files = textured_files(paths.mesh, result.V, result.F, result.corner_uv, image,
                           vertex_colors=result.vertex_colors if args.keep_vertex_colors else None)
    if paths.bake is not None:
        files[paths.bake] = png_bytes(result.image, paths.bake)
    if paths.preview is not None:
        files[paths.preview] = png_bytes(
            preview(result, size_px=args.preview_size, lighting=args.preview_lighting,
                    views=[v.strip() for v in args.preview_views.split(",")]), paths.preview)
    if paths.atlas is not None:
        files[paths.atlas] = png_bytes(atlas_image(result, size_px=args.atlas_image_size), paths.atlas)
    for p, data in files.items():
        outs.write_bytes(p, data)
    return list(files)


def _write(result: Any, paths: _Outputs, args: argparse.Namespace, outs: OutputSet, t0: float, *,
           write_all: bool) -> list[Path]:
    """Stage the outputs (all, or only the report) and commit them together."""
    staged = _stage_outputs(result, paths, args, outs) if write_all else []
    result.report["outputs"] = [str(p) for p in staged] + ([str(paths.report)] if paths.report else [])
    result.report["timings"]["cli_total_s"] = time.perf_counter() - t0
    if paths.report is not None:
        outs.write_bytes(paths.report, (json.dumps(result.report, indent=1) + "\n").encode("utf-8"))
    return outs.commit()


def _summary(rep: dict[str, Any], alpha: float, written: list[Path]) -> None:
    from uvbake.atlas.pipeline import atlas_size, size_text

    atlas = rep["atlas"]
    efficiency = atlas.get("efficiency", 0)
    # charts that overlap (an atlas left invalid, e.g. --paper) count the texels they share more than once
    twice = " (overlapping charts counted more than once)" if efficiency > 1 else ""
    print(f"uvbake: {rep['triangles']} triangles -> {rep['charts_final']} chart(s) "
          f"({rep['charts_input']} before cuts and splits), alpha {alpha}; "
          f"atlas {'valid' if rep['valid'] else 'NOT valid'}, packing {100 * efficiency:.1f}% "
          f"of {size_text(atlas_size(rep))} px{twice} at {atlas.get('texel_density', 0):.4g} px/unit, "
          f"{rep['timings']['cli_total_s']:.2f} s -> {', '.join(str(p) for p in written) or 'nothing written'}")
    print(f"uvbake: {certificate_summary(rep['charts'])}")
    budget = rep["options"].get("max_charts")
    if budget is not None and rep["charts_final"] > budget:
        why = Counter(s["reason"] for s in rep["splits"] if s["reason"] != "packing")
        split = ", ".join(f"{n} {reason}" for reason, n in sorted(why.items()))
        print(f"uvbake: note: --max-charts {budget} not kept: {rep['charts_final']} charts ({rep['charts_input']} from "
              f"charting" + (f"; split where charts {split}" if split else "") + "); a valid atlas comes first",
              file=sys.stderr)
    for w in (rep.get("repair") or {}).get("warnings", []) + _budget_warnings(rep):
        print(f"uvbake: warning: {w}", file=sys.stderr)
    for c in rep["charts"]:
        if not c["converged"]:
            print(f"uvbake: {_unconverged(c)}", file=sys.stderr)


def _unconverged(c: dict[str, Any]) -> str:
    """The line for a chart whose solve stopped before the gradient test, with the advice its stop calls
    for: more iterations only help a solve cut at --max-iter."""
    where = f"|grad| {c['grad_norm']:.2e} after {c['iterations']} iterations"
    if c["stop_reason"] == "roundoff limited":
        return (f"note: {c['name']} stopped where rounding hides further decrease of the energy ({where}; "
                f"thin triangles limit it)")
    if c["stop_reason"] == "step too small":
        return (f"note: {c['name']} stopped where no step lowers the energy any further ({where}): rounding, "
                f"or a triangle kept from folding over; more iterations would not help")
    advice = "; raise --max-iter" if c["stop_reason"] in ("max_iter", "max_eval") else ""
    return f"warning: {c['name']} stopped before convergence ({c['stop_reason']}, {where}){advice}"


def _budget_warnings(rep: dict[str, Any]) -> list[str]:
    """The distortion budget's promise, checked on the finished atlas: no triangle below 1/S^2 of its fair
    texel share (with the guarantee; only the guarantee's split cap can leave one)."""
    opts = rep.get("options", {})
    share = rep.get("min_texel_share")
    if not opts.get("guarantee") or opts.get("max_stretch") is None or share is None:
        return []
    floor = 1.0 / float(opts["max_stretch"]) ** 2
    if share >= floor * (1 - 1e-9):
        return []
    return [f"the distortion budget is not kept: a triangle has {share:.3g} of its fair texel share, under "
            f"1/S^2 = {floor:.3g} for --max-stretch {opts['max_stretch']:g} (the guarantee's split cap was "
            f"reached); allow more charts (--max-charts) or a looser --max-stretch"]


def certificate_summary(charts: list[dict[str, Any]]) -> str:
    """One line from the per-chart certificates of the JSON report: 'local minimum: yes, lambda_min = ...'
    (the smallest over charts)."""
    known = [c for c in charts if c.get("is_local_minimum") is not None]
    if not known:
        return "local minimum: not certified"
    # not certified: a saddle (converged, negative curvature) or a solve stopped before the gradient test
    saddles = sum(1 for c in known if c["is_local_minimum"] is False and c.get("converged", True))
    stopped = sum(1 for c in known if c["is_local_minimum"] is False and not c.get("converged", True))
    why = [f"{n} {w}" for n, w in ((saddles, "at a saddle"), (stopped, "stopped before the gradient test")) if n]
    word = "yes" if not why else \
        f"{'no' if saddles else 'not certified'} ({saddles + stopped} of {len(charts)} charts: {', '.join(why)})"
    # charts stopped at F's floor 0 (alpha = 1, or developable) are global minima and carry no lambda_min
    lams = [c["lambda_min"] for c in known if c.get("lambda_min") is not None]
    return f"local minimum: {word}" + (f", lambda_min = {min(lams):.3g}" if lams else ", global (F at its floor 0)")


def run(args: argparse.Namespace) -> int:
    """``uvbake [unwrap] MESH ...``: unwrap, bake, write; the exit status (1 when the atlas is not valid)."""
    t0 = time.perf_counter()
    paths = _outputs(args)
    with OutputSet(_targets(paths), inputs=[args.mesh], force=args.force) as outs:   # before any work
        result = _solve(args, paths.bake_mode)
        rep = result.report
        disagree = bool(args.cross_check and not rep["cross_check"]["agree"])
        invalid = not rep["valid"] and not args.paper
        written = _write(result, paths, args, outs, t0, write_all=not (invalid or disagree) or args.keep_invalid)
    if not args.quiet:
        _summary(rep, args.alpha, written)
    if not (invalid or disagree):
        return 0
    if args.keep_invalid:
        kept = " (written anyway: --keep-invalid)"
    else:
        kept = (f"; wrote only the report {paths.report}" if paths.report else "; nothing was written") + \
            " (pass --keep-invalid to write the outputs anyway)"
    if disagree:
        print(f"uvbake: failed: the backends disagree: {rep['cross_check']['message']}{kept}", file=sys.stderr)
    else:
        print(f"uvbake: failed: the atlas is not valid ({_what_is_wrong(rep)}){kept}", file=sys.stderr)
    return 1


def _what_is_wrong(rep: dict[str, Any]) -> str:
    verdict = rep["atlas"]["validation"]
    counts = (verdict["n_flipped"] - len(verdict["degenerate"]), len(verdict["degenerate"]), verdict["n_overlaps"])
    words = ("flipped", "degenerate", "overlapping pairs")
    return ", ".join(f"{n} {w}" for n, w in zip(counts, words) if n) or "see the report"
