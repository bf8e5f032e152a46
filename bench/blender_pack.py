"""Blender's ``bpy.ops.uv.pack_islands`` on given charts; run with the bpy venv's python (bpy pins numpy 1.26).

    /work/venvs/bpy/bin/python bench/blender_pack.py IN.npz OUT.npz

IN.npz: ``n``, ``uv{i}`` (k_i,2), ``f{i}`` (t_i,3), ``margin`` (fraction of the UV square). The charts
become one mesh with one UV map (disjoint islands); pack_islands runs with shape_method='CONCAVE',
rotate=True (rotate_method='ANY'), scale=True, margin_method='FRACTION'. OUT.npz: ``corner_uv`` (m,3,2)
per face corner in the input face order and ``time_s`` (the operator call only).
"""

import sys
import time

import bpy
import numpy as np


def main(src, dst):
    z = np.load(src)
    n = int(z["n"])
    uvs = [z[f"uv{i}"] for i in range(n)]
    faces = [z[f"f{i}"] for i in range(n)]
    offs = np.cumsum([0] + [len(u) for u in uvs])
    U = np.vstack(uvs)
    F = np.vstack([f + o for f, o in zip(faces, offs)])
    lo, span = U.min(axis=0), np.ptp(U, axis=0).max()
    U = (U - lo) / span
    bpy.ops.wm.read_factory_settings(use_empty=True)
    mesh = bpy.data.meshes.new("charts")
    mesh.from_pydata([(u, v, 0.0) for u, v in U], [], [tuple(int(i) for i in f) for f in F])
    mesh.update()
    layer = mesh.uv_layers.new(name="UVMap")
    loop_vert = np.empty(len(mesh.loops), np.int64)
    mesh.loops.foreach_get("vertex_index", loop_vert)
    layer.data.foreach_set("uv", U[loop_vert].astype(np.float32).ravel())
    obj = bpy.data.objects.new("charts", mesh)
    bpy.context.scene.collection.objects.link(obj)
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.mesh.select_all(action="SELECT")
    bpy.ops.uv.select_all(action="SELECT")
    t0 = time.perf_counter()
    bpy.ops.uv.pack_islands(rotate=True, rotate_method="ANY", scale=True, margin_method="FRACTION",
                            margin=float(z["margin"]), shape_method="CONCAVE")
    dt = time.perf_counter() - t0
    bpy.ops.object.mode_set(mode="OBJECT")
    out = np.empty(2 * len(mesh.loops), np.float32)
    mesh.uv_layers["UVMap"].data.foreach_get("uv", out)
    out = out.reshape(-1, 2).astype(np.float64)
    start = np.empty(len(mesh.polygons), np.int64)
    mesh.polygons.foreach_get("loop_start", start)
    corner = out[start[:, None] + np.arange(3)[None, :]]
    # Blender keeps each polygon's vertex order from from_pydata; check it
    lv = loop_vert[start[:, None] + np.arange(3)[None, :]]
    if not np.array_equal(lv, F):
        raise SystemExit("Blender reordered face corners")
    np.savez(dst, corner_uv=corner, time_s=dt)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
