"""The bootstrap spread of a Fréchet distance (anigs.metrics.bootstrap)."""
from __future__ import annotations

import numpy as np
import pytest

from anigs.metrics.bootstrap import bootstrap_frechet, bootstrap_gap, frechet_lowrank, resample_groups
from anigs.metrics.frechet import frechet_distance


def _feats(n: int, d: int, shift: float, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    mix = rng.normal(size=(d, d)) / np.sqrt(d)
    return rng.normal(size=(n, d)) @ mix + shift


def test_lowrank_equals_the_sqrtm_form():
    a, b = _feats(300, 40, 0.0, 1), _feats(250, 40, 0.3, 2)
    ref = frechet_distance(a, b)
    assert ref.eps_used == 0
    assert frechet_lowrank(a, b) == pytest.approx(ref.value, rel=1e-9)
    # fewer samples than dimensions: still exact (sqrtm succeeds without offset here too)
    a, b = _feats(30, 60, 0.0, 3), _feats(30, 60, 0.2, 4)
    ref = frechet_distance(a, b)
    if ref.eps_used == 0:
        assert frechet_lowrank(a, b) == pytest.approx(ref.value, rel=1e-6)


def test_identical_sets_give_zero():
    a = _feats(64, 400, 0.0, 5)
    assert frechet_lowrank(a, a) == pytest.approx(0.0, abs=1e-8)
    assert frechet_distance(a, a.copy()).value == pytest.approx(0.0, abs=1e-6)


def test_bootstrap_is_deterministic_for_a_seed():
    a, b = _feats(64, 20, 0.0, 6), _feats(64, 20, 0.5, 7)
    groups = np.arange(64) // 2
    s1 = bootstrap_frechet(a, b, groups, 50, seed=3)
    s2 = bootstrap_frechet(a, b, groups, 50, seed=3)
    s3 = bootstrap_frechet(a, b, groups, 50, seed=4)
    assert s1 == s2 and s1.std != s3.std
    assert s1.groups == 32 and s1.interval[0] < s1.mean < s1.interval[1]
    assert np.array_equal(resample_groups(10, 5, 1), resample_groups(10, 5, 1))


def test_spread_shrinks_with_more_clips():
    d = 16
    stds = []
    for n in (32, 512):
        a, b = _feats(n, d, 0.0, 8), _feats(n, d, 0.5, 9)
        stds.append(bootstrap_frechet(a, b, np.arange(n), 100, seed=0).std)
    assert stds[1] < 0.5 * stds[0]  # ~ 1/sqrt(n): 4x fewer at 16x the clips


def test_bootstrap_needs_paired_inputs():
    with pytest.raises(ValueError, match="paired"):
        bootstrap_frechet(np.zeros((4, 3)), np.zeros((5, 3)), np.arange(4))
    with pytest.raises(ValueError, match="2 groups"):
        bootstrap_frechet(np.zeros((4, 3)), np.zeros((4, 3)), np.zeros(4))


def test_gap_between_two_sets_on_the_same_draws():
    ref = _feats(128, 16, 0.0, 10)
    near, far = _feats(128, 16, 0.1, 11), _feats(128, 16, 0.6, 12)
    g = np.arange(128) // 2
    gap = bootstrap_gap(near, far, ref, g, 100, seed=0)
    assert gap.interval[1] < 0  # near is closer to the reference on every draw's central 90%
    same = bootstrap_gap(near, near.copy(), ref, g, 20, seed=0)
    assert same.mean == 0 and same.std == 0
    # the gap's draws are those of bootstrap_frechet: its mean is the difference of their means
    a, b = bootstrap_frechet(near, ref, g, 100, 0), bootstrap_frechet(far, ref, g, 100, 0)
    assert gap.mean == pytest.approx(a.mean - b.mean, rel=1e-9)
