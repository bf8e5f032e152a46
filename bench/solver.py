"""LM solver benchmark on the disk-like research meshes: prints a Markdown table.

    python bench/solver.py [--meshes beetle camelhead halftunnel] [--alphas 0 0.1 0.5 0.9] [--inits lscm random]

Needs ../shared/meshes (not shipped). Iterations are factorisations, rejected steps included;
'grad' is the scale-free gradient norm (mesh and map at unit mean edge length); random starts go
through the alpha = 0.1 continuation (its iterations are included and shown in brackets);
'lambda_min' is the second-order certificate (smallest Hessian eigenvalue off the rigid gauge, in
the scale-free frame; its time is included).
"""

import argparse
import platform
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
MESHES = HERE.parent.parent / "shared" / "meshes"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--meshes", nargs="+", default=["halftunnel", "camelhead", "beetle"])
    ap.add_argument("--alphas", nargs="+", type=float, default=[0.0, 0.1, 0.5, 0.9])
    ap.add_argument("--inits", nargs="+", default=["lscm", "random"])
    ap.add_argument("--max-iter", type=int, default=1000)
    args = ap.parse_args()
    if not MESHES.is_dir():
        sys.exit(f"bench/solver.py: {MESHES} not found; the research meshes live beside the checkout")
    import uvbake
    from uvbake.flatten.solvers.linalg import cholmod_available
    from uvbake.io.load import load_mesh

    print(f"# uvbake LM solver, {platform.processor() or platform.machine()}, "
          f"linear solver {'CHOLMOD' if cholmod_available() else 'SuperLU'}\n")
    print("| mesh | vertices | alpha | init | iterations | time (s) | F* | grad norm | converged | lambda_min "
          "| flipped |")
    print("|---|---:|---:|---|---:|---:|---:|---:|---|---:|---:|")
    for name in args.meshes:
        m = load_mesh(MESHES / f"{name}.off")
        for init in args.inits:
            for alpha in args.alphas:
                r = uvbake.parameterize(m.V, m.F, alpha=alpha, init=init, max_iter=args.max_iter)
                cont = r.extra.get("continuation")
                its = f"{r.iterations}" + (f" ({cont['iterations']} at 0.1)" if cont else "")
                print(f"| {name} | {len(m.V):,} | {alpha:g} | {init} | {its} | {r.time_s:.2f} | "
                      f"{r.energy:.6g} | {r.grad_norm:.1e} | {'yes' if r.converged else 'no: ' + r.stop_reason} | "
                      f"{r.lambda_min:.2e}{'' if r.is_local_minimum else ' (not a minimum)'} | {r.n_flipped} |", flush=True)


if __name__ == "__main__":
    main()
