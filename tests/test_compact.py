"""Compaction of a shape layout at full resolution (uvbake.atlas.compact): sliding never moves a chart
up or right, lowering the far edge never grows the layout's box, and both keep the exact gutter and the
border margin; the compacted layout scaled back to the border is at least as dense.

Distances are checked with test_pack's independent helpers (vertex-triangle distances, edge crossings).
"""

import numpy as np
import pytest
from test_shapepack import mixed_charts

from uvbake.atlas.compact import compact
from uvbake.atlas.fit import _layout_box, scale_to_border
from uvbake.atlas.shapepack import ShapePacker

from test_pack import min_gap


def placed(packer, p):
    out = []
    for i, uv in enumerate(packer.uvs):
        c, s = np.cos(p.rotation[i]), np.sin(p.rotation[i])
        out.append(p.density * (uv @ np.array([[c, s], [-s, c]])) + p.offset[i])
    return out


def coarse_layout(seed, size, g, c=4, height=None):
    """A layout packed on a raster ``c`` times coarser and scaled to the ``size x height`` atlas
    (fit_width's kind): up to a coarse texel of slack around every chart."""
    uvs, faces = mixed_charts(seed, n=12)
    packer = ShapePacker(uvs, faces, [np.zeros(1)] * len(uvs))
    cw, ch, cg = size // c, (height or size) // c, -(-g // c)
    p = packer.pack(np.sqrt(cw * ch * 0.35 / packer.area.sum()), cw, None, cg)
    q = scale_to_border(packer, p, size, height or size, g, c, cg)
    assert q is not None
    return packer, faces, q


def assert_valid(packer, faces, p, size, g, height=None):
    Q = placed(packer, p)
    assert min_gap(Q, faces) >= g * (1 - 1e-9)
    lo = np.min([x.min(axis=0) for x in Q], axis=0)
    hi = np.max([x.max(axis=0) for x in Q], axis=0)
    m = (g + 1) // 2
    assert (lo >= m * (1 - 1e-9)).all()
    assert (hi <= np.array([size, height or size]) - m * (1 - 1e-9)).all()


@pytest.mark.parametrize("seed,g,size", [(0, 4, 512), (1, 2, 256), (2, 8, 512)])
def test_sliding_never_moves_a_chart_up_or_right_and_keeps_the_gutter(seed, g, size):
    packer, faces, p = coarse_layout(seed, size, g)
    q = compact(packer, p, size, size, g, steps=0)
    d = q.offset - p.offset
    # whole-texel moves (to rounding of the offsets), never positive
    np.testing.assert_allclose(d, np.round(d), atol=1e-9 * size)
    assert (d <= 1e-9 * size).all()
    assert np.abs(d).sum() > 0                # a coarse layout has slack: something moves
    np.testing.assert_array_equal(q.rotation, p.rotation)
    assert q.density == p.density
    assert_valid(packer, faces, q, size, g)


@pytest.mark.parametrize("seed,g,size,height", [(0, 4, 512, 512), (2, 4, 512, 512), (4, 6, 512, 512),
                                                (7, 4, 512, 320), (1, 4, 256, 512)])
def test_lowering_the_far_edge_never_grows_the_box_and_scaling_back_is_denser(seed, g, size, height):
    packer, faces, p = coarse_layout(seed, size, g, height=height)
    q = compact(packer, p, size, height, g)
    lo0, hi0 = _layout_box(packer, p)
    lo1, hi1 = _layout_box(packer, q)
    # the slides lower every coordinate; the far-edge moves stay inside the footprints' box, which is
    # the vertices' box widened by less than one texel (conservative rasterisation) on each side
    assert (hi1 <= hi0 + 1 + 1e-9).all() and (lo1 >= lo0 - 1 - 1e-9).all()
    assert_valid(packer, faces, q, size, g, height)
    # these layouts exercise the far-edge moves (on the row and the transposed column tables)
    assert np.abs(q.offset - compact(packer, p, size, height, g, steps=0).offset).sum() > 0
    r = scale_to_border(packer, q, size, height, g)
    assert r is not None and r.density >= p.density * (1 - 1e-12)
    assert_valid(packer, faces, r, size, g, height)


def test_compaction_is_deterministic():
    packer, faces, p = coarse_layout(0, 512, 4)
    a, b = compact(packer, p, 512, 512, 4), compact(packer, p, 512, 512, 4)
    assert a.offset.tobytes() == b.offset.tobytes()


def test_a_layout_outside_the_atlas_is_returned_unchanged():
    packer, faces, p = coarse_layout(0, 512, 4)
    assert compact(packer, p, 256, 256, 4) is p


@pytest.mark.parametrize("seed,g,c", [(0, 4, 2), (2, 5, 2), (7, 4, 4)])
def test_compaction_on_a_coarser_raster_keeps_the_gutter_and_is_not_sparser(seed, g, c):
    """pack._compacted on a raster c times coarser: gutter ceil(g / c) coarse texels is >= g once
    scaled back by c, so the result keeps the exact gutter and border margin."""
    from uvbake.atlas.pack import _compacted

    packer, faces, p = coarse_layout(seed, 512, g)
    q = _compacted(packer, p, 512, 512, g, c)
    assert q.density >= p.density
    assert_valid(packer, faces, q, 512, g)
    if c == 2:                   # a 4x coarser layout has slack at half resolution: something moves
        assert q is not p and q.density > p.density
