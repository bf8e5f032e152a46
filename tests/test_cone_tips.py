"""A cone's tip inside a chart: the discrete conformal map shears its fan, a slit from the tip opens it
into a wedge that lies flat (uvbake.atlas.charting._cone_tips)."""

import numpy as np
import pytest

import uvbake
from uvbake.atlas.charting import _cone_tips, make_charts
from uvbake.atlas.conformal import conformal_factor
from uvbake.atlas.guarantee import shear_ratios
from uvbake.mesh.arrays import triangle_areas
from uvbake.mesh.charts import Chart


def pyramid(sides=6, height=8.0):
    """A fan of ``sides`` triangles around an apex ``height`` above a unit polygon: one chart, the apex
    its only interior vertex, whose angles sum to far less than a full turn."""
    t = 2 * np.pi * np.arange(sides) / sides
    V = np.vstack([[0.0, 0.0, height], np.column_stack([np.cos(t), np.sin(t), np.zeros(sides)])])
    F = np.array([[0, 1 + k, 1 + (k + 1) % sides] for k in range(sides)])
    return V, F


def test_the_conformal_map_shears_a_cone_tip_and_the_tip_is_found():
    V, F = pyramid()
    uv, logf = conformal_factor(V, F)
    assert shear_ratios(V, F, uv).max() > 16.0                  # past max_stretch^2 at the default 4
    chart = Chart(V, F, np.arange(len(V)), np.arange(len(F)))
    area = triangle_areas(V, F)
    np.testing.assert_array_equal(_cone_tips(chart, uv, logf, area, np.log(4.0))[:1], [0])
    # a flat fan (angles summing to a full turn) has no tip, and its map keeps both bounds
    Vf = V * [1.0, 1.0, 0.0]
    uvf, logff = conformal_factor(Vf, F)
    assert len(_cone_tips(Chart(Vf, F, np.arange(len(V)), np.arange(len(F))), uvf, logff, area, np.log(4.0))) == 0


@pytest.mark.parametrize("sides,height", [(6, 8.0), (8, 12.0), (5, 6.0)])
def test_a_cone_tip_is_slit_open_before_the_solve(sides, height):
    V, F = pyramid(sides, height)
    charts, starts, log = make_charts(V, F)
    assert len(charts) == 1                                    # a slit adds no chart
    cone = [c for c in log["budget_cuts"] if c.get("cone")]
    assert len(cone) == 1 and cone[0]["slit"] and cone[0]["seam_length"] > 0
    # opened along the slit, the fan is a wedge: its start keeps angles (every triangle isometric)
    assert shear_ratios(charts[0].V, charts[0].F, starts[0]).max() == pytest.approx(1.0, abs=1e-6)
    res = uvbake.unwrap((V, F), alpha=0.5, texture_size_px=256)
    rep = res.report
    assert rep["valid"] and rep["charts_final"] == 1
    assert not [s for s in rep["splits"] if s["reason"] in ("sheared", "starved")]
    assert rep["min_texel_share"] == pytest.approx(1.0, abs=1e-6)
