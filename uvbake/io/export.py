"""Textured-mesh export: OBJ + MTL + PNG, or a self-contained GLB, with per-corner UVs and seams kept.

    paths = save_textured("out.glb", V, F, corner_uv, image)     # or "out.obj" (writes out.mtl, out.png)
    save_png("texture.png", image)
    V2, F2, corner_uv2 = load_textured_uv("out.glb")

UV convention: ``corner_uv`` is uvbake's internal convention, v up (origin bottom-left, as in OBJ), and
``image`` is stored row 0 = top (as PNG). OBJ ``vt`` lines get ``(u, v)`` unchanged; glTF's texture
origin is the top-left, so the GLB stores ``TEXCOORD_0 = (u, 1 - v)`` with the same image bytes.
:func:`load_textured_uv` converts back, so it always returns v-up UVs.

Seams: OBJ keeps ``v`` exactly as given and writes one ``vt`` per distinct corner UV, so a vertex on a
seam is one ``v`` with several ``vt``. glTF has one UV per vertex, so the GLB splits vertices per
distinct (vertex, UV) pair; corners of one vertex inside one chart stay shared.

Atomicity: every file is first written under a temporary name in the target folder; only when all
of them are complete are they renamed into place (:class:`uvbake.io.atomic.OutputSet`). A failure
leaves no new files and every existing file untouched.
"""

from __future__ import annotations

import io as _io
import os
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from uvbake.errors import InputError
from uvbake.io.atomic import OutputSet, atomic_write_bytes
from uvbake.io.formats import TEXTURED_EXTENSIONS
from uvbake.io.gltf import glb_bytes
from uvbake.io.obj import save_obj
from uvbake.io.uvread import read_uv


def save_textured(path: str | os.PathLike[str], V: ArrayLike, F: ArrayLike, corner_uv: ArrayLike, image: Any, *,
                  vertex_colors: ArrayLike | None = None, name: str = "uvbake") -> list[Path]:
    """Write a textured mesh: ``.obj`` (with ``.mtl`` and ``.png`` beside it) or ``.glb``.

    Parameters
    ----------
    path : str or Path
        Output file; its extension picks the format. The caller makes sure it is not the input.
    V : (n,3) float array
    F : (m,3) int array
    corner_uv : (m,3,2) float array
        Atlas UVs per corner, v up.
    image : (H,W,3) or (H,W,4) uint8 array, or a PIL image
        The texture, row 0 at the top.
    vertex_colors : (n,3) float array in [0,1], optional
        Written as ``v x y z r g b`` (OBJ) or ``COLOR_0`` (GLB). Viewers multiply them with the
        texture, so pass them only when the texture does not already carry them.
    name : str
        Material and mesh name.

    Returns
    -------
    list of Path
        The files written (OBJ: the .obj, .mtl and .png; GLB: the .glb).
    """
    files = textured_files(path, V, F, corner_uv, image, vertex_colors=vertex_colors, name=name)
    with OutputSet(list(files)) as outs:
        for p, data in files.items():
            outs.write_bytes(p, data)
        outs.commit()
    return list(files)


def textured_files(path: str | os.PathLike[str], V: ArrayLike, F: ArrayLike, corner_uv: ArrayLike, image: Any, *,
                   vertex_colors: ArrayLike | None = None, name: str = "uvbake") -> dict[Path, bytes]:
    """The files of a textured mesh as ``{Path: bytes}`` (main file first), without writing them.

    Same parameters as :func:`save_textured`; a caller writing several outputs together passes
    these to one :class:`uvbake.io.atomic.OutputSet`.
    """
    path = Path(path)
    ext = path.suffix.lower()
    if ext not in TEXTURED_EXTENSIONS:
        raise InputError(f"{path}: unknown textured-mesh format {path.suffix!r}; use .obj or .glb")
    V, F, corner_uv, image, vertex_colors = _check(path, V, F, corner_uv, image, vertex_colors)
    name = "".join(c if c.isalnum() or c in "-_." else "_" for c in str(name)) or "uvbake"
    if ext == ".obj":
        return _obj_files(path, V, F, corner_uv, image, vertex_colors, name)
    return {path: glb_bytes(V, F, corner_uv, _png_bytes(image), vertex_colors=vertex_colors, name=name)}


def textured_paths(path: str | os.PathLike[str]) -> list[Path]:
    """The files :func:`save_textured` writes for ``path`` (OBJ: .obj, .mtl, .png; GLB: .glb)."""
    path = Path(path)
    if path.suffix.lower() == ".obj":
        return [path, path.with_suffix(".mtl"), path.with_suffix(".png")]
    return [path]


def save_png(path: str | os.PathLike[str], image: Any) -> Path:
    """Write a texture as PNG (lossless), atomically.

    Parameters
    ----------
    path : str or Path
        Must end in ``.png``; its folder must exist.
    image : (H,W), (H,W,3) or (H,W,4) uint8 array, or a PIL image
        Row 0 at the top (v = 1).

    Returns
    -------
    Path
    """
    path = Path(path)
    if path.suffix.lower() != ".png":
        raise InputError(f"{path}: a texture is written as PNG; give a path ending in .png")
    image = _check_image(path, image)
    data = _png_bytes(image)
    atomic_write_bytes(path, data)
    return path


def load_textured_uv(path: str | os.PathLike[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Read back a textured mesh written by :func:`save_textured`.

    Returns
    -------
    V : (k,3) float64 array
        OBJ: the ``v`` lines as written. GLB: the split vertices.
    F : (m,3) int64 array
    corner_uv : (m,3,2) float64 array
        Per-corner UVs, v up (the GLB's ``1 - v`` is undone).
    """
    path = Path(path)
    ext = path.suffix.lower()
    if ext in TEXTURED_EXTENSIONS:
        parts = read_uv(path)
        if len(parts) != 1 or parts[0].corner_uv is None:
            raise InputError(f"{path}: has no texture coordinates on every face; export it again")
        return parts[0].V, parts[0].F, parts[0].corner_uv
    raise InputError(f"{path}: unknown textured-mesh format {path.suffix!r}; use .obj or .glb")


# --------------------------------------------------------------------------------------------------
# checks and helpers


def _check(path: Path, V: ArrayLike, F: ArrayLike, corner_uv: ArrayLike, image: Any, vertex_colors: ArrayLike | None
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F)
    corner_uv = np.asarray(corner_uv, dtype=np.float64)
    if V.ndim != 2 or V.shape[1] != 3:
        raise InputError(f"{path}: V must be (n,3), got shape {V.shape}; pass vertex positions")
    if F.ndim != 2 or F.shape[1] != 3 or len(F) == 0 or not np.issubdtype(F.dtype, np.integer) \
            or F.min() < 0 or F.max() >= len(V):
        raise InputError(f"{path}: F must be (m,3), m > 0, with indices in 0..{len(V) - 1}; "
                         "pass triangles indexing V")
    F = F.astype(np.int64)
    if corner_uv.shape != (len(F), 3, 2) or not np.all(np.isfinite(corner_uv)):
        raise InputError(f"{path}: corner_uv must be finite (m,3,2)=({len(F)},3,2), got "
                         f"{corner_uv.shape}; pass the atlas UVs per face corner")
    if not np.all(np.isfinite(V)):
        raise InputError(f"{path}: V holds NaN or infinite coordinates; repair the mesh first")
    image = _check_image(path, image)
    colors: np.ndarray | None = None
    if vertex_colors is not None:
        colors = np.asarray(vertex_colors)
        if colors.dtype == np.uint8:
            colors = colors / 255.0
        colors = colors.astype(np.float64)
        if colors.ndim != 2 or colors.shape[0] != len(V) or colors.shape[1] not in (3, 4):
            raise InputError(f"{path}: vertex_colors must be (n,3)={V.shape}, got "
                             f"{colors.shape}; pass one RGB colour per vertex")
        colors = np.clip(colors[:, :3], 0.0, 1.0)
    return V, F, corner_uv, image, colors


def _check_image(path: str | os.PathLike[str], image: Any) -> np.ndarray:
    if hasattr(image, "convert") and hasattr(image, "mode"):  # a PIL image
        image = np.asarray(image.convert("RGBA" if image.mode in ("RGBA", "LA", "PA") else "RGB"))
    image = np.asarray(image)
    if image.ndim == 2:
        image = np.repeat(image[..., None], 3, axis=2)
    if image.ndim != 3 or image.shape[2] not in (3, 4) or image.dtype != np.uint8 \
            or min(image.shape[:2]) < 1:
        raise InputError(f"{path}: image must be (H,W,3) or (H,W,4) uint8, got {image.shape} "
                         f"{image.dtype}; pass a baked texture")
    return np.ascontiguousarray(image)


def png_bytes(image: Any, name: str | os.PathLike[str] = "image") -> bytes:
    """A texture (see :func:`save_png`) encoded as PNG, for writers that stage their own files."""
    return _png_bytes(_check_image(name, image))


def _png_bytes(image: np.ndarray) -> bytes:
    """Lossless PNG encoding of an (H,W,3|4) uint8 image."""
    from PIL import Image

    buf = _io.BytesIO()
    Image.fromarray(image).save(buf, format="PNG")
    return buf.getvalue()


# --------------------------------------------------------------------------------------------------
# OBJ + MTL + PNG


def _obj_files(path, V, F, corner_uv, image, vertex_colors, name):
    mtl_path, png_path = path.with_suffix(".mtl"), path.with_suffix(".png")
    uv, uv_faces = np.unique(corner_uv.reshape(-1, 2), axis=0, return_inverse=True)
    uv_faces = uv_faces.reshape(-1, 3)
    mtl = (f"# written by uvbake\nnewmtl {name}\nKa 1 1 1\nKd 1 1 1\nKs 0 0 0\nd 1\nillum 1\n"
           f"map_Kd {png_path.name}\n")
    obj = save_obj(path, V, F, uv=uv, uv_faces=uv_faces, vertex_colors=vertex_colors,
                   mtllib=mtl_path.name, material=name, as_text=True)
    return {path: obj.encode("utf-8"), mtl_path: mtl.encode("utf-8"), png_path: _png_bytes(image)}
