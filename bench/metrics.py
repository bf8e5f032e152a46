"""The benchmarks' metrics: uvbake's one definition (:mod:`uvbake.analysis.metrics`), re-exported.

Kept as a module so ``bench/peers.py`` and ``bench/scaling.py`` read ``metrics.distortion(...)``; the
definitions and their documentation live in uvbake/analysis/metrics.py.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from uvbake.analysis.metrics import (  # noqa: E402,F401
    MapMetrics,
    area_below,
    chart_ids,
    corners,
    cut_edges,
    distortion,
    flipped,
    measure,
    packing_efficiency,
    signed_areas,
    singular_values,
    texel_share,
    texel_summary,
    uv_seam_length,
    weighted_median,
)

seam_length = uv_seam_length
