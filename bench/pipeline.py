"""Time per pipeline stage and packing efficiency: python bench/pipeline.py [--alpha 0.5] [--bake checker]

Runs `uvbake.unwrap` (what the `uvbake` command runs, without file output) on the sample scenes and,
when ../shared/meshes is present, on beetle and camelhead, and prints a Markdown table. The whole
command on camelhead is also timed end to end (process start, imports and file writes included).
"""

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
SHARED = HERE.parent.parent / "shared" / "meshes"
SCENES = HERE.parent / "sample_scenes"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--alpha", type=float, default=0.5)
    ap.add_argument("--bake", default="checker", choices=["checker", "vertex-colors", "none"])
    ap.add_argument("--texture-size", type=int, default=1024)
    args = ap.parse_args()
    import uvbake

    cases = sorted(SCENES.glob("*.ply")) + [SHARED / f"{m}.off" for m in ("beetle", "camelhead")
                                             if (SHARED / f"{m}.off").exists()]
    # solve_s includes the guarantee's splits (release 1 had a separate split-and-merge stage)
    stages = ["load_repair_s", "charts_s", "solve_s", "pack_s", "validate_s", "bake_s", "total_s"]
    print(f"alpha {args.alpha}, texture {args.texture_size} px, gutter 4 px, bake {args.bake}\n")
    print("| input | triangles | charts in -> out | " + " | ".join(s[:-2] for s in stages) + " | packing | valid |")
    print("|---|---:|---|" + "---:|" * len(stages) + "---:|---|")
    for path in cases:
        bake = None if args.bake == "none" else args.bake
        if bake == "vertex-colors" and uvbake.load_mesh(path).vertex_colors is None:
            bake = "checker"
        r = uvbake.unwrap(path, alpha=args.alpha, texture_size_px=args.texture_size, bake=bake).report
        t = r["timings"]
        print(f"| {path.stem} | {r['triangles']:,} | {r['charts_input']} -> {r['charts_final']} | "
              + " | ".join(f"{t[s]:.2f}" for s in stages)
              + f" | {100 * r['atlas']['efficiency']:.1f}% | {'yes' if r['valid'] else 'NO'} |", flush=True)
    camel = SHARED / "camelhead.off"
    if camel.exists():
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-m", "uvbake", str(camel), "--alpha", str(args.alpha), "--bake",
                            f"{tmp}/checker.png", "-o", f"{tmp}/camelhead.obj", "-q"], check=True)
            print(f"\nwhole `uvbake camelhead.off --alpha {args.alpha} --bake checker.png` command: "
                  f"{time.perf_counter() - t0:.1f} s (target: under 20 s)")


if __name__ == "__main__":
    main()
