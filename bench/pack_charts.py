"""Chart sets for bench/pack.py, cached in bench/.cache/pack/ (rebuilt when absent; uvbake's own sets
under a hash of uvbake's sources, so they follow the code).

- ``uvbake:<mesh>``: the final charts of ``uvbake.unwrap`` (default options) on every mesh in
  ../shared/meshes and sample_scenes/, with the whole command's time (to relate packing time to it);
- ``xatlas:<mesh>``: ``xatlas.parametrize``'s output split into islands by UV connectivity (xatlas
  duplicates vertices along its seams, so faces sharing an output vertex are one chart);
- ``ribbon``: a long twisted strip (a 40 x 1 helicoid band, a quarter turn per unit length), one chart,
  flattened by ``uvbake.parameterize``;
- with ``kits=True`` instead: ``uvbake:kit<n>x<t>``, uvbake's charts of a kit of ``n`` separate closed
  parts of ``t`` triangles (icospheres of random sizes, scattered; two charts each), the input of an
  asset pipeline's many small parts, and ``xatlas:kit<n>x<t>``, xatlas's charts of the same kit.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared" / "meshes"
CACHE = REPO / "bench" / ".cache" / "pack"


def mesh_paths():
    paths = sorted(SHARED.glob("*.off")) if SHARED.exists() else []
    return paths + sorted((REPO / "sample_scenes").glob("*.ply"))


#: the kits' parts: (number of parts, icosphere subdivisions: 0 is 20 triangles, 1 is 80)
KITS = ((100, 1), (300, 0), (1000, 0))


def kit_mesh(n, subdivisions, seed=0):
    """(V, F) of ``n`` separate icospheres, sizes uniform in [0.2, 1], scattered in a 40-unit cube."""
    import trimesh
    from trimesh import creation

    rng = np.random.default_rng(seed)
    s = creation.icosphere(subdivisions=subdivisions)
    parts = [trimesh.Trimesh(s.vertices * rng.uniform(0.2, 1.0) + rng.uniform(-20, 20, 3), s.faces, process=False)
             for _ in range(n)]                                # one per part: building the input, not a hot path
    m = trimesh.util.concatenate(parts)
    return np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64)


def _kit_path(n, subdivisions):
    """The kit written once as a PLY under the cache (xatlas_charts and uvbake_charts read paths)."""
    import trimesh

    f = CACHE / f"kit{n}x{20 * 4 ** subdivisions}.ply"
    if not f.exists():
        V, F = kit_mesh(n, subdivisions)
        trimesh.Trimesh(V, F, process=False).export(f)
    return f


def ribbon(length=40.0, width=1.0, nu=400, nv=8, turns_per_unit=0.25):
    """A twisted strip: (V, F) of a helicoid band along x, one disk."""
    u, v = np.meshgrid(np.linspace(0, length, nu + 1), np.linspace(-width / 2, width / 2, nv + 1), indexing="ij")
    phi = 2 * np.pi * turns_per_unit * u
    V = np.column_stack([u.ravel(), (v * np.cos(phi)).ravel(), (v * np.sin(phi)).ravel()])
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    a = (i * (nv + 1) + j).ravel()
    b, c, d = a + nv + 1, a + nv + 2, a + 1
    return V, np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])


def uvbake_charts(path):
    import uvbake

    t0 = time.perf_counter()
    res = uvbake.unwrap(str(path))
    total = time.perf_counter() - t0
    return ([r.uv for r in res.results], [c.F for c in res.charts],
            dict(command_s=total, pack_s=res.report["timings"]["pack_s"]))


def xatlas_charts(path):
    import scipy.sparse as sp
    import xatlas
    from scipy.sparse.csgraph import connected_components

    import uvbake

    m = uvbake.load_mesh(str(path))
    vmap, idx, uv = xatlas.parametrize(m.V.astype(np.float32), m.F.astype(np.uint32))
    idx = idx.astype(np.int64)
    nf, nv = len(idx), len(uv)
    rows = np.repeat(np.arange(nf), 3)
    A = sp.csr_matrix((np.ones(3 * nf), (rows, idx.ravel())), shape=(nf, nv))
    n, lab = connected_components(A @ A.T, directed=False)
    uvs, faces = [], []
    for k in range(n):                                  # one iteration per chart
        f = idx[lab == k]
        used, inv = np.unique(f, return_inverse=True)
        uvs.append(uv[used].astype(np.float64))
        faces.append(inv.reshape(-1, 3).astype(np.int64))
    return uvs, faces, {}


def ribbon_chart():
    import uvbake

    V, F = ribbon()
    r = uvbake.parameterize(V, F, alpha=0.5)
    return [r.uv], [F], {}


def _save(path, uvs, faces, info):
    np.savez_compressed(path, n=len(uvs), **{f"uv{i}": u for i, u in enumerate(uvs)},
                        **{f"f{i}": f for i, f in enumerate(faces)},
                        **{k: np.float64(v) for k, v in info.items()})


def _load(path):
    z = np.load(path)
    n = int(z["n"])
    info = {k: float(z[k]) for k in z.files if k in ("command_s", "pack_s")}
    return [z[f"uv{i}"] for i in range(n)], [z[f"f{i}"] for i in range(n)], info


def _code_key():
    """The first 12 hex digits of a SHA-256 over uvbake's Python sources (paths and bytes)."""
    import hashlib

    h = hashlib.sha256()
    for f in sorted((REPO / "uvbake").rglob("*.py")):
        h.update(str(f.relative_to(REPO)).encode())
        h.update(f.read_bytes())
    return h.hexdigest()[:12]


def set_key(uvs, faces):
    """The first 12 hex digits of a SHA-256 over a chart set's arrays (for caches of its packings)."""
    import hashlib

    h = hashlib.sha256()
    for a in [*uvs, *faces]:
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()[:12]


def chart_sets(names=None, log=sys.stderr, kits=False):
    """{name: (uvs, faces, info)}; computed once and cached (``kits``: the kit sets instead)."""
    CACHE.mkdir(parents=True, exist_ok=True)
    makers = {} if kits else {"ribbon": ribbon_chart}
    for p in [_kit_path(n, d) for n, d in KITS] if kits else mesh_paths():
        makers[f"uvbake:{p.stem}"] = lambda p=p: uvbake_charts(p)
        makers[f"xatlas:{p.stem}"] = lambda p=p: xatlas_charts(p)
    out = {}
    for name, make in makers.items():
        if names and not any(s in name for s in names):
            continue
        # uvbake's own sets depend on its code: keyed by a hash of its sources, so a change rebuilds them
        tag = f"__{_code_key()}" if name.startswith("uvbake:") else ""
        f = CACHE / (name.replace(":", "__") + tag + ".npz")
        if not f.exists():
            print(f"# making {name}", file=log, flush=True)
            try:
                _save(f, *make())
            except Exception as e:                     # a failing chart source is reported, not fatal
                print(f"# {name}: {type(e).__name__}: {e}", file=log, flush=True)
                continue
        out[name] = _load(f)
    return out


if __name__ == "__main__":
    for k, (u, f, info) in chart_sets(sys.argv[1:]).items():
        print(k, len(u), sum(len(x) for x in f), info)
