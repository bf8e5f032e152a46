"""The input's units at any scale.

A mesh whose coordinates reach past 2**64 (or stay under 2**-64) is worked on scaled by an exact power
of two, 2**-k (``uvbake.atlas.pipeline._load``): areas and squared lengths neither overflow nor
underflow there. What the user gives (a texel density) and gets back (the report's lengths, areas and
densities, the charts' coordinates and their maps) is in the input's units: these functions convert.
"""

from __future__ import annotations

import dataclasses

import numpy as np

#: Report entries in the working units, by the power of 2**k that brings them to the input's:
#: lengths 1, areas 2, densities (texels or UV units per length) -1.
_ATLAS_KEYS = {"scale": -1, "texel_size_world": 1, "texel_density": -1}


def working_density(texel_density: float | None, k: int) -> float | None:
    """A texel density in pixels per input unit, in pixels per working unit (2**k input units)."""
    return None if texel_density is None else float(np.ldexp(texel_density, k))


def _scaled(x: float, e: int) -> float | None:
    """x * 2**e, or None where that is not a finite float (an area of a mesh at 1e200 units)."""
    with np.errstate(over="ignore"):
        y = float(np.ldexp(x, e))
    return y if np.isfinite(y) else None


def to_input_units(report: dict, charts: list, results: list, k: int) -> tuple[list, list]:
    """The report's lengths, areas and densities in the input's units (in place; ``coordinate_exponent``
    records k), and the charts and their maps scaled back (new objects; exact: powers of two)."""
    if not k:
        return charts, results
    for key, e in _ATLAS_KEYS.items():
        if key in report["atlas"]:
            report["atlas"][key] = _scaled(report["atlas"][key], e * k)
    for record in (*report["cuts"], *report["budget_cuts"], *report["splits"]):
        if "seam_length" in record:
            record["seam_length"] = _scaled(record["seam_length"], k)
    report["seam_length_added"] = _scaled(report["seam_length_added"], k)
    for chart in report["charts"]:
        chart["area_3d"] = _scaled(chart["area_3d"], 2 * k)
    report["coordinate_exponent"] = k     # worked on at 2**-k (exact); every figure above is in input units
    charts = [dataclasses.replace(c, V=np.ldexp(c.V, k)) for c in charts]
    results = [dataclasses.replace(r, uv=np.ldexp(r.uv, k)) for r in results]
    return charts, results
