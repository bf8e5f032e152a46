"""``unwrap``: the whole pipeline, from a mesh to a validated, packed and baked atlas, with one report.

    load -> repair -> charts (auto-cut) -> parameterize -> validate / split -> pack -> validate -> bake

Flip- and overlap-free guarantee (``guarantee=True``). The paper's energy is kept exactly; a chart
whose solution has flipped or overlapping triangles is split in two with a short cut separating the
bad region (``uvbake.mesh.cut.split_where``) and both parts are solved again, until every chart
validates. Smaller charts of a smooth surface are closer to developable, so the split recursion
ends; a single triangle always flattens exactly, which bounds it. Every split is reported.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from uvbake.analysis.metrics import chart_distortion, distortion_summary
from uvbake.errors import ChartError, InputError, NotDiskError
from uvbake.flatten.options import DEFAULTS, SolveOptions
from uvbake.flatten.solve import parameterize_charts
from uvbake.io.load import load_mesh
from uvbake.mesh.arrays import check_arrays, rigid_align
from uvbake.mesh.charts import Chart, check_chart, split_charts
from uvbake.mesh.cut import cut_to_disks, seam_length
from uvbake.mesh.repair import repair as repair_mesh
from uvbake.mesh.topology import face_adjacency

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

    def save(self, path, *, report_path=None):
        """Write the textured mesh (OBJ+MTL+PNG or GLB by extension) and optionally the JSON report."""
        import json

        from uvbake.io.atomic import atomic_write
        from uvbake.io.export import save_textured

        image = self.image if self.image is not None else _blank(self.report["atlas"]["texture_size_px"])
        written = save_textured(path, self.V, self.F, self.corner_uv, image, vertex_colors=self.vertex_colors)
        if report_path is not None:
            with atomic_write(report_path) as fh:
                json.dump(self.report, fh, indent=1)
            written = list(written) + [report_path]
        return written


def _blank(size):
    return np.full((size, size, 3), 255, np.uint8)


def unwrap(source, *, alpha=DEFAULTS.alpha, init=DEFAULTS.init, backend=DEFAULTS.backend, tol=DEFAULTS.tol,
           max_iter=DEFAULTS.max_iter, seed=DEFAULTS.seed,
           face_labels=None, texture_size_px=1024, gutter_px=None, bake=None, auto_cut=True,
           repair=True, guarantee=True, max_splits=256, continuation=DEFAULTS.continuation, workers=None,
           progress=None, callback=None, texel_density=None, mip_levels=None):
    """Unwrap a mesh into a validated texture atlas.

    Parameters
    ----------
    source : path, (V, F) tuple, trimesh.Trimesh or Open3D mesh
    alpha, init, backend, tol, max_iter, seed, continuation
        As in :func:`uvbake.parameterize`.
    face_labels : (m,) int array, optional
        Per-face segment labels (overrides labels stored in the file).
    texture_size_px : int or None
        Side of the square texture (16 to 16384); None (with ``texel_density``): the atlas grows to fit.
    gutter_px : int, optional
        Minimum gap between charts, in texels (default 4, or what ``mip_levels`` needs).
    texel_density : float, optional
        Texels per world unit, fixed: the same density for every asset (see :func:`uvbake.pack_charts`).
    mip_levels : int, optional
        Mip levels whose bilinear filtering must not bleed between charts; sets the gutter.
    bake : {None, "checker", "vertex-colors"}
        Texture to bake.
    auto_cut : bool
        Cut closed charts and charts with handles into disks (False: such charts are an error).
    repair : bool
        Repair non-manifold input (bowties, non-manifold edges, specks, duplicates) with warnings.
    guarantee : bool
        Split charts until no triangle is flipped and no two overlap (False: the paper's result as is).
    max_splits : int
        Cap on splits; past it the remaining invalid charts are reported, not hidden.
    progress : callable, optional
        ``progress(stage, done, total)`` with stage in {"charts", "solve", "split", "pack", "bake"}.
    callback : callable, optional
        Per-iteration solver callback (see :func:`uvbake.parameterize`).

    Returns
    -------
    UnwrapResult
    """
    from threadpoolctl import threadpool_limits

    from uvbake.flatten.solvers.linalg import cholmod_available

    cholmod_available()          # load CHOLMOD's BLAS first, so the limit below reaches it too
    # One BLAS thread in every stage: charts are solved in parallel threads, and two BLAS pools
    # spinning against each other on two cores cost camelhead's whole command 24.0 s against 20.6 s.
    with threadpool_limits(limits=1):
        return _unwrap(source, alpha=alpha, init=init, backend=backend, tol=tol, max_iter=max_iter, seed=seed,
                       face_labels=face_labels, texture_size_px=texture_size_px, gutter_px=gutter_px, bake=bake,
                       auto_cut=auto_cut, repair=repair, guarantee=guarantee, max_splits=max_splits,
                       continuation=continuation, workers=workers, progress=progress, callback=callback,
                       texel_density=texel_density, mip_levels=mip_levels)


def _unwrap(source, *, alpha, init, backend, tol, max_iter, seed, face_labels, texture_size_px, gutter_px, bake,
            auto_cut, repair, guarantee, max_splits, continuation, workers, progress, callback, texel_density,
            mip_levels):
    t0 = time.perf_counter()
    timings = {}
    solve_options = SolveOptions(alpha=alpha, init=init, backend=backend, tol=tol, max_iter=max_iter, seed=seed,
                                 continuation=continuation)
    if bake not in BAKE_MODES:
        raise InputError(f"bake={bake!r} is not one of None, 'checker', 'vertex-colors'")
    check_texture(texture_size_px, gutter_px, texel_density)
    options = dict(options=solve_options, callback=callback)
    note = progress or (lambda stage, done, total: None)

    t = time.perf_counter()
    mesh, V, F, labels, colors, repair_report = _load_repaired(source, face_labels, repair)
    if bake == "vertex-colors" and colors is None:
        raise InputError(f"{mesh.source}: has no vertex colours to bake; use --bake-mode checker")
    timings["load_repair_s"] = time.perf_counter() - t

    t = time.perf_counter()
    charts, cuts = _disk_charts(V, F, labels, auto_cut=auto_cut)
    n_charts_input = len(charts)
    timings["charts_s"] = time.perf_counter() - t
    note("charts", len(charts), len(charts))

    t = time.perf_counter()
    results = parameterize_charts(charts, workers=workers,
                                  progress=lambda d, n, r: note("solve", d, n), **options)
    timings["solve_s"] = time.perf_counter() - t
    unconstrained = _distortion_summary(charts, results)

    t = time.perf_counter()
    splits, merges = [], []
    if guarantee:
        charts, results, splits, known_invalid = _split_until_valid(
            charts, results, options, max_splits=max_splits, workers=workers, note=note)
        if splits:
            # merging may add at most 30% to the time solving and splitting took (camelhead at
            # alpha 0.5: 17 -> 6 charts with no limit, but 97 s instead of 17 s)
            budget_s = max(1.0, 0.3 * (time.perf_counter() - t + timings["solve_s"]))
            charts, results, merges = _merge_back(V, F, charts, results, options, note=note, budget_s=budget_s,
                                                  known_invalid=known_invalid)
    timings["split_s"] = time.perf_counter() - t

    from uvbake.atlas.pack import corner_uvs, pack_charts

    t = time.perf_counter()
    packed = pack_charts([r.uv for r in results], [c.F for c in charts], texture_size_px=texture_size_px,
                         gutter_px=gutter_px, texel_density=texel_density, mip_levels=mip_levels)
    texture_size_px, gutter_px = packed.width_px, packed.gutter_px      # grown, or derived from mip_levels
    corner_uv = corner_uvs(packed, [c.F for c in charts], [c.face_index for c in charts], len(F))
    timings["pack_s"] = time.perf_counter() - t
    note("pack", 1, 1)

    from uvbake.validate.core import validate

    t = time.perf_counter()
    chart_ids = np.empty(len(F), np.int64)
    for i, c in enumerate(charts):
        chart_ids[c.face_index] = i
    verdict = validate(corner_uv, F, chart_ids=chart_ids, resolution_px=texture_size_px)
    timings["validate_s"] = time.perf_counter() - t

    image = None
    t = time.perf_counter()
    if bake is not None:
        from uvbake.atlas.bake import bake_checker, bake_vertex_colors

        if bake == "checker":
            image = bake_checker(V, F, corner_uv, texture_size_px=texture_size_px,
                                 texel_size_world=packed.texel_size_world)
        else:
            image = bake_vertex_colors(V, F, corner_uv, colors, texture_size_px=texture_size_px)
        note("bake", 1, 1)
    timings["bake_s"] = time.perf_counter() - t
    timings["total_s"] = time.perf_counter() - t0

    report = {
        "input": mesh.source,
        "vertices": int(len(V)),
        "triangles": int(len(F)),
        "options": solve_options.report()
        | dict(texture_size_px=texture_size_px, gutter_px=gutter_px, bake=bake, auto_cut=auto_cut,
               repair=repair, guarantee=guarantee, texel_density=texel_density, mip_levels=mip_levels),
        "repair": repair_report,
        "charts_input": n_charts_input,
        "charts_final": len(charts),
        "cuts": cuts,
        "splits": splits,
        "merges": merges,
        "seam_length_added": float(sum(c["seam_length"] for c in cuts) + sum(s["seam_length"] for s in splits)
                                   - sum(m["seam_length"] for m in merges)),
        "distortion": {"unconstrained": unconstrained, "final": _distortion_summary(charts, results)},
        "charts": [dict(name=c.name, label=c.label, triangles=int(len(c.F)),
                        **_distortion(c, r), **r.to_dict()) for c, r in zip(charts, results)],
        "atlas": dict(texture_size_px=texture_size_px, gutter_px=gutter_px, **_pack_summary(packed),
                      validation=verdict.to_dict()),
        "valid": bool(verdict.valid),
        "all_converged": bool(all(r.converged for r in results)),
        "n_flipped_total": int(sum(r.n_flipped for r in results)),
        "timings": timings,
    }
    return UnwrapResult(V, F, corner_uv, charts, results, chart_ids, image, colors, report)


def _load_repaired(source, face_labels, repair):
    """The mesh, its arrays after repair (when asked), and the repair report (None when not asked)."""
    mesh = load_mesh(source, face_labels=face_labels)
    V, F, labels, colors = mesh.V, mesh.F, mesh.face_labels, mesh.vertex_colors
    # NaN or infinite coordinates are corrupt data, not a reconstruction artefact: refuse them
    # (naming the vertices) rather than silently dropping faces
    check_arrays(V, F, where=str(mesh.source))
    if not repair:
        return mesh, V, F, labels, colors, None
    rep = repair_mesh(V, F)
    if rep.actions:
        labels = None if labels is None else labels[rep.face_index]
        colors = None if colors is None else colors[rep.vertex_index]
        V, F = rep.V, rep.F
    return mesh, V, F, labels, colors, rep.to_dict()


def check_texture(texture_size_px, gutter_px, texel_density=None):
    if texture_size_px is None and texel_density is not None:
        limit = 16384 // 8
    elif isinstance(texture_size_px, bool) or not isinstance(texture_size_px, (int, np.integer)) \
            or not 16 <= texture_size_px <= 16384:
        raise InputError(f"texture_size_px={texture_size_px!r} must be a whole number of texels from 16 to 16384")
    else:
        limit = texture_size_px // 8
    if gutter_px is None:
        return
    if isinstance(gutter_px, bool) or not isinstance(gutter_px, (int, np.integer)) \
            or not 0 <= gutter_px <= limit:
        raise InputError(f"gutter_px={gutter_px!r} must be a whole number of texels from 0 to "
                         f"{limit} (an eighth of the texture)")


def _disk_charts(V, F, labels, *, auto_cut):
    """Charts from labels/components; closed charts and handles are cut into disks when allowed."""
    charts = split_charts(V, F, labels, check=False)
    out, cuts = [], []
    for c in charts:
        try:
            check_chart(c.V, c.F, name=c.name)
            out.append(c)
            continue
        except NotDiskError as exc:               # closed or with handles: cut it, if allowed
            if not auto_cut:
                raise NotDiskError(f"{exc} (or drop --no-auto-cut to let uvbake cut it)") from None
        sub = cut_to_disks(c.V, c.F)
        parts = _subcharts(c, sub)
        for p in parts:
            check_chart(p.V, p.F, name=p.name)
        cuts.append(dict(chart=c.name, parts=len(parts), seam_length=seam_length(c.V, c.F, sub)))
        out.extend(parts)
    for i, c in enumerate(out):
        c.name = f"chart {i}" + (f" (label {c.label})" if c.label >= 0 else "")
    return out, cuts


def _subcharts(chart, sub_labels, *, with_local=False):
    """Split ``chart`` by per-face labels into edge-connected charts mapped into the whole mesh
    (and, with ``with_local``, each part's vertex indices in ``chart``)."""
    parts = split_charts(chart.V, chart.F, np.asarray(sub_labels, dtype=np.int64), check=False)
    out = [Chart(p.V, p.F, chart.vertex_map[p.vertex_map], chart.face_index[p.face_index], chart.label,
                 f"{chart.name}.{k}") for k, p in enumerate(parts)]
    return (out, [p.vertex_map for p in parts]) if with_local else out


def _invalid_faces(chart, result):
    """Flipped, degenerate and overlapping faces of a solved chart (exact check)."""
    from uvbake.validate.core import validate

    rep = validate(result.uv, chart.F, chart_ids=np.zeros(len(chart.F), np.int64), resolution_px=1024)
    det = _dets(chart, result.uv)
    bad = set(np.flatnonzero(det <= 0).tolist()) | set(np.asarray(rep.flipped).tolist())
    bad |= set(np.asarray(rep.overlap_pairs).ravel().tolist())
    return np.array(sorted(bad), dtype=np.int64), rep


def _dets(chart, uv):
    from uvbake.flatten.energy import jacobians, triangle_frames

    _, Q, _ = triangle_frames(chart.V, chart.F)
    return np.linalg.det(jacobians(Q, chart.F, uv))


def _split_until_valid(charts, results, options, *, max_splits, workers, note):
    from uvbake.mesh.cut import split_where

    splits, known_invalid = [], []
    todo = list(range(len(charts)))
    charts, results = list(charts), list(results)
    while todo and len(splits) < max_splits:
        new_charts, parents, starts = [], [], []
        for i in todo:
            bad, rep = _invalid_faces(charts[i], results[i])
            if len(bad) == 0:
                continue
            c = charts[i]
            if len(c.F) == 1:
                continue                      # a single triangle cannot be split further
            sub = split_where(c.V, c.F, bad)
            parts, local = _subcharts(c, sub, with_local=True)
            known_invalid.append(c.face_index)
            for p, loc in zip(parts, local):
                # warm start from the parent's map where its restriction has nothing flipped
                # (the split moved the bad region away from this part); otherwise a fresh start
                uv = results[i].uv[loc]
                starts.append(uv if np.all(_dets(p, uv) > 0) else None)
            splits.append(dict(chart=c.name, faces=int(len(c.F)), flipped=int(len(rep.flipped)),
                               overlapping_pairs=int(len(rep.overlap_pairs)), parts=len(parts),
                               seam_length=seam_length(c.V, c.F, sub)))
            parents.append(i)
            new_charts.append(parts)
            if len(splits) >= max_splits:
                break
        if not parents:
            break
        flat = [p for parts in new_charts for p in parts]
        note("split", len(splits), len(splits))
        solved = parameterize_charts(flat, workers=workers, starts=starts, **options)
        # replace parents by their parts, keep order stable
        replace = dict(zip(parents, new_charts))
        solved_iter = iter(solved)
        out_c, out_r, todo = [], [], []
        for i, (c, r) in enumerate(zip(charts, results)):
            if i in replace:
                for p in replace[i]:
                    todo.append(len(out_c))
                    out_c.append(p)
                    out_r.append(next(solved_iter))
            else:
                out_c.append(c)
                out_r.append(r)
        charts, results = out_c, out_r
    return charts, results, splits, known_invalid


def _merge_back(V, F, charts, results, options, *, note, budget_s, known_invalid=(), max_attempts_per_chart=2):
    """Greedily re-join neighbouring charts along their longest shared seams.

    Splitting decides top-down, so parts often end smaller than they need to be. Each candidate union
    is kept only if it is still a disk with holes and its own solution validates (no flip, no overlap).
    The longest shared seams go first: they save the most seam and bound the most similar geometry.
    Each union starts from the two parts' maps, rigidly aligned on their shared seam vertices, and
    the pass stops after ``budget_s`` seconds.
    """

    deadline = time.perf_counter() + budget_s
    charts, results = list(charts), list(results)
    merges = []
    attempts = 0
    budget = max_attempts_per_chart * len(charts)
    tried = set()
    while attempts < budget and time.perf_counter() < deadline:
        owner = np.empty(len(F), np.int64)
        for i, c in enumerate(charts):
            owner[c.face_index] = i
        fi, fj, e = face_adjacency(F, len(V))
        a, b = owner[fi], owner[fj]
        cross = a != b
        if not cross.any():
            break
        lo, hi = np.minimum(a[cross], b[cross]), np.maximum(a[cross], b[cross])
        length = np.linalg.norm(V[e[cross, 0]] - V[e[cross, 1]], axis=1)
        key = lo * len(charts) + hi
        uniq, inv = np.unique(key, return_inverse=True)
        seam = np.bincount(inv, weights=length)
        order = np.argsort(-seam)
        merged = False
        for k in order:
            i, j = divmod(int(uniq[k]), len(charts))
            sig = (tuple(charts[i].face_index[:3]), len(charts[i].F), tuple(charts[j].face_index[:3]), len(charts[j].F))
            if sig in tried:
                continue
            tried.add(sig)
            attempts += 1
            faces = np.concatenate([charts[i].face_index, charts[j].face_index])
            inside = np.zeros(len(F), bool)
            inside[faces] = True
            if any(inside[p].all() for p in known_invalid):
                continue              # it would contain a chart already split for being invalid
            vmap, local = np.unique(F[faces], return_inverse=True)
            union = Chart(V[vmap], local.reshape(-1, 3), vmap, faces, charts[i].label, charts[i].name)
            try:
                check_chart(union.V, union.F, name=union.name)
            except ChartError:
                continue
            start = _aligned_union_start(union, charts[i], results[i].uv, charts[j], results[j].uv)
            res = parameterize_charts([union], starts=[start], **options)[0]
            if len(_invalid_faces(union, res)[0]) == 0:
                merges.append(dict(charts=[charts[i].name, charts[j].name], faces=int(len(faces)),
                                   seam_length=float(seam[k])))
                charts = [c for n, c in enumerate(charts) if n not in (i, j)] + [union]
                results = [r for n, r in enumerate(results) if n not in (i, j)] + [res]
                merged = True
                note("merge", len(merges), len(merges))
                break
            if attempts >= budget or time.perf_counter() >= deadline:
                break
        if not merged:
            break
    return charts, results, merges


def _aligned_union_start(union, ci, uvi, cj, uvj):
    """Start map of the union of two charts: chart j's map moved rigidly (2D Kabsch, no reflection)
    onto chart i's at their shared vertices, shared vertices averaged."""
    shared, ii, jj = np.intersect1d(ci.vertex_map, cj.vertex_map, return_indices=True)
    _, _, uvj_aligned = rigid_align(uvj[jj], uvi[ii], uvj)
    pos = np.searchsorted(union.vertex_map, ci.vertex_map)
    start = np.zeros((len(union.vertex_map), 2))
    count = np.zeros(len(union.vertex_map))
    start[pos] += uvi
    count[pos] += 1
    pos = np.searchsorted(union.vertex_map, cj.vertex_map)
    start[pos] += uvj_aligned
    count[pos] += 1
    return start / count[:, None]


def _distortion(chart, result):
    return chart_distortion(chart.V, chart.F, result.uv)


def _distortion_summary(charts, results):
    return distortion_summary([_distortion(c, r) for c, r in zip(charts, results)],
                              flipped=sum(r.n_flipped for r in results), energy=sum(r.energy for r in results))


def _pack_summary(packed):
    d = packed.to_dict() if hasattr(packed, "to_dict") else {}
    return {k: v for k, v in d.items() if k in ("efficiency", "scale", "texel_size_world", "texel_density", "method",
                                                 "time_s")}
