"""``unwrap``: the whole pipeline, from a mesh to a validated, packed and baked atlas, with one report.

    load -> repair -> charting (labels kept; disks; distortion budget) -> solve (injective)
         -> pack -> validate -> bake

Each stage is a function in its own module; this one only chains them and writes the report.
Guarantee (``guarantee=True``): charting (:mod:`uvbake.atlas.charting`) decides the charts before
any solve so that each one's conformal map is flip-free and gives every triangle at least
1/max_stretch of the chart's texel density; the LM then never lets a determinant reach zero
(:mod:`uvbake.atlas.guarantee`), and whatever still starves or overlaps is split once per bad region
and only the parts are solved again, from the parent's map. ``guarantee=False`` is the paper's
formulation as is (charts from labels and disk cuts only, plain LM, nothing repaired).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from uvbake.analysis.metrics import chart_distortions, distortion_summary
from uvbake.atlas.source import load_source
from uvbake.atlas.units import to_input_units, working_density
from uvbake.cancel import check_cancelled
from uvbake.errors import InputError
from uvbake.flatten.options import DEFAULTS, SolveOptions
from uvbake.flatten.solve import parameterize_charts
from uvbake.mesh.topology import face_adjacency

#: More separate pieces than this is refused up front, before any work: each piece becomes at least
#: one chart and none is dropped silently; at this many, packing alone takes tens of seconds (the
#: measurements: docs/decisions/atlas-speed.md).
MAX_PIECES = 5000

BAKE_MODES = (None, "checker", "vertex-colors")


@dataclass
class UnwrapResult:
    """What :func:`unwrap` produced.

    Attributes
    ----------
    V : (n,3) float array, F : (m,3) int array
        The mesh that was unwrapped (after repair).
    corner_uv : (m,3,2) float array
        Atlas UVs per triangle corner in [0,1]^2 (v up), the layout of Open3D's ``texture_uvs``.
    charts : list of Chart
        The final charts (after cuts and splits); ``chart_ids (m,)`` gives each face's chart.
    results : list of ParamResult
        One per final chart.
    image : (H,W,3) uint8 array or None
        The baked texture.
    report : dict
        JSON-ready report (per chart and atlas).
    """

    V: np.ndarray
    F: np.ndarray
    corner_uv: np.ndarray
    charts: list
    results: list
    chart_ids: np.ndarray
    image: np.ndarray | None
    vertex_colors: np.ndarray | None
    report: dict = field(default_factory=dict)

    def save(self, path: str | os.PathLike[str], *, report_path: str | os.PathLike[str] | None = None,
             keep_vertex_colors: bool = False, force: bool = False) -> list[Path]:
        """Write the textured mesh (OBJ+MTL+PNG or GLB by extension) and optionally the JSON report.

        The texture alone carries the colour: viewers multiply vertex colours (glTF ``COLOR_0``, OBJ
        ``v x y z r g b``) with the texture, so a colour bake would show its colours squared and a
        checker would look tinted. ``keep_vertex_colors=True`` writes them anyway (for tools that
        read them as data). All files are written together or none (:class:`uvbake.io.atomic.OutputSet`);
        ``force`` replaces read-only files.
        """
        import json

        from uvbake.io.atomic import OutputSet
        from uvbake.io.export import textured_files

        image = self.image if self.image is not None else _blank(atlas_size(self.report))
        colors = self.vertex_colors if keep_vertex_colors else None
        files = textured_files(path, self.V, self.F, self.corner_uv, image, vertex_colors=colors)
        names = [("path", p) for p in files]
        if report_path is not None:
            files[Path(report_path)] = (json.dumps(self.report, indent=1) + "\n").encode("utf-8")
            names.append(("report_path", Path(report_path)))
        source = self.report.get("input")
        with OutputSet(names, inputs=[source] if isinstance(source, str) else [], force=force) as outs:
            for p, data in files.items():
                outs.write_bytes(p, data)
            return outs.commit()


def _blank(size):
    """A white texture of ``size`` texels (one side, or (width, height))."""
    from uvbake.atlas.bake import texture_dims

    W, H = texture_dims(size)
    return np.full((H, W, 3), 255, np.uint8)


def unwrap(source: Any, *, alpha: float = DEFAULTS.alpha, init: str = DEFAULTS.init, backend: str = DEFAULTS.backend,
           tol: float = DEFAULTS.tol, max_iter: int = DEFAULTS.max_iter, seed: int = DEFAULTS.seed,
           face_labels: ArrayLike | None = None, texture_size_px: int | None = 1024, gutter_px: int | None = None,
           bake: str | None = None, auto_cut: bool = True, repair: bool = True, weld: bool | None = None,
           guarantee: bool = True, max_stretch: float | None = None, max_charts: int | None = None,
           max_splits: int | None = None, continuation: bool = DEFAULTS.continuation, workers: int | None = None,
           progress: Callable[[str, int, int], None] | None = None, callback: Callable | None = None,
           texel_density: float | None = None, mip_levels: int | None = None,
           pack_splits: bool = True, materials: bool = True) -> UnwrapResult:
    """Unwrap a mesh into a validated texture atlas.

    Parameters
    ----------
    source : path, (V, F) tuple, trimesh.Trimesh or Open3D mesh
    alpha, init, backend, tol, max_iter, seed, continuation
        As in :func:`uvbake.parameterize` (``init`` is used where the charting's conformal start is
        not: with ``guarantee=False``).
    face_labels : (m,) int array, optional
        Per-face segment labels (overrides labels stored in the file). A chart never spans two labels.
    materials : bool
        An OBJ file whose faces use two or more materials (``usemtl``) is labelled by material, so no
        chart spans two (as xatlas does); False: materials are ignored.
    texture_size_px : int, (int, int) or None
        Side of the square texture (16 to 16384), or (width, height) for a rectangular one; None (with
        ``texel_density``): the atlas grows to fit.
    gutter_px : int, optional
        Minimum gap between charts, in texels (default 4, or what ``mip_levels`` needs).
    texel_density : float, optional
        Texels per world unit, fixed: the same density for every asset (see :func:`uvbake.pack_charts`).
    mip_levels : int, optional
        Mip levels whose bilinear filtering must not bleed between charts; sets the gutter.
    pack_splits : bool
        Cut the largest chart across its long axis (shortest 3D seam, its solved map kept on both
        sides) while that packs the atlas at least 1 point denser, below 66% (with ``guarantee``).
    bake : {None, "checker", "vertex-colors"}
        Texture to bake.
    auto_cut : bool
        Cut closed charts and charts with handles into disks (False: such charts are an error).
    repair : bool
        Repair non-manifold input (bowties, non-manifold edges, specks, duplicates) with warnings.
    weld : bool or None
        Weld coincident boundary vertices: None only for soup-like input, True always, False never.
        The input's own cuts (duplicated positions along a seam) otherwise stay cuts.
    guarantee : bool
        No flipped, overlapping, starved or sheared triangle (False: the paper's result as is).
    max_stretch : float, optional
        Distortion budget (> 1, default 4): every triangle's area factor, relative to its chart's,
        at least 1/max_stretch (charts are cut before solving so their conformal maps keep it;
        1/max_stretch^2 after the solve), and its angle distortion sigma1/sigma2 at most max_stretch^2.
    max_charts : int, optional
        Chart budget: charting stops cutting at this many charts, but for charts whose conformal map
        collapses triangles (the guarantee's splits still happen).
    max_splits : int, optional
        Cap on the guarantee's splits of each kind, distortion (starved, sheared) and validity (flips,
        overlaps) (default: four per chart entering the solve or one per 8 triangles, whichever is
        more, at least 256); past it the remaining invalid charts are reported, not hidden.
    workers : int, optional
        Charts solved in parallel threads; the result does not depend on it.
    progress : callable, optional
        ``progress(stage, done, total)`` with stage in {"charts", "solve", "iterate", "split", "pack",
        "bake"}: per chart decided, per chart solved and per LM iteration. An exception raised in it
        (e.g. on Ctrl-C) stops the run between two iterations.
    callback : callable, optional
        Per-iteration solver callback (see :func:`uvbake.parameterize`).

    Returns
    -------
    UnwrapResult
    """
    from uvbake.flatten.solvers.linalg import one_blas_thread

    # One BLAS thread in every stage: charts are solved in parallel threads, and two BLAS pools
    # spinning against each other on two cores cost camelhead's whole command 24.0 s against 20.6 s.
    with one_blas_thread():
        return _unwrap(source, alpha=alpha, init=init, backend=backend, tol=tol, max_iter=max_iter, seed=seed,
                       face_labels=face_labels, texture_size_px=texture_size_px, gutter_px=gutter_px, bake=bake,
                       auto_cut=auto_cut, repair=repair, weld=weld, guarantee=guarantee, max_stretch=max_stretch,
                       max_charts=max_charts, max_splits=max_splits, continuation=continuation, workers=workers,
                       progress=progress, callback=callback, texel_density=texel_density, mip_levels=mip_levels,
                       pack_splits=pack_splits, materials=materials)


@dataclass
class _Run:
    """One unwrap's state, passed from stage to stage: the options, the mesh and what each stage made."""

    opts: dict
    solve_options: SolveOptions
    note: object
    solve_kwargs: dict
    timings: dict = field(default_factory=dict)
    V: np.ndarray | None = None
    F: np.ndarray | None = None
    labels: np.ndarray | None = None
    colors: np.ndarray | None = None
    source_name: object = None
    repair_report: dict | None = None
    pinch_keys: np.ndarray | None = None   # copies repair made of one input vertex (uvbake.flatten.pinches)
    k: int = 0
    charts: list = field(default_factory=list)
    starts: list | None = None
    chart_log: dict = field(default_factory=dict)
    n_charts_input: int = 0
    results: list = field(default_factory=list)
    splits: list = field(default_factory=list)
    instances: Any = None                  # uvbake.atlas.instances.Instances, when pieces repeat
    instances_plan: Any = None             # uvbake.atlas.instances.Plan: what the copies will get


def _unwrap(source, **opts):
    from uvbake.atlas.charting import DEFAULT_MAX_STRETCH, check_budget

    t0 = time.perf_counter()
    solve_options = SolveOptions(**{k: opts[k] for k in ("alpha", "init", "backend", "tol", "max_iter", "seed",
                                                         "continuation")})
    if opts["bake"] not in BAKE_MODES:
        raise InputError(f"bake={opts['bake']!r} is not one of None, 'checker', 'vertex-colors'")
    opts["texture_size_px"] = check_texture(opts["texture_size_px"], opts["gutter_px"], opts["texel_density"],
                                            opts["mip_levels"])
    opts["max_stretch"], opts["max_charts"] = check_budget(
        DEFAULT_MAX_STRETCH if opts["max_stretch"] is None else opts["max_stretch"], opts["max_charts"])
    if not isinstance(opts["materials"], bool):
        raise InputError(f"materials={opts['materials']!r} must be True or False (label OBJ faces by material)")
    if opts["weld"] not in (None, True, False):
        raise InputError(f"weld={opts['weld']!r} must be True, False or None (weld only soup-like input)")
    run = _Run(opts, solve_options, _noter(opts["progress"]), {})
    run.solve_kwargs = dict(options=solve_options, callback=_per_iteration(run.note, opts["callback"],
                                                                             opts["max_iter"]))
    _stage_load(run, source)
    _stage_charts(run)
    _check_room(run.n_charts_input, opts)
    _stage_solve(run)
    packed, corner_uv, chart_ids, verdict = _pack_and_validate(run, {k: opts[k] for k in (
        "texture_size_px", "gutter_px", "mip_levels")} | {"texel_density": working_density(opts["texel_density"], run.k)})
    # grown, or from mip_levels; one number for a square atlas, else [width, height]
    opts["texture_size_px"] = packed.width_px if packed.width_px == packed.height_px else [packed.width_px,
                                                                                          packed.height_px]
    opts["gutter_px"] = packed.gutter_px
    run.note("pack", 1, 1)
    image = _stage_bake(run, corner_uv, packed)
    run.timings["total_s"] = time.perf_counter() - t0
    report = _report(run, corner_uv, packed, verdict)
    V = np.ldexp(run.V, run.k) if run.k else run.V     # the input's coordinates (the scaling by 2**-k is exact)
    charts, results = to_input_units(report, run.charts, run.results, run.k)
    return UnwrapResult(V, run.F, corner_uv, charts, results, chart_ids, image, run.colors, report)


def _check_room(n, opts):
    """Refuse, before the solve, ``n`` charts that no packing of a fixed-size atlas can hold (the splits
    only add charts): shrunk to points, each chart holds a disk of radius g/2 of its own (charts are g
    texels apart, ceil(g/2) from the border), inside the atlas grown by g/2 - ceil(g/2) a side
    (docs/decisions/atlas.md, eighth session: such runs failed only in the packing, after every solve)."""
    from uvbake.atlas.pack import _check_gutter, _check_size

    if opts["texture_size_px"] is None or not opts["guarantee"]:
        return
    W, H = _check_size(opts["texture_size_px"], opts["texel_density"])
    g = _check_gutter(opts["gutter_px"], opts["mip_levels"], W, H)
    m = (g + 1) // 2
    if g > 0 and n * np.pi * g * g / 4 > (W - 2 * m + g) * (H - 2 * m + g):
        raise InputError(f"{n} charts cannot fit a {W}x{H}-texel atlas with gutter_px={g}: "
                         f"even shrunk to points {g} texels apart they need more room; reduce gutter_px or increase "
                         f"texture_size_px")


def _noter(progress):
    """``note(stage, done, total)``: polls for SIGINT/SIGTERM (every stage and iteration), then tells
    the user's ``progress``."""
    def note(stage, done, total):
        check_cancelled()
        if progress is not None:
            progress(stage, done, total)

    return note


def _per_iteration(note, callback, max_iter):
    def per_iteration(info):
        note("iterate", info["iteration"], max_iter)
        return callback(info) if callback is not None else None

    return per_iteration


def _stage_load(run, source):
    opts = run.opts
    t = time.perf_counter()
    run.V, run.F, run.labels, run.colors, run.source_name, run.repair_report, run.pinch_keys, run.k = load_source(
        source, opts["face_labels"], opts["repair"], opts["weld"], opts["materials"])
    if opts["bake"] == "vertex-colors" and run.colors is None:
        raise InputError(f"{run.source_name}: has no vertex colours to bake; use --bake-mode checker")
    run.timings["load_repair_s"] = time.perf_counter() - t
    check_cancelled()
    n_pieces = _count_pieces(run.F, len(run.V), run.labels)
    if n_pieces > MAX_PIECES:
        labels = "" if run.labels is None else \
            "give coarser face labels (for an OBJ file's materials: materials=False), "
        raise InputError(f"{run.source_name}: the mesh is {n_pieces} separate pieces, which would be at least "
                         f"{n_pieces} charts; uvbake unwraps at most {MAX_PIECES} pieces (none is dropped "
                         f"silently); {labels}weld coincident vertices (weld=True), or remove the small pieces first")


def _stage_charts(run):
    opts = run.opts
    t = time.perf_counter()
    if opts["guarantee"]:
        _make_charts(run)
    else:
        from uvbake.atlas.charting import disk_charts

        run.charts, cuts = disk_charts(run.V, run.F, run.labels, auto_cut=opts["auto_cut"])
        for i, c in enumerate(run.charts):
            c.name = f"chart {i}" + (f" (label {c.label})" if c.label >= 0 else "")
        run.starts, run.chart_log = None, dict(cuts=cuts, budget_cuts=[], over_budget=[], conformal_solves=0,
                                                    conformal_triangles=0)
        run.note("charts", len(run.charts), len(run.charts))
    run.n_charts_input = len(run.charts) + (0 if run.instances is None else run.instances_plan.charts)
    run.timings["charts_s"] = time.perf_counter() - t


def _make_charts(run):
    """The budget's charting (uvbake.atlas.charting.make_charts), of each piece's original only when
    pieces repeat (uvbake.atlas.instances; not with a chart or split budget, which count every chart)."""
    from functools import partial

    from uvbake.atlas.charting import make_charts

    opts = run.opts
    make = partial(make_charts, max_stretch=opts["max_stretch"], max_charts=opts["max_charts"],
                   auto_cut=opts["auto_cut"], progress=run.note)
    if opts["max_charts"] is None and opts["max_splits"] is None:
        from uvbake.atlas.instances import chart_originals, find_instances

        run.instances = find_instances(run.V, run.F, run.labels, run.pinch_keys)
        if run.instances is not None:
            run.charts, run.starts, run.chart_log, run.instances_plan = chart_originals(
                run.instances, run.V, run.labels, run.pinch_keys, make)
            return
    run.charts, run.starts, run.chart_log = make(run.V, run.F, run.labels, pinch_keys=run.pinch_keys)


def _stage_solve(run):
    opts = run.opts
    t = time.perf_counter()
    if opts["guarantee"]:
        from uvbake.atlas.guarantee import equalise_densities, snap_copies, solve_valid

        # the guarantee's solve fills holes with light fans (uvbake.flatten.holes): a hole's border cannot fold
        kwargs = dict(run.solve_kwargs, options=run.solve_options.replace(fill_holes=True))
        run.charts, run.results, run.splits = solve_valid(
            run.charts, run.starts, kwargs, max_stretch=opts["max_stretch"], workers=opts["workers"],
            max_splits=opts["max_splits"], note=run.note, pinch_keys=run.pinch_keys)
        if run.instances is not None:              # every copy's charts: its original's, maps scaled
            from uvbake.atlas.instances import add_copies

            run.charts, run.results, run.splits = add_copies(run.instances, run.instances_plan, run.V, run.charts,
                                                             run.results, run.splits)
        for c, r in zip(run.charts, equalise_densities(run.charts, run.results)):
            snap_copies(c, r)
    else:
        run.results = parameterize_charts(run.charts, workers=opts["workers"],
                                          progress=lambda d, n, r: run.note("solve", d, n), **run.solve_kwargs)
    run.timings["solve_s"] = time.perf_counter() - t


def _stage_bake(run, corner_uv, packed):
    bake = run.opts["bake"]
    image = None
    t = time.perf_counter()
    if bake is not None:
        from uvbake.atlas.bake import bake_checker, bake_vertex_colors

        size = run.opts["texture_size_px"]
        if bake == "checker":
            image = bake_checker(run.V, run.F, corner_uv, texture_size_px=size,
                                 texel_size_world=packed.texel_size_world)
        else:
            image = bake_vertex_colors(run.V, run.F, corner_uv, run.colors, texture_size_px=size)
        run.note("bake", 1, 1)
    run.timings["bake_s"] = time.perf_counter() - t
    return image


def _report(run, corner_uv, packed, verdict):
    """The JSON-ready report of a finished run."""
    from uvbake.analysis.metrics import texel_summary

    opts, log, charts, results = run.opts, run.chart_log, run.charts, run.results
    texels = texel_summary(run.V, run.F, corner_uv)
    per_chart = chart_distortions([c.V for c in charts], [c.F for c in charts], [r.uv for r in results])
    shown = ("texture_size_px", "gutter_px", "bake", "auto_cut", "repair", "weld", "guarantee", "max_stretch",
             "max_charts", "texel_density", "mip_levels", "pack_splits", "materials")
    report = {
        "input": run.source_name,
        "vertices": int(len(run.V)),
        "triangles": int(len(run.F)),
        "options": run.solve_options.report() | {k: opts[k] for k in shown},
        "repair": run.repair_report,
        "charts_input": run.n_charts_input,
        "charts_final": len(charts),
        "cuts": log["cuts"],
        "budget_cuts": log["budget_cuts"],
        "over_budget": log["over_budget"],
        "splits": run.splits,
        "instance_copies": 0 if run.instances is None else run.instances.copies,
        "pinches_welded": _pinches_welded(run),
        "seam_length_added": float(sum(c["seam_length"] for c in log["cuts"])
                                   + sum(c.get("seam_length", 0.0) for c in log["budget_cuts"])
                                   + sum(s["seam_length"] for s in run.splits)),
        "distortion": {"final": distortion_summary(per_chart, flipped=sum(r.n_flipped for r in results),
                                                   energy=sum(r.energy for r in results))},
        "charts": [dict(name=c.name, label=c.label, triangles=int(len(c.F)), **d, **r.to_dict())
                   for c, r, d in zip(charts, results, per_chart)],
        "atlas": dict(texture_size_px=int(packed.width_px), width_px=int(packed.width_px),
                      height_px=int(packed.height_px), gutter_px=opts["gutter_px"], **_pack_summary(packed),
                      validation=verdict.to_dict()),
        **texels,
        "valid": bool(verdict.valid),
        "all_converged": bool(all(r.converged for r in results)),
        "n_flipped_total": int(sum(r.n_flipped for r in results)),
        "timings": run.timings,
    }
    return report


def _pinches_welded(run):
    """Points where the final charts hold several of repair's copies of one input vertex, solved as
    one vertex (:mod:`uvbake.flatten.pinches`; 0 without the guarantee, which alone welds them)."""
    if run.pinch_keys is None or not run.opts["guarantee"]:
        return 0
    from uvbake.flatten.pinches import pinch_count

    return pinch_count([run.pinch_keys[c.vertex_map] for c in run.charts], [c.F for c in run.charts],
                       [len(c.V) for c in run.charts])


def _count_pieces(F, n_vertices, labels):
    """Edge-connected pieces of each label (the charts before any cut), counted without building them."""
    from uvbake.mesh.graph import components

    fi, fj, _ = face_adjacency(F, n_vertices)
    if labels is not None:
        same = np.asarray(labels)[fi] == np.asarray(labels)[fj]
        fi, fj = fi[same], fj[same]
    m = len(F)
    return components(m, fi, fj)[0]


def _pack_and_validate(run, pack_options):
    """Pack the charts (splitting the largest where that packs denser, with the guarantee on), then
    validate the packed atlas once (the report's verdict)."""
    from uvbake.atlas.pack import corner_uvs, pack_charts
    from uvbake.validate.core import validate

    t = time.perf_counter()
    F = run.F

    def pack(uvs, Fs):
        return pack_charts(uvs, Fs, progress=lambda done, total: run.note("pack", done, total), **pack_options)

    if run.opts["guarantee"] and run.opts["pack_splits"]:
        from uvbake.atlas.packsplit import BoxLayouts, split_for_packing

        # splits are judged on the fast rectangle packer (each chart's rectangle found once), which places at
        # a scale of its own in a square: with a fixed texel density or a rectangular atlas, trials are full packings
        square = not isinstance(pack_options["texture_size_px"], (tuple, list))
        boxes = None if pack_options.get("texel_density") is not None or not square else BoxLayouts(
            pack_options["texture_size_px"], pack_options["gutter_px"], pack_options["mip_levels"])
        run.charts, run.results, packed, split = split_for_packing(run.charts, run.results, pack, boxes=boxes,
                                                                   max_charts=run.opts["max_charts"])
        run.splits = list(run.splits) + split
    else:
        packed = pack([r.uv for r in run.results], [c.F for c in run.charts])
    charts = run.charts
    corner_uv = corner_uvs(packed, [c.F for c in charts], [c.face_index for c in charts], len(F))
    chart_ids = np.empty(len(F), np.int64)
    for i, c in enumerate(charts):
        chart_ids[c.face_index] = i
    run.timings["pack_s"] = time.perf_counter() - t
    t = time.perf_counter()
    # the exact pass is the proof; the raster only classifies overlapping pairs, so a valid atlas skips it
    verdict = validate(corner_uv, F, chart_ids=chart_ids, resolution_px=max(packed.width_px, packed.height_px),
                       count_covered=False)
    run.timings["validate_s"] = time.perf_counter() - t
    return packed, corner_uv, chart_ids, verdict


def check_texture(texture_size_px: int | tuple[int, int] | None, gutter_px: int | None,
                  texel_density: float | None = None, mip_levels: int | None = None) -> int | tuple[int, int] | None:
    """Refuse a bad texture size or gutter (naming the parameter), the gutter ``mip_levels`` derives
    included; returns the size as one number for a square texture ((N, N) too), (width, height) for a
    rectangular one, None for a growing atlas."""
    def whole(n):
        return not isinstance(n, bool) and isinstance(n, (int, np.integer)) and 16 <= n <= 16384

    size: int | tuple[int, int] | None
    if texture_size_px is None and texel_density is not None:
        size, limit = None, 16384 // 8
    elif isinstance(texture_size_px, (tuple, list)) and len(texture_size_px) == 2 and all(map(whole, texture_size_px)):
        W, H = (int(n) for n in texture_size_px)
        size, limit = (W if W == H else (W, H)), min(W, H) // 8
    elif whole(texture_size_px):
        size = int(texture_size_px)            # type: ignore[arg-type]
        limit = size // 8
    else:
        raise InputError(f"texture_size_px={texture_size_px!r} must be a whole number of texels from 16 to 16384, "
                         "or a (width, height) pair of them")
    if gutter_px is None:
        _check_mip_gutter(mip_levels, limit, size)
        return size
    if isinstance(gutter_px, bool) or not isinstance(gutter_px, (int, np.integer)) \
            or not 0 <= gutter_px <= limit:
        side = "'s shorter side" if isinstance(size, tuple) else ""
        raise InputError(f"gutter_px={gutter_px!r} must be a whole number of texels from 0 to "
                         f"{limit} (an eighth of the texture{side})")
    return size


def mip_room(mip_levels: int, need: int) -> int:
    """The least texture side with room for a ``need``-texel gutter (eight times it) that ``mip_levels``
    levels can halve evenly (a multiple of 2**(mip_levels-1))."""
    q = 2 ** (int(mip_levels) - 1)
    return -(-8 * need // q) * q


def mip_levels_within(limit: int) -> int:
    """The most mip levels whose gutter (uvbake.atlas.shapepack.mip_gutter_px) is at most ``limit`` texels
    (0 when not even one level's is)."""
    from uvbake.atlas.shapepack import mip_gutter_px

    return max([k for k in range(1, 9) if mip_gutter_px(k) <= limit], default=0)


def _check_mip_gutter(mip_levels, limit, size):
    """The gutter mip_levels derives, held to the same eighth of the texture as a gutter_px given: an
    atlas of gutters takes a long packing search to fail (bench/shapes.py's fingers, mip_levels=8 in
    1024 px: a 545-texel gutter, 17 s of CPU before the packer gave up)."""
    from uvbake.atlas.shapepack import mip_gutter_px

    if isinstance(mip_levels, bool) or not isinstance(mip_levels, (int, np.integer)) or not 1 <= mip_levels <= 8:
        return                                  # not a level count: uvbake.atlas.pack's check names it
    need = mip_gutter_px(int(mip_levels))
    if need > limit:
        side = "'s shorter side" if isinstance(size, tuple) else ""
        most = mip_levels_within(limit)
        fewer = f"pass mip_levels={most} or fewer, or" if most else "pass"
        raise InputError(f"mip_levels={mip_levels} needs a {need}-texel gutter, more than {limit} (an eighth of the "
                         f"texture{side}); {fewer} a texture_size_px of at least {mip_room(mip_levels, need)}")


def atlas_size(report: dict) -> int | tuple[int, int]:
    """The atlas of an unwrap report as one side (square) or (width, height)."""
    atlas = report["atlas"]
    W, H = atlas.get("width_px", atlas["texture_size_px"]), atlas.get("height_px", atlas["texture_size_px"])
    return int(W) if W == H else (int(W), int(H))


def size_text(size: int | tuple[int, int] | list[int]) -> str:
    """A texture size as a user types it: 1024, or 2048x1024."""
    return f"{size[0]}x{size[1]}" if isinstance(size, (tuple, list)) else str(size)


def _pack_summary(packed):
    d = packed.to_dict() if hasattr(packed, "to_dict") else {}
    return {k: v for k, v in d.items() if k in ("efficiency", "scale", "texel_size_world", "texel_density", "method",
                                                 "time_s")}
