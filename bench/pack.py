"""Packing benchmark: uvbake's packer against xatlas's and Blender's on the same charts, one run.

    python bench/pack.py                      # every chart set (bench/pack_charts.py), 1024 px, gutter 4
    python bench/pack.py --only scene,ribbon  # chart sets whose name contains one of these
    python bench/pack.py --no-blender         # skip Blender (it needs /work/venvs/bpy or --bpy-python)
    python bench/pack.py --commands           # the whole uvbake command per mesh: packing's share of it
    python bench/pack.py --cli                # the same for the README's job run as users run it
    python bench/pack.py --kits               # kits of 200-2000 small charts instead (bench/pack_charts.py)

Chart sets (bench/pack_charts.py, cached): uvbake's own final charts on every mesh in ../shared/meshes and
sample_scenes/, xatlas's charts (``xatlas.parametrize`` split into islands) on the same meshes, and a long
twisted ribbon (one chart). Packers, each on the same charts with the same gutter:

- ``uvbake``: ``pack_charts(method="auto")`` in a 1024 x 1024 atlas (for the ribbon also the best of
  2048 x 512, 4096 x 256, 8192 x 128 and 16384 x 64, the same texel count, as non-square atlases, and
  a growing atlas of free aspect at the texel density of 1024^2 texels for the chart's area);
- ``xatlas``: ``xatlas.Atlas.add_uv_mesh`` + ``generate`` with ``PackOptions(resolution=1024,
  padding=ceil((gutter-1)/2), rotate_charts=True)`` and texels_per_unit estimated by xatlas (one
  packing). xatlas returns a W x H atlas cropped to its charts, often far from square (2018 x 1048 on
  bumpy): its efficiency is measured in the square of side max(W, H) that a square texture needs, and
  its own W x H figure is given in brackets;
- ``blender``: ``bpy.ops.uv.pack_islands(shape_method='CONCAVE', rotate=True, margin_method='FRACTION',
  margin=gutter / 2048)`` (Blender's margin is kept around every island, so two islands end up two
  margins apart); run in the bpy venv as a subprocess, time of the operator call only; its result is
  cached in bench/.cache/pack/ under a hash of the chart set (a set that changes is packed again).

A peer whose layout breaks the gutter (charts closer than gutter - GAP_TOL_PX texels) is run again at
the least setting of its own that keeps it (xatlas's padding 1-3 texels more, Blender's margin 1.25-3
times its own), and the summary lines compare uvbake with the peers both as run and keeping the gutter.

Efficiency = sum of |triangle areas| in texels / atlas texels. Every result's exact minimum distance
between charts is measured (``min gap``, texels); a packing whose gap is under the gutter is flagged.
``share`` = uvbake's packing time / the whole ``uvbake`` command on that mesh (the command time measured
when the chart set was made, with the packing time replaced by this one).
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "bench"))

from pack_charts import CACHE, chart_sets, set_key  # noqa: E402

from uvbake.atlas.distance import min_chart_distance  # noqa: E402
from uvbake.atlas.pack import pack_charts  # noqa: E402
from uvbake.mesh.arrays import signed_areas  # noqa: E402

from packers import spread  # noqa: E402

BPY = Path("/work/venvs/bpy/bin/python")
#: A layout keeps the gutter when its charts are at least gutter - GAP_TOL_PX texels apart: Blender
#: stores UVs as float32, which rounds its 4-texel margins on a 1024-texel atlas to 3.9998 (2e-4 short).
GAP_TOL_PX = 1e-3


def area_px(uvs, faces, W, H):
    return sum(np.abs(signed_areas(u * [W, H], f)).sum() for u, f in zip(uvs, faces))


def gap_px(uvs, faces, W, H):
    if len(uvs) < 2:
        return math.inf
    return min_chart_distance([u * [W, H] for u in uvs], faces)


def per_vertex(corner, faces):
    """Per-chart per-vertex UVs from per-corner UVs in stacked face order."""
    out, k = [], 0
    for f in faces:
        c = corner[k:k + len(f)]
        uv = np.zeros((f.max() + 1, 2))
        uv[f.ravel()] = c.reshape(-1, 2)
        out.append(uv)
        k += len(f)
    return out


def run_uvbake(uvs, faces, N, g, size=0, density=None):
    t0 = time.perf_counter()
    if density is None:
        r = pack_charts(uvs, faces, texture_size_px=size or N, gutter_px=g)
    else:           # a growing atlas of free aspect at a fixed texel density
        r = pack_charts(uvs, faces, texture_size_px=None, gutter_px=g, texel_density=density, aspect="free")
    dt = time.perf_counter() - t0
    W, H = r.width_px, r.height_px
    return dict(eff=r.efficiency, time=dt, gap=gap_px(r.uv, faces, W, H), atlas=f"{W}x{H}",
                note=r.method, density=r.texel_density)


def run_xatlas(uvs, faces, N, g, padding=None):
    import xatlas

    offs = np.cumsum([0] + [len(u) for u in uvs])
    U = np.vstack(spread(uvs)).astype(np.float32)
    F = np.vstack([f + o for f, o in zip(faces, offs)]).astype(np.uint32)
    t0 = time.perf_counter()
    atlas = xatlas.Atlas()
    atlas.add_uv_mesh(U, F)
    po = xatlas.PackOptions()
    po.resolution = N
    po.padding = max(0, math.ceil((g - 1) / 2)) if padding is None else padding
    po.rotate_charts = True
    po.bilinear = False
    atlas.generate(pack_options=po)
    dt = time.perf_counter() - t0
    vmap, idx, auv = atlas.get_mesh(0)
    W, H = int(atlas.width), int(atlas.height)
    corner = auv[idx].astype(np.float64)
    if len(idx) != len(F) or not np.array_equal(vmap[idx], F):
        return dict(eff=float("nan"), time=dt, gap=float("nan"), atlas=f"{W}x{H}", note="faces reordered")
    out = per_vertex(corner, faces)
    note = f"{atlas.atlas_count} atlases" if atlas.atlas_count != 1 else ""
    side = max(W, H)               # a square texture holds xatlas's W x H atlas only at side max(W, H)
    area = area_px(out, faces, W, H)
    return dict(eff=area / side ** 2, own=area / (W * H), time=dt, gap=gap_px(out, faces, W, H),
                atlas=f"{W}x{H}", note=note, setting=f"padding {po.padding}")


def run_blender(uvs, faces, N, g, bpy_python, cache=None, margin=None):
    """Blender's packing (``margin``: a fraction of the UV square, default g / 2N); its corner UVs are
    cached per chart set, size, gutter and margin (it takes up to a minute)."""
    margin = g / (2 * N) if margin is None else margin
    setting = f"margin {margin * 2 * N:.3g} px"
    if cache is not None and cache.exists():
        z = np.load(cache)
        out = per_vertex(z["corner_uv"], faces)
        return dict(eff=area_px(out, faces, N, N) / (N * N), time=float(z["time_s"]), gap=gap_px(out, faces, N, N),
                    atlas=f"{N}x{N}", note="", setting=setting)
    with tempfile.TemporaryDirectory() as d:
        src, dst = Path(d) / "in.npz", Path(d) / "out.npz"
        np.savez(src, n=len(uvs), margin=margin, **{f"uv{i}": u for i, u in enumerate(uvs)},
                 **{f"f{i}": f for i, f in enumerate(faces)})
        p = subprocess.run([str(bpy_python), str(REPO / "bench" / "blender_pack.py"), str(src), str(dst)],
                           capture_output=True, text=True)
        if p.returncode or not dst.exists():
            return dict(eff=float("nan"), time=float("nan"), gap=float("nan"), atlas="", note="failed: "
                        + (p.stderr.strip().splitlines() or ["?"])[-1][:60])
        z = np.load(dst)
        if cache is not None:
            np.savez(cache, corner_uv=z["corner_uv"], time_s=z["time_s"])
        out = per_vertex(z["corner_uv"], faces)
        return dict(eff=area_px(out, faces, N, N) / (N * N), time=float(z["time_s"]), gap=gap_px(out, faces, N, N),
                    atlas=f"{N}x{N}", note="", setting=setting)


#: Settings a peer is rerun with when its layout breaks the gutter: xatlas's padding (texels each side)
#: one to three more, Blender's margin 1.25 to 3 times its own (two margins between islands).
XATLAS_MORE_PADDING = (1, 2, 3)
BLENDER_MORE_MARGIN = (1.25, 1.5, 2.0, 3.0)


def at_gutter(first, rerun, settings, g):
    """``first`` when it keeps the gutter, else the first rerun (``rerun(setting)``) that does, or None:
    a layout closer than the gutter is not a packing at that gutter, so the comparison takes the peer
    at the least setting of its own that keeps it."""
    if first is None or not first["gap"] < g - GAP_TOL_PX:
        return first
    for k in settings:                        # one peer run per setting, at most four
        c = rerun(k)
        if c["gap"] >= g - GAP_TOL_PX:
            return c
    return None


def commands(log=sys.stdout, only=None):
    """The whole command (``uvbake.unwrap``, defaults) on every mesh: packing time and its share.

    Shares are given in wall time (the report's timings) and in CPU time of this process
    (``time.process_time``; on a shared machine the wall share moves with the other jobs, the CPU
    share much less): "pack CPU" around every packing (``pack_charts`` and packsplit's box layouts,
    ``BoxLayouts``), "stage CPU" around the whole packing stage (also packsplit's cuts).
    """
    from pack_charts import mesh_paths

    import uvbake
    import uvbake.atlas.pack as pack_module
    import uvbake.atlas.packsplit as split_module

    cpu = {"pack": 0.0, "stage": 0.0}

    def timed(fn, key):
        def run(*a, **k):
            t = time.process_time()
            try:
                return fn(*a, **k)
            finally:
                cpu[key] += time.process_time() - t
        return run

    # the pipeline imports these at call time; pack_charts and BoxLayouts never call each other
    orig = pack_module.pack_charts, split_module.BoxLayouts.__call__, split_module.split_for_packing
    pack_module.pack_charts = timed(orig[0], "pack")
    split_module.BoxLayouts.__call__ = timed(orig[1], "pack")
    split_module.split_for_packing = timed(orig[2], "stage")
    uvbake.unwrap(str(mesh_paths()[-1]))             # imports and caches warmed up once
    print("| mesh | charts | packing | method | texel density (px/unit) | pack (s) | command (s) | share "
          "| pack CPU (s) | stage CPU (s) | command CPU (s) | CPU share | stage CPU share |", file=log)
    print("|---|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|", file=log)
    for path in mesh_paths():
        if only and not any(o in path.stem for o in only):
            continue
        cpu.update(pack=0.0, stage=0.0)
        t0 = time.process_time()
        r = uvbake.unwrap(str(path))
        c = time.process_time() - t0
        a, t = r.report["atlas"], r.report["timings"]
        stage = cpu["stage"] or cpu["pack"]          # no split stage: the one packing is the stage
        print(f"| {path.stem} | {r.report['charts_final']} | {100 * a['efficiency']:.1f} % | {a['method']} "
              f"| {a['texel_density']:.4g} | {t['pack_s']:.2f} | {t['total_s']:.2f} "
              f"| {100 * t['pack_s'] / t['total_s']:.0f} % | {cpu['pack']:.3f} | {stage:.3f} | {c:.2f} "
              f"| {100 * cpu['pack'] / c:.0f} % | {100 * stage / c:.0f} % |", file=log, flush=True)
    pack_module.pack_charts, split_module.BoxLayouts.__call__, split_module.split_for_packing = orig


def cli_commands(log=sys.stdout, only=None):
    """The README's main job as a user runs it, ``uvbake MESH --alpha 0.5 --bake checker.png`` (1024 px,
    OBJ + PNG + JSON report written), one subprocess per mesh: packing's wall time against the whole
    command's (both from the report's timings: ``pack_s``, ``cli_total_s``, which includes imports,
    loading, the bake and the writes), and the subprocess's CPU time (user + sys)."""
    import json
    import resource

    from pack_charts import mesh_paths

    print("| mesh | charts | packing | pack (s) | command (s) | share | command CPU (s) |", file=log)
    print("|---|---:|---:|---:|---:|---:|---:|", file=log)
    for path in mesh_paths():
        if only and not any(o in path.stem for o in only):
            continue
        with tempfile.TemporaryDirectory() as tmp:
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            subprocess.run([sys.executable, "-m", "uvbake", str(path), "--alpha", "0.5", "--bake", "checker.png",
                            "-o", f"{tmp}/out.obj", "--json", f"{tmp}/r.json", "-q"], check=True)
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            rep = json.loads(Path(f"{tmp}/r.json").read_text())
        t = rep["timings"]
        cpu = after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime
        print(f"| {path.stem} | {rep['charts_final']} | {100 * rep['atlas']['efficiency']:.1f} % | {t['pack_s']:.2f} "
              f"| {t['cli_total_s']:.2f} | {100 * t['pack_s'] / t['cli_total_s']:.0f} % | {cpu:.2f} |", file=log, flush=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default=None, help="comma-separated substrings of chart-set names")
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--gutter", type=int, default=4)
    ap.add_argument("--no-blender", action="store_true")
    ap.add_argument("--no-xatlas", action="store_true")
    ap.add_argument("--bpy-python", default=str(BPY))
    ap.add_argument("--commands", action="store_true", help="time the whole uvbake command on every mesh instead")
    ap.add_argument("--cli", action="store_true", help="time the README's job (CLI with a checker bake) on every mesh")
    ap.add_argument("--kits", action="store_true", help="kits of many small parts instead of the meshes")
    args = ap.parse_args(argv)
    if args.cli:
        return cli_commands(only=args.only.split(",") if args.only else None)
    if args.commands:
        return commands(only=args.only.split(",") if args.only else None)
    N, g = args.size, args.gutter
    sets = chart_sets(args.only.split(",") if args.only else None, kits=args.kits)
    blender = not args.no_blender and Path(args.bpy_python).exists()
    print(f"# texture {N} px, gutter {g} px; efficiency % / time s / min gap px; one run each")
    print("| charts from | mesh | charts | uvbake | xatlas | blender | uvbake atlas, method | share of command |")
    print("|---|---|---:|---|---|---|---|---:|")
    rows = []
    for name, (uvs, faces, info) in sets.items():
        src, _, mesh = name.partition(":")
        if not mesh:
            src, mesh = "-", name
        cells = {"uvbake": run_uvbake(uvs, faces, N, g)}
        if mesh == "ribbon":            # non-square atlases of the same texel count, the best one
            tries = [run_uvbake(uvs, faces, N, g, size=(N << k, N >> k)) for k in (1, 2, 3, 4)]
            cells["uvbake-nonsquare"] = max(tries, key=lambda c: c["eff"])
            world = sum(np.abs(signed_areas(u, f)).sum() for u, f in zip(uvs, faces))
            cells["uvbake-free"] = run_uvbake(uvs, faces, N, g, size=None, density=N / np.sqrt(world))
        if not args.no_xatlas:
            cells["xatlas"] = run_xatlas(uvs, faces, N, g)
            pad = max(0, math.ceil((g - 1) / 2))
            cells["xatlas@g"] = at_gutter(cells["xatlas"], lambda k: run_xatlas(uvs, faces, N, g, padding=pad + k),
                                          XATLAS_MORE_PADDING, g)
        if blender:
            key = f"blender__{name.replace(':', '__')}__{N}_{g}__{set_key(uvs, faces)}"
            cells["blender"] = run_blender(uvs, faces, N, g, args.bpy_python, cache=CACHE / f"{key}.npz")
            cells["blender@g"] = at_gutter(
                cells["blender"], lambda k: run_blender(uvs, faces, N, g, args.bpy_python, margin=k * g / (2 * N),
                                                        cache=CACHE / f"{key}__m{k:g}.npz"),
                BLENDER_MORE_MARGIN, g)

        def fmt(c, fair=None):
            if c is None:
                return "-"
            flag = " **gap < gutter**" if c["gap"] < g - GAP_TOL_PX else ""
            own = f" ({100 * c['own']:.1f} in {c['atlas']})" if "own" in c and c["own"] != c["eff"] else ""
            if flag and fair is not c:        # the peer at the least setting that keeps the gutter
                flag += (f"; at the gutter ({fair['setting']}): {100 * fair['eff']:.1f} / {fair['gap']:.1f}"
                         if fair is not None else "; no setting tried keeps the gutter")
            return f"{100 * c['eff']:.1f}{own} / {c['time']:.2f} / {c['gap']:.1f}{flag}"
        share = ""
        if "command_s" in info:
            t = cells["uvbake"]["time"]
            share = f"{100 * t / (info['command_s'] - info['pack_s'] + t):.0f} %"
        u = cells["uvbake"]
        desc = f"{u['atlas']}, {u['note']}"
        if "uvbake-nonsquare" in cells:
            v = cells["uvbake-nonsquare"]
            desc += f"; {v['atlas']}: {fmt(v)}"
            v = cells["uvbake-free"]
            desc += f"; growing, free aspect, {v['density']:.4g} px/unit: {v['atlas']}: {fmt(v)}"
        print(f"| {src} | {mesh} | {len(uvs)} | {fmt(u)} | {fmt(cells.get('xatlas'), cells.get('xatlas@g'))} "
              f"| {fmt(cells.get('blender'), cells.get('blender@g'))} "
              f"| {desc} | {share} |", flush=True)
        rows.append((name, len(uvs), cells))
    multi = [r for r in rows if r[1] > 1]
    if multi:
        print()
        for k in ("uvbake", "xatlas", "xatlas@g", "blender", "blender@g"):
            e = [r[2][k]["eff"] for r in multi if r[2].get(k) is not None and np.isfinite(r[2][k]["eff"])]
            if e:
                what = f"{k[:-2]} at the gutter" if k.endswith("@g") else k
                print(f"# {what}: median efficiency over {len(e)} multi-chart atlases {100 * np.median(e):.1f} %")
        for keys, what in ((("xatlas", "blender"), "as run"), (("xatlas@g", "blender@g"), "keeping the gutter")):
            worst = []
            for name, n, c in multi:
                peers = [c[k]["eff"] for k in keys if c.get(k) is not None and np.isfinite(c[k]["eff"])]
                if peers:
                    worst.append((100 * (c["uvbake"]["eff"] - max(peers)), name))
            if worst:
                d, name = min(worst)
                print(f"# uvbake minus best peer {what}: worst {d:+.1f} points ({name})")

if __name__ == "__main__":
    main()
