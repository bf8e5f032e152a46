"""Randomised sweep of inputs and options, each atlas checked against what uvbake promises.

    PYTHONPATH=. python3 bench/sweep.py [--seed 1] [--draws 200] [--only K]

Each draw takes a base mesh (``bench/shapes.py``'s shapes but the three slowest, and cow, bumpy,
halftunnel and fandisk from ../shared/meshes when present), maybe one connectivity change (10 % of
the faces flipped, the mesh as a triangle soup, 5 % of the faces duplicated, ten triangles attached to
existing edges) and maybe one geometric one (2-20 % of the faces removed, an anisotropic scaling, noise
of 1 % of the extent), then random options: alpha, contiguous face-label patches, ``max_stretch``,
``max_charts``, texture size or texel density, ``workers=2``, ``weld=True``. Checked: a valid atlas,
a least texel share of at least 1/max_stretch^2, at most 0.5 % of the area below 1/4 of its fair share
(at the default budget or tighter), one input label per chart. A one-line refusal (``UvbakeError``)
is printed, not counted: an impossible request is refused by design. Each draw's line gives its CPU
seconds, and the last line the three slowest draws (a cost growing faster than the input shows there
first: seed 26's draw 34 found merge_back quadratic in the chart count). Exits 1 when a draw fails or
crashes; ``--only K`` reruns draw K alone (the draws before it are drawn, not run) and saves its input
to sweep_case.npz. Findings and what they changed: docs/decisions/atlas.md (ninth session).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "meshes"


def _bases():
    from bench.shapes import shapes
    from uvbake.io import load_mesh

    out = {k: (np.asarray(m.vertices, float), np.asarray(m.faces, np.int64))
           for k, m in shapes().items() if k not in ("many_parts", "coil_tube", "sliver_pipe")}
    for name in ("cow", "bumpy", "halftunnel", "fandisk"):
        if (SHARED / f"{name}.off").exists():
            m = load_mesh(SHARED / f"{name}.off")
            out[name] = (m.V, m.F)
    return out


def _patches(rng, V, F, k):
    """``k`` face labels grown breadth-first from random seed faces over shared edges (contiguous)."""
    import trimesh

    adj = trimesh.Trimesh(V, F, process=False).face_adjacency
    lab = np.full(len(F), -1)
    lab[rng.choice(len(F), k, replace=False)] = np.arange(k)
    for _ in range(len(F)):                             # growth rounds, until every face is reached
        grew = False
        for x, y in ((adj[:, 0], adj[:, 1]), (adj[:, 1], adj[:, 0])):
            take = (lab[x] >= 0) & (lab[y] < 0)
            lab[y[take]] = lab[x[take]]
            grew |= bool(take.any())
        if not grew:
            break
    lab[lab < 0] = 0
    return lab


def _connectivity(rng, V, F, desc):
    r = rng.random()
    if r < 0.2:
        F = F.copy()
        flip = rng.random(len(F)) < 0.1
        F[flip] = F[flip][:, ::-1]
        desc.append("flips")
    elif r < 0.4:
        V, F = V[F].reshape(-1, 3), np.arange(3 * len(F)).reshape(-1, 3)
        desc.append("soup")
    elif r < 0.55:
        F = np.vstack([F, F[rng.random(len(F)) < 0.05]])
        desc.append("duplicated faces")
    elif r < 0.7:
        edge = F[rng.choice(len(F), 10, replace=False)][:, :2]
        tip = V[edge].mean(axis=1) + rng.normal(0.0, 0.1 * np.ptp(V), (10, 3))
        F = np.vstack([F, np.column_stack([edge, len(V) + np.arange(10)])])
        V = np.vstack([V, tip])
        desc.append("fins")
    return V, F


def _geometry(rng, V, F, desc):
    r = rng.random()
    if r < 0.25:
        F = F[rng.random(len(F)) > rng.uniform(0.02, 0.2)]
        desc.append("holes")
    elif r < 0.4:
        V = V * rng.uniform(0.05, 3.0, 3)
        desc.append("anisotropic")
    elif r < 0.55:
        V = V + rng.normal(0.0, 0.01 * np.ptp(V), V.shape)
        desc.append("noise")
    return V, F


def _options(rng, V, F):
    kw = dict(alpha=float(rng.choice([0.0, 0.1, 0.5, 0.9, 1.0])))
    if rng.random() < 0.3:
        kw["face_labels"] = _patches(rng, V, F, int(rng.integers(2, 12)))
    if rng.random() < 0.2:
        kw["max_stretch"] = float(rng.choice([1.5, 2.0, 8.0]))
    if rng.random() < 0.15:
        kw["max_charts"] = int(rng.integers(1, 6))
    if rng.random() < 0.15:
        kw["texture_size_px"] = int(rng.choice([64, 256, 2048]))
    if rng.random() < 0.1:
        kw["workers"] = 2
    if rng.random() < 0.1:
        kw["weld"] = True
    if rng.random() < 0.08:
        X = V[F]
        area = 0.5 * np.linalg.norm(np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0]), axis=1).sum()
        kw.update(texture_size_px=None, texel_density=float(rng.uniform(20, 200) / np.sqrt(area)))
    return kw


def _failures(res, V, F, kw):
    """What the atlas breaks of uvbake's promises (empty: nothing)."""
    from uvbake.mesh.repair import repair

    rep, bad = res.report, []
    budget = kw.get("max_stretch", 4.0)
    if not rep["valid"]:
        bad.append("invalid")
    if rep["min_texel_share"] < 1.0 / budget ** 2 - 1e-9:
        bad.append(f"least share {rep['min_texel_share']:.4f}")
    if budget <= 4.0 and rep["area_below_quarter"] > 0.005 + 1e-9:
        bad.append(f"{100 * rep['area_below_quarter']:.2f} % of the area below 1/4")
    if "face_labels" in kw:
        lab = np.asarray(kw["face_labels"])[repair(V, F, weld=kw.get("weld"), face_labels=kw["face_labels"]).face_index]
        if any(len(np.unique(lab[c.face_index])) > 1 for c in res.charts):
            bad.append("a chart spans two labels")
    return bad


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--draws", type=int, default=200)
    ap.add_argument("--only", type=int, default=None, help="run draw K alone and save its input to sweep_case.npz")
    args = ap.parse_args(argv)
    import uvbake

    rng = np.random.default_rng(args.seed)
    bases = _bases()
    names = sorted(bases)
    failed, refused, t0 = 0, 0, time.process_time()
    slow: list = []                                     # (CPU s, draw, input, triangles) of each atlas made
    for i in range(args.draws if args.only is None else args.only + 1):      # one iteration per draw
        name = names[rng.integers(len(names))]
        desc = [name]
        V, F = _connectivity(rng, *bases[name], desc)
        V, F = _geometry(rng, V, F, desc)
        kw = _options(rng, V, F)
        if args.only is not None and i != args.only:
            continue
        if args.only is not None:
            np.savez("sweep_case.npz", V=V, F=F, **{k: np.asarray(v) for k, v in kw.items() if v is not None})
        shown = {k: v for k, v in kw.items() if k != "face_labels"} | ({"labels": True} if "face_labels" in kw else {})
        t = time.process_time()
        try:
            res = uvbake.unwrap((V, F), **kw)
        except uvbake.UvbakeError as exc:
            refused += 1
            slow.append((time.process_time() - t, i, " ".join(desc) + ", refused", len(F)))
            print(f"{i:4d} {' '.join(desc):34s} refused after {slow[-1][0]:.2f} s: {str(exc)[:150]}", flush=True)
            continue
        except Exception as exc:                        # a crash is a failure, reported and counted
            failed += 1
            print(f"{i:4d} {' '.join(desc):34s} CRASH {type(exc).__name__}: {exc}", flush=True)
            continue
        cpu = time.process_time() - t
        slow.append((cpu, i, " ".join(desc), len(F)))
        bad = _failures(res, V, F, kw)
        failed += bool(bad)
        print(f"{i:4d} {' '.join(desc):34s} {str(shown):70s} charts {len(res.charts):5d} "
              f"least {res.report['min_texel_share']:.3f} cpu {cpu:6.2f} s" + (f"  FAILED: {'; '.join(bad)}" if bad else ""),
              flush=True)
    print(f"# seed {args.seed}: {failed} failed, {refused} refused, of {args.draws if args.only is None else 1} "
          f"draws in {time.process_time() - t0:.0f} s of CPU")
    # the slowest draws (this process's CPU; workers=2 draws spend some in their workers): where a cost
    # grows faster than the input shows first
    print("# slowest: " + ", ".join(f"draw {i} {cpu:.1f} s ({d}, {n} triangles)" for cpu, i, d, n in sorted(slow)[::-1][:3]))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    sys.exit(main())
