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
