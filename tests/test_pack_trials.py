"""What keeps packing splits cheap (issue 13, packing's share of the command): the MaxRects free-space
update and BoxLayouts (each chart's rectangle found once across the split rounds' trial layouts).

Distances are checked with test_pack's independent helper (vertex-to-triangle distances, edge crossings).
"""

import numpy as np
import pytest

import uvbake
import uvbake.atlas.pack as pack_module
from uvbake.atlas import packsplit
from uvbake.atlas.maxrects import _RULES, _maxrects, _scores, min_area_rect
from uvbake.atlas.pack import pack_charts
from uvbake.atlas.packsplit import BoxLayouts

from meshgen import cone, cut_cylinder, torus
from test_pack import chart_set, grid_chart, min_gap

N, G = 256, 3


def _reference_maxrects(sizes, order, rule, allow_turn=True):
    """MaxRects as first written (one orientation at a time, every free rectangle tested for containment
    in every other after each placement; the same placement scores): the reference the faster update
    must match exactly."""
    free = np.array([[0.0, 0.0, 1.0, 1.0]])
    placed = np.empty((0, 4))
    pos, turned = np.zeros((len(sizes), 2)), np.zeros(len(sizes), bool)
    for i in order:
        best = None
        fw, fh = free[:, 2] - free[:, 0], free[:, 3] - free[:, 1]
        for t, (w, h) in enumerate((sizes[i], sizes[i][::-1])):
            if t == 1 and (not allow_turn or sizes[i][0] == sizes[i][1]):
                break
            idx = np.flatnonzero((fw >= w) & (fh >= h))
            if not len(idx):
                continue
            s1, s2 = _scores(rule, free, idx, w, h, placed)
            j = np.lexsort((s2, s1))[0]
            if best is None or (s1[j], s2[j]) < best[:2]:
                best = (s1[j], s2[j], idx[j], t, w, h)
        if best is None:
            return None
        _, _, f, t, w, h = best
        r = np.array([free[f, 0], free[f, 1], free[f, 0] + w, free[f, 1] + h])
        pos[i], turned[i] = r[:2], bool(t)
        placed = np.vstack([placed, r])
        keep, pieces = [], []
        for q in free:
            if q[0] < r[2] and q[2] > r[0] and q[1] < r[3] and q[3] > r[1]:
                pieces += [p for p, ok in (([q[0], q[1], r[0], q[3]], q[0] < r[0]), ([r[2], q[1], q[2], q[3]], q[2] > r[2]),
                                           ([q[0], q[1], q[2], r[1]], q[1] < r[1]), ([q[0], r[3], q[2], q[3]], q[3] > r[3]))
                           if ok]
            else:
                keep.append(q)
        A = np.array(keep + [np.array(p) for p in pieces]).reshape(-1, 4)
        out = []
        for a in range(len(A)):                  # contained in another (of equal ones the first stays)
            inside = [b for b in range(len(A)) if b != a and np.all(A[a, :2] >= A[b, :2]) and np.all(A[a, 2:] <= A[b, 2:])]
            if not any(not np.array_equal(A[a], A[b]) or b < a for b in inside):
                out.append(A[a])
        free = np.array(out).reshape(-1, 4)
    return pos, turned


@pytest.mark.parametrize("seed", range(8))
def test_maxrects_places_every_box_exactly_where_the_reference_update_does(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 16))
    sizes = rng.uniform(0.03, 0.35, (n, 2))
    if seed % 2:                                 # many equal sizes: ties between free rectangles and turns
        sizes = np.round(sizes * 8) / 32 + 0.01
        sizes[0] = sizes[0, 0]
    order = rng.permutation(n)
    for rule in _RULES:
        for turn in (True, False):
            got, ref = _maxrects(sizes, order, rule, turn), _reference_maxrects(sizes, order, rule, turn)
            assert (got is None) == (ref is None)
            if ref is not None:
                assert np.array_equal(got[0], ref[0]) and np.array_equal(got[1], ref[1])


@pytest.mark.parametrize("seed", range(6))
def test_the_few_boxes_packer_places_every_box_where_the_numpy_one_does(seed, monkeypatch):
    # up to _FEW_BOXES boxes MaxRects runs on Python floats; with ties (equal sizes, sizes on a 1/16
    # grid that touch exactly, contact scores summed over placed boxes) it must agree to the bit
    import uvbake.atlas.maxrects as mr

    rng = np.random.default_rng(100 + seed)
    for trial in range(40):
        n = int(rng.integers(1, mr._FEW_BOXES + 1))
        sizes = rng.uniform(0.03, 0.45, (n, 2)) if trial % 2 else rng.integers(1, 6, (n, 2)) / 16.0
        order = rng.permutation(n)
        for rule in _RULES:
            for turn in (True, False):
                few = mr._maxrects_few(sizes, order, rule, turn)
                monkeypatch.setattr(mr, "_FEW_BOXES", 0)
                full = mr._maxrects(sizes, order, rule, turn)
                monkeypatch.setattr(mr, "_FEW_BOXES", 8)
                assert (few is None) == (full is None)
                if full is not None:
                    assert np.array_equal(few[0], full[0]) and np.array_equal(few[1], full[1])


def _charts(seed, n=6):
    uvs, faces = chart_set(seed, n)
    return [np.asarray(u, float) for u in uvs], [np.asarray(f, np.int64) for f in faces]


@pytest.mark.parametrize("seed", range(3))
def test_box_layouts_are_the_maxrects_packing(seed):
    uvs, faces = _charts(seed)
    ref = pack_charts(uvs, faces, texture_size_px=N, gutter_px=G, method="maxrects")
    layouts = BoxLayouts(N, G)
    layouts(uvs[:3], faces[:3])                               # some charts known already
    got = layouts(uvs, faces)
    assert got.efficiency == ref.efficiency and got.method == "maxrects"
    assert all(np.array_equal(a, b) for a, b in zip(got.uv, ref.uv))
    assert min_gap([u * N for u in got.uv], faces) >= G * (1 - 1e-9)
    assert layouts.fill(uvs, faces) == pytest.approx(pack_module._box_fill(uvs, faces, pack_module.min_area_rects(uvs)),
                                                     rel=1e-12)


def test_box_layouts_find_each_charts_rectangle_once(monkeypatch):
    uvs, faces = _charts(4)
    seen = []
    real = pack_module.min_area_rects
    monkeypatch.setattr(packsplit, "min_area_rects", lambda Ps, *a: seen.append(len(Ps)) or real(Ps, *a))
    layouts = BoxLayouts(N, G)
    layouts(uvs[:4], faces[:4])
    layouts(uvs, faces)
    assert layouts.fill(uvs, faces) > 0 and layouts.rect(uvs[5], faces[5]).shape == (3,)
    assert seen == [4, 2]
    # a chart with the same UVs in a new array is a new chart (identity, not content, is the key)
    layouts([u.copy() for u in uvs[:1]], faces[:1])
    assert seen == [4, 2, 1]


@pytest.mark.parametrize("shape", ["cone1.0", "cone1.5", "cone1.8", "torus", "strip"])
def test_packing_splits_keep_what_they_kept_with_maxrects_packings_as_trials(shape):
    """Cones opened along a generator (annulus sectors, filling their boxes badly: the split charts are
    shape-packed), a torus and a long strip (split charts kept as boxes): packing splits judged by
    BoxLayouts keep the same charts and the same layout, to the bit, as when each trial is
    ``pack_charts(method="maxrects")`` and the fill is measured from scratch."""
    if shape == "torus":
        V, F = torus(24, 12, R=3.0, r=0.5)
    elif shape == "strip":
        V, F = cut_cylinder(40, 8, radius=1.0, height=1.0, sweep=1.8 * np.pi)
    else:
        V, F = cone(40, 8, sweep=float(shape[4:]) * np.pi, r0=0.4, r1=1.2, slope=0.8)
    res = uvbake.unwrap((V, F), alpha=0.5, pack_splits=False)

    class Plain:                                  # no identity cache: rectangles found on every call
        def __call__(self, uvs, faces):
            return pack_charts(uvs, faces, method="maxrects")

        def fill(self, uvs, faces):
            return pack_module._box_fill(uvs, faces, pack_module.min_area_rects(uvs))

        def rect(self, uv, F):
            return np.array(min_area_rect(uv))
    out = [packsplit.split_for_packing(res.charts, res.results, pack_charts, boxes=b) for b in (BoxLayouts(), Plain())]
    assert len(out[0][0]) == len(out[1][0]) > len(res.charts)
    assert out[0][2].efficiency == out[1][2].efficiency and out[0][2].method == out[1][2].method
    assert all(np.array_equal(a, b) for a, b in zip(out[0][2].uv, out[1][2].uv))


class _Chart:
    def __init__(self, F):
        self.F = F


class _Result:
    def __init__(self, uv):
        self.uv = uv


def test_an_atlas_of_many_charts_is_packed_once_and_not_split(monkeypatch):
    """A long strip holding most of the area among MAX_ATLAS_CHARTS other charts: the atlas packs
    sparsely and the strip holds more than MIN_SHARE, yet one more chart makes it too many to split."""
    strip, sF = grid_chart(40, 2, 20.0, 1.0)
    uvs, faces = [strip], [sF]
    for k in range(packsplit.MAX_ATLAS_CHARTS):
        uv, F = grid_chart(2, 2, 0.5, 0.5, shift=(k, 3.0))
        uvs.append(uv)
        faces.append(F)
    calls = []

    def pack(u, f):
        calls.append(len(u))
        return pack_charts(u, f)
    charts, results = [_Chart(F) for F in faces], [_Result(u) for u in uvs]
    assert packsplit._largest(charts, results) == 0
    out = packsplit.split_for_packing(charts, results, pack, boxes=BoxLayouts())
    assert out[2].efficiency < packsplit.BELOW_EFFICIENCY and calls == [len(uvs)] and out[3] == []
    # the same atlas without one of the small charts gets its strip cut (a cut that gives no pieces here)
    cuts = []
    monkeypatch.setattr(packsplit, "split_straight", lambda c, r, theta=None: cuts.append(len(c.F)))
    out = packsplit.split_for_packing(charts[:-1], results[:-1], pack, boxes=BoxLayouts())
    assert cuts == [len(sF)] and out[3] == []


def test_a_chart_whose_length_alone_keeps_the_atlas_sparse_is_cut_first_whatever_its_share():
    """A strip 12 long among squares: it holds under MIN_SHARE of the area, but a square atlas holding it
    packs at most area / 12^2, under BELOW_EFFICIENCY, so it is the chart to cut."""
    strip, sF = grid_chart(48, 2, 12.0, 0.5)
    uvs, faces = [strip], [sF]
    for k in range(7):
        uv, F = grid_chart(4, 4, 2.0, 2.0, shift=(3 * k, 3.0))
        uvs.append(uv)
        faces.append(F)
    charts, results = [_Chart(F) for F in faces], [_Result(u) for u in uvs]
    area = np.array([np.abs(packsplit.signed_areas(u, F)).sum() for u, F in zip(uvs, faces)])
    assert area[0] < packsplit.MIN_SHARE * area.sum()                      # not by its share
    assert 12.0 ** 2 * packsplit.BELOW_EFFICIENCY > area.sum()             # by its length
    assert packsplit._largest(charts, results) == 0
    # once the strip is in pieces of a few units, nothing binds and no chart holds MIN_SHARE
    halves = [grid_chart(12, 2, 3.0, 0.5, shift=(0, 5 * k))[0] for k in range(4)]
    short = [_Result(u) for u in halves + uvs[1:]]
    assert packsplit._largest([_Chart(grid_chart(12, 2, 3.0, 0.5)[1])] * 4 + charts[1:], short) is None
