"""Per-chart flattening beside libigl (LSCM, ARAP, SLIM) and the atlas tools: the paper's Table 4 study.

    python bench/flatten_peers.py                      # everything (about 5 minutes on 2 cores)
    python bench/flatten_peers.py --quick              # small meshes only, no UVAtlas (about 20 s)
    python bench/flatten_peers.py --meshes camelhead --methods uvbake-0.1 lscm uvatlas

Writes ``bench/results/flatten_peers.md`` (the peers table and the Table 4 verdicts), ``flatten_peers.json`` (every
number) and ``flatten_peers.png``. Peers come from the optional ``bench`` extra (``pip install -e .[bench]``):
libigl (LSCM, ARAP, SLIM), xatlas; Open3D (UVAtlas) is a runtime dependency already. A missing peer
is reported as skipped, never an error.

Methods
-------
- ``uvbake-0.1``, ``uvbake-0.5``: ``uvbake.parameterize(V, F, alpha=..., init="lscm")`` per chart; time
  is the whole call (LSCM start included).
- ``lscm``: ``igl.lscm`` with the two farthest boundary vertices pinned at their 3D distance.
- ``arap``: ``igl.arap_precomputation`` / ``igl.arap_solve`` (2D elements energy), 100 local/global
  iterations from the LSCM map, one vertex pinned, ``with_dynamics=False`` (the dynamics option
  misbehaves on meshes with large coordinates). Time includes the LSCM start.
- ``slim``: ``igl.slim_precompute`` + 20 ``igl.slim_solve`` iterations of the symmetric Dirichlet energy
  from the LSCM map (SLIM needs a flip-free start: where LSCM flips, SLIM's result is not meaningful and
  the table says so), no constraints. Time includes the LSCM start.
- ``xatlas``: ``xatlas.Atlas`` with default chart and pack options on the whole mesh (it cuts its own
  charts and packs them). Its UVs are normalised by atlas width and height separately, so u is
  multiplied by the width and v by the height (texels) before measuring.
- ``uvatlas``: Open3D's ``TriangleMesh.compute_uvatlas()`` (size 512, gutter 1, max stretch 1/6) on the
  whole mesh; it cuts and packs.

Per-chart methods run on each input chart (labelled scenes: the labelled charts; research meshes: the
mesh itself), so their seams are the chart borders; they do not pack. Overlaps of per-chart methods
are counted within charts (their charts are not laid out together); for packers over the whole atlas.
Metric definitions are in ``uvbake/analysis/metrics.py``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
if str(HERE.parent) not in sys.path:
    sys.path.insert(0, str(HERE.parent))                # this checkout's uvbake first
from peers import MESHES, RESULTS, SCENES  # noqa: E402

from uvbake.analysis import metrics  # noqa: E402

RESEARCH = ["halftunnel", "camelhead", "beetle"]
SAMPLE = ["disk_holes", "sphere_cap", "scene", "multi_component"]
CLOSED = ["bumpy", "cow", "fandisk"]          # Table 4 only, opened by removing one vertex's faces
METHODS = ["uvbake-0.1", "uvbake-0.5", "uvbake-atlas-0.1", "uvbake-atlas-0.5", "lscm", "arap", "slim", "xatlas", "uvatlas"]
PER_CHART = {"uvbake-0.1", "uvbake-0.5", "lscm", "arap", "slim"}
TABLE4_METHODS = ["uvbake-0.1", "uvbake-0.5", "uvbake-atlas-0.1", "uvbake-atlas-0.5", "lscm", "arap"]
ARAP_ITERS = 100
SLIM_ITERS = 20


# --------------------------------------------------------------------------------------------------
# cases


def open_closed(V, F):
    """A genus-0 closed mesh made a disk by removing the faces around vertex 0.

    Removes the faces incident to vertex 0 and drops that vertex: one boundary loop (its link).
    """
    keep = ~np.any(F == 0, axis=1)
    F = F[keep]
    used = np.unique(F)
    remap = np.full(len(V), -1)
    remap[used] = np.arange(len(used))
    return V[used], remap[F]


def load_case(name):
    """(V, F, charts) of a case; charts are uvbake Chart records (one for a single-chart mesh)."""
    import uvbake
    from uvbake.io.load import load_mesh

    if name in SAMPLE:
        m = load_mesh(SCENES / f"{name}.ply")
        V, F, labels = m.V, m.F, m.face_labels
    else:
        m = load_mesh(MESHES / f"{name}.off")
        V, F, labels = m.V, m.F, None
        if name in CLOSED:
            V, F = open_closed(V, F)
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    return V, F, uvbake.split_charts(V, F, labels)


# --------------------------------------------------------------------------------------------------
# methods: per chart (return per-vertex uv of the chart) and whole mesh (return per-corner uv)


def _pins(V, F):
    from uvbake.flatten.starts import farthest_boundary_pair

    p, q = farthest_boundary_pair(V, F)
    return p, q


def igl_lscm(V, F):
    import igl

    p, q = _pins(V, F)
    b = np.array([p, q], dtype=np.int64)
    bc = np.array([[0.0, 0.0], [np.linalg.norm(V[q] - V[p]), 0.0]])
    uv, _ = igl.lscm(V, F, b, bc)
    return uv


def igl_arap(V, F):
    import igl

    uv0 = igl_lscm(V, F)
    p, _ = _pins(V, F)
    data = igl.ARAPData()
    data.max_iter = ARAP_ITERS
    data.with_dynamics = False
    b = np.array([p], dtype=np.int32)
    igl.arap_precomputation(V, F, 2, b, data)
    return igl.arap_solve(uv0[[p]], data, uv0)


def igl_slim(V, F, iters=SLIM_ITERS, uv0=None):
    import igl

    if uv0 is None:
        uv0 = igl_lscm(V, F)
    start_flipped = int(len(metrics.flipped(F, uv0)))
    data = igl.slim_precompute(np.asfortranarray(V), np.asfortranarray(F.astype(np.int32)),
                               np.asfortranarray(uv0), igl.MappingEnergyType.SYMMETRIC_DIRICHLET,
                               np.zeros(0, np.int32), np.zeros((0, 2), order="F"), 0.0)
    return np.asarray(igl.slim_solve(data, iters))[:, :2], dict(start_flipped=start_flipped)


def uvbake_run(alpha):
    def run(V, F):
        import uvbake

        r = uvbake.parameterize(V, F, alpha=alpha, init="lscm")
        return r.uv, dict(iterations=r.iterations, converged=r.converged, solver_flipped=r.n_flipped)
    return run


def xatlas_run(V, F):
    import xatlas

    atlas = xatlas.Atlas()
    atlas.add_mesh(V.astype(np.float32), F.astype(np.uint32))
    atlas.generate()
    vmap, idx, uvs = atlas[0]
    if not np.array_equal(vmap[idx].astype(np.int64), F):
        raise RuntimeError("xatlas reordered faces")
    C = uvs[idx].astype(np.float64)                       # normalised by width and height separately
    info = dict(own_charts=int(atlas.chart_count), atlases=int(atlas.atlas_count),
                utilization=float(atlas.utilization), width=int(atlas.width), height=int(atlas.height))
    texel = C * np.array([atlas.width, atlas.height], dtype=np.float64)
    side = float(max(atlas.width, atlas.height))
    return texel, info, texel / side, (atlas.width / side) * (atlas.height / side)


def uvbake_atlas_run(alpha):
    """The whole uvbake pipeline (what the CLI runs): splits charts until nothing flips or overlaps."""
    def run(V, F):
        import uvbake

        res = uvbake.unwrap((V, F), alpha=alpha, texture_size_px=1024, gutter_px=4)
        C = res.corner_uv.astype(np.float64)
        info = dict(own_charts=int(res.report["charts_final"]), splits=len(res.report["splits"]),
                    valid=bool(res.report["valid"]))
        return C, info, C, 1.0
    return run


def uvatlas_run(V, F):
    import open3d as o3d

    m = o3d.t.geometry.TriangleMesh()
    m.vertex.positions = o3d.core.Tensor(V.astype(np.float32))
    m.triangle.indices = o3d.core.Tensor(F.astype(np.int32))
    stretch, n_charts, parts = m.compute_uvatlas()
    C = m.triangle.texture_uvs.numpy().astype(np.float64)
    return C, dict(own_charts=int(n_charts), max_stretch=float(stretch)), C, 1.0


PER_CHART_FN = {"uvbake-0.1": uvbake_run(0.1), "uvbake-0.5": uvbake_run(0.5), "lscm": igl_lscm,
                "arap": igl_arap, "slim": igl_slim}
ATLAS_FN = {"xatlas": xatlas_run, "uvatlas": uvatlas_run,
            "uvbake-atlas-0.1": uvbake_atlas_run(0.1), "uvbake-atlas-0.5": uvbake_atlas_run(0.5)}
NEEDS = {"lscm": "igl", "arap": "igl", "slim": "igl", "xatlas": "xatlas", "uvatlas": "open3d"}


def available(method):
    import importlib.util

    mod = NEEDS.get(method)
    return mod is None or importlib.util.find_spec(mod) is not None


# --------------------------------------------------------------------------------------------------
# one run


def run_method(method, V, F, charts):
    """Run one method on one case and measure it: a dict of numbers."""
    import uvbake

    rec = dict(method=method)
    if method in PER_CHART:
        fn = PER_CHART_FN[method]
        C = np.zeros((len(F), 3, 2))
        t_total = 0.0
        n_overlaps = n_overlaps_global = 0
        extras = []
        offset = 0.0
        c_total = 0.0
        for ch in charts:
            t0, c0 = time.perf_counter(), time.process_time()
            out = fn(ch.V, ch.F)
            t_total += time.perf_counter() - t0
            c_total += time.process_time() - c0
            uv, extra = (out if isinstance(out, tuple) else (out, {}))
            uv = np.asarray(uv, dtype=np.float64)
            extras.append(extra)
            ok = np.all(np.isfinite(uv))
            if ok:
                rep = uvbake.validate(uv, ch.F)
                n_overlaps += rep.n_overlaps
                n_overlaps_global += _global_overlaps(rep)
            else:
                n_overlaps = -1
            # lay charts apart so no two charts share a UV by accident (cut detection)
            uvc = uv - np.nanmin(uv, axis=0) + [offset, 0.0]
            offset = float(np.nanmax(uvc[:, 0])) + 1.0 if ok else offset + 1.0
            C[ch.face_index] = uvc[ch.F]
        rec.update(time_s=t_total, cpu_s=c_total, packed=False, packing=None, own_charts=len(charts),
                   overlaps=n_overlaps, overlaps_global=n_overlaps_global)
        if extras and "start_flipped" in extras[0]:
            rec["start_flipped"] = sum(e["start_flipped"] for e in extras)
        if extras and "iterations" in extras[0]:
            rec["iterations"] = [e["iterations"] for e in extras]
            rec["converged"] = all(e["converged"] for e in extras)
    else:
        t0, c0 = time.perf_counter(), time.process_time()
        C, info, C_unit, frame_area = ATLAS_FN[method](V, F)
        rec["time_s"] = time.perf_counter() - t0
        rec["cpu_s"] = time.process_time() - c0
        rep = uvbake.validate(C_unit, F)
        rec.update(info, packed=True, packing=metrics.packing_efficiency(C_unit) / frame_area,
                   overlaps=rep.n_overlaps, overlaps_global=_global_overlaps(rep))
        if "own_charts" not in rec:
            rec["own_charts"] = None
    if not np.all(np.isfinite(C)):
        rec.update(finite=False)
        return rec
    mm = metrics.measure(V, F, C)
    rec.update(finite=True, angle_mean=mm.angle_mean, angle_max=mm.angle_max, area=mm.area,
               collapsed=mm.n_collapsed, charts=mm.n_charts, flipped=mm.n_flipped, seam=mm.seam_length)
    return rec


def _global_overlaps(rep):
    """Overlapping pairs in which neither face is flipped: boundary/global overlaps, not local fold-overs."""
    if not rep.n_overlaps:
        return 0
    flipped = np.zeros(rep.n_faces, bool)
    flipped[rep.flipped] = True
    P = rep.overlap_pairs
    return int(np.count_nonzero(~flipped[P[:, 0]] & ~flipped[P[:, 1]]))


# --------------------------------------------------------------------------------------------------
# output


def _fmt(x, nd=3):
    if x is None:
        return "—"
    if isinstance(x, float) and not np.isfinite(x):
        return "inf"
    return f"{x:.{nd}f}"


def peers_table(records, cases, methods):
    lines = ["| mesh | method | time (s) | CPU (s) | flipped | overlap pairs | angle mean | angle max | area | charts "
             "| seam length | packing |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for case in cases:
        for method in methods:
            r = records.get((case, method))
            if r is None:
                continue
            if "skipped" in r:
                lines.append(f"| {case} | {method} | skipped: {r['skipped']} ||||||||||")
                continue
            if not r.get("finite", True):
                lines.append(f"| {case} | {method} | {r['time_s']:.2f} | non-finite UVs ||||||||||")
                continue
            flips = f"{r['flipped']:,}" + (f" ({r['collapsed']} collapsed)" if r["collapsed"] else "")
            charts = f"{r['charts']:,}"
            if r.get("own_charts") not in (None, r["charts"]):
                charts += f" ({r['own_charts']:,})"
            name = method + (f" (start: {r['start_flipped']:,} flipped)" if r.get("start_flipped") else "")
            lines.append(
                f"| {case} | {name} | {r['time_s']:.2f} | {r['cpu_s']:.2f} | {flips} | {r['overlaps']:,} | "
                f"{_fmt(r['angle_mean'])} | {_fmt(r['angle_max'], 1)} | {_fmt(r['area'])} | {charts} | "
                f"{_fmt(r['seam'], 2)} | {_fmt(r['packing'], 2)} |")
    return "\n".join(lines)


def table4(records, cases):
    methods = [m for m in TABLE4_METHODS if any((c, m) in records for c in cases)]
    lines = ["| mesh | " + " | ".join(methods) + " |", "|---|" + "---|" * len(methods)]
    for case in cases:
        cells = []
        for m in methods:
            r = records.get((case, m))
            if r is None or "skipped" in r:
                cells.append("—")
            elif not r.get("finite", True):
                cells.append("non-finite")
            else:
                cells.append(f"{r['flipped']:,} / {'yes' if r['overlaps_global'] else 'no'}"
                             + (f" ({r['overlaps_global']:,})" if r["overlaps_global"] else ""))
        lines.append(f"| {case} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def plot(records, cases, methods, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(17, 5))
    colors = dict(zip(methods, plt.cm.tab10(np.arange(len(methods)))))
    ax = axes[0]
    width = 0.8 / len(methods)
    for j, m in enumerate(methods):
        ys = [records.get((c, m), {}).get("time_s", np.nan) if "skipped" not in records.get((c, m), {})
              else np.nan for c in cases]
        ax.bar(np.arange(len(cases)) + (j - len(methods) / 2 + 0.5) * width, ys, width, label=m,
               color=colors[m])
    ax.set_yscale("log")
    ax.set_xticks(np.arange(len(cases)))
    ax.set_xticklabels(cases, rotation=30, ha="right")
    ax.set_ylabel("wall time (s), log scale")
    ax.set_title("speed")
    ax.legend(fontsize=8)
    markers = dict(zip(cases, "osD^v<>ph*"))
    for ax, key, label in ((axes[1], "area", "area distortion (mean |log s²σ1σ2|)"),
                           (axes[2], "seam", "seam length (3D units)")):
        for (c, m), r in records.items():
            if c not in cases or m not in methods or "skipped" in r or not r.get("finite", True):
                continue
            ax.scatter(r[key], r["angle_mean"], color=colors[m], marker=markers[c], s=40,
                       edgecolor="k" if r["flipped"] or r["overlaps"] else "none")
        ax.set_xlabel(label)
        ax.set_ylabel("angle distortion (area-weighted mean σ1/σ2)")
        ax.set_yscale("log")
        if key == "seam":
            ax.set_xscale("symlog", linthresh=1.0)
    for c in cases:
        axes[1].scatter([], [], marker=markers[c], color="grey", label=c)
    axes[1].legend(fontsize=8, title="mesh (black edge: flips or overlaps)", title_fontsize=8)
    axes[1].set_title("quality (lower left is better)")
    axes[2].set_title("seams traded for distortion")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def machine():
    try:
        from uvbake.flatten.solvers.linalg import cholmod_available
        lin = "CHOLMOD" if cholmod_available() else "SuperLU"
    except Exception:  # pragma: no cover
        lin = "?"
    vers = {}
    from importlib.metadata import PackageNotFoundError, version
    for mod in ("libigl", "xatlas", "open3d", "numpy", "scipy"):
        try:
            vers[mod] = version(mod)
        except PackageNotFoundError:
            vers[mod] = "missing"
    load = ", load average at the end %.1f / %.1f / %.1f" % os.getloadavg()
    return (f"{platform.machine()}, {os.cpu_count()} cores{load}, Python {platform.python_version()}, uvbake linear "
            f"solver {lin}; " + ", ".join(f"{k} {v}" for k, v in vers.items()))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--meshes", nargs="+", default=None, help=f"from {RESEARCH + SAMPLE + CLOSED}")
    ap.add_argument("--methods", nargs="+", default=METHODS, choices=METHODS)
    ap.add_argument("--quick", action="store_true", help="halftunnel and sample scenes, no UVAtlas")
    ap.add_argument("--no-table4", action="store_true", help="skip the opened closed meshes of Table 4")
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args(argv)

    have_meshes = MESHES.is_dir()
    if args.meshes:
        cases = args.meshes
    else:
        cases = ([m for m in RESEARCH if m != "beetle" and m != "camelhead"] if args.quick else RESEARCH)
        cases = (cases if have_meshes else []) + SAMPLE
    methods = [m for m in args.methods if not (args.quick and m == "uvatlas")]
    t4_cases = [] if (args.no_table4 or args.quick or args.meshes or not have_meshes) else CLOSED
    if not have_meshes:
        print(f"note: {MESHES} not found; research meshes skipped", file=sys.stderr)

    records = {}
    for case in cases + t4_cases:
        V, F, charts = load_case(case)
        print(f"{case}: {len(V):,} vertices, {len(F):,} faces, {len(charts)} chart(s)", file=sys.stderr)
        for method in (methods if case not in CLOSED else [m for m in methods if m in TABLE4_METHODS]):
            if not available(method):
                records[(case, method)] = dict(method=method, skipped=f"{NEEDS[method]} not installed")
                continue
            r = run_method(method, V, F, charts)
            r.update(case=case, vertices=len(V), faces=len(F))
            records[(case, method)] = r
            print(f"  {method:11s} {r['time_s']:8.2f} s  flipped {r.get('flipped')}  overlaps "
                  f"{r.get('overlaps')}  angle {r.get('angle_mean', float('nan')):.4f}  area "
                  f"{r.get('area', float('nan')):.4f}  charts {r.get('charts')}", file=sys.stderr, flush=True)

    args.out.mkdir(parents=True, exist_ok=True)
    sizes = {c: next(r for (cc, _), r in records.items() if cc == c) for c in cases + t4_cases}
    head = [f"# uvbake and peers ({time.strftime('%Y-%m-%d')})", "", f"Machine: {machine()}.", "",
            "Meshes: " + ", ".join(f"{c} ({sizes[c]['vertices']:,} v, {sizes[c]['faces']:,} f)"
                                   for c in cases + t4_cases) + ".", ""]
    md = head + ["## Peers", "", peers_table(records, cases, methods), "",
                 "time: wall seconds of the whole method (CPU: process CPU seconds, all threads; other jobs shared the "
                 "2 cores during this run, so wall times are inflated where the load average exceeds 2) (uvbake: `parameterize` incl. its LSCM start; ARAP and "
                 "SLIM: incl. the LSCM start); flipped: against the chart's orientation (collapsed: zero UV "
                 "area, left out of the distortion columns); overlap pairs: `uvbake.validate` (per-chart "
                 "methods: within charts; packers: whole atlas); angle: sigma1/sigma2, area-weighted mean and "
                 "max; area: area-weighted mean |log(s^2 sigma1 sigma2)| after the best global s (weighted "
                 "median); charts: components through uncut edges (the method's own count in brackets where "
                 "it differs); seam length: 3D length of cut interior edges; packing: UV area / atlas area. SLIM 'start: k "
                 "flipped': its LSCM start had flipped triangles, where the symmetric Dirichlet energy is "
                 "infinite, and SLIM returned that start unchanged or barely moved.",
                 ""]
    if any(c in RESEARCH + CLOSED for c in cases + t4_cases):
        t4c = [c for c in RESEARCH + CLOSED if c in cases + t4_cases]
        md += ["## Table 4 verdicts: flipped triangles / global overlaps", "", table4(records, t4c), "",
               "global overlaps: overlapping pairs of which neither face is flipped (boundary crossings, not "
               "local fold-overs; count in brackets). ABF / ABF++ (the paper's other peer) has no Python package "
               "and is not run. " + ("bumpy, cow and fandisk are closed: opened here by removing the faces "
                                      "around vertex 0 (one small hole), not by the paper's cuts." if t4_cases
                                      else ""), ""]
    (args.out / "flatten_peers.md").write_text("\n".join(md) + "\n")
    (args.out / "flatten_peers.json").write_text(json.dumps(
        [dict(r, case=c) for (c, _), r in records.items()], indent=1, default=float) + "\n")
    try:
        plot(records, cases, methods, args.out / "flatten_peers.png")
    except ImportError:
        print("matplotlib missing: no plot", file=sys.stderr)
    print("\n".join(md))


if __name__ == "__main__":
    main()
