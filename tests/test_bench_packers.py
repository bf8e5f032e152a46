"""The peer packers of bench/packers.py (xatlas, rectpack) as uvbake placers: gutters and shapes kept."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from uvbake.atlas.pack import pack_charts

from test_pack import chart_set, min_gap, signed_areas

_PATH = Path(__file__).resolve().parents[1] / "bench" / "packers.py"
_spec = importlib.util.spec_from_file_location("bench_packers", _PATH)
packers = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(packers)


def test_xatlas_keeps_gutter_shape_and_orientation():
    pytest.importorskip("xatlas")
    uvs, faces = chart_set(5, n=6)
    res = pack_charts(uvs, faces, texture_size_px=512, gutter_px=4, method=packers.xatlas_placer)
    assert min_gap(res.uv, faces) >= 4 / 512 * (1 - 1e-9)
    for uv, F, q in zip(uvs, faces, res.uv):
        assert q.min() >= 0 and q.max() <= 1
        np.testing.assert_allclose(signed_areas(q, F), res.scale ** 2 * signed_areas(uv, F), rtol=1e-8, atol=1e-15)


def test_rectpack_method_keeps_gutter():
    pytest.importorskip("rectpack")
    uvs, faces = chart_set(6, n=6)
    res = pack_charts(uvs, faces, texture_size_px=512, gutter_px=4, method=packers.rectpack_placer)
    assert min_gap(res.uv, faces) >= 4 / 512 * (1 - 1e-9)


def test_xatlas_packs_charts_that_share_a_uv_position_apart():
    """Charts as conformal maps leave them, each with a vertex at the origin: xatlas's add_uv_mesh
    would join them into one chart packed on top of itself; the placer spreads them first."""
    pytest.importorskip("xatlas")
    uvs, faces = chart_set(5, n=6)
    uvs = [uv - uv[0] for uv in uvs]                    # every chart's first vertex at (0, 0)
    res = pack_charts(uvs, faces, texture_size_px=512, gutter_px=4, method=packers.xatlas_placer)
    assert min_gap(res.uv, faces) >= 4 / 512 * (1 - 1e-9)


def test_spread_moves_charts_apart_and_keeps_their_shapes():
    uvs, _ = chart_set(5, n=6)
    uvs = [uv - uv[0] for uv in uvs]
    out = packers.spread(uvs)
    boxes = [(o.min(axis=0), o.max(axis=0)) for o in out]
    for i in range(len(out)):
        np.testing.assert_allclose(out[i] - out[i][0], uvs[i] - uvs[i][0], rtol=0, atol=1e-12)   # translated only
        for j in range(i):                               # boxes pairwise disjoint
            (a0, a1), (b0, b1) = boxes[i], boxes[j]
            assert np.any(a1 < b0) or np.any(b1 < a0)
