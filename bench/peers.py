"""uvbake's atlases beside the tools users pick today, on every shared mesh and sample scene, in one run.

    python bench/peers.py                                   # everything (about 10-15 minutes on 2 cores)
    python bench/peers.py --meshes camelhead cow --methods uvbake xatlas --alphas 0.1 0.5
    python bench/peers.py --out /tmp/peers --name peers_before

Writes ``<out>/<name>.md`` (the table) and ``<name>.json`` (every number); default
``bench/results/peers``. Every method runs in a fresh process, one at a time, so the parent measures
that process's whole CPU time (``resource.getrusage(RUSAGE_CHILDREN)`` before and after; user +
system, all threads) besides the CPU of the unwrap call alone (``time.process_time`` inside it):

- ``uvbake-A``: unwrap CPU of ``uvbake.unwrap((V, F), face_labels=..., alpha=A)`` without a bake on
  the mesh already read, after uvbake's imports (as xatlas's is timed on arrays with the module
  loaded; repair included; see bench/peer_worker.py); whole CPU of the command
  ``uvbake MESH --alpha A --bake checker.png`` (1024 px checker, OBJ + MTL + PNG + JSON report
  written). The quality columns measure the in-process result (on the repaired mesh).
- ``xatlas``: ``xatlas.Atlas`` + ``generate()`` with defaults (what ``xatlas.parametrize`` runs);
  whole CPU: the worker process (imports, reading the mesh, the unwrap, writing the UVs).
- ``blender``: Smart UV Project then ``pack_islands`` through pip ``bpy`` in its own venv
  (``bench/blender_smart_project.py``; venv python from ``--bpy-python`` or ``$UVBAKE_BPY_PYTHON``,
  default ``/work/venvs/bpy/bin/python``). Unwrap CPU: the two operators (with edit mode), excluding
  ``import bpy`` and building the mesh; whole CPU: the process.
- ``uvatlas``: Open3D's ``compute_uvatlas()`` with defaults; whole CPU as for xatlas.

Peers get the mesh exactly as loaded (``uvbake.io.load.load_mesh``, no repair), closed meshes included. A
missing peer is reported as skipped, a crash or a timeout as failed; the run goes on.

Columns (definitions in uvbake/analysis/metrics.py; UVs measured in texel units of the method's own atlas
rectangle, so xatlas's per-axis normalisation is undone):

- charts: components of faces joined through uncut edges; seam: 3D length of cut interior edges.
- flipped, overlap pairs: ``uvbake.validate`` on the per-corner UVs (whole atlas).
- min share, < 1/4, < 1/16: the least texel share and the fraction of the surface area below 1/4
  and 1/16 of its fair share.
- angle: area-weighted mean sigma1/sigma2; area: area-weighted mean |log(area ratio)| after the best
  global scale (collapsed triangles left out of both and counted among the flipped).
- packing: sum of |UV triangle areas| / atlas rectangle area (chart texels / atlas texels, the
  definition of ``PackResult.efficiency``; meaningful only without overlaps).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
if str(HERE.parent) not in sys.path:
    sys.path.insert(0, str(HERE.parent))                # this checkout's uvbake first
from uvbake.analysis import metrics  # noqa: E402

ROOT = HERE.parent
MESHES = ROOT.parent / "shared" / "meshes"
SCENES = ROOT / "sample_scenes"
RESULTS = HERE / "results"
METHODS = ["uvbake", "xatlas", "blender", "uvatlas"]
DEFAULT_BPY = "/work/venvs/bpy/bin/python"
TEXTURE_PX = 1024
GUTTER_PX = 4


def mesh_paths():
    """Every mesh of ../shared/meshes (when present) and every sample scene, by name."""
    paths = sorted(MESHES.glob("*.off")) if MESHES.is_dir() else []
    paths += sorted(SCENES.glob("*.ply"))
    return {p.stem: p for p in paths}


def child_env():
    """The children import uvbake from this checkout (and its plugins) first (and run in it: ``-m`` puts the cwd first)."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), str(ROOT / "plugins")] + ([env["PYTHONPATH"]] if
                                                                               env.get("PYTHONPATH") else []))
    return env


def run_child(cmd, timeout, *, ok_codes=(0,)):
    """Run a command: (CPU seconds of it and its waited-for children, user + system; wall; exit code).

    An exit code outside ``ok_codes`` raises RuntimeError with the last line of its stderr.
    """
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=child_env(), cwd=ROOT)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if proc.returncode not in ok_codes:
        tail = (proc.stderr.strip().splitlines() or ["(no message)"])[-1]
        raise RuntimeError(f"exit {proc.returncode}: {tail}")
    return cpu, wall, proc.returncode


def uvbake_command():
    """How to run the uvbake command from this checkout (``python -m uvbake`` once it has __main__)."""
    return [sys.executable, "-m", "uvbake" if (ROOT / "uvbake" / "__main__.py").exists() else "uvbake.cli"]


# --------------------------------------------------------------------------------------------------
# methods: each returns (V, F, corner_uv, width, height, record)


def run_uvbake(path, inp, tmp, alpha, timeout, **_):
    out = tmp / "uvbake.npz"
    cpu, wall, _ = run_child([sys.executable, str(HERE / "peer_worker.py"), "uvbake", str(inp), str(out),
                              "--mesh", str(path), "--alpha", str(alpha)], timeout)
    d = np.load(out)
    rec = dict(unwrap_cpu_s=float(d["unwrap_cpu_s"]), worker_cpu_s=cpu, worker_wall_s=wall,
               own_charts=int(d["charts"]), valid=bool(d["valid"]))
    report = tmp / "report.json"
    try:
        # exit 1: the atlas is not valid (files are written all the same): the CPU time still counts
        ccpu, cwall, code = run_child(uvbake_command() + [str(path), "--alpha", str(alpha), "--bake",
                                                          str(tmp / "checker.png"), "-o", str(tmp / "out.obj"),
                                                          "--json", str(report), "-q"], timeout, ok_codes=(0, 1))
        r = json.loads(report.read_text())
        rec.update(whole_cpu_s=ccpu, whole_wall_s=cwall, command_exit=code, command_charts=r.get("charts_final"),
                   command_bake_wall_s=r.get("timings", {}).get("bake_s"))
    except (RuntimeError, subprocess.TimeoutExpired) as exc:
        rec.update(whole_cpu_s=None, command_error=str(exc))
    return d["V"], d["F"], d["corner_uv"], 1, 1, rec


def run_peer(method, path, inp, tmp, timeout, bpy_python, **_):
    out = tmp / f"{method}.npz"
    if method == "blender":
        cmd = [bpy_python, str(HERE / "blender_smart_project.py"), str(inp), str(out),
               "--gutter-px", str(GUTTER_PX), "--texture-size", str(TEXTURE_PX)]
    else:
        cmd = [sys.executable, str(HERE / "peer_worker.py"), method, str(inp), str(out)]
    cpu, wall, _ = run_child(cmd, timeout)
    d = np.load(out)
    rec = dict(unwrap_cpu_s=float(d["unwrap_cpu_s"]), whole_cpu_s=cpu, whole_wall_s=wall)
    for k in ("charts", "atlases", "max_stretch", "smart_cpu_s", "pack_cpu_s", "build_cpu_s", "import_cpu_s"):
        if k in d:
            rec["own_charts" if k == "charts" else k] = d[k].item()
    width, height = (int(d["width"]), int(d["height"])) if "width" in d else (1, 1)
    return None, None, d["corner_uv"], width, height, rec


def missing(method, bpy_python):
    """Why a method cannot run here, or None."""
    if method == "blender":
        return None if Path(bpy_python).exists() else f"no bpy python at {bpy_python} (--bpy-python)"
    mod = {"xatlas": "xatlas", "uvatlas": "open3d"}.get(method)
    return None if mod is None or importlib.util.find_spec(mod) else f"{mod} not installed"


# --------------------------------------------------------------------------------------------------
# measuring


def measure(V, F, corner_uv, width=1, height=1):
    """Every column of the table for one atlas (per-corner UVs normalised to its w x h rectangle)."""
    import uvbake

    C = np.asarray(corner_uv, np.float64) * np.array([width, height], dtype=np.float64)   # texel units
    side = float(max(width, height))
    unit = C / side
    rep = uvbake.validate(unit, F)
    d = metrics.distortion(V, F, C)
    rec = dict(charts=int(metrics.chart_ids(F, C).max()) + 1, seam=metrics.uv_seam_length(V, F, C),
               flipped=int(rep.n_flipped), overlaps=int(rep.n_overlaps), angle=d["angle_mean"], area=d["area"],
               collapsed=d["n_collapsed"],
               packing=metrics.packing_efficiency(unit, F) / ((width / side) * (height / side)))
    rec.update(metrics.texel_summary(V, F, C))
    return rec


def run_case(name, path, methods, alphas, *, timeout, bpy_python, log):
    from uvbake.io.load import load_mesh

    mesh = load_mesh(path)
    V = np.asarray(mesh.V, np.float64)
    F = np.asarray(mesh.F, np.int64)
    log(f"{name}: {len(V):,} vertices, {len(F):,} faces")
    rows = []
    with tempfile.TemporaryDirectory(prefix="uvbake_peers_") as tmpdir:
        tmp = Path(tmpdir)
        inp = tmp / "mesh.npz"
        np.savez(inp, V=V, F=F)
        runs = [(f"uvbake-{a:g}", "uvbake", a) for a in alphas if "uvbake" in methods]
        runs += [(m, m, None) for m in METHODS[1:] if m in methods]
        for label, method, alpha in runs:
            rec = dict(mesh=name, method=label, vertices=len(V), faces=len(F))
            why = missing(method, bpy_python)
            if why:
                rec["skipped"] = why
            else:
                try:
                    if method == "uvbake":
                        Vm, Fm, C, w, h, extra = run_uvbake(path, inp, tmp, alpha, timeout)
                    else:
                        Vm, Fm, C, w, h, extra = run_peer(method, path, inp, tmp, timeout, bpy_python)
                    rec.update(extra)
                    rec.update(measure(V if Vm is None else Vm, F if Fm is None else Fm, C, w, h))
                except subprocess.TimeoutExpired:
                    rec["failed"] = f"timeout after {timeout:g} s"
                except Exception as exc:   # a peer's crash is a result, not the end of the run
                    rec["failed"] = f"{type(exc).__name__}: {exc}"
            rows.append(rec)
            log("  " + one_line(rec))
    return rows


# --------------------------------------------------------------------------------------------------
# output


def _num(x, fmt):
    return "—" if x is None or (isinstance(x, float) and not np.isfinite(x)) else format(x, fmt)


def _share(x):
    return "—" if x is None else (f"{x:.2g}" if x < 0.01 else f"{x:.2f}")


def one_line(r):
    if "skipped" in r or "failed" in r:
        return f"{r['method']:11s} {r.get('skipped') or r.get('failed')}"
    return (f"{r['method']:11s} cpu {r['unwrap_cpu_s']:7.2f} / {_num(r.get('whole_cpu_s'), '7.2f')} s  "
            f"charts {r['charts']:4d}  flipped {r['flipped']}  overlaps {r['overlaps']}  "
            f"min share {_share(r['min_texel_share'])}  <1/16 {100 * r['area_below_sixteenth']:.1f}%  "
            f"packing {100 * r['packing']:.1f}%")


def table(rows):
    head = ("| mesh | method | CPU unwrap (s) | CPU whole (s) | charts | seam | flipped | overlap pairs "
            "| min share | area < 1/4 | area < 1/16 | angle | area | packing |")
    lines = [head, "|---|---|" + "---:|" * 12]
    for r in rows:
        if "skipped" in r or "failed" in r:
            lines.append(f"| {r['mesh']} | {r['method']} | {'skipped' if 'skipped' in r else 'failed'}: "
                         f"{r.get('skipped') or r.get('failed')} |" + " |" * 11)
            continue
        charts = f"{r['charts']:,}" + (f" ({r['own_charts']:,})" if r.get("own_charts") not in (None, r["charts"])
                                       else "")
        lines.append(
            f"| {r['mesh']} | {r['method']} | {r['unwrap_cpu_s']:.2f} | {_num(r.get('whole_cpu_s'), '.2f')} | "
            f"{charts} | {r['seam']:.3g} | {r['flipped']:,} | {r['overlaps']:,} | {_share(r['min_texel_share'])} | "
            f"{100 * r['area_below_quarter']:.1f}% | {100 * r['area_below_sixteenth']:.1f}% | "
            f"{r['angle']:.3f} | {r['area']:.3f} | {100 * r['packing']:.1f}% |")
    return "\n".join(lines)


def commit():
    try:
        out = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True,
                             text=True, timeout=10)
        dirty = subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain", "--", "uvbake", "bench"],
                               capture_output=True, text=True, timeout=10).stdout.strip()
        return out.stdout.strip() + (" with uncommitted changes" if dirty else "") if out.returncode == 0 else "?"
    except (OSError, subprocess.SubprocessError):
        return "?"


def machine(load_start):
    from importlib.metadata import PackageNotFoundError, version

    vers = {}
    for mod in ("xatlas", "open3d", "numpy", "scipy"):
        try:
            vers[mod] = version(mod)
        except PackageNotFoundError:
            vers[mod] = "missing"
    model = "?"
    try:
        model = next(line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo") if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return (f"{model} ({platform.machine()}, {os.cpu_count()} cores), Python {platform.python_version()}; "
            + ", ".join(f"{k} {v}" for k, v in vers.items())
            + "; load average (1 min) %.1f at the start, %.1f at the end" % (load_start, os.getloadavg()[0]))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    names = mesh_paths()
    ap.add_argument("--meshes", nargs="+", default=None, help=f"subset of {sorted(names)} (default: all)")
    ap.add_argument("--methods", nargs="+", default=METHODS, choices=METHODS)
    ap.add_argument("--alphas", nargs="+", type=float, default=[0.5], help="uvbake's alphas (default 0.5)")
    ap.add_argument("--timeout", type=float, default=900.0, help="seconds per process before it counts as failed")
    ap.add_argument("--bpy-python", default=os.environ.get("UVBAKE_BPY_PYTHON", DEFAULT_BPY))
    ap.add_argument("--out", type=Path, default=RESULTS)
    ap.add_argument("--name", default="peers", help="file stem of the .md and .json written (default peers)")
    args = ap.parse_args(argv)
    unknown = sorted(set(args.meshes or []) - set(names))
    if unknown:
        ap.error(f"unknown mesh(es) {unknown}; choose from {sorted(names)}")
    if not MESHES.is_dir():
        print(f"note: {MESHES} not found; only the sample scenes are run", file=sys.stderr)

    def log(msg):
        print(msg, file=sys.stderr, flush=True)

    load_start = os.getloadavg()[0]
    t0 = time.perf_counter()
    rows = []
    for name in (args.meshes or list(names)):
        rows += run_case(name, names[name], args.methods, args.alphas, timeout=args.timeout,
                         bpy_python=args.bpy_python, log=log)
    minutes = (time.perf_counter() - t0) / 60.0
    md = [f"# uvbake and peers ({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())})", "",
          f"`python bench/peers.py {' '.join(argv if argv is not None else sys.argv[1:])}`".replace(" `", "`")
          + f" on uvbake commit {commit()}.", "",
          f"Machine: {machine(load_start)}. The run took {minutes:.1f} min. CPU seconds are process CPU "
          "(user + system, all threads), so they are far less sensitive than wall time to other jobs "
          "sharing the cores, but not immune (caches, memory bandwidth).", "",
          table(rows), "",
          "CPU unwrap: the unwrap call alone, imports and file reading excluded as for xatlas (uvbake: "
          "`uvbake.unwrap((V, F), alpha=A)`, repair included, no bake; blender: `smart_project` + `pack_islands`). CPU whole: the whole process "
          "(uvbake: the command `uvbake MESH --alpha A --bake checker.png`; peers: a process importing the "
          "tool, reading the mesh, unwrapping and writing the UVs). charts: through uncut edges (the "
          "method's own count in brackets where it differs). seam: 3D length of cut edges. flipped, "
          "overlap pairs: `uvbake.validate`. min share, area < 1/4, < 1/16: texel share s_t = (UV area_t / "
          "UV total) / (3D area_t / 3D total), its least value and the surface fraction below 1/4 and "
          "1/16. angle: area-weighted mean sigma1/sigma2. area: area-weighted mean |log area ratio| after "
          "the best global scale. packing: chart texels / atlas texels. Definitions: bench/peers.py, "
          "uvbake/analysis/metrics.py.", ""]
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / f"{args.name}.md").write_text("\n".join(md) + "\n")
    (args.out / f"{args.name}.json").write_text(json.dumps(rows, indent=1, default=float) + "\n")
    print("\n".join(md))


if __name__ == "__main__":
    main()
