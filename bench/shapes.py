"""uvbake on shapes the project's meshes do not cover, against xatlas: validity, texel share, CPU.

    PYTHONPATH=. python3 bench/shapes.py [--alphas 0 0.1 0.5 0.9]

Eleven shapes built with trimesh (spheres, a capsule, two tori, a subdivided box, a cylinder, a cone,
an annulus, a noisy sphere, a sphere with four long legs, a long box): for each alpha, in-process
``uvbake.unwrap((V, F), alpha=a)`` without a bake, its flips and overlapping pairs
(``uvbake.validate``) and least texel share; at alpha 0.5 the CPU ratio against ``xatlas.parametrize``
(process CPU seconds, both modules imported first). Nothing is read from disk: the shapes are the
same on every machine.
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def shapes():
    import trimesh
    from trimesh import creation

    rng = np.random.default_rng(0)
    noisy = creation.icosphere(subdivisions=4)
    noisy = trimesh.Trimesh(noisy.vertices * (1 + 0.03 * rng.standard_normal((len(noisy.vertices), 1))),
                            noisy.faces, process=False)
    legs = creation.icosphere(subdivisions=4)
    d = np.array([[1, 1, -1], [1, -1, -1], [-1, 1, -1], [-1, -1, -1]]) / np.sqrt(3)
    u = legs.vertices / np.linalg.norm(legs.vertices, axis=1, keepdims=True)
    reach = np.clip((u @ d.T).max(axis=1) - 0.93, 0, None) / 0.07       # 1 at a leg's axis, 0 off it
    legs = trimesh.Trimesh(legs.vertices * (1 + 2.5 * reach)[:, None], legs.faces, process=False)
    box = creation.box(extents=(1.0, 1.3, 0.8)).subdivide().subdivide().subdivide()
    long_box = creation.box(extents=(10.0, 1.0, 1.0))
    for _ in range(4):
        long_box = long_box.subdivide()
    return {
        "icosphere": creation.icosphere(subdivisions=4),
        "uv_sphere": creation.uv_sphere(count=[48, 48]),
        "capsule": creation.capsule(height=2.0, radius=0.5, count=[48, 48]),
        "torus": creation.torus(major_radius=2.0, minor_radius=0.5, major_sections=64, minor_sections=24),
        "thin_torus": creation.torus(major_radius=3.0, minor_radius=0.2, major_sections=96, minor_sections=16),
        "box": box,
        "cylinder": creation.cylinder(radius=0.5, height=3.0, sections=64).subdivide(),
        "cone": creation.cone(radius=1.0, height=2.0, sections=64).subdivide().subdivide(),
        "annulus": creation.annulus(r_min=0.5, r_max=1.0, height=0.3, sections=64).subdivide(),
        "noisy_sphere": noisy,
        "legged_sphere": legs,
        "long_box": long_box,
    }


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--alphas", type=float, nargs="+", default=[0.0, 0.1, 0.5, 0.9])
    args = ap.parse_args(argv)
    import xatlas

    import uvbake
    from uvbake.analysis.metrics import texel_summary
    from uvbake.validate import validate

    uvbake.unwrap(tuple(np.asarray(a) for a in (shapes()["box"].vertices, shapes()["box"].faces)), alpha=0.5)
    print("| shape | triangles | alpha | charts | flipped | overlapping pairs | least share | area < 1/4 | "
          "uvbake CPU s | xatlas CPU s | ratio |")
    print("|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    ratios, least, valid, runs = [], [], 0, 0
    for name, m in shapes().items():
        V, F = np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64)
        xa = float("nan")
        if 0.5 in args.alphas:
            t = time.process_time()
            xatlas.parametrize(V, F)
            xa = time.process_time() - t
        for a in args.alphas:
            t = time.process_time()
            res = uvbake.unwrap((V, F), alpha=a)
            cpu = time.process_time() - t
            rep = validate(res.corner_uv, res.F, chart_ids=res.chart_ids, resolution_px=1024)
            ts = texel_summary(res.V, res.F, res.corner_uv)
            runs += 1
            valid += int(rep.n_flipped == 0 and rep.n_overlaps == 0)
            least.append(ts["min_texel_share"])
            r = cpu / xa if a == 0.5 else float("nan")
            if a == 0.5:
                ratios.append(r)
            print(f"| {name} | {len(F)} | {a} | {res.report['charts_final']} | {rep.n_flipped} | {rep.n_overlaps} | "
                  f"{ts['min_texel_share']:.3f} | {100 * ts['area_below_quarter']:.2f}% | {cpu:.2f} | "
                  f"{xa if a == 0.5 else float('nan'):.2f} | {r:.1f} |", flush=True)
    print(f"\n# {valid} of {runs} runs valid; least texel share {min(least):.3f}")
    if ratios:
        print(f"# CPU ratio uvbake / xatlas at alpha 0.5: median {np.median(ratios):.2f}, "
              f"{min(ratios):.2f}-{max(ratios):.2f}")


if __name__ == "__main__":
    main()
