"""Pieces that repeat (a kit's, a foliage mesh's) are charted and flattened once: uvbake.atlas.instances."""

from pathlib import Path

import numpy as np
import pytest

import uvbake
from uvbake.atlas.instances import copy_records, find_instances
from uvbake.io.load import load_mesh

from meshgen import helical_strip, torus

SCENES = Path(__file__).resolve().parents[1] / "sample_scenes"


def _turn(seed):
    """A proper rotation (det +1) from a seed."""
    q, _ = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    return q * np.sign(np.linalg.det(q))


def _kit(pieces):
    """One mesh of (V, F) pieces laid end to end."""
    off = np.cumsum([0] + [len(V) for V, _ in pieces])
    return np.concatenate([V for V, _ in pieces]), np.concatenate([F + o for (_, F), o in zip(pieces, off)])


def test_copies_turned_scaled_and_moved_are_found_and_nothing_else():
    T, F = torus()
    S, G = helical_strip(turns=1.0)
    mirror = T * [1.0, 1.0, -1.0]                                  # a mirror image: no proper rotation
    noisy = T + np.random.default_rng(3).normal(0, 1e-4, T.shape)  # a near copy, far over REL_TOL
    pieces = [(T, F),                                              # 0: the torus's original
              (0.5 * T @ _turn(1).T + [5.0, 0, 0], F),             # 1: a copy at half size
              (S, G),                                              # 2: the strip's original
              (mirror + [0, 9.0, 0], F),                           # 3: not a copy (mirrored)
              (2.0 * T @ _turn(2).T - [3.0, 4.0, 0], F),           # 4: a copy at twice the size
              (noisy + [0, 0, 7.0], F),                            # 5: not a copy (noise)
              (S @ _turn(4).T * 3.0, G),                           # 6: the strip's copy
              (T + [9.0, 9.0, 9.0], np.roll(F, 1, axis=0)),        # 7: the same torus, faces listed otherwise
              # 8: a small copy far out, its coordinates stored as float32 (as PLY and glTF hold them):
              # similar only to that rounding, 2e-4 of its size
              ((0.1 * T @ _turn(8).T + 1000.0).astype(np.float32).astype(np.float64), F)]
    inst = find_instances(*_kit(pieces))
    assert inst is not None and inst.copies == 4
    np.testing.assert_array_equal(inst.original, [0, 0, 2, 3, 0, 5, 2, 7, 0])
    np.testing.assert_allclose(inst.scale[[1, 4, 6]], [0.5, 2.0, 3.0], rtol=1e-12)
    assert inst.scale[8] == pytest.approx(0.1, rel=1e-3)
    # the mesh of originals has every piece but the copies
    V, F2, *_ = inst.reduced(_kit(pieces)[0], None, None)
    assert len(F2) == 4 * len(F) + len(G) and len(V) == 4 * len(T) + len(S)


def test_labels_pinches_and_lone_pieces_are_never_copies():
    T, F = torus()
    V, F2 = _kit([(T, F), (T + 5.0, F)])
    assert find_instances(V, F2).copies == 1
    labels = np.concatenate([np.zeros(len(F), np.int64), np.ones(len(F), np.int64)])
    assert find_instances(V, F2, labels) is None                   # one label each: their own charts
    keys = np.full(len(V), -1)
    keys[len(T) + 3] = 7                                           # a repaired pinch in the second piece
    assert find_instances(V, F2, None, keys) is None
    assert find_instances(T, F) is None                            # one piece: nothing repeats


def _similarity_residual(P, Q):
    """Least |Q - (s R P + t)| over 2D similarities (a proper rotation R), as a share of Q's size, and s."""
    P, Q = P - P.mean(axis=0), Q - Q.mean(axis=0)
    U, sv, Vt = np.linalg.svd(P.T @ Q)
    d = np.sign(np.linalg.det(Vt.T @ U.T))
    R = Vt.T @ np.diag([1.0, d]) @ U.T
    s = (sv * [1.0, d]).sum() / (P * P).sum()
    return np.abs(Q - s * P @ R.T).max() / np.abs(Q).max(), s


def test_every_copy_gets_its_originals_charts_and_map_scaled_and_the_records_add_up():
    T, F = torus()
    S, G = helical_strip(turns=2.0)
    pieces = [(T, F), (S, G), (0.7 * T @ _turn(5).T + 6.0, F), (S @ _turn(6).T * 1.5 - 4.0, G),
              (1.3 * T @ _turn(7).T - 6.0, F)]
    V, F2 = _kit(pieces)
    res = uvbake.unwrap((V, F2), alpha=0.5, texture_size_px=512)
    rep = res.report
    assert rep["valid"] and rep["instance_copies"] == 3
    # each piece's faces, in order: the atlas corner UVs of a copy are its original's under a 2D
    # similarity of the copy's scale (packing turns and moves each chart; charts split alike)
    starts = np.cumsum([0] + [len(f) for _, f in pieces])
    for orig, copy, scale in ((0, 2, 0.7), (1, 3, 1.5), (0, 4, 1.3)):
        a = res.corner_uv[starts[orig]:starts[orig + 1]]
        b = res.corner_uv[starts[copy]:starts[copy + 1]]
        ids_a = res.chart_ids[starts[orig]:starts[orig + 1]]
        ids_b = res.chart_ids[starts[copy]:starts[copy + 1]]
        for c in np.unique(ids_a):                              # one per chart of the original
            on = ids_a == c
            assert len(np.unique(ids_b[on])) == 1               # the same faces make one chart of the copy
            err, s = _similarity_residual(a[on].reshape(-1, 2), b[on].reshape(-1, 2))
            assert err <= 1e-7
            assert s == pytest.approx(scale, rel=1e-6)          # one texel density over the atlas
    # the charting's records name every copy's cuts too (the closed torus is cut; the strip, a disk,
    # is not), and everything adds up as for distinct pieces
    names = sorted(c["chart"] for c in rep["cuts"])
    assert len(names) == 3 and names[1:] == [names[0] + " (instance 1)", names[0] + " (instance 2)"]
    # each cut adds parts - 1 charts, each merge back takes one away
    assert rep["charts_input"] == len(pieces) + sum(c["parts"] - 1 for c in rep["cuts"]) \
        + sum(c["parts"] - 1 if "parts" in c else -1 for c in rep["budget_cuts"])
    assert rep["charts_final"] == rep["charts_input"] + sum(s["parts"] - 1 for s in rep["splits"])
    seams = [c["seam_length"] for c in rep["cuts"]] + [c.get("seam_length", 0.0) for c in rep["budget_cuts"]] \
        + [s["seam_length"] for s in rep["splits"]]
    assert rep["seam_length_added"] == pytest.approx(sum(seams), rel=1e-12)
    copied = [c for c in rep["charts"] if "instance_of" in c]       # a copy's solver record is its original's
    assert copied and all(c["time_s"] == 0.0 and "(instance" in c["name"] for c in copied)
    cut = {c["chart"]: c["seam_length"] for c in rep["cuts"]}
    first = next(n for n in cut if "(instance" not in n)
    assert cut[first + " (instance 2)"] == pytest.approx(1.3 * cut[first], rel=1e-12)


def test_a_copys_solve_splits_are_its_originals():
    # alpha 1 shears the cap's rim past the budget: the solve splits it (tests/test_shear.py)
    mesh = load_mesh(str(SCENES / "sphere_cap.ply"))
    V, F = mesh.V, mesh.F
    V2, F2 = _kit([(V, F), (0.5 * V @ _turn(9).T + 3.0, F)])
    rep = uvbake.unwrap((V2, F2), alpha=1.0, texture_size_px=256).report
    assert rep["valid"] and rep["instance_copies"] == 1
    sheared = [s for s in rep["splits"] if s["reason"] == "sheared"]
    own = [s for s in sheared if "(instance" not in s["chart"]]
    assert own and len(sheared) == 2 * len(own)
    for s in own:
        twin = next(t for t in sheared if t["chart"] == s["chart"] + " (instance 1)")
        assert twin["parts"] == s["parts"] and twin["seam_length"] == pytest.approx(0.5 * s["seam_length"], rel=1e-12)


def test_a_chart_budget_charts_every_piece_itself():
    T, F = torus()
    V, F2 = _kit([(T, F), (T + 5.0, F)])
    assert uvbake.unwrap((V, F2), alpha=0.5, texture_size_px=256, max_charts=64).report["instance_copies"] == 0
    assert uvbake.unwrap((V, F2), alpha=0.5, texture_size_px=256).report["instance_copies"] == 1


def test_records_are_made_for_each_copy_of_the_piece_they_name():
    recs = [dict(chart="chart 0", parts=2, seam_length=2.0), dict(merged=["chart 1.0", "chart 1.1"], triangles=4),
            dict(chart="chart 2.1 (label 3)", parts=3, seam_length=1.0), dict(note="no chart")]
    out = copy_records(recs, [0, 5, 0], {0: [(1, 0.5), (2, 3.0)]})
    assert out[:4] == recs
    assert out[4:] == [dict(chart="chart 0 (instance 1)", parts=2, seam_length=1.0),
                       dict(chart="chart 0 (instance 2)", parts=2, seam_length=6.0),
                       dict(chart="chart 2.1 (label 3) (instance 1)", parts=3, seam_length=0.5),
                       dict(chart="chart 2.1 (label 3) (instance 2)", parts=3, seam_length=3.0)]
