"""Preview renders of a textured mesh for regression images, with Open3D's offscreen renderer.

    img = uvbake.render.preview(result, path="preview.png")            # an UnwrapResult
    img = uvbake.render.preview(V, F, corner_uv, image, size_px=256)    # or arrays

The mesh is drawn from fixed cameras (:data:`VIEWS`: front, back, and an angle) and the views are put
side by side in one RGB image (``(S, 3 S + 2 * SEPARATOR_PX, 3)`` uint8 for ``size_px = S``).

Headless on CPU. Open3D 0.20's ``OffscreenRenderer`` (Filament) picks its Vulkan backend when the only
Vulkan device is a software one: Mesa's lavapipe (llvmpipe) from Debian's ``mesa-vulkan-drivers``
through the loader in ``libvulkan1``. No display, no EGL device, no ``OPEN3D_CPU_RENDERING`` (0.20 does
not read it) and no ``EGL_PLATFORM`` are needed. Rendering runs in a child process by default
(``isolate=True``): the Filament engine prints to the C-level stdout, keeps threads alive and can abort
the process on a broken driver; in a child it does none of that to the caller, a hang is cut by
``timeout_s`` and a failure becomes a :class:`RenderError` naming the fix. The child costs about 2 s
(importing Open3D and starting the engine).

Determinism and colour. Filament's post-processing (tone mapping, colour grading, and a temporal
dithering that changes the bytes from one frame to the next) is turned off, so the same inputs give the
same bytes on the same machine. Without it the unlit shader writes ``0.5 * base_color_lin *
srgb_to_linear(texel)`` to the 8-bit target with no sRGB encoding; uvbake therefore hands the renderer
the texture re-encoded as ``linear_to_srgb(texel)`` (so the shader's decoding gives back ``texel``) and a
base colour whose linear value is 2, and the output bytes are the texture's own values (within a few
levels: 8-bit re-quantisation and texture filtering). Views are rendered at ``SUPERSAMPLE`` times the
size and box-filtered down (deterministic anti-aliasing). Open3D's renderer samples ``texture_uvs``
with v up (image row 0 at v = 1), the convention of uvbake's ``corner_uv`` (checked by
``tests/test_render.py``).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from uvbake.errors import InputError, UvbakeError
from uvbake.pictures import atlas_image  # noqa: F401  (the 2D atlas picture beside the 3D preview)
from uvbake.views import DEFAULT_VIEWS, LIGHTING, TURNTABLE_ELEVATION_DEG, VIEWS  # noqa: F401  (named here too)


class RenderError(UvbakeError, RuntimeError):
    """The offscreen renderer could not run; the message says what to install or set."""


LIT_SUN, LIT_AMBIENT = 200000.0, 60000.0      # Filament lux; chosen by eye on the sample scene
FOV_DEG = 30.0
SUPERSAMPLE = 2
SEPARATOR_PX = 2
SEPARATOR_RGB = (200, 200, 200)
#: sRGB-encoded base colour whose linear value is 2: cancels the unlit shader's factor 0.5.
_BASE_COLOR = 1.055 * 2.0 ** (1.0 / 2.4) - 0.055


def preview(source: Any, F: ArrayLike | None = None, corner_uv: ArrayLike | None = None, image: Any = None, *,
            path: str | os.PathLike[str] | None = None, size_px: int = 256, views: Any = DEFAULT_VIEWS,
            background: Sequence[int] = (255, 255, 255), lighting: str = "unlit",
            vertex_colors: ArrayLike | None = None, isolate: bool = True, timeout_s: float = 120.0) -> np.ndarray:
    """Render the textured mesh from fixed cameras into one image.

    Parameters
    ----------
    source : UnwrapResult or (n,3) float array
        An :class:`uvbake.atlas.pipeline.UnwrapResult` (then ``F``, ``corner_uv``, ``image`` come from it) or
        the vertex positions ``V``.
    F : (m,3) int array
    corner_uv : (m,3,2) float array
        Per-corner atlas UVs, v up.
    image : (H,W,3) uint8 array, optional
        The texture (row 0 = top). ``None``: a light grey texture (the shape only).
    path : str or Path, optional
        Also write the PNG here (atomically).
    size_px : int
        Side of each square view (32 to 2048).
    views : sequence of names from :data:`VIEWS`, or "turntable:N"
        "turntable:N": N views around the vertical axis (y up) at :data:`TURNTABLE_ELEVATION_DEG`,
        starting from the front, as one strip.
    background : RGB triple, 0..255
    lighting : {"unlit", "lit"}
        "unlit" (default): the texture's own colours (what the goldens compare). "lit": shaded by a sun
        light over the camera's shoulder plus ambient light, to see the shape.
    vertex_colors : (n,3) float array in [0,1], optional
        Multiplied with the texture, as glTF viewers do with ``COLOR_0`` (to see what a file that
        carries both looks like). Default: the texture alone.
    isolate : bool
        Render in a child process (default; see the module docstring). ``False`` renders in this process.
    timeout_s : float
        Give up on the child after this long.

    Returns
    -------
    (size_px, len(views) * size_px + separators, 3) uint8 array
    """
    V, F, corner_uv, image = _inputs(source, F, corner_uv, image)
    if isinstance(size_px, bool) or not isinstance(size_px, (int, np.integer)) or not 32 <= size_px <= 2048:
        raise InputError(f"size_px={size_px!r} must be a whole number of pixels from 32 to 2048")
    directions = view_directions(views)
    if lighting not in LIGHTING:
        raise InputError(f"lighting={lighting!r} is not one of {', '.join(LIGHTING)}")
    bg = np.asarray(background)
    if bg.shape != (3,) or np.any(bg < 0) or np.any(bg > 255):
        raise InputError(f"background={background!r} must be an RGB triple of values 0..255")
    params: dict[str, Any] = dict(size_px=int(size_px), views=directions, background=[int(b) for b in bg],
                                  lighting=lighting)
    if vertex_colors is not None:
        vertex_colors = np.asarray(vertex_colors, np.float64)
        if vertex_colors.ndim != 2 or vertex_colors.shape[0] != len(V) or vertex_colors.shape[1] < 3:
            raise InputError(f"vertex_colors must be ({len(V)},3), got shape {vertex_colors.shape}")
        vertex_colors = np.ascontiguousarray(np.clip(vertex_colors[:, :3], 0.0, 1.0))
    if isolate:
        out = _render_in_child(V, F, corner_uv, image, params, timeout_s, vertex_colors)
    else:
        out = render_views(V, F, corner_uv, image, vertex_colors=vertex_colors, **params)
    if path is not None:
        save_png(path, out)
    return out


def _inputs(source: Any, F: Any, corner_uv: Any, image: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    if hasattr(source, "corner_uv") and hasattr(source, "F"):
        V, F, corner_uv, image = source.V, source.F, source.corner_uv, source.image if image is None else image
    else:
        V = source
    if F is None or corner_uv is None:
        raise InputError("preview needs V, F and corner_uv (or an UnwrapResult)")
    V = np.ascontiguousarray(V, dtype=np.float64)
    F = np.ascontiguousarray(F, dtype=np.int64)
    corner_uv = np.ascontiguousarray(corner_uv, dtype=np.float64)
    if V.ndim != 2 or V.shape[1] != 3 or len(V) == 0 or not np.all(np.isfinite(V)):
        raise InputError(f"V must be a finite (n,3) array, got shape {V.shape}")
    if F.ndim != 2 or F.shape[1] != 3 or len(F) == 0 or F.min() < 0 or F.max() >= len(V):
        raise InputError(f"F must be an (m,3) array of vertex indices into V, got shape {F.shape}")
    if corner_uv.shape != (len(F), 3, 2) or not np.all(np.isfinite(corner_uv)):
        raise InputError(f"corner_uv must be a finite ({len(F)},3,2) array, got shape {corner_uv.shape}")
    return V, F, corner_uv, _check_image(image)


def _check_image(image):
    if image is None:
        image = np.full((16, 16, 3), 200, np.uint8)
    image = np.asarray(image)
    if image.ndim == 3 and image.shape[2] == 4:
        image = image[:, :, :3]
    if image.dtype != np.uint8 or image.ndim != 3 or image.shape[2] != 3:
        raise InputError(f"image must be an (H,W,3) uint8 array, got {image.dtype} {image.shape}")
    return np.ascontiguousarray(image)


def save_png(path: str | os.PathLike[str], img: ArrayLike) -> Path:
    """Write an RGB uint8 image as PNG, atomically (see :func:`uvbake.io.export.save_png`)."""
    from uvbake.io.export import save_png as _save_png

    return _save_png(path, np.asarray(img, dtype=np.uint8))


def view_directions(views: Any) -> list[list[list[float]]]:
    """[[direction, up], ...] (JSON-ready lists) of view names, or of "turntable:N"."""
    if isinstance(views, str):
        views = (views,)
    views = tuple(views)
    if len(views) == 1 and str(views[0]).startswith("turntable:"):
        n = str(views[0]).split(":", 1)[1]
        if not n.isdigit() or not 1 <= int(n) <= 36:
            raise InputError(f"views {views[0]!r}: say turntable:N with N from 1 to 36")
        az = np.radians(360.0 * np.arange(int(n)) / int(n))
        el = np.radians(TURNTABLE_ELEVATION_DEG)
        return [[[float(np.sin(a) * np.cos(el)), float(np.sin(el)), float(np.cos(a) * np.cos(el))], [0.0, 1.0, 0.0]]
                for a in az]
    bad = [v for v in views if v not in VIEWS]
    if not views or bad:
        raise InputError(f"views {bad or views!r} not known; use names from {sorted(VIEWS)} or turntable:N")
    return [[list(VIEWS[v][0]), list(VIEWS[v][1])] for v in views]


def cameras(V: np.ndarray, views: Any = DEFAULT_VIEWS) -> tuple[np.ndarray, list[tuple[np.ndarray, np.ndarray]]]:
    """(centre, [(eye, up), ...]) of the cameras: the bounding sphere fills the view.

    ``views``: names from :data:`VIEWS`, "turntable:N", or [direction, up] pairs."""
    if isinstance(views, str) or (len(views) and isinstance(views[0], str)):
        views = view_directions(views)
    lo, hi = V.min(axis=0), V.max(axis=0)
    centre = (lo + hi) / 2.0
    radius = float(np.linalg.norm(V - centre, axis=1).max()) or 1.0
    dist = radius / np.sin(np.radians(FOV_DEG / 2.0)) * 1.02
    out = []
    for d, up in views:
        d, up = np.asarray(d, np.float64), np.asarray(up, np.float64)
        out.append((centre + dist * d / np.linalg.norm(d), up))
    return centre, out


def _linear_to_srgb_u8(img):
    x = img.astype(np.float64) / 255.0
    y = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)
    return np.clip(np.rint(y * 255.0), 0, 255).astype(np.uint8)


def render_views(V: np.ndarray, F: np.ndarray, corner_uv: np.ndarray, image: np.ndarray, *, size_px: int, views: Any,
                 background: Sequence[int], lighting: str = "unlit", vertex_colors: np.ndarray | None = None
                 ) -> np.ndarray:
    """Render in this process (Open3D must be importable and able to start its engine)."""
    import open3d as o3d

    R = o3d.visualization.rendering
    ss = SUPERSAMPLE
    try:
        renderer = R.OffscreenRenderer(size_px * ss, size_px * ss)
    except Exception as exc:                       # pragma: no cover - depends on the machine
        raise RenderError(f"Open3D's offscreen renderer did not start ({exc}); install libvulkan1 and "
                          "mesa-vulkan-drivers (Debian) or a GPU driver") from exc
    scene = renderer.scene
    scene.view.set_post_processing(False)
    scene.set_background([b / 255.0 for b in background] + [1.0])
    mesh = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(V), o3d.utility.Vector3iVector(F.astype(np.int32)))
    mesh.triangle_uvs = o3d.utility.Vector2dVector(corner_uv.reshape(-1, 2))
    mesh.triangle_material_ids = o3d.utility.IntVector(np.zeros(len(F), np.int32))
    if vertex_colors is not None:
        mesh.vertex_colors = o3d.utility.Vector3dVector(np.asarray(vertex_colors, np.float64))
    tex = o3d.geometry.Image(_linear_to_srgb_u8(image))
    mesh.textures = [tex]
    mat = R.MaterialRecord()
    mat.albedo_img = tex
    if lighting == "lit":
        mesh.compute_vertex_normals()
        mat.shader = "defaultLit"
        mat.base_color = [1.0, 1.0, 1.0, 1.0]
        mat.base_roughness = 0.9
        mat.base_metallic = 0.0
        scene.scene.set_indirect_light_intensity(LIT_AMBIENT)
    else:
        mat.shader = "defaultUnlit"
        mat.base_color = [_BASE_COLOR, _BASE_COLOR, _BASE_COLOR, 1.0]
    scene.add_geometry("mesh", mesh, mat)
    centre, cams = cameras(V, views)
    bg = np.asarray(background, np.uint8)
    tiles = []
    for eye, up in cams:
        renderer.setup_camera(FOV_DEG, centre.astype(np.float32), eye.astype(np.float32), up.astype(np.float32))
        if lighting == "lit":         # the sun over the camera's shoulder (upper left), towards the centre
            side = np.cross(up, centre - eye)
            sun = (centre - eye) / np.linalg.norm(centre - eye) - 0.5 * up + 0.5 * side / (np.linalg.norm(side) or 1)
            scene.scene.set_sun_light((sun / np.linalg.norm(sun)).astype(np.float32), [1.0, 1.0, 1.0], LIT_SUN)
            scene.scene.enable_sun_light(True)
        img = np.asarray(renderer.render_to_image())[:, :, :3]
        for _ in range(3):                         # the engine may present a frame before the upload
            if np.any(img != bg):
                break
            img = np.asarray(renderer.render_to_image())[:, :, :3]
        img = img.astype(np.float64).reshape(size_px, ss, size_px, ss, 3).mean(axis=(1, 3))
        tiles.append(np.clip(np.rint(img), 0, 255).astype(np.uint8))
    del renderer
    sep = np.empty((size_px, SEPARATOR_PX, 3), np.uint8)
    sep[:] = SEPARATOR_RGB
    parts = []
    for i, t in enumerate(tiles):
        if i:
            parts.append(sep)
        parts.append(t)
    return np.ascontiguousarray(np.hstack(parts))


def _render_in_child(V, F, corner_uv, image, params, timeout_s, vertex_colors=None):
    with tempfile.TemporaryDirectory(prefix="uvbake-render-") as tmp:
        src, dst = Path(tmp) / "in.npz", Path(tmp) / "out.npy"
        extra = {} if vertex_colors is None else {"vertex_colors": vertex_colors}
        np.savez(src, V=V, F=F, corner_uv=corner_uv, image=image, params=np.array(json.dumps(params)), **extra)
        env = dict(os.environ)
        try:
            proc = subprocess.run([sys.executable, "-m", "uvbake.render", str(src), str(dst)],
                                  stdin=subprocess.DEVNULL, capture_output=True, text=True, env=env,
                                  timeout=timeout_s)
        except subprocess.TimeoutExpired:
            raise RenderError(f"the preview renderer did not finish in {timeout_s:g} s; check that Vulkan "
                              "works (vulkaninfo) or pass a larger timeout_s") from None
        if proc.returncode != 0 or not dst.exists():
            tail = " | ".join(line for line in (proc.stderr or "").strip().splitlines()[-3:])
            raise RenderError(f"the preview renderer failed (exit {proc.returncode}: {tail or 'no message'}); "
                              "headless rendering needs libvulkan1 and mesa-vulkan-drivers (Debian) "
                              "or a GPU driver")
        return np.load(dst)


def _child(argv):
    src, dst = argv
    with np.load(src) as d:
        params = json.loads(str(d["params"]))
        colors = d["vertex_colors"] if "vertex_colors" in d.files else None
        out = render_views(d["V"], d["F"], d["corner_uv"], d["image"], vertex_colors=colors, **params)
    np.save(dst, out)
    sys.stdout.flush()
    os._exit(0)          # skip Filament's teardown at interpreter exit (slow, and chatty)


if __name__ == "__main__":
    _child(sys.argv[1:])
