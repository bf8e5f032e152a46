"""Large textures: the packing's full-resolution work runs on at most a 2048-texel raster, gutters exact."""

import numpy as np
import pytest

from uvbake.atlas import fit
from uvbake.atlas import pack as pack_module
from uvbake.atlas.pack import pack_charts

from test_pack import grid_chart, min_gap, signed_areas


def _kit(n, seed=0):
    rng = np.random.default_rng(seed)
    uvs, faces = [], []
    for k in range(n):
        uv, F = grid_chart(2, 2, float(rng.uniform(0.5, 1.5)), float(rng.uniform(0.5, 1.5)), shift=(3 * k, 0.0))
        uvs.append(uv)
        faces.append(F)
    return uvs, faces


def _spy(monkeypatch, module, name):
    seen = []
    real = getattr(module, name)

    def spied(*args, **kw):
        seen.append(args)
        return real(*args, **kw)

    monkeypatch.setattr(module, name, spied)
    return seen


@pytest.mark.parametrize("size, widest", [(1024, 1024), (2048, 2048), (8192, 2048)])
def test_the_fine_trial_of_many_charts_runs_on_at_most_a_2048_raster(monkeypatch, size, widest):
    uvs, faces = _kit(pack_module._FIT_SCALE_FROM + 1)          # enough charts for fit_scale, too many for boxes
    searches = _spy(monkeypatch, fit, "_search")
    res = pack_charts(uvs, faces, texture_size_px=size, gutter_px=4)
    widths = [args[1] for args in searches]
    assert max(widths) == widest                                 # the last trial's raster, as wide as allowed
    gap = min_gap([q * size for q in res.uv], faces)
    assert gap >= 4 * (1 - 1e-9)
    assert min(q.min() for q in res.uv) * size >= 2 * (1 - 1e-9) and max(q.max() for q in res.uv) <= 1


@pytest.mark.parametrize("size, raster", [(1024, 1024), (2048, 2048), (16384, 2048)])
def test_compaction_runs_on_at_most_a_2048_raster(monkeypatch, size, raster):
    from uvbake.atlas import compact

    monkeypatch.setattr(pack_module, "_BIG_MESH_FACES", 0)            # compaction for these few faces,
    monkeypatch.setattr(pack_module, "_COMPACT_FULL_FACES", 0)       # at the rule's full resolution
    calls = _spy(monkeypatch, compact, "compact")
    uvs, faces = _kit(12, seed=1)
    res = pack_charts(uvs, faces, texture_size_px=size, gutter_px=4, method="shape")
    assert [args[2] for args in calls] == [raster]                   # the compaction raster's width
    assert min_gap([q * size for q in res.uv], faces) >= 4 * (1 - 1e-9)


def test_a_large_growing_atlas_is_grown_on_a_coarser_raster_at_the_exact_density(monkeypatch):
    # a fixed texel density that needs about 9,000 texels a side: grown on a raster 4 times coarser
    # (at most 4096 a side), the layout scaled back; the density is the one asked, the sides keep the
    # mip levels' quantum, the gutter is exact
    uvs, faces = _kit(6, seed=2)
    area = sum(float(np.abs(signed_areas(u, F)).sum()) for u, F in zip(uvs, faces))
    density = 9000 / np.sqrt(area / 0.8)
    grows = _spy(monkeypatch, fit, "grow_square")
    res = pack_charts(uvs, faces, texture_size_px=None, texel_density=density, mip_levels=4)   # gutter 36
    assert res.texel_density == density
    assert res.width_px == res.height_px and res.width_px % 8 == 0 and res.width_px > 8000
    (packer, g, d), = [args[:3] for args in grows]
    assert res.gutter_px == 36 and g == 36 // 4 and d == density / 4   # the coarse raster's gutter, density
    assert min_gap([q * res.width_px for q in res.uv], faces) >= 36 * (1 - 1e-9)
    assert min(q.min() for q in res.uv) * res.width_px >= 18 * (1 - 1e-9) and max(q.max() for q in res.uv) <= 1
