"""uvbake against xatlas where the research meshes say little: rough surfaces, size, triangle soup.

    PYTHONPATH=. python3 bench/stress.py [--only NAME ...] [--alphas 0.5]

Built with trimesh and numpy (nothing read from disk, the same inputs on every machine):
- ``noise_X``: a 20,480-triangle sphere whose vertices are moved radially by X (0.5 % to 5 %) of its
  radius times a standard normal: scan noise from mild (under an edge length) to rough (above it);
- ``noise5_small``: 5 % on a 5,120-triangle sphere;
- ``heightfield``: a gently waving 300 x 300 vertex grid (178,802 triangles, one chart);
- ``cow_x16``: the research cow subdivided twice (88,320 triangles; skipped without ../shared/meshes);
- ``soup``: 600 separate random triangles (600 charts);
- ``mobius``: a Moebius strip (not orientable);
- ``holes_60``: a 5,120-triangle sphere less 60 random triangles (a scan with small holes);
- ``poisson_knot`` and ``bpa_knot``: what Open3D rebuilds from 20,000 points sampled on
  ``bench/shapes.py``'s torus knot: a screened Poisson surface (depth 7, the 5 % least dense
  vertices trimmed: slivers and open rims) and a ball-pivoting one (holes, many pieces). Open3D's
  reconstruction is multithreaded and may differ in its last bits between machines;
- ``helix_ribbon``: a strip along four turns of a helix, radial across: flattened, one chart winds
  four times around a point, so it cannot be one valid chart;
- ``gyroid_ball``, ``cheese`` and ``schwarz_p``: closed surfaces of genus 2, 10 and 5 from implicit
  functions (a gyroid in a ball, a slab with 14 round holes, a block of Schwarz's P surface), by
  scikit-image's marching cubes (the bench extra; skipped without it).
For each: in-process ``uvbake.unwrap((V, F), alpha=a)`` without a bake and ``xatlas.parametrize``,
process CPU seconds, charts, validity (both tools' atlases), the least texel share and the area below
a quarter of its fair share, and uvbake's stage times.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def _noisy_sphere(subdivisions, sigma):
    from trimesh import creation

    rng = np.random.default_rng(7)
    s = creation.icosphere(subdivisions=subdivisions)
    V = np.asarray(s.vertices) * (1 + sigma * rng.standard_normal((len(s.vertices), 1)))
    return V, np.asarray(s.faces)


def _heightfield(k=300):
    from shapes import _grid

    x, y = np.meshgrid(np.linspace(0, 1, k), np.linspace(0, 1, k), indexing="ij")
    z = 0.05 * np.sin(6 * x) * np.cos(5 * y)
    return np.stack([x, y, z], -1).reshape(-1, 3), _grid(k, k, False)


def _soup(n=600):
    rng = np.random.default_rng(5)
    centre = rng.uniform(0, 10, (n, 1, 3))
    return (centre + rng.normal(0, 0.2, (n, 3, 3))).reshape(-1, 3), np.arange(3 * n).reshape(-1, 3)


def _mobius(n=120, w=8):
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, n, endpoint=False), np.linspace(-0.3, 0.3, w), indexing="ij")
    V = np.stack([(1 + v * np.cos(u / 2)) * np.cos(u), (1 + v * np.cos(u / 2)) * np.sin(u), v * np.sin(u / 2)],
                 -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(n), np.arange(w - 1), indexing="ij")
    a = (i * w + j).ravel()
    last = i.ravel() == n - 1                 # the last column joins the first one flipped over
    b = np.where(last, w - 1 - j.ravel(), a + w)
    bb = np.where(last, w - 2 - j.ravel(), a + w + 1)
    return V, np.concatenate([np.stack([a, b, a + 1], 1), np.stack([a + 1, b, bb], 1)])


def _cow_x16():
    import trimesh

    import uvbake

    path = ROOT.parent / "shared" / "meshes" / "cow.off"
    if not path.exists():
        return None
    m = uvbake.load_mesh(str(path))
    t = trimesh.Trimesh(m.V, m.F, process=False).subdivide().subdivide()
    return np.asarray(t.vertices), np.asarray(t.faces)


def _holey_sphere(k=60):
    from trimesh import creation

    s = creation.icosphere(subdivisions=4)
    keep = np.ones(len(s.faces), bool)
    keep[np.random.default_rng(7).choice(len(s.faces), k, replace=False)] = False
    return np.asarray(s.vertices), np.asarray(s.faces)[keep]


def _rebuilt(method, n=20000):
    """Open3D's reconstruction of ``n`` points (with their normals) sampled on the torus knot."""
    import open3d as o3d
    import trimesh
    from shapes import _torus_knot

    knot = _torus_knot()
    pts, face = trimesh.sample.sample_surface(knot, n, seed=0)
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
    cloud.normals = o3d.utility.Vector3dVector(knot.face_normals[face])
    if method == "poisson":
        mesh, density = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(cloud, depth=7)
        density = np.asarray(density)
        mesh.remove_vertices_by_mask(density < np.quantile(density, 0.05))
    else:
        d = float(np.mean(cloud.compute_nearest_neighbor_distance()))
        mesh = o3d.geometry.TriangleMesh.create_from_point_cloud_ball_pivoting(cloud, o3d.utility.DoubleVector([1.5 * d, 3 * d]))
    return np.asarray(mesh.vertices), np.asarray(mesh.triangles)


def _helix_ribbon(turns=4, n=800, w=6):
    """A strip along a helix, radial across (0.9 to 1.1 around a radius-1 axis, pitch 0.15 per radian):
    nearly developable, and flattened it winds about ``turns`` times around one point, so one chart
    overlaps itself; cut into pieces of under a turn it lies flat."""
    t, r = np.meshgrid(np.linspace(0, 2 * np.pi * turns, n), np.linspace(0.9, 1.1, w), indexing="ij")
    V = np.stack([r * np.cos(t), r * np.sin(t), 0.15 * t], -1).reshape(-1, 3)
    idx = np.arange(n * w).reshape(n, w)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    return V, np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def _implicit(f, n, lo=-1.2, hi=1.2):
    """The zero level set of ``f`` on an n^3 grid (scikit-image's marching cubes, in the bench extra), its
    largest piece; None without scikit-image."""
    try:
        from skimage.measure import marching_cubes
    except ImportError:
        return None
    import trimesh

    x = np.linspace(lo, hi, n)
    X, Y, Z = np.meshgrid(x, x, x, indexing="ij")
    V, F, _, _ = marching_cubes(f(X, Y, Z), 0.0, spacing=(x[1] - x[0],) * 3)
    m = max(trimesh.Trimesh(V, F, process=True).split(only_watertight=False), key=lambda p: len(p.faces))
    return np.asarray(m.vertices), np.asarray(m.faces)


def _gyroid_ball():
    """A gyroid inside a ball: a closed surface of genus 2 with tunnels through it."""
    return _implicit(lambda X, Y, Z: np.maximum(np.sin(4 * X) * np.cos(4 * Y) + np.sin(4 * Y) * np.cos(4 * Z)
                                                + np.sin(4 * Z) * np.cos(4 * X), X ** 2 + Y ** 2 + Z ** 2 - 1), 48)


def _cheese():
    """A slab with 14 round holes through it: a closed surface of genus 10 (some holes merge)."""
    rng = np.random.default_rng(3)
    H = rng.uniform(-0.9, 0.9, (14, 2))

    def f(X, Y, Z):
        slab = np.maximum(np.abs(Z) - 0.12, np.maximum(np.abs(X) - 1, np.abs(Y) - 1))
        return np.maximum(slab, -np.min([np.hypot(X - h[0], Y - h[1]) - 0.13 for h in H], axis=0))
    return _implicit(f, 72, -1.15, 1.15)


def _schwarz_p():
    """A block of the Schwarz P minimal surface, closed by the block's faces: genus 5."""
    return _implicit(lambda X, Y, Z: np.maximum(np.cos(5 * X) + np.cos(5 * Y) + np.cos(5 * Z),
                                                np.maximum(np.abs(X), np.maximum(np.abs(Y), np.abs(Z))) - 1), 56)


def inputs():
    out = {f"noise_{s:g}%": (lambda s=s: _noisy_sphere(5, s / 100)) for s in (0.5, 1, 2, 5)}
    out.update(noise5_small=lambda: _noisy_sphere(4, 0.05), heightfield=_heightfield, cow_x16=_cow_x16,
               soup=_soup, mobius=_mobius, holes_60=_holey_sphere, poisson_knot=lambda: _rebuilt("poisson"),
               bpa_knot=lambda: _rebuilt("bpa"), helix_ribbon=_helix_ribbon, gyroid_ball=_gyroid_ball,
               cheese=_cheese, schwarz_p=_schwarz_p)
    return out


def main(argv=None):
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parent))          # bench/shapes.py's grid
    ap = argparse.ArgumentParser()
    ap.add_argument("--only", nargs="+")
    ap.add_argument("--alphas", type=float, nargs="+", default=[0.5])
    args = ap.parse_args(argv)
    import xatlas

    import uvbake
    from uvbake.validate import validate

    uvbake.unwrap(_mobius())                  # imports and caches warmed up once
    print("| input | triangles | alpha | uvbake CPU s | xatlas CPU s | ratio | charts (xatlas) | valid (xatlas) | "
          "least texel share | area < 1/4 | uvbake stages (s) |")
    print("|---|---:|---|---:|---:|---:|---|---|---:|---:|---|")
    for name, make in inputs().items():
        if args.only and name not in args.only:
            continue
        mesh = make()
        if mesh is None:
            print(f"# {name}: skipped (../shared/meshes or scikit-image is not there)")
            continue
        V, F = np.asarray(mesh[0], np.float64), np.asarray(mesh[1], np.int64)
        t = time.process_time()
        atlas = xatlas.Atlas()
        atlas.add_mesh(V.astype(np.float32), F.astype(np.uint32))
        atlas.generate()
        x_cpu = time.process_time() - t
        _, x_idx, x_uv = atlas.get_mesh(0)
        xv = validate(x_uv.astype(np.float64)[x_idx], resolution_px=1024)
        x_ok = "True" if xv.valid else \
            f"False: {len(xv.flipped)} flipped or collapsed, {len(xv.overlap_pairs)} overlapping"
        for a in args.alphas:
            t = time.process_time()
            r = uvbake.unwrap((V, F), alpha=a)
            cpu = time.process_time() - t
            ok = validate(r.corner_uv, r.F, chart_ids=r.chart_ids, resolution_px=1024).valid      # the repaired faces
            stages = ", ".join(f"{k[:-2]} {v:.2f}" for k, v in r.report["timings"].items()
                               if k not in ("total_s", "bake_s"))
            print(f"| {name} | {len(F)} | {a:g} | {cpu:.2f} | {x_cpu:.2f} | {cpu / x_cpu:.1f} | "
                  f"{r.report['charts_final']} ({atlas.chart_count}) | {ok} ({x_ok}) | {r.report['min_texel_share']:.3f} | "
                  f"{100 * r.report['area_below_quarter']:.2f}% | {stages} |", flush=True)


if __name__ == "__main__":
    main()
