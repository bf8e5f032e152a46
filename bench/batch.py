"""Batch throughput on Dask: python bench/batch.py [--assets 200] [--full] [--out bench/results/batch.md]

Builds a corpus of small, varied meshes from the sample scenes and ../shared/meshes (Open3D quadric
decimation to 80-400 triangles, random rotations and anisotropic scales, midpoint subdivision of
coarser decimations; closed meshes are cut by uvbake itself), then unwraps all of it

1. in a plain in-process loop (``uvbake.unwrap`` + ``save``; one interpreter, imports paid once),
2. with ``uvbake.batch.run`` on a LocalCluster of 1 worker process, and
3. of 2 worker processes (one thread each),

and reports assets/hour/core, the scaling efficiency T1 / (2 T2), the overhead per asset of the Dask
path against the plain loop, and where that overhead goes (from the per-asset times in the summary). Default options:
alpha 0.5, texture 256 px, no bake and no preview (the per-asset work is small, so the overheads
show); ``--full`` adds the checker bake and 96 px previews. The load average is printed beside
every phase: on a shared machine the figures are lower bounds.
"""

import argparse
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
SHARED = HERE.parent.parent / "shared" / "meshes"
SCENES = HERE.parent / "sample_scenes"


def make_corpus(folder: Path, n: int, seed: int = 0) -> list:
    """``n`` meshes from every base mesh in turn: decimated, transformed, some subdivided (deterministic)."""
    import open3d as o3d

    bases = sorted(SCENES.glob("*.ply")) + sorted(SHARED.glob("*.off"))
    rng = np.random.default_rng(seed)
    meshes = []
    for p in bases:
        m = o3d.io.read_triangle_mesh(str(p))
        m.remove_duplicated_vertices()
        meshes.append((p.stem, m))
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for i in range(n):
        name, base = meshes[i % len(meshes)]
        kind = ("decimated", "transformed", "subdivided")[(i // len(meshes)) % 3]
        target = int(np.exp(rng.uniform(np.log(80), np.log(400))))
        m = o3d.geometry.TriangleMesh(base)
        if kind == "subdivided":
            m = m.simplify_quadric_decimation(max(40, target // 4)).subdivide_midpoint(1)
        else:
            m = m.simplify_quadric_decimation(min(target, len(base.triangles)))
        V = np.asarray(m.vertices)
        if kind != "decimated":
            q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
            V = (V - V.mean(0)) @ q * rng.uniform(0.5, 2.0, size=3) + rng.normal(size=3)
        m.vertices = o3d.utility.Vector3dVector(V)
        m.remove_unreferenced_vertices()
        path = folder / f"{i:03d}_{name}_{kind}.ply"
        o3d.io.write_triangle_mesh(str(path), m, write_ascii=False)
        paths.append(path)
    return paths


def plain_loop(paths, out: Path, opts):
    """The baseline: one process, one asset after the other, imports paid once."""
    from uvbake.atlas.pipeline import unwrap

    ok = 0
    for p in paths:
        d = out / p.stem
        d.mkdir(parents=True, exist_ok=True)
        try:
            r = unwrap(p, workers=1, **opts)
            r.save(d / f"{p.stem}_uv.obj")
            ok += 1
        except Exception as exc:  # noqa: BLE001 - a benchmark counts failures, it does not stop on them
            print(f"  plain loop: {p.name}: {type(exc).__name__}: {exc}", file=sys.stderr)
    return ok


def dask_run(paths, out: Path, n_workers, opts, timeout_s):
    from distributed import Client, LocalCluster

    from uvbake import batch

    t = time.perf_counter()
    with LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True, dashboard_address=None) as cl, \
            Client(cl) as client:
        t_start = time.perf_counter() - t
        t = time.perf_counter()
        table = batch.run(paths, out, client=client, timeout_per_asset_s=timeout_s, html=False, **opts)
        t_run = time.perf_counter() - t
        t = time.perf_counter()
        again = batch.run(paths, out, client=client, timeout_per_asset_s=timeout_s, html=False, **opts)
        t_rerun = time.perf_counter() - t
    assert set(again.column("status").to_pylist()) <= {"cached", "failed", "timeout", "crashed", "invalid", "lost"}
    return table.to_pylist(), t_start, t_run, t_rerun


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--assets", type=int, default=200)
    ap.add_argument("--full", action="store_true", help="bake a checker and render 96 px previews")
    ap.add_argument("--timeout", type=float, default=120.0, help="per-asset time limit (s)")
    ap.add_argument("--out", type=Path, help="also write the Markdown here")
    args = ap.parse_args()
    opts = dict(alpha=0.5, texture_size_px=256)
    opts.update(dict(bake="checker", preview_size_px=96) if args.full else dict(bake=None, preview_size_px=0,
                                                                                atlas_image="charts"))
    plain_opts = {k: v for k, v in opts.items() if k not in ("preview_size_px", "atlas_image")}
    lines = []

    def say(s=""):
        print(s, flush=True)
        lines.append(s)

    tmp = Path(tempfile.mkdtemp(prefix="uvbake-bench-batch-"))
    try:
        t = time.perf_counter()
        paths = make_corpus(tmp / "corpus", args.assets)
        tris = [_triangles(p) for p in paths]
        say(f"corpus: {len(paths)} meshes from {len({p.stem.split('_', 1)[1].rsplit('_', 1)[0] for p in paths})} "
            f"bases, {min(tris)}-{max(tris)} triangles (median {int(np.median(tris))}), made in "
            f"{time.perf_counter() - t:.0f} s; options {opts}; {os.cpu_count()} cores, shared machine")
        say()
        t = time.perf_counter()
        load0 = os.getloadavg()[0]
        ok = plain_loop(paths, tmp / "plain", plain_opts)
        t_plain = time.perf_counter() - t
        say(f"plain loop (1 core): {ok}/{len(paths)} ok in {t_plain:.1f} s (load avg before {load0:.1f}, "
            f"after {os.getloadavg()[0]:.1f})")
        runs = {}
        for n in (1, 2):
            load0 = os.getloadavg()[0]
            rows, t_start, t_run, t_rerun = dask_run(paths, tmp / f"dask{n}", n, opts, args.timeout)
            runs[n] = (rows, t_run)
            st = {}
            for r in rows:
                st[r["status"]] = st.get(r["status"], 0) + 1
            say(f"dask, {n} worker(s): {st} in {t_run:.1f} s (+ {t_start:.1f} s cluster start; rerun, all "
                f"cached: {t_rerun:.2f} s) (load avg before {load0:.1f}, after {os.getloadavg()[0]:.1f})")
        n_assets = len(paths)
        rows1, t1 = runs[1]
        _, t2 = runs[2]
        ok1 = [r for r in rows1 if r["status"] == "done"]
        startup = float(np.mean([r["t_startup_s"] for r in ok1]))
        child_work = float(np.mean([r["t_total_s"] + r["t_save_s"] + r["t_preview_s"] + r["t_atlas_s"]
                                    for r in ok1]))
        asset_wall = float(np.mean([r["t_asset_s"] for r in ok1]))
        say()
        say("| path | workers | wall (s) | assets/hour | assets/hour/core | scaling efficiency |")
        say("|---|---:|---:|---:|---:|---:|")
        say(f"| plain loop | 1 | {t_plain:.1f} | {3600 * n_assets / t_plain:,.0f} | {3600 * n_assets / t_plain:,.0f} | |")
        say(f"| dask | 1 | {t1:.1f} | {3600 * n_assets / t1:,.0f} | {3600 * n_assets / t1:,.0f} | |")
        say(f"| dask | 2 | {t2:.1f} | {3600 * n_assets / t2:,.0f} | {1800 * n_assets / t2:,.0f} | "
            f"{t1 / (2 * t2):.2f} |")
        say()
        per = (t1 - t_plain) / n_assets
        say(f"overhead of the Dask path per asset, 1 worker against the plain loop: {per:.2f} s "
            f"({t1 / n_assets:.2f} s against {t_plain / n_assets:.2f} s per asset), made of: the same work in a "
            f"forked child instead of in-process {child_work - t_plain / n_assets:+.2f} s (mean unwrap+save+"
            f"thumbnails {child_work:.2f} s; imports left to the child {startup:.3f} s); fork, staging, commit, "
            f"hashes and marker {asset_wall - child_work:.2f} s; Dask scheduling, client-side input hashing and "
            f"the summary {t1 / n_assets - asset_wall:.2f} s.")
        if args.out:
            args.out.write_text("\n".join(lines) + "\n")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _triangles(path):
    with open(path, "rb") as fh:
        for line in fh:
            if line.startswith(b"element face"):
                return int(line.split()[-1])
            if line.startswith(b"end_header"):
                return 0
    return 0


if __name__ == "__main__":
    main()
