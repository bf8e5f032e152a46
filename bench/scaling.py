"""How uvbake's LM cost grows with the mesh, beside SLIM (20 iterations) and LSCM (one solve).

    python bench/scaling.py                    # 1k to 1M triangles (about 15 minutes on 2 cores)
    python bench/scaling.py --quick            # 1k to 30k triangles (under a minute)
    python bench/scaling.py --max-triangles 250000 --slim-max-vertices 110000

The charts are generated smooth surfaces: a k x k grid over the unit square lifted onto a height field
with two bumps and a saddle (non-developable, so LM has work to do), triangulated with alternating
diagonals (2 (k-1)^2 triangles, one boundary loop). Sizes run from about 1,000 to 1,000,000 triangles
and include a 103,684-vertex chart (k = 322) beside the 103,521-vertex disk of the targets.

Every (size, method) runs in a fresh subprocess, so peak memory is that run's alone: ``peak MB`` is the
process's peak resident set (ru_maxrss) minus its resident set just before the call (imports and the
mesh excluded).

- ``lm``: ``uvbake.parameterize(V, F, alpha=ALPHA, init="lscm", max_iter=--max-iter)``; total time is
  the whole call; time per iteration is the mean gap between consecutive iteration callbacks (one
  Hessian assembly and one CHOLMOD refactorisation + solve each; rejected steps included), so it
  excludes the LSCM start and the symbolic analysis.
- ``slim``: ``igl.slim_precompute`` + ``igl.slim_solve(data, 20)`` from uvbake's LSCM start (not timed).
- ``lscm``: ``igl.lscm`` with two boundary vertices pinned.

Writes ``bench/results/scaling.md``, ``scaling.json`` and ``scaling.png`` (log-log, with fitted
exponents: least squares of log time on log vertex count).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
GRID_SIDES = [23, 40, 72, 123, 224, 322, 448, 708]     # 968 ... 999,698 triangles
ALPHA = 0.5


def surface(k):
    """Smooth non-developable height-field chart on a k x k grid: (V, F)."""
    x, y = np.meshgrid(np.linspace(0.0, 1.0, k), np.linspace(0.0, 1.0, k), indexing="xy")
    z = (0.25 * np.exp(-((x - 0.3) ** 2 + (y - 0.35) ** 2) / 0.03)
         + 0.2 * np.exp(-((x - 0.7) ** 2 + (y - 0.65) ** 2) / 0.05)
         + 0.15 * (x - 0.5) * (y - 0.5))
    V = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    i, j = np.meshgrid(np.arange(k - 1), np.arange(k - 1), indexing="ij")
    a = (i * k + j).ravel()
    b, c, d = a + 1, a + k, a + k + 1
    flip = ((i + j) % 2 == 0).ravel()
    F1 = np.where(flip[:, None], np.stack([a, b, d], 1), np.stack([a, b, c], 1))
    F2 = np.where(flip[:, None], np.stack([a, d, c], 1), np.stack([b, d, c], 1))
    return V, np.concatenate([F1, F2]).astype(np.int64)


def _rss_mb():
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def child(method, k, alpha, max_iter):
    """Run one (method, size) in this process and print one JSON line."""
    V, F = surface(k)
    rec = dict(method=method, k=k, vertices=len(V), triangles=len(F))
    if method == "lm":
        import uvbake
        from uvbake.flatten.solvers.linalg import cholmod_available

        cholmod_available()
        stamps, cpu = [], []

        def cb(info):
            stamps.append(time.perf_counter())
            cpu.append(time.process_time())
            return False

        base = _rss_mb()
        t0, c0 = time.perf_counter(), time.process_time()
        r = uvbake.parameterize(V, F, alpha=alpha, init="lscm", max_iter=max_iter, callback=cb)
        rec["time_s"] = time.perf_counter() - t0
        rec["cpu_s"] = time.process_time() - c0
        gaps = np.diff(stamps)
        rec["per_iter_cpu_s"] = float(np.diff(cpu).mean()) if len(cpu) > 1 else float("nan")
        rec.update(iterations=r.iterations, converged=r.converged, flipped=r.n_flipped,
                   per_iter_s=float(gaps.mean()) if len(gaps) else float("nan"),
                   first_iter_at_s=float(stamps[0] - t0) if stamps else float("nan"),
                   linear_solver=r.extra.get("linear_solver"))
    elif method == "slim":
        import igl
        from threadpoolctl import threadpool_limits  # noqa: F401  (igl uses Eigen's own threads)

        from uvbake.flatten.starts import lscm

        uv0 = lscm(V, F)
        base = _rss_mb()
        t0, c0 = time.perf_counter(), time.process_time()
        data = igl.slim_precompute(np.asfortranarray(V), np.asfortranarray(F.astype(np.int32)),
                                   np.asfortranarray(uv0), igl.MappingEnergyType.SYMMETRIC_DIRICHLET,
                                   np.zeros(0, np.int32), np.zeros((0, 2), order="F"), 0.0)
        igl.slim_solve(data, 20)
        rec["time_s"] = time.perf_counter() - t0
        rec["cpu_s"] = time.process_time() - c0
    elif method == "lscm":
        import igl

        from uvbake.flatten.starts import farthest_boundary_pair

        p, q = farthest_boundary_pair(V, F)
        b = np.array([p, q], dtype=np.int64)
        bc = np.array([[0.0, 0.0], [np.linalg.norm(V[q] - V[p]), 0.0]])
        base = _rss_mb()
        t0, c0 = time.perf_counter(), time.process_time()
        igl.lscm(V, F, b, bc)
        rec["time_s"] = time.perf_counter() - t0
        rec["cpu_s"] = time.process_time() - c0
    else:
        raise SystemExit(f"unknown method {method}")
    rec["peak_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0 - base
    print(json.dumps(rec))


def run(method, k, alpha, max_iter, timeout):
    cmd = [sys.executable, __file__, "--child", method, str(k), str(alpha), str(max_iter)]
    try:
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return dict(method=method, k=k, error=f"timeout {timeout:g} s")
    if out.returncode:
        return dict(method=method, k=k, error=out.stderr.strip().splitlines()[-1] if out.stderr else "failed")
    return json.loads(out.stdout.strip().splitlines()[-1])


def fit(n, t):
    n, t = np.asarray(n, float), np.asarray(t, float)
    ok = np.isfinite(t) & (t > 0)
    if ok.sum() < 2:
        return float("nan")
    return float(np.polyfit(np.log(n[ok]), np.log(t[ok]), 1)[0])


def main(argv=None):
    if argv is None and len(sys.argv) > 1 and sys.argv[1] == "--child":
        _, _, method, k, alpha, max_iter = sys.argv
        child(method, int(k), float(alpha), int(max_iter))
        return
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="up to 30,000 triangles")
    ap.add_argument("--max-triangles", type=int, default=1_000_000)
    ap.add_argument("--slim-max-vertices", type=int, default=110_000,
                    help="SLIM above this is skipped (20 iterations on 103k vertices take over a minute)")
    ap.add_argument("--alpha", type=float, default=ALPHA)
    ap.add_argument("--max-iter", type=int, default=200, help="LM iteration cap")
    ap.add_argument("--timeout", type=float, default=900.0, help="seconds per run")
    ap.add_argument("--fit-min-vertices", type=int, default=5_000,
                    help="exponents are also fitted on sizes from this many vertices up")
    ap.add_argument("--out", type=Path, default=RESULTS)
    ap.add_argument("--render", action="store_true", help="re-make the table and plot from OUT/scaling.json")
    args = ap.parse_args(argv)
    cap = 30_000 if args.quick else args.max_triangles
    sides = [k for k in GRID_SIDES if 2 * (k - 1) ** 2 <= cap * 1.01]

    rows = []
    if args.render:
        rows = json.loads((args.out / "scaling.json").read_text())["rows"]
        sides = sorted({r["k"] for r in rows})
    for k in ([] if args.render else sides):
        for method in ("lscm", "lm", "slim"):
            if method == "slim" and k * k > args.slim_max_vertices:
                continue
            r = run(method, k, args.alpha, args.max_iter, args.timeout)
            r.setdefault("vertices", k * k)
            rows.append(r)
            print(json.dumps(r), file=sys.stderr, flush=True)

    def series(method, key):
        rs = [r for r in rows if r["method"] == method and key in r]
        return np.array([r["vertices"] for r in rs]), np.array([r[key] for r in rs])

    fits = {}
    for label, method, key in (("LM time per iteration", "lm", "per_iter_s"),
                               ("LM CPU time per iteration", "lm", "per_iter_cpu_s"),
                               ("LM total time", "lm", "time_s"),
                               ("LM iterations", "lm", "iterations"), ("LM peak memory", "lm", "peak_mb"),
                               ("SLIM 20 iterations", "slim", "time_s"), ("SLIM 20 iterations, CPU", "slim", "cpu_s"),
                               ("LSCM solve", "lscm", "time_s")):
        n, t = series(method, key)
        big = n >= args.fit_min_vertices
        fits[label] = dict(all=fit(n, t), large=fit(n[big], t[big]),
                           range=[int(n.min()), int(n.max())] if len(n) else None)

    by = {(r["method"], r["k"]): r for r in rows}
    lines = [f"# uvbake scaling ({time.strftime('%Y-%m-%d')})", "",
             f"Machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}. "
             f"Generated smooth height-field chart (one boundary loop), alpha = {args.alpha:g}, LSCM start, LM cap "
             f"{args.max_iter} iterations.", "",
             "| vertices | triangles | LM iterations | LM time / iteration (s) | LM CPU / iteration (s) "
             "| LM total (s) | LM total CPU (s) | LM peak MB | converged | flipped | SLIM 20 it. (s) "
             "| SLIM CPU (s) | SLIM peak MB | LSCM (s) | LSCM peak MB |",
             "|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|"]

    def g(m, k, key, fmt):
        r = by.get((m, k))
        if r is None:
            return "—"
        if "error" in r:
            return r["error"]
        v = r.get(key)
        return "—" if v is None else format(v, fmt)

    for k in sides:
        lm = by.get(("lm", k), {})
        lines.append(f"| {k * k:,} | {2 * (k - 1) ** 2:,} | {g('lm', k, 'iterations', 'd')} | "
                     f"{g('lm', k, 'per_iter_s', '.4f')} | {g('lm', k, 'per_iter_cpu_s', '.4f')} | "
                     f"{g('lm', k, 'time_s', '.2f')} | {g('lm', k, 'cpu_s', '.2f')} | "
                     f"{g('lm', k, 'peak_mb', '.0f')} | {'yes' if lm.get('converged') else 'no'} | "
                     f"{g('lm', k, 'flipped', 'd')} | {g('slim', k, 'time_s', '.2f')} | "
                     f"{g('slim', k, 'cpu_s', '.2f')} | "
                     f"{g('slim', k, 'peak_mb', '.0f')} | {g('lscm', k, 'time_s', '.3f')} | "
                     f"{g('lscm', k, 'peak_mb', '.0f')} |")
    lines += ["", "Fitted exponents p in time ~ n^p (n = vertices; least squares in log-log):", "",
              f"| quantity | p, all sizes | p, n >= {args.fit_min_vertices:,} |", "|---|---:|---:|"]
    for label, f in fits.items():
        lines.append(f"| {label} | {f['all']:.2f} | {f['large']:.2f} |")
    lines += ["", "Peak MB: the run's peak resident set minus the resident set just before the call. CPU: "
              "process CPU seconds (all threads); other jobs shared the 2 cores (load average at the end "
              "%.1f), so wall times are inflated and the CPU columns are the cleaner measure." % os.getloadavg()[1]]
    md = "\n".join(lines) + "\n"
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "scaling.md").write_text(md)
    (args.out / "scaling.json").write_text(json.dumps(dict(rows=rows, fits=fits), indent=1) + "\n")
    try:
        plot(series, fits, args.out / "scaling.png")
    except ImportError:
        print("matplotlib missing: no plot", file=sys.stderr)
    print(md)


def plot(series, fits, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(13, 5))
    ax = axes[0]
    for label, method, key, style in (("LM time per iteration", "lm", "per_iter_s", "o-"),
                                      ("LM total time", "lm", "time_s", "s-"),
                                      ("SLIM 20 iterations", "slim", "time_s", "^-"),
                                      ("LSCM solve", "lscm", "time_s", "d-")):
        n, t = series(method, key)
        if len(n):
            ax.loglog(n, t, style, label=f"{label} (p = {fits[label]['large']:.2f})")
    n, t = series("lm", "per_iter_s")
    if len(n):
        ref = n / n[0]
        ax.loglog(n, t[0] * ref, "k:", lw=1, label="n^1 from the smallest")
        ax.loglog(n, t[0] * ref ** 1.2, "k--", lw=1, label="n^1.2 from the smallest")
    ax.set_xlabel("vertices")
    ax.set_ylabel("seconds")
    ax.set_title("time against chart size (p: fitted on the larger sizes)")
    ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    ax = axes[1]
    for label, method, style in (("LM", "lm", "o-"), ("SLIM", "slim", "^-"), ("LSCM", "lscm", "d-")):
        n, m = series(method, "peak_mb")
        if len(n):
            ax.loglog(n, np.maximum(m, 1e-1), style, label=label)
    n, it = series("lm", "iterations")
    ax2 = ax.twinx()
    ax2.semilogx(n, it, "x--", color="grey", label="LM iterations")
    ax2.set_ylabel("LM iterations")
    ax.set_xlabel("vertices")
    ax.set_ylabel("peak memory added by the call (MB)")
    ax.set_title("memory and iterations")
    ax.legend(loc="upper left", fontsize=8)
    ax2.legend(loc="lower right", fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()
