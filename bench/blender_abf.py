"""Blender's angle-based unwrap (ABF++, Sheffer et al. 2005) of one chart, for bench/paper.py's Table 4.

Blender as a module (``bpy``) pins numpy 1.26, so it lives in its own venv and this file runs there
as a subprocess:

    /work/venvs/bpy/bin/python bench/blender_abf.py IN.npz OUT.npz

IN.npz holds ``V (n,3)`` and ``F (m,3)``; OUT.npz gets ``uv (m,3,2)`` per corner (Blender's loop order
is the face's vertex order) and ``time_s`` (the unwrap operator alone). The mesh is one chart, so
nothing is marked as a seam; Blender scales and places the island in [0,1]^2 (``margin=0``).
Also importable from uvbake's Python: :func:`abf` writes the input, runs the venv and reads back.
"""

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

BPY_PYTHON = os.environ.get("UVBAKE_BPY_PYTHON", "/work/venvs/bpy/bin/python")


def abf(V, F, *, timeout_s=600):
    """Per-vertex UVs (n,2) of Blender's ANGLE_BASED unwrap, run in the bpy venv; None when that venv
    is missing."""
    import numpy as np

    if not Path(BPY_PYTHON).exists():
        return None
    with tempfile.TemporaryDirectory() as tmp:
        src, dst = Path(tmp) / "in.npz", Path(tmp) / "out.npz"
        np.savez(src, V=np.asarray(V, np.float64), F=np.asarray(F, np.int64))
        subprocess.run([BPY_PYTHON, str(Path(__file__).resolve()), str(src), str(dst)], check=True,
                       timeout=timeout_s, capture_output=True)
        out = np.load(dst)
        C = out["uv"]
        uv = np.zeros((len(V), 2))
        uv[np.asarray(F).ravel()] = C.reshape(-1, 2)      # one island: corners of a vertex agree
        return uv, float(out["time_s"])


def _main(src, dst):
    import bpy

    # isort: split
    import bmesh  # noqa: F401  (Blender's mesh module: importable only after bpy)
    import numpy as np

    data = np.load(src)
    V, F = data["V"], data["F"]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    mesh = bpy.data.meshes.new("chart")
    mesh.from_pydata(V.tolist(), [], F.tolist())
    mesh.update()
    obj = bpy.data.objects.new("chart", mesh)
    bpy.context.collection.objects.link(obj)
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)
    mesh.uv_layers.new(name="UVMap")
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.mesh.select_all(action="SELECT")
    t0 = time.perf_counter()
    bpy.ops.uv.unwrap(method="ANGLE_BASED", margin=0.0)
    dt = time.perf_counter() - t0
    bpy.ops.object.mode_set(mode="OBJECT")
    uv = np.zeros(2 * len(mesh.loops))
    mesh.uv_layers.active.data.foreach_get("uv", uv)
    np.savez(dst, uv=uv.reshape(len(F), 3, 2), time_s=dt)


if __name__ == "__main__":
    _main(sys.argv[1], sys.argv[2])
