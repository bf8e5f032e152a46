"""The process that unwraps one asset of a batch (forked by :mod:`uvbake.batch.zygote`, or run as
``python -m uvbake.batch.child SPEC.json``).

:func:`uvbake.batch.task.process` runs every asset in such a process, so the asset's time limit can
really stop it (a kill of the whole process, whatever native code it is in: CHOLMOD, Open3D) and a
crash takes down this process only, never the Dask worker. It writes everything into the staging
folder named by the spec and nothing elsewhere; the worker moves the files into place afterwards.

Writes (in the staging folder): the textured mesh (``<stem>_uv.obj`` + ``.mtl`` + ``.png``, or
``<stem>_uv.glb``), ``report.json`` (uvbake's report), ``preview.png`` and ``atlas.png`` (thumbnails
for the HTML report) and last ``row.json`` (the summary row's numbers); on an error ``error.json``
(``{"error": one line}``) and exit status 1.
"""

from __future__ import annotations

import json
import os
import sys
import threading
import time
from pathlib import Path
from typing import Any

#: name -> function(UnwrapResult, size_px) -> (H,W,3) uint8: the atlas thumbnails the batch can draw.
#: "auto" picks "texture" when a texture was baked, else "charts". Add entries to offer more.
ATLAS_IMAGES: dict[str, Any] = {}


def _atlas_texture(result, size_px):
    from PIL import Image

    img = Image.fromarray(result.image)
    img.thumbnail((size_px, size_px), Image.Resampling.LANCZOS)   # deterministic resampling
    return __import__("numpy").asarray(img)


def _atlas_charts(result, size_px):
    from uvbake.validate.core import validate

    # the validator's own picture: every chart in its colour, overlaps red, flipped triangles blue
    return validate(result.corner_uv, result.F, chart_ids=result.chart_ids, resolution_px=size_px).overlap_image()


ATLAS_IMAGES.update(texture=_atlas_texture, charts=_atlas_charts)


def _watch_parent(watch_pid):
    """Exit when the worker that started us is gone (a killed Dask worker must not leave us running)."""
    parent = os.getppid()
    while True:
        time.sleep(0.5)
        try:
            if watch_pid:
                os.kill(watch_pid, 0)
        except ProcessLookupError:
            os._exit(70)
        if os.getppid() != parent:
            os._exit(70)


def run(spec: dict) -> dict:
    """Unwrap, save and draw one asset as the spec says; return the row's numbers."""
    t_start = time.perf_counter()
    from uvbake.atlas.pipeline import unwrap
    from uvbake.io.atomic import atomic_write
    from uvbake.io.export import save_png

    staging = Path(spec["staging"])
    opts = spec["options"]
    t_import = time.perf_counter() - t_start
    result = unwrap(spec["input"], workers=1, **opts["unwrap"])
    t = time.perf_counter()
    mesh_path = staging / f"{spec['stem']}_uv.{opts['format']}"
    written = [Path(p).name for p in result.save(mesh_path)]
    timings = {f"t_{k}": float(v) for k, v in result.report["timings"].items()}
    timings["t_save_s"] = time.perf_counter() - t
    images = {}
    t = time.perf_counter()
    if opts["preview_size_px"]:
        from uvbake.render import RenderError, preview

        try:    # already in a child process of our own, so the renderer needs no second one
            preview(result, path=staging / "preview.png", size_px=opts["preview_size_px"], isolate=False)
            images["preview"] = "preview.png"
        except RenderError as exc:
            images["preview_error"] = str(exc)
    timings["t_preview_s"] = time.perf_counter() - t
    t = time.perf_counter()
    if opts["atlas_image"]:
        kind = opts["atlas_image"]
        if kind == "auto":
            kind = "texture" if result.image is not None else "charts"
        save_png(staging / "atlas.png", ATLAS_IMAGES[kind](result, opts["atlas_size_px"]))
        images["atlas"] = "atlas.png"
    timings["t_atlas_s"] = time.perf_counter() - t
    timings["t_startup_s"] = t_import

    rep = result.report
    final = rep["distortion"]["final"]
    verdict = rep["atlas"]["validation"]
    row = dict(
        vertices=rep["vertices"], triangles=rep["triangles"], charts_input=rep["charts_input"],
        charts=rep["charts_final"], valid=rep["valid"], n_flipped=verdict["n_flipped"],
        n_overlaps=verdict["n_overlaps"], angle_distortion=final["angle_distortion_mean"],
        angle_distortion_max=final["angle_distortion_max"], area_distortion=final["area_distortion_mean"],
        packing=rep["atlas"].get("efficiency"), all_converged=rep["all_converged"],
        repairs=len((rep.get("repair") or {}).get("actions", []) or []),
        mesh=mesh_path.name, files=written, **images, **timings,
    )
    with atomic_write(staging / "report.json") as fh:
        json.dump(rep, fh, indent=1)
    return row


def main(argv: list[str]) -> None:
    spec = json.loads(Path(argv[0]).read_text())
    threading.Thread(target=_watch_parent, args=(spec.get("watch_pid"),), daemon=True).start()
    staging = Path(spec["staging"])
    try:
        row = run(spec)
    except Exception as exc:  # noqa: BLE001 - any failure of this one asset becomes its one-line record
        line = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
        (staging / "error.json").write_text(json.dumps({"error": f"{type(exc).__name__}: {line}"}))
        sys.stdout.flush()
        os._exit(1)
    (staging / "row.json").write_text(json.dumps(row))
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(0)          # skip Open3D/Filament teardown at interpreter exit (slow, and chatty)


if __name__ == "__main__":
    main(sys.argv[1:])
