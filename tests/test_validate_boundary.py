"""Overlap-freedom proven from a chart's boundary (uvbake.validate.boundary): whenever it says
proven, the exact all-triangle check finds no pair; what it cannot prove is left to that check."""

import numpy as np
import pytest

from uvbake.atlas.conformal import conformal_factor
from uvbake.validate.boundary import boundary_proves_injective, proven_injective
from uvbake.validate.core import overlap_pairs

from meshgen import bumpy_disk, grid, plane


def _spiral(turns, nu=60, nv=4, growth=0.15):
    """A strip wound ``turns`` times around the origin, every triangle positive: it overlaps itself
    once turns > 1 (the radius grows less than the strip is wide)."""
    V, F = grid(nu, nv)
    s, t = V[:, 0] / V[:, 0].max(), V[:, 1] / V[:, 1].max()
    theta = 2 * np.pi * turns * s
    r = 1.0 + 0.5 * t + growth * s
    uv = np.column_stack([r * np.cos(theta), r * np.sin(theta)])
    e1, e2 = uv[F[:, 1]] - uv[F[:, 0]], uv[F[:, 2]] - uv[F[:, 0]]
    if np.sum(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]) < 0:
        uv[:, 1] *= -1
    return uv, F


def _dets(uv, F):
    e1, e2 = uv[F[:, 1]] - uv[F[:, 0]], uv[F[:, 2]] - uv[F[:, 0]]
    return e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]


def test_flat_and_conformal_maps_are_proven_and_have_no_overlap():
    for V, F in (plane(12, 9, jitter=0.3), bumpy_disk(12, amp=0.4), bumpy_disk(16, amp=0.8, seed=3)):
        uv, _ = conformal_factor(np.asarray(V, float), np.asarray(F))
        assert np.all(_dets(uv, F) > 0)
        assert boundary_proves_injective(uv, F)
        assert len(overlap_pairs(uv, F)) == 0


@pytest.mark.parametrize("turns", [0.6, 0.9, 1.2, 1.6])
def test_a_strip_wound_past_a_full_turn_is_not_proven_and_does_overlap(turns):
    uv, F = _spiral(turns)
    assert np.all(_dets(uv, F) > 0)                     # locally injective everywhere
    pairs = overlap_pairs(uv, F)
    proven = boundary_proves_injective(uv, F)
    assert proven == (turns < 1.0)
    assert (len(pairs) > 0) == (turns > 1.0)


def test_random_deformations_never_prove_an_overlapping_map():
    """Property: proven implies no overlapping pair, over flip-free and folded random maps."""
    rng = np.random.default_rng(9)
    n_proven = n_overlapping = 0
    for k in range(150):
        V, F = bumpy_disk(8 + k % 6, amp=0.5, seed=k)
        uv, _ = conformal_factor(np.asarray(V, float), np.asarray(F))
        uv = uv + rng.normal(scale=rng.uniform(0.0, 0.02), size=uv.shape) * np.ptp(uv)
        if k % 5 == 0:                                  # a smooth twist, large enough to fold some
            ang = rng.uniform(0, 6) * np.linalg.norm(uv - uv.mean(axis=0), axis=1)
            c, s = np.cos(ang), np.sin(ang)
            uv = np.column_stack([c * uv[:, 0] - s * uv[:, 1], s * uv[:, 0] + c * uv[:, 1]])
        pairs = overlap_pairs(uv, F)
        proven = boundary_proves_injective(uv, F)
        n_proven += proven
        n_overlapping += len(pairs) > 0
        if proven:
            assert len(pairs) == 0 and np.all(_dets(uv, F) > 0)
    assert n_proven >= 30 and n_overlapping >= 30        # both kinds were exercised


def test_flips_touching_boundaries_and_batches():
    V, F = plane(6, 5, jitter=0.0)
    uv = np.asarray(V, float)[:, :2].copy()
    assert boundary_proves_injective(uv, F)
    flipped = uv.copy()
    inner = np.flatnonzero((uv[:, 0] > 0.1) & (uv[:, 0] < 0.9) & (uv[:, 1] > 0.1) & (uv[:, 1] < 0.9))[0]
    flipped[inner] += [5.0, 0.0]                        # drags one interior vertex across its ring
    assert np.any(_dets(flipped, F) <= 0) and not boundary_proves_injective(flipped, F)
    # a boundary vertex moved onto another boundary edge: a contact, not proven
    corner = int(np.argmin(uv[:, 0] + uv[:, 1]))
    touching = uv.copy()
    touching[corner] = [uv[:, 0].max() * 0.5, uv[:, 1].max()]      # onto the top edge
    assert not boundary_proves_injective(touching, F)
    # many charts at once: each chart's own verdict
    wound, Fw = _spiral(1.3)
    batch = proven_injective([uv, flipped, wound, uv + 100.0], [F, F, Fw, F])
    assert batch.tolist() == [True, False, False, True]


# ---- validate's use of the proof: faces of proven charts away from the other charts take no pair test

def _annulus(n_theta=64, n_r=8, r0=0.5, r1=1.0):
    """A closed ring of quads, r0 <= |uv| <= r1, every triangle positive."""
    V, F = grid(n_theta + 1, n_r)
    theta, r = 2 * np.pi * V[:, 0], r0 + (r1 - r0) * V[:, 1]
    uv = np.column_stack([r * np.cos(theta), r * np.sin(theta)])
    weld = np.arange(len(V))
    last = V[:, 0] == 1.0
    weld[last] = np.flatnonzero(V[:, 0] == 0.0)              # the seam's column is the first one
    F = weld[F]
    if np.sum(_dets(uv, F)) < 0:
        uv[:, 1] *= -1
    keep = np.unique(F)
    new = np.zeros(len(V), np.int64)
    new[keep] = np.arange(len(keep))
    return uv[keep], new[F]


def _square(n=24, size=1.0, at=(0.0, 0.0)):
    V, F = grid(n, n, jitter=0.2, seed=n)
    return V * size + np.asarray(at), F


def _atlas(*charts):
    """Per-corner UVs and chart ids of the charts laid as given."""
    corners = np.concatenate([uv[F] for uv, F in charts])
    ids = np.repeat(np.arange(len(charts)), [len(F) for _, F in charts])
    return corners, ids


LAYOUTS = {
    "apart": lambda: _atlas(_square(), _square(at=(1.5, 0.0))),
    "corner overlap": lambda: _atlas(_square(), _square(at=(0.7, 0.7))),
    "edge to edge": lambda: _atlas(_square(), _square(at=(1.0, 0.0))),
    "disk in the ring's hole": lambda: _atlas(_annulus(), _square(size=0.6, at=(-0.3, -0.3))),
    "disk on the ring": lambda: _atlas(_annulus(), _square(size=0.2, at=(0.65, -0.1))),
    "square over the hole": lambda: _atlas(_annulus(), _square(size=1.2, at=(-0.6, -0.6))),
    "spiral beside a square": lambda: _atlas(_spiral(1.5, nu=200, nv=4), _square(at=(4.0, 0.0))),
    "ring lying inside a square": lambda: _atlas(_square(size=3.0, at=(-1.5, -1.5)), _annulus()),
}


@pytest.mark.parametrize("name", sorted(LAYOUTS))
def test_pairs_with_the_boundary_proof_are_the_full_checks(name, monkeypatch):
    import uvbake.validate.core as core
    from uvbake.validate import validate

    corners, ids = LAYOUTS[name]()
    fast = validate(corners, chart_ids=ids, resolution_px=256)
    fast_pairs = overlap_pairs(corners, None, chart_ids=ids)
    monkeypatch.setattr(core, "pair_faces", lambda *args: args[-1])
    full = validate(corners, chart_ids=ids, resolution_px=256)
    np.testing.assert_array_equal(fast.overlap_pairs, full.overlap_pairs)
    np.testing.assert_array_equal(fast_pairs, full.overlap_pairs)
    np.testing.assert_array_equal(overlap_pairs(corners, None, chart_ids=ids, prove=False), full.overlap_pairs)
    assert fast.valid == full.valid
    assert fast.valid == (name in ("apart", "edge to edge", "disk in the ring's hole"))
    assert fast.n_candidates <= full.n_candidates
    if name in ("apart", "disk in the ring's hole", "spiral beside a square"):   # a proven chart away from the rest
        assert fast.n_candidates < full.n_candidates


def test_proven_charts_apart_take_no_pair_test():
    from uvbake.validate import validate
    from uvbake.validate.boundary import pair_faces
    from uvbake.validate.candidates import _half_edges
    from uvbake.validate.core import _prepare

    corners, ids = LAYOUTS["apart"]()
    report = validate(corners, chart_ids=ids, resolution_px=256)
    assert report.valid and report.n_candidates == 0
    _, vid, _ = _prepare(corners, None)
    live, sign = np.ones(len(corners), bool), np.ones(len(corners), np.int8)
    assert not pair_faces(corners, vid, ids, 2, *_half_edges(vid), sign, live).any()
    # a vertex shared by the charts: the first face of the second chart gets its first corner at the
    # first chart's first corner, with the same vertex id, so the two corners weld into one vertex;
    # then neither chart is tried and every face is kept
    k = len(corners) // 2
    assert ids[k] == 1 and ids[0] == 0
    corners[k, 0] = corners[0, 0]
    F = np.arange(3 * len(corners)).reshape(-1, 3)
    F[k, 0] = F[0, 0]
    _, vid, _ = _prepare(corners, F)
    assert vid[k, 0] == vid[0, 0]
    assert pair_faces(corners, vid, ids, 2, *_half_edges(vid), sign, live).all()


@pytest.mark.parametrize("seed", range(6))
def test_pairs_with_the_proof_on_random_moves_of_a_split_grid(seed, monkeypatch):
    """A jittered grid cut into four quadrant charts, each moved by a random offset (even seeds: outwards,
    apart; odd seeds: anywhere, onto each other; some not at all: then the quadrants share vertices and
    are not tried): the proof's pairs are the full check's."""
    import uvbake.validate.core as core
    from uvbake.validate import validate

    rng = np.random.default_rng(seed)
    V, F = grid(40, 40, jitter=0.3, seed=seed)
    c = V[F].mean(axis=1)
    ids = (c[:, 0] > 0.5).astype(np.int64) + 2 * (c[:, 1] > 0.5)
    outward = np.array([[-1.0, -1.0], [1.0, -1.0], [-1.0, 1.0], [1.0, 1.0]])
    move = (outward * rng.uniform(0.01, 0.5, (4, 1)) if seed % 2 == 0 else rng.normal(0.0, 0.3, (4, 2)))
    move *= rng.random((4, 1)) < 0.75
    corners = V[F] + move[ids][:, None, :]
    fast = validate(corners, F, chart_ids=ids, resolution_px=256)
    monkeypatch.setattr(core, "pair_faces", lambda *args: args[-1])
    full = validate(corners, F, chart_ids=ids, resolution_px=256)
    np.testing.assert_array_equal(fast.overlap_pairs, full.overlap_pairs)
    assert fast.valid == full.valid
    assert fast.n_candidates <= full.n_candidates
