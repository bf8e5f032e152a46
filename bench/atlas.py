"""uvbake's atlas stage against xatlas: CPU time, charts, flips, overlaps and texel share.

    PYTHONPATH=. python3 bench/atlas.py [--alphas 0 0.1 0.5 0.9] [--meshes a.off b.ply ...] [--no-xatlas]

In-process ``uvbake.unwrap(mesh, alpha=a)`` without a bake against ``xatlas.parametrize`` (plain
generate, its defaults), process CPU seconds (time.process_time: all threads of this process).
Flips and overlapping pairs come from ``uvbake.validate``; texel shares and where the seams lie (3D length,
share on creases of 30 degrees or more) from ``uvbake.analysis.metrics``.
Every mesh in ../shared/meshes and sample_scenes by default.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def _meshes():
    out = sorted((ROOT.parent / "shared" / "meshes").glob("*.off"))
    return out + sorted((ROOT / "sample_scenes").glob("*.ply"))


def _xatlas(V, F):
    """xatlas.parametrize's work (Atlas.add_mesh + generate, its defaults), to read its chart count."""
    import xatlas

    t = time.process_time()
    atlas = xatlas.Atlas()
    atlas.add_mesh(V.astype(np.float32), F.astype(np.uint32))
    atlas.generate()
    vmapping, indices, uvs = atlas[0]
    cpu = time.process_time() - t
    Fx = indices.astype(np.int64)
    # the input's vertex ids (xatlas splits vertices along its seams): seams are edges whose UVs differ
    return dict(cpu=cpu, charts=int(atlas.chart_count), **_measure(V, vmapping[Fx].astype(np.int64), uvs[Fx]))


def _measure(V, F, corner_uv, chart_ids=None):
    from uvbake.analysis.metrics import seam_placement, texel_summary
    from uvbake.validate import validate

    rep = validate(corner_uv, F, chart_ids=chart_ids, resolution_px=1024)
    seams = seam_placement(V, F, corner_uv)
    return dict(flips=int(rep.n_flipped), overlaps=int(rep.n_overlaps), seam=seams["seam_length"],
                on_creases=seams["on_creases"], **texel_summary(V, F, corner_uv))


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--alphas", type=float, nargs="+", default=[0.0, 0.1, 0.5, 0.9])
    ap.add_argument("--meshes", nargs="+")
    ap.add_argument("--no-xatlas", action="store_true")
    ap.add_argument("--max-stretch", type=float, default=None)
    args = ap.parse_args(argv)
    import uvbake
    from uvbake.io import load_mesh

    uvbake.unwrap(str(ROOT / "sample_scenes" / "sphere_cap.ply"), alpha=0.5)   # imports out of the timings

    print("| mesh | alpha | uvbake CPU s | xatlas CPU s | charts (xatlas) | flips | overlaps | "
          "min share | area < 1/4 | area < 1/16 | xatlas min share | xatlas < 1/4 | seam (xatlas) | "
          "on creases (xatlas) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for path in [Path(p) for p in args.meshes] if args.meshes else _meshes():
        mesh = load_mesh(str(path))
        xa = None if args.no_xatlas else _xatlas(mesh.V, mesh.F)
        for a in args.alphas:
            t = time.process_time()
            res = uvbake.unwrap(str(path), alpha=a, max_stretch=args.max_stretch)
            cpu = time.process_time() - t
            m = _measure(res.V, res.F, res.corner_uv, res.chart_ids)
            x = xa or dict(cpu=float("nan"), charts="-", min_texel_share=float("nan"), area_below_quarter=float("nan"),
                           seam=float("nan"), on_creases=float("nan"))
            print(f"| {path.stem} | {a} | {cpu:.2f} | {x['cpu']:.2f} | {res.report['charts_final']} ({x['charts']}) | "
                  f"{m['flips']} | {m['overlaps']} | {m['min_texel_share']:.3f} | {100 * m['area_below_quarter']:.2f}% | "
                  f"{100 * m['area_below_sixteenth']:.2f}% | {x['min_texel_share']:.3f} | "
                  f"{100 * x['area_below_quarter']:.2f}% | {m['seam']:.3g} ({x['seam']:.3g}) | "
                  f"{100 * m['on_creases']:.0f}% ({100 * x['on_creases']:.0f}%) |", flush=True)


if __name__ == "__main__":
    main()
