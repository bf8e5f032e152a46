"""The paper's experiments (Mejia, Acosta and Ruiz-Salguero 2017) on the meshes we have: prints Markdown.

    python bench/paper.py                                  # everything (several minutes on 2 cores)
    python bench/paper.py --only table3 --meshes beetle
    python bench/paper.py --only fig6 fig7 --mesh-fig cow

- Table 3: iterations, gradient norm and the second-order certificate from a random start at
  alpha = 0.5 (the paper's Table 3 does not restate its alpha here; 0.5 is its running example),
  beside the paper's iteration counts: uvbake's default trust-region Newton step and its damped
  (Levenberg-Marquardt, the paper's) step. uvbake's random start goes through the alpha = 0.1
  continuation (its iterations are counted, and shown in brackets).
- Fig. 6: one mesh from four starts (isomap, laplacian, random, lscm): the start, the map after
  10 iterations and the final map (docs/paper/fig6_<mesh>.png), and the final energies.
- Fig. 7/10: F per iteration for alpha in 0.1..0.9 from LSCM, and the relative sensitivity S(alpha)
  (Eq. 10) over alpha = 0, 0.1, ..., 1 (docs/paper/fig7_<mesh>.png).
- Table 4: flipped triangles and overlapping pairs of uvbake (alpha 0.5, one chart, LSCM start),
  LSCM and ARAP (libigl, as in bench/peers.py) and ABF++ (Blender's angle-based unwrap through bpy
  in its own venv, bench/blender_abf.py). A missing peer is reported as skipped.

Meshes: beetle (a disk with 11 holes), cow and fandisk (closed: the largest of the two disks the
pipeline's cut, uvbake.mesh.cut.cut_to_disks, makes of them). Needs ../shared/meshes.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
DOCS = HERE.parent / "docs" / "paper"

# The paper's Table 3: LM iterations from random starts.
PAPER_TABLE3 = {"beetle": 988, "sliced-glove": 985, "cow": 3195, "fandisk": 6699, "foot": 10211, "bull": 17918}
FIG6_INITS = ("isomap", "laplacian", "random", "lscm")


def load(name):
    """One disk of the mesh: the mesh itself when it is one (beetle), else the largest chart of the
    pipeline's cut (uvbake.mesh.cut.cut_to_disks) for closed meshes."""
    from peers import MESHES

    import uvbake
    from uvbake.io.load import load_mesh
    from uvbake.mesh.cut import cut_to_disks

    m = load_mesh(MESHES / f"{name}.off")
    V, F = np.asarray(m.V, np.float64), np.asarray(m.F, np.int64)
    charts = uvbake.split_charts(V, F, cut_to_disks(V, F))
    c = max(charts, key=lambda c: len(c.F))
    return c.V, c.F


def _save_small(fig, path):
    """Save a figure as a 16-colour palette PNG (line drawings: a tenth of the RGBA size)."""
    import io

    from PIL import Image

    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    buf.seek(0)
    Image.open(buf).convert("RGB").quantize(colors=16).save(path, optimize=True)


def table3(meshes, alpha=0.5):
    import uvbake

    lines = ["| mesh | vertices | init | iterations (at 0.1) | damped LM (at 0.1) | paper | F* | grad norm "
             "| lambda_min | local min | time (s) |",
             "|---|---:|---|---:|---:|---:|---:|---:|---:|---|---:|"]
    rows = []

    def its(r):
        cont = r.extra.get("continuation")
        return f"{r.iterations}" + (f" ({cont['iterations']})" if cont else "")

    for name in meshes:
        V, F = load(name)
        r = uvbake.parameterize(V, F, alpha=alpha, init="random", seed=0)
        lm = uvbake.parameterize(V, F, alpha=alpha, init="random", seed=0, step="damped", certificate=False)
        lines.append(f"| {name} | {len(V):,} | random | {its(r)} | {its(lm)} | {PAPER_TABLE3.get(name, '—'):,} | "
                     f"{r.energy:.10g} | {r.grad_norm:.1e} | {r.lambda_min:.3g} | "
                     f"{'yes' if r.is_local_minimum else 'no'} | {r.time_s:.1f} |")
        rows.append((name, alpha, "random", r))
        print(lines[-1], file=sys.stderr, flush=True)
    return "\n".join(lines), rows


def _draw(ax, uv, F, title):
    from matplotlib.collections import LineCollection

    E = np.unique(np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1), axis=0)
    ax.add_collection(LineCollection(uv[E], linewidths=0.15, colors="k"))
    ax.set_xlim(uv[:, 0].min(), uv[:, 0].max())
    ax.set_ylim(uv[:, 1].min(), uv[:, 1].max())
    ax.set_aspect("equal")
    ax.set_axis_off()
    ax.set_title(title, fontsize=7)


def fig6(name, alpha=0.5, snapshot=10):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    import uvbake

    V, F = load(name)
    fig, axes = plt.subplots(3, len(FIG6_INITS), figsize=(2.2 * len(FIG6_INITS), 6.2), dpi=110)
    lines = ["| start | flipped at start | iterations | F* | rel. difference to lscm | lambda_min |",
             "|---|---:|---:|---:|---:|---:|"]
    finals = {}
    rows = []
    for j, init in enumerate(FIG6_INITS):
        start = uvbake.parameterize(V, F, alpha=alpha, init=init, max_iter=0, certificate=False)
        mid = uvbake.parameterize(V, F, alpha=alpha, init=init, max_iter=snapshot, certificate=False)
        r = uvbake.parameterize(V, F, alpha=alpha, init=init)
        finals[init] = r
        rows.append((name, alpha, init, r))
        for i, (res, label) in enumerate([(start, "start"), (mid, f"after {snapshot} iterations"),
                                          (r, f"final, {r.iterations} it.")]):
            _draw(axes[i, j], res.uv, F, f"{init}: {label}\nF = {res.energy:.6g}")
        finals[init + "_start_flipped"] = start.n_flipped
    ref = finals["lscm"].energy
    for init in FIG6_INITS:
        r = finals[init]
        lines.append(f"| {init} | {finals[init + '_start_flipped']:,} | {r.iterations} | {r.energy:.12g} | "
                     f"{abs(r.energy - ref) / ref:.1e} | {r.lambda_min:.3g} |")
    fig.tight_layout()
    DOCS.mkdir(parents=True, exist_ok=True)
    path = DOCS / f"fig6_{name}.png"
    _save_small(fig, path)
    plt.close(fig)
    return "\n".join(lines) + f"\n\n![Fig. 6 on {name}]({path.relative_to(HERE.parent)})", rows


def fig7(name, alphas=(0.1, 0.3, 0.5, 0.7, 0.9)):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    import uvbake
    from uvbake.analysis.sensitivity import sweep

    V, F = load(name)
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(8, 3.2), dpi=110)
    rows = []
    for alpha in alphas:
        r = uvbake.parameterize(V, F, alpha=alpha, init="lscm")
        rows.append((name, alpha, "lscm", r))
        h = np.asarray(r.history)
        a1.semilogy(np.arange(len(h)), np.maximum(h - r.energy, 1e-16 * r.energy) / r.energy,
                    label=f"alpha {alpha:g} ({r.iterations} it.)")
    a1.set_xlabel("LM iteration")
    a1.set_ylabel("(F - F*) / F*")
    a1.legend(fontsize=7)
    s = sweep(V, F, np.round(np.linspace(0, 1, 11), 2), overlaps=False)
    a = [rec.alpha for rec in s.records]
    a2.plot(a, s.sensitivity, "o-")
    a2.set_xlabel("alpha")
    a2.set_ylabel("S(alpha) (Eq. 10)")
    fig.suptitle(f"{name}: F per iteration from LSCM, and the relative sensitivity", fontsize=9)
    fig.tight_layout()
    DOCS.mkdir(parents=True, exist_ok=True)
    path = DOCS / f"fig7_{name}.png"
    _save_small(fig, path)
    plt.close(fig)
    lines = ["| alpha | " + " | ".join(f"{x:g}" for x in a) + " |", "|---|" + "---:|" * len(a),
             "| F* | " + " | ".join(f"{rec.energy:.5g}" for rec in s.records) + " |",
             "| S(alpha) | " + " | ".join(f"{x:.3g}" for x in s.sensitivity) + " |",
             "| iterations | " + " | ".join(f"{rec.iterations}" for rec in s.records) + " |"]
    return "\n".join(lines) + f"\n\n![Fig. 7 on {name}]({path.relative_to(HERE.parent)})", rows


def table4(meshes):
    from blender_abf import abf
    from flatten_peers import available, igl_arap, igl_lscm

    import uvbake

    def ours(V, F):
        return uvbake.parameterize(V, F, alpha=0.5, init="lscm").uv

    methods = {"uvbake (alpha 0.5)": (ours, None), "LSCM (libigl)": (igl_lscm, "lscm"),
               "ARAP (libigl)": (igl_arap, "arap"), "ABF++ (Blender)": (lambda V, F: abf(V, F), None)}
    lines = ["| mesh | " + " | ".join(methods) + " |", "|---|" + "---|" * len(methods)]
    for name in meshes:
        V, F = load(name)
        cells = []
        for label, (fn, need) in methods.items():
            if need and not available(need):
                cells.append("skipped")
                continue
            t0 = time.perf_counter()
            out = fn(V, F)
            if out is None:
                cells.append("skipped (no bpy venv)")
                continue
            uv = out[0] if isinstance(out, tuple) else out
            rep = uvbake.validate(np.asarray(uv, dtype=np.float64), F)
            cells.append(f"{rep.n_flipped:,} / {rep.n_overlaps:,} ({time.perf_counter() - t0:.1f} s)")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
        print(lines[-1], file=sys.stderr, flush=True)
    return "\n".join(lines) + "\n\n(flipped triangles / overlapping triangle pairs, time incl. start)"


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--meshes", nargs="+", default=["beetle", "cow", "fandisk"])
    ap.add_argument("--mesh-fig", default="cow", help="mesh of Figs. 6 and 7 (default cow)")
    ap.add_argument("--only", nargs="+", default=["table3", "fig6", "fig7", "table4"],
                    choices=["table3", "fig6", "fig7", "table4"])
    args = ap.parse_args(argv)
    from peers import MESHES

    if not MESHES.is_dir():
        sys.exit(f"bench/paper.py: {MESHES} not found; the research meshes live beside the checkout")
    if "table3" in args.only:
        print("## Table 3: random starts, alpha 0.5\n\n" + table3(args.meshes)[0] + "\n", flush=True)
    if "fig6" in args.only:
        print(f"## Fig. 6: four starts on {args.mesh_fig}, alpha 0.5\n\n" + fig6(args.mesh_fig)[0] + "\n", flush=True)
    if "fig7" in args.only:
        print(f"## Fig. 7/10: F per iteration and S(alpha) on {args.mesh_fig}\n\n" + fig7(args.mesh_fig)[0] + "\n",
              flush=True)
    if "table4" in args.only:
        print("## Table 4: flips and overlaps\n\n" + table4(args.meshes) + "\n", flush=True)


if __name__ == "__main__":
    main()
