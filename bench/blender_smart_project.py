"""Blender's Smart UV Project on one mesh, for bench/peers.py (runs under the bpy venv's Python).

    /work/venvs/bpy/bin/python bench/blender_smart_project.py IN.npz OUT.npz [--gutter-px 4 --texture-size 1024]

IN.npz holds ``V (n,3)`` and ``F (m,3)``. OUT.npz gets ``corner_uv (m,3,2)`` (face order of F, UVs in
[0,1]^2), ``unwrap_cpu_s`` (process CPU seconds of the operators: edit mode and ``smart_project``,
``smart_cpu_s``, then ``pack_islands``, ``pack_cpu_s``), ``build_cpu_s`` (building the mesh with
``from_pydata``) and ``import_cpu_s`` (``import bpy``). bpy 4.5 pins numpy 1.26, so this file runs in its own venv and imports nothing from
uvbake. Options: Smart UV Project with Blender's defaults (angle limit 66 degrees, no island margin),
then ``pack_islands`` with Blender's defaults (concave shapes, any rotation) but a margin of
``gutter_px / texture_size_px`` of the atlas side (``margin_method='FRACTION'``), uvbake's default gutter.
"""

import argparse
import time

T_START = time.process_time()
import bpy  # noqa: E402
import numpy as np  # noqa: E402

T_IMPORT = time.process_time() - T_START


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("inp")
    ap.add_argument("out")
    ap.add_argument("--gutter-px", type=float, default=4.0)
    ap.add_argument("--texture-size", type=float, default=1024.0)
    args = ap.parse_args()
    data = np.load(args.inp)
    V, F = np.asarray(data["V"], dtype=np.float64), np.asarray(data["F"], dtype=np.int64)

    t0 = time.process_time()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    mesh = bpy.data.meshes.new("peer")
    mesh.from_pydata(V.tolist(), [], F.tolist())
    mesh.update()
    obj = bpy.data.objects.new("peer", mesh)
    bpy.context.scene.collection.objects.link(obj)
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)
    build = time.process_time() - t0

    t0 = time.process_time()
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.mesh.select_all(action="SELECT")
    bpy.ops.uv.smart_project()
    t1 = time.process_time()
    bpy.ops.uv.select_all(action="SELECT")
    bpy.ops.uv.pack_islands(margin_method="FRACTION", margin=args.gutter_px / args.texture_size)
    bpy.ops.object.mode_set(mode="OBJECT")
    t2 = time.process_time()

    me = obj.data
    m = len(me.polygons)
    loop_start = np.empty(m, np.int64)
    me.polygons.foreach_get("loop_start", loop_start)
    loop_vert = np.empty(len(me.loops), np.int64)
    me.loops.foreach_get("vertex_index", loop_vert)
    uv = np.empty(2 * len(me.loops), np.float64)
    me.uv_layers.active.data.foreach_get("uv", uv)
    idx = loop_start[:, None] + np.arange(3)
    if m != len(F) or not np.array_equal(loop_vert[idx], F):
        raise SystemExit("blender reordered or changed the faces; cannot compare per face")
    np.savez(args.out, corner_uv=uv.reshape(-1, 2)[idx], unwrap_cpu_s=t2 - t0, smart_cpu_s=t1 - t0,
             pack_cpu_s=t2 - t1, build_cpu_s=build,
             import_cpu_s=T_IMPORT)


if __name__ == "__main__":
    main()
