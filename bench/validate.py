"""Benchmark of uvbake.validate: time against triangle count and raster resolution.

    python bench/validate.py            # the full table
    python bench/validate.py --quick    # 100k triangles at 2048 only

The atlas is a packed grid of square charts in [0,1]^2, each a jittered grid of quads (interior
vertices moved by up to 15 % of the spacing, so no flips), one in five mirrored as a whole, a gutter
between charts, given as per-corner UVs (m,3,2) without faces, so corners are welded by their UV bits
as for an atlas read from a file. It is valid; a last block shifts every tenth chart onto its
neighbour, so the raster finds overlap pixels and the exact pass confirms thousands of pairs.
Each cell is the best of ``--repeat`` runs (default 3).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np


def packed_atlas(n_triangles, *, seed=0, quads_per_side=14, gutter=0.15, overlapping=False):
    """Per-corner UVs (m,3,2) of a valid atlas of about ``n_triangles`` triangles in [0,1]^2.

    With ``overlapping``, every tenth chart is shifted by 40 % of its size onto its neighbour.
    """
    rng = np.random.default_rng(seed)
    q = quads_per_side
    per_chart = 2 * q * q
    n_charts = max(1, int(round(n_triangles / per_chart)))
    c = int(np.ceil(np.sqrt(n_charts)))
    g = np.linspace(0.0, 1.0, q + 1)
    x, y = np.meshgrid(g, g, indexing="xy")
    V = np.stack([x.ravel(), y.ravel()], axis=1)
    i, j = np.meshgrid(np.arange(q), np.arange(q), indexing="ij")
    a = (i * (q + 1) + j).ravel()
    b, cc, d = a + 1, a + q + 2, a + q + 1
    F = np.concatenate([np.stack([a, b, cc], 1), np.stack([a, cc, d], 1)])
    interior = (V[:, 0] > 0) & (V[:, 0] < 1) & (V[:, 1] > 0) & (V[:, 1] < 1)
    size = (1.0 - gutter) / c
    out = []
    for k in range(n_charts):  # a loop over charts (hundreds), not triangles
        W = V + interior[:, None] * rng.uniform(-0.15, 0.15, V.shape) / q
        if k % 5 == 0:
            W = W * np.array([-1.0, 1.0]) + np.array([1.0, 0.0])  # mirrored as a whole
        row, col = divmod(k, c)
        off = (np.array([col, row]) + gutter / 2) / c
        if overlapping and k % 10 == 3 and col + 1 < c:
            off[0] += 0.4 / c
        out.append((W * size + off)[F])
    return np.concatenate(out)


def best_of(fn, repeat):
    """Shortest wall time of ``repeat`` calls, and the result of that call."""
    best, result = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        r = fn()
        t = time.perf_counter() - t0
        if t < best:
            best, result = t, r
    return best, result


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="100k triangles at 2048 px only")
    p.add_argument("--repeat", type=int, default=3)
    args = p.parse_args(argv)

    import uvbake.validate as V

    print(f"uvbake.validate benchmark ({os.cpu_count()} cpus, numpy {np.__version__})")
    sizes = [100_000] if args.quick else [10_000, 30_000, 100_000, 300_000]
    resolutions = [2048] if args.quick else [512, 1024, 2048, 4096]
    header = (
        f"{'triangles':>10} {'res px':>7} {'time s':>8} {'prepare':>8} {'orient':>8} {'raster':>8} "
        f"{'cands':>8} {'exact':>8} {'n cand':>9} {'n exact':>8} {'pairs':>7} valid"
    )
    print(header)
    print("-" * len(header))
    cases = [(n, False) for n in sizes] + [(100_000, True)]
    for n, overlapping in cases:
        uv = packed_atlas(n, overlapping=overlapping)
        if overlapping:
            print("atlas with overlaps (every 10th chart shifted onto its neighbour):")
        for res in resolutions:
            if args.quick or n == 100_000 or res == 2048:
                t, r = best_of(lambda: V.validate(uv, resolution_px=res), args.repeat)
                ts = r.timings_s
                print(
                    f"{len(uv):>10,} {res:>7} {t:>8.3f} {ts['prepare']:>8.3f} {ts['orientation']:>8.3f} "
                    f"{ts['raster']:>8.3f} {ts['candidates']:>8.3f} {ts['exact']:>8.3f} "
                    f"{r.n_candidates:>9,} {r.n_exact:>8,} {r.n_overlaps:>7,} {r.valid}"
                )
                sys.stdout.flush()


if __name__ == "__main__":
    main()
