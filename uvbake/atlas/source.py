"""The unwrap's input: a mesh loaded from any source, checked, brought near unit size and repaired."""

from __future__ import annotations

from typing import Any

import numpy as np

from uvbake.mesh.arrays import unit_exponent


def load_source(source: Any, face_labels: Any, repair: bool, weld: bool | None, materials: bool = True) -> tuple:
    """Load and (optionally) repair: V, F, labels, colours, the source's name, the repair report, the
    pinch keys (:func:`uvbake.flatten.pinches.repair_copies`, or None) and the exponent of the scale.
    ``materials``: an OBJ file's materials label its faces (:func:`uvbake.io.load.load_mesh`)."""
    from uvbake.io.load import load_mesh
    from uvbake.mesh.arrays import check_arrays

    mesh = load_mesh(source, face_labels=face_labels, materials=materials)
    V, F, labels, colors = mesh.V, mesh.F, mesh.face_labels, mesh.vertex_colors
    # NaN or infinite coordinates are corrupt data, not a reconstruction artefact: refuse them
    # (naming the vertices) rather than silently dropping faces
    V, F = check_arrays(V, F, where=str(mesh.source))
    # any finite scale: work near unit size by a power of two (exact), export the input's coordinates
    k = unit_exponent(V)
    k = k if abs(k) > 64 else 0
    V = np.ldexp(V, -k) if k else V
    repair_report, pinch_keys = None, None
    if repair:
        from uvbake.flatten.pinches import repair_copies
        from uvbake.mesh.repair import repair as repair_mesh

        rep = repair_mesh(V, F, weld=weld, face_labels=labels)
        repair_report = rep.to_dict()
        if rep.actions:
            labels = None if labels is None else labels[rep.face_index]
            colors = None if colors is None else colors[rep.vertex_index]
            V, F = rep.V, rep.F
            pinch_keys = repair_copies(rep.vertex_index, V if rep.welded else None)
    return V, F, labels, colors, mesh.source, repair_report, pinch_keys, k
