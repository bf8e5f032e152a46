"""One unwrap in a fresh process, for bench/peers.py: the parent measures the whole process's CPU.

    python bench/peer_worker.py {uvbake,xatlas,uvatlas} IN.npz OUT.npz [--mesh PATH --alpha A]

IN.npz holds ``V (n,3)``, ``F (m,3)`` (the mesh as loaded, for the peers). OUT.npz gets
``corner_uv (m,3,2)`` in the face order of the faces it measures, ``width``/``height`` (the atlas
rectangle in texels; 1 x 1 for atlases normalised to [0,1]^2), ``unwrap_cpu_s`` (``time.process_time``
around the unwrap call only, all threads) and ``charts`` (the method's own count).

- ``uvbake``: ``uvbake.unwrap((V, F), face_labels=labels, alpha=A)`` without a bake, on the mesh
  read from PATH by ``uvbake.io.load_mesh`` before the clock starts (the same atlas as
  ``uvbake.unwrap(PATH)``), after a first call on a 32-triangle grid that imports the modules uvbake
  loads lazily: like xatlas's, the timed call is the unwrap alone (repair included), not the process's
  imports or the file's parsing, which the whole-command column counts. OUT also holds the repaired
  ``V``, ``F`` it unwrapped.
- ``xatlas``: ``xatlas.Atlas().add_mesh(V, F)`` then ``generate()`` with default options (what
  ``xatlas.parametrize`` runs; the Atlas object also gives the atlas width and height, which
  ``parametrize`` drops). xatlas normalises u by the width and v by the height separately.
- ``uvatlas``: Open3D's ``TriangleMesh.compute_uvatlas()`` with its defaults (size 512, gutter 1,
  max stretch 1/6).
"""

import argparse
import time


def _grid(k=4):
    """A flat k x k grid of 2 k^2 triangles (the warm-up mesh)."""
    import numpy as np

    x, y = np.meshgrid(np.arange(k + 1.0), np.arange(k + 1.0))
    V = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    i = (np.arange(k)[:, None] * (k + 1) + np.arange(k)).ravel()
    F = np.concatenate([np.column_stack([i, i + 1, i + k + 2]), np.column_stack([i, i + k + 2, i + k + 1])])
    return V, F


def run_uvbake(mesh, alpha):
    import uvbake
    from uvbake.io import load_mesh

    uvbake.unwrap(_grid(), alpha=alpha)               # imports out of the timing (no state is kept)
    m = load_mesh(mesh)
    t0 = time.process_time()
    res = uvbake.unwrap((m.V, m.F), face_labels=m.face_labels, alpha=alpha)
    t = time.process_time() - t0
    rep = res.report
    return dict(corner_uv=res.corner_uv, V=res.V, F=res.F, unwrap_cpu_s=t,
                charts=int(rep.get("charts_final", len(res.charts))), valid=bool(rep.get("valid", True)))


def run_xatlas(V, F):
    import numpy as np
    import xatlas

    t0 = time.process_time()
    atlas = xatlas.Atlas()
    atlas.add_mesh(V.astype(np.float32), F.astype(np.uint32))
    atlas.generate()
    t = time.process_time() - t0
    vmap, idx, uvs = atlas[0]
    if not np.array_equal(vmap[idx].astype(np.int64), F):
        raise SystemExit("xatlas reordered the faces; cannot compare per face")
    return dict(corner_uv=uvs[idx].astype(np.float64), unwrap_cpu_s=t, charts=int(atlas.chart_count),
                width=int(atlas.width), height=int(atlas.height), atlases=int(atlas.atlas_count))


def run_uvatlas(V, F):
    import numpy as np
    import open3d as o3d

    m = o3d.t.geometry.TriangleMesh()
    m.vertex.positions = o3d.core.Tensor(V.astype(np.float32))
    m.triangle.indices = o3d.core.Tensor(F.astype(np.int32))
    t0 = time.process_time()
    stretch, n_charts, _ = m.compute_uvatlas()
    t = time.process_time() - t0
    if not np.array_equal(m.triangle.indices.numpy().astype(np.int64), F):
        raise SystemExit("UVAtlas changed the faces; cannot compare per face")
    return dict(corner_uv=m.triangle.texture_uvs.numpy().astype(np.float64), unwrap_cpu_s=t,
                charts=int(n_charts), max_stretch=float(stretch))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("method", choices=["uvbake", "xatlas", "uvatlas"])
    ap.add_argument("inp")
    ap.add_argument("out")
    ap.add_argument("--mesh", help="mesh file (uvbake loads it itself)")
    ap.add_argument("--alpha", type=float, default=0.5)
    args = ap.parse_args()
    import numpy as np

    if args.method == "uvbake":
        out = run_uvbake(args.mesh, args.alpha)
    else:
        data = np.load(args.inp)
        V, F = np.asarray(data["V"], np.float64), np.asarray(data["F"], np.int64)
        out = (run_xatlas if args.method == "xatlas" else run_uvatlas)(V, F)
    out.setdefault("width", 1)
    out.setdefault("height", 1)
    np.savez(args.out, **out)


if __name__ == "__main__":
    main()
