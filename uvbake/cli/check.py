"""``uvbake check``: validate the UVs of any textured mesh file (ours, xatlas's, Blender's).

    uvbake check mesh.obj [--image overlaps.png] [--json report.json] [--resolution 2048]

Exit status 0 when the UVs are bijective, 1 when they are not, 2 on bad input (missing or unreadable
file, no texture coordinates, bad option). The verdict is one line on stdout; errors are one line on
stderr. Output files are written atomically. Face numbers in the JSON report count the triangles of
the file in order, geometries of a scene one after the other.
"""

from __future__ import annotations

import argparse
import json
import os
from typing import TYPE_CHECKING

from uvbake.cli.common import EXIT_FAILED, EXIT_OK, ArgumentParser
from uvbake.cli.common import run as run_command
from uvbake.errors import InputError
from uvbake.io.atomic import atomic_write_bytes

if TYPE_CHECKING:                     # the readers and the validator load numpy: imported when run
    import numpy as np

__all__ = ["main", "run", "add_arguments", "load_uv_mesh"]



DESCRIPTION = "Check that the UVs of a textured mesh are bijective (no flips, no overlaps)."


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The arguments of ``uvbake check PATH ...``."""
    p.add_argument(
        "path",
        help="mesh with texture coordinates: .obj (vt), .glb/.gltf (TEXCOORD_0), .ply (s,t or u,v)",
    )
    p.add_argument("--image", metavar="PNG", help="write the overlap image here: charts in colour, overlaps "
                   "red, flipped triangles blue, v up, with a legend strip below")
    p.add_argument("--json", metavar="JSON", help="write the full report here")
    p.add_argument(
        "--resolution", metavar="N", type=int, default=2048, help="raster side in pixels (default 2048)"
    )
    p.add_argument(
        "--allow-subpixel",
        action="store_true",
        help="overlaps that claim no common pixel at --resolution do not fail the check",
    )


def load_uv_mesh(path: str | os.PathLike[str]) -> tuple[np.ndarray, np.ndarray]:
    """Load the UVs of a textured mesh, welded for validation.

    Vertices are welded when both their 3D position and their UV are bit-identical, inside each
    geometry: files split vertices at UV seams (and often at normal creases), so this recovers the
    UV mesh's connectivity without joining charts that merely touch in UV space.

    Parameters
    ----------
    path : str or path

    Returns
    -------
    uv : (n,2) float64
    F : (m,3) int64
    """
    import numpy as np

    from uvbake.io.uvread import read_uv
    from uvbake.validate.candidates import _row_ids
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise InputError(f"no such file: {path}; pass the path of a .obj, .glb, .gltf or .ply mesh")
    parts = read_uv(path)
    uvs, faces, offset = [], [], 0
    n_tri = sum(len(part.F) for part in parts)
    for part in parts:
        if part.corner_uv is None:
            continue
        corner_uv = part.corner_uv.reshape(-1, 2)
        keys = (np.column_stack([part.V[part.F].reshape(-1, 3), corner_uv]) + 0.0).view(np.int64)
        ids = _row_ids(keys)  # +0.0 above folds -0.0 into 0.0
        welded = np.empty((int(ids.max()) + 1 if len(ids) else 0, 2))
        welded[ids] = corner_uv
        uvs.append(welded)
        faces.append(ids.reshape(-1, 3) + offset)
        offset += len(welded)
    if not faces:
        what = "no triangles" if n_tri == 0 else "no texture coordinates"
        raise InputError(f"{path} has {what}; unwrap it first (e.g. `uvbake {path}`)")
    return np.concatenate(uvs), np.concatenate(faces)


def run(args: argparse.Namespace) -> int:
    """``uvbake check``: the exit status is 0 when the UVs are bijective, 1 when they are not."""
    from uvbake.io.export import save_png
    from uvbake.pictures import legend_lines, with_legend
    from uvbake.validate.core import validate
    uv, F = load_uv_mesh(args.path)
    for out in (args.image, args.json):
        if out and not os.path.isdir(os.path.dirname(os.path.abspath(out))):
            raise InputError(f"folder of {out} does not exist; create it or choose another path")
    # per-corner UVs make it an atlas (raster on [0,1]^2 when the UVs lie there); F keeps the welding
    report = validate(uv[F], F, resolution_px=args.resolution, allow_subpixel=args.allow_subpixel)
    if args.image:   # the overlap picture with a legend strip below it (what was found, in words)
        save_png(args.image, with_legend(report.overlap_image(), legend_lines(report.to_dict())))
    if args.json:
        doc = {"path": os.fspath(args.path), **report.to_dict()}
        atomic_write_bytes(args.json, (json.dumps(doc, indent=1) + "\n").encode())
    print(f"{args.path}: {report.summary()}")
    return EXIT_OK if report.valid else EXIT_FAILED


def main(argv: list[str] | None = None) -> int:
    """Run ``uvbake check``; return the exit status (0 valid, 1 invalid, 2 bad input)."""
    parser = ArgumentParser(prog="uvbake check", description=DESCRIPTION)
    add_arguments(parser)
    return run_command("uvbake check", lambda: run(parser.parse_args(argv)))
