"""Issue 7's acceptance matrix: every input, alpha and init, end to end through the CLI.

    python bench/guarantee.py [--meshes ...] [--alphas 0 0.1 0.5 0.9] [--inits lscm random] [--out DIR]

For each run: `uvbake MESH --alpha A --init I -o DIR/x.obj --json DIR/x.json`, then the exported OBJ
is judged again by `uvbake check` (the exact validator, independent of the pipeline's own verdict).
Prints a Markdown table: charts before/after cuts and splits, seam length added, flips and
overlapping pairs in the exported atlas, angle/area distortion before and after the guarantee, time.
"""

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
SHARED = HERE.parent.parent / "shared" / "meshes"
SCENES = HERE.parent / "sample_scenes"


def inputs(names):
    found = sorted(SCENES.glob("*.ply")) + (sorted(SHARED.glob("*.off")) if SHARED.is_dir() else [])
    return [p for p in found if not names or p.stem in names]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--meshes", nargs="*", default=[])
    ap.add_argument("--alphas", nargs="+", default=["0", "0.1", "0.5", "0.9"])
    ap.add_argument("--inits", nargs="+", default=["lscm", "random"])
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    out = Path(args.out or tempfile.mkdtemp(prefix="uvbake-guarantee-"))
    out.mkdir(parents=True, exist_ok=True)
    print("| input | alpha | init | exit | charts in -> out | splits | seam added | flipped | overlapping pairs "
          "| check | angle dist. (unconstr. -> final) | area dist. | time (s) |")
    print("|---|---:|---|---:|---|---:|---:|---:|---:|---|---|---|---:|")
    failures = 0
    for mesh in inputs(args.meshes):
        for alpha in args.alphas:
            for init in args.inits:
                stem = f"{mesh.stem}-{alpha}-{init}"
                obj, rep = out / f"{stem}.obj", out / f"{stem}.json"
                t = time.perf_counter()
                run = subprocess.run([sys.executable, "-m", "uvbake.cli", str(mesh), "--alpha", alpha, "--init",
                                      init, "-o", str(obj), "--json", str(rep), "-q"], capture_output=True, text=True)
                dt = time.perf_counter() - t
                if run.returncode != 0:
                    failures += 1
                    print(f"| {mesh.stem} | {alpha} | {init} | {run.returncode} | {run.stderr.strip()[:120]} |||||||||",
                          flush=True)
                    continue
                r = json.loads(rep.read_text())
                chk = subprocess.run([sys.executable, "-m", "uvbake.cli", "check", str(obj),
                                      "--json", str(out / f"{stem}.check.json")], capture_output=True, text=True)
                c = json.loads((out / f"{stem}.check.json").read_text())
                n_flip = len(c.get("flipped", []))
                n_over = len(c.get("overlap_pairs", []))
                failures += chk.returncode != 0
                du, df = r["distortion"]["unconstrained"], r["distortion"]["final"]
                print(f"| {mesh.stem} | {alpha} | {init} | 0 | {r['charts_input']} -> {r['charts_final']} | "
                      f"{len(r['splits'])} | {r['seam_length_added']:.3g} | {n_flip} | {n_over} | "
                      f"{'valid' if chk.returncode == 0 else 'INVALID'} | "
                      f"{du['angle_distortion_mean']:.3f} -> {df['angle_distortion_mean']:.3f} | "
                      f"{du['area_distortion_mean']:.3f} -> {df['area_distortion_mean']:.3f} | {dt:.1f} |", flush=True)
    print(f"\n{failures} failing run(s); outputs in {out}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
