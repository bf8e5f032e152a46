"""uvbake on shapes the project's meshes do not cover, against xatlas: validity, texel share, CPU.

    PYTHONPATH=. python3 bench/shapes.py [--alphas 0 0.1 0.5 0.9]

Twenty-one shapes built with trimesh and numpy (spheres, a capsule, two tori, a subdivided box, a cylinder,
a cone, an annulus, a noisy sphere, a sphere with four long legs, a long box; open tubes straight, bent
and coiled, a torus knot, a terrain, a sphere with five thin fingers, a sphere with 30 spikes, a bent
capped pipe of sliver triangles, 100 separate small spheres): for each alpha, in-process
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
    spiky = creation.icosphere(subdivisions=3)
    spiky.vertices[rng.choice(len(spiky.vertices), 30, replace=False)] *= 3.0
    fingers = creation.icosphere(subdivisions=4)
    d = rng.standard_normal((5, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    u = fingers.vertices / np.linalg.norm(fingers.vertices, axis=1, keepdims=True)
    reach = np.clip((u @ d.T).max(axis=1) - 0.97, 0, None) / 0.03
    fingers = trimesh.Trimesh(fingers.vertices * (1 + 5 * reach)[:, None], fingers.faces, process=False)
    # a capped tube of sliver triangles (a CAD cylinder's long facets split evenly, aspect up to 400), bent
    pipe = creation.cylinder(radius=0.2, height=10.0, sections=24)
    pv, pf = trimesh.remesh.subdivide_to_size(pipe.vertices, pipe.faces, max_edge=0.3)
    pv = np.column_stack([(4 + pv[:, 0]) * np.cos(pv[:, 2] / 4) - 4, pv[:, 1], (4 + pv[:, 0]) * np.sin(pv[:, 2] / 4)])
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
        "open_tube": _tube(lambda z, x: (x, z)),
        "bent_tube": _tube(lambda z, x: ((4 + x) * np.cos(z / 4) - 4, (4 + x) * np.sin(z / 4))),
        "coil_tube": _tube(lambda z, x: ((1.2 + x) * np.cos(z / 1.2), (1.2 + x) * np.sin(z / 1.2) + 0.05 * z), 500, 20.0),
        "torus_knot": _torus_knot(),
        "terrain": _terrain(rng),
        "fingers": fingers,
        "spiky_sphere": spiky,
        "sliver_pipe": trimesh.Trimesh(pv, pf, process=False),
        "many_parts": _many_parts(rng),
    }


def _many_parts(rng, n=100):
    """``n`` separate closed spheres of 80 triangles, scattered (a kit of small parts: one chart or two each)."""
    import trimesh
    from trimesh import creation

    parts = []
    for _ in range(n):                        # one iteration per part
        s = creation.icosphere(subdivisions=1)
        parts.append(trimesh.Trimesh(s.vertices * rng.uniform(0.2, 1.0) + rng.uniform(-20, 20, 3), s.faces,
                                     process=False))
    return trimesh.util.concatenate(parts)


def _grid(nu, nv, wrap_v):
    """Two triangles per cell of an nu x nv vertex grid, the v direction closed when ``wrap_v``."""
    idx = np.arange(nu * nv).reshape(nu, nv)
    b = np.roll(idx, -1, axis=1) if wrap_v else idx[:, 1:]
    a = idx if wrap_v else idx[:, :-1]
    a0, b0, a1, b1 = a[:-1], b[:-1], a[1:], b[1:]
    return np.concatenate([np.stack([a0, a1, b1], -1).reshape(-1, 3), np.stack([a0, b1, b0], -1).reshape(-1, 3)])


def _tube(path, nu=250, length=10.0, radius=0.2, nv=32):
    """An open tube of near-square cells (two boundary loops) along ``path(z, x) -> (x', z')`` in its plane."""
    import trimesh

    z, a = np.meshgrid(np.linspace(0, length, nu), np.linspace(0, 2 * np.pi, nv, endpoint=False), indexing="ij")
    x, y = radius * np.cos(a), radius * np.sin(a)
    px, pz = path(z, x)
    return trimesh.Trimesh(np.stack([px, y, pz], -1).reshape(-1, 3), _grid(nu, nv, True), process=False)


def _torus_knot(nu=240, nv=16, p=2, q=3, radius=0.3):
    """A (2,3) torus knot's tube: a torus (genus 1) knotted around itself."""
    import trimesh

    t = np.linspace(0, 2 * np.pi, nu, endpoint=False)

    def curve(t):
        r = np.cos(q * t) + 2
        return np.stack([r * np.cos(p * t), r * np.sin(p * t), -np.sin(q * t)], -1)

    c = curve(t)
    T = curve(t + 1e-4) - c
    T /= np.linalg.norm(T, axis=1, keepdims=True)
    N = np.cross(T, [0.0, 0.0, 1.0])
    N /= np.linalg.norm(N, axis=1, keepdims=True)
    B = np.cross(T, N)
    a = np.linspace(0, 2 * np.pi, nv, endpoint=False)
    V = c[:, None] + radius * (np.cos(a)[None, :, None] * N[:, None] + np.sin(a)[None, :, None] * B[:, None])
    F = _grid(nu + 1, nv, True)
    return trimesh.Trimesh(V.reshape(-1, 3), F % (nu * nv), process=False)


def _terrain(rng, n=70):
    """A height field of 25 random bumps and pits (an open disk, no two regions alike)."""
    import trimesh

    x, y = np.meshgrid(np.linspace(0, 4, n), np.linspace(0, 4, n), indexing="ij")
    z = np.zeros_like(x)
    for cx, cy, h, s in rng.uniform([0, 0, -1.5, 0.1], [4, 4, 1.5, 0.6], (25, 4)):   # one iteration per bump
        z += h * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * s * s))
    return trimesh.Trimesh(np.stack([x, y, z], -1).reshape(-1, 3), _grid(n, n, False), process=False)


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
