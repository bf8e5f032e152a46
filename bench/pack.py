"""Benchmark of uvbake.pack_charts: packing efficiency and time per packer, texture size and gutter.

    python bench/pack.py              # all scenes, methods maxrects / xatlas / rectpack (those installed)
    python bench/pack.py --quick      # scene.ply only, texture 1024, gutter 4

Chart sets are real flattened charts (``uvbake.parameterize_charts(charts, alpha=0.5)``):
- scene.ply (8 labelled charts), multi_component.ply (4 components), both from sample_scenes/;
- beetle-30 / camelhead-40: the research meshes in ../shared/meshes cut into pieces by k-means on face
  centroids (each piece split into edge-connected charts; pieces that are not disks are skipped).

Every packing is checked: shapes kept (rigid + common scale), all UVs in [0,1]^2, and the exact minimum
distance between charts (boundary segment distances) at least the gutter. The efficiency column is
sum of |triangle areas| in texels / texture_size_px**2. Times are the best of ``--repeat`` runs.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

import uvbake  # noqa: E402
from uvbake.atlas.distance import min_chart_distance  # noqa: E402
from uvbake.atlas.pack import pack_charts  # noqa: E402
from uvbake.errors import InputError  # noqa: E402

from packers import rectpack_placer, xatlas_placer  # noqa: E402

SHARED = REPO.parent / "shared" / "meshes"


def flatten(charts):
    res = uvbake.parameterize_charts(charts, alpha=0.5)
    return [r.uv for r in res], [c.F for c in charts]


def scene(path):
    m = uvbake.load_mesh(path)
    return flatten(uvbake.split_charts(m.V, m.F, m.face_labels))


def kmeans_pieces(path, k, seed=0):
    """Cut a mesh into about ``k`` charts by k-means (Lloyd, 20 rounds) on face centroids."""
    from uvbake.errors import ChartError
    from uvbake.mesh.charts import check_chart

    m = uvbake.load_mesh(path)
    C = m.V[m.F].mean(axis=1)
    rng = np.random.default_rng(seed)
    centers = C[rng.choice(len(C), k, replace=False)]
    for _ in range(20):
        lab = np.argmin(((C[:, None, :] - centers[None]) ** 2).sum(-1), axis=1)
        centers = np.array([C[lab == j].mean(0) if np.any(lab == j) else centers[j] for j in range(k)])
    charts = uvbake.split_charts(m.V, m.F, lab.astype(np.int64), check=False)
    ok = []
    for c in charts:
        if len(c.F) < 4:
            continue
        try:
            check_chart(c.V, c.F, name=c.name)
        except ChartError:
            continue
        ok.append(c)
    return flatten(ok)


def datasets(quick=False):
    out = {"scene.ply": lambda: scene(REPO / "sample_scenes" / "scene.ply")}
    if quick:
        return out
    out["multi_component.ply"] = lambda: scene(REPO / "sample_scenes" / "multi_component.ply")
    if (SHARED / "beetle.off").exists():
        out["beetle-30"] = lambda: kmeans_pieces(SHARED / "beetle.off", 30)
    if (SHARED / "camelhead.off").exists():
        out["camelhead-40"] = lambda: kmeans_pieces(SHARED / "camelhead.off", 40)
    return out


PLACERS = {"xatlas": xatlas_placer, "rectpack": rectpack_placer}


def available_methods():
    methods = ["maxrects"]
    for name in ("xatlas", "rectpack"):
        try:
            __import__(name)
            methods.append(name)
        except ImportError:
            print(f"# {name} not installed: skipped", file=sys.stderr)
    return methods


def check(res, uvs, faces):
    """Shapes kept, in the unit square, gutter kept; returns the measured gap in texels."""
    for uv, q in zip(uvs, res.uv):
        rng = np.random.default_rng(0)
        i, j = np.triu_indices(len(uv), 1) if len(uv) < 300 else rng.integers(0, len(uv), (2, 2000))
        d0 = np.linalg.norm(uv[i] - uv[j], axis=1) * res.scale
        d1 = np.linalg.norm(q[i] - q[j], axis=1)
        assert np.allclose(d0, d1, rtol=1e-9, atol=1e-12), "shape changed"
        assert q.min() >= 0 and q.max() <= 1, "outside [0,1]^2"
    gap = min_chart_distance(res.uv, faces) * res.texture_size_px
    assert gap >= res.gutter_px * (1 - 1e-9), f"gutter {gap} < {res.gutter_px}"
    return gap


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--methods", default=None, help="comma-separated subset of maxrects,xatlas,rectpack")
    args = ap.parse_args(argv)
    methods = args.methods.split(",") if args.methods else available_methods()
    sizes = [1024] if args.quick else [1024, 2048]
    gutters = [4] if args.quick else [2, 4]
    print("| scene | charts | method | texture | gutter | efficiency | time (s) | min gap (px) |")
    print("|---|---:|---|---:|---:|---:|---:|---:|")
    summary = {}
    for name, make in datasets(args.quick).items():
        uvs, faces = make()
        for method in methods:
            for N in sizes:
                for g in gutters:
                    best, res = np.inf, None
                    for _ in range(args.repeat):
                        t0 = time.perf_counter()
                        try:
                            r = pack_charts(uvs, faces, texture_size_px=N, gutter_px=g,
                                            method=PLACERS.get(method, method))
                        except (InputError, RuntimeError) as e:   # a peer failing is reported, not fatal
                            r = e
                            break
                        dt = time.perf_counter() - t0
                        if dt < best:
                            best, res = dt, r
                    if isinstance(r, Exception):
                        print(f"| {name} | {len(uvs)} | {method} | {N} | {g} | failed: {r} | | |", flush=True)
                        continue
                    gap = check(res, uvs, faces)
                    summary.setdefault(method, []).append(res.efficiency)
                    print(f"| {name} | {len(uvs)} | {method} | {N} | {g} | {100 * res.efficiency:.1f} % "
                          f"| {best:.3f} | {gap:.2f} |", flush=True)
    print()
    for method, effs in summary.items():
        print(f"# {method}: median efficiency {100 * np.median(effs):.1f} %, min {100 * np.min(effs):.1f} %")


if __name__ == "__main__":
    main()
