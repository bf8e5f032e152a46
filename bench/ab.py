"""Two source trees of uvbake side by side on the same inputs: CPU, charts, least texel share, validity and
a hash of the corner UVs (the same bytes or not).

    python bench/ab.py --trees /tmp/base . --alpha 0.5 --reps 2 mesh:cow shape:terrain stress:heightfield

``/tmp/base`` is, for instance, ``git worktree add /tmp/base <commit>``. Each run is a fresh subprocess with
``PYTHONPATH`` set to its tree, the trees alternated ``--reps`` times; a cell shows the least CPU of its runs.
Inputs: ``mesh:NAME`` (../shared/meshes/NAME.off), ``shape:NAME`` (bench/shapes.py), ``stress:NAME``
(bench/stress.py; those are not warmed up first, the others are unwrapped once before the timed call;
Open3D's reconstructions there vary between runs, so their bytes differ even within a tree).
In-process ``uvbake.unwrap(input, alpha=...)``, process CPU seconds (user + system).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

BENCH = Path(__file__).resolve().parent

_RUN = r"""
import hashlib, json, sys, time
sys.path.insert(0, sys.argv[3])
import numpy as np
import uvbake

kind, name = sys.argv[1].split(":")
alpha = float(sys.argv[2])
if kind == "shape":
    from shapes import shapes
    m = shapes()[name]
    src = (np.asarray(m.vertices, float), np.asarray(m.faces, np.int64))
elif kind == "mesh":
    src = f"{sys.argv[3]}/../../shared/meshes/{name}.off"
else:
    from stress import inputs
    V, F = inputs()[name]()
    src = (np.asarray(V, float), np.asarray(F, np.int64))
if kind != "stress":
    uvbake.unwrap(src, alpha=alpha)
t = time.process_time()
r = uvbake.unwrap(src, alpha=alpha)
cpu = time.process_time() - t
print(json.dumps(dict(cpu=cpu, charts=r.report["charts_final"], share=r.report["min_texel_share"],
                      valid=r.report["valid"], hash=hashlib.sha1(np.ascontiguousarray(r.corner_uv).tobytes()).hexdigest()[:10])))
"""


def _one(tree: str, item: str, alpha: float) -> dict | None:
    env = dict(os.environ, PYTHONPATH=str(Path(tree).resolve()))
    p = subprocess.run([sys.executable, "-c", _RUN, item, str(alpha), str(BENCH)], env=env, capture_output=True,
                       text=True, cwd=BENCH)
    lines = p.stdout.strip().splitlines()
    if p.returncode or not lines:
        print(f"# {item} in {tree}: failed: {p.stderr.strip().splitlines()[-1:]}", file=sys.stderr)
        return None
    return json.loads(lines[-1])


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("items", nargs="+")
    ap.add_argument("--trees", nargs=2, required=True)
    ap.add_argument("--alpha", type=float, default=0.5)
    ap.add_argument("--reps", type=int, default=1)
    args = ap.parse_args(argv)
    print(f"| input | {args.trees[0]} | {args.trees[1]} | same bytes |")
    print("|---|---|---|---|")
    for item in args.items:
        runs: dict[str, list[dict]] = {t: [] for t in args.trees}
        for _ in range(args.reps):
            for tree in args.trees:
                r = _one(tree, item, args.alpha)
                if r is not None:
                    runs[tree].append(r)
        cells = []
        for tree in args.trees:
            rs = runs[tree]
            cells.append("failed" if not rs else f"{min(r['cpu'] for r in rs):.2f} s, {rs[0]['charts']} charts, "
                         f"least share {rs[0]['share']:.3f}, {'valid' if rs[0]['valid'] else 'NOT valid'}")
        hashes = {r["hash"] for rs in runs.values() for r in rs}
        print(f"| {item} | {cells[0]} | {cells[1]} | {'yes' if len(hashes) == 1 else 'no'} |", flush=True)


if __name__ == "__main__":
    main()
