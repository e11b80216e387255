"""The plane rule (anigs.effects.rules): a bed of flower heads is not a flat surface, a flat rug on the
floor is; a part's verdict does not depend on which other parts were checked before it.

On the synthetic garden a 35-Gaussian clump of flowers was rejected "on large flat surfaces" because
RANSAC sliced the bed of flower heads around it into layers, and whether it did depended on how many
random draws the parts checked before had used (garden flower recall 0.452 -> 0.408).
"""
from __future__ import annotations

import numpy as np
import pytest

from anigs.effects.config import REGIONS, EffectsConfig
from anigs.effects.rules import check_candidates

RADIUS = 0.4167  # the garden's neighbourhood radius: plane tolerance 0.10, link 0.42, least plane extent 0.83
RED, GREEN, SOIL = (0.9, 0.2, 0.3), (0.2, 0.6, 0.2), (0.45, 0.35, 0.25)


def _bed(seed: int, head_height: float, head_spread: float):
    """A 1.5 x 1 bed of 300 flower heads (every fourth a green stem) at ``head_height`` +- ``head_spread``
    above a sparse soil grid; the heads within 0.35 of the bed's centre are the flowers region, the rest
    unlabelled (as the lifted regions leave them). Returns means [N,3], colours [N,3], region [N], height [N]."""
    rng = np.random.default_rng(seed)
    heads = rng.uniform([0, 0, 0], [1.5, 1.0, 0], (300, 3))
    heads[:, 2] = np.clip(rng.normal(head_height, head_spread, 300), 0.05, 0.5)
    gx, gy = np.meshgrid(np.arange(-1, 2.5, 0.3), np.arange(-1, 2, 0.3))
    soil = np.column_stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)])
    means = np.vstack([heads, soil])
    colours = np.vstack([np.tile(RED, (300, 1)), np.tile(SOIL, (len(soil), 1))])
    stem = np.arange(300) % 4 == 0
    colours[:300][stem] = GREEN
    region = np.full(len(means), -1)
    centre = np.linalg.norm(heads - [0.75, 0.5, head_height], axis=1) < 0.35
    region[:300][centre & ~stem] = REGIONS.index("flowers")
    return means, colours, region, means[:, 2]


def _flowers(means, colours, region, height, seed=0):
    _, cands, _ = check_candidates(means, colours, region, height, 1.6, RADIUS, EffectsConfig(), None, seed=seed)
    return [c for c in cands if c.region == "flowers"]


@pytest.mark.parametrize("seed", range(20))
def test_a_bed_of_flower_heads_is_not_a_flat_surface(seed):
    cands = _flowers(*_bed(seed, 0.28, 0.1))
    assert len(cands) == 1 and len(cands[0].indices) >= 30
    assert cands[0].kept and cands[0].rule == "", (cands[0].rule, cands[0].figures)


@pytest.mark.parametrize("seed", range(5))
def test_a_flat_rug_on_the_floor_is_still(seed):
    cands = _flowers(*_bed(seed, 0.05, 0.005))
    assert len(cands) == 1 and not cands[0].kept and cands[0].rule == "plane", cands[0].figures


@pytest.mark.parametrize("seed", range(6))
def test_a_parts_verdict_does_not_depend_on_the_parts_checked_before_it(seed):
    means, colours, region, height = _bed(seed, 0.28, 0.08)  # a thinner bed: a close call for the rule
    alone = _flowers(means, colours, region, height)[0]
    # a bush far away, checked first (foliage comes before flowers), draws its own RANSAC samples
    bush = np.random.default_rng(9).normal([6.0, 6.0, 0.8], 0.3, (200, 3))
    both = _flowers(np.vstack([means, bush]), np.vstack([colours, np.tile(GREEN, (200, 1))]),
                    np.concatenate([region, np.full(200, REGIONS.index("foliage"))]),
                    np.concatenate([height, bush[:, 2]]))[0]
    assert np.array_equal(alone.indices, both.indices)
    assert alone.figures == both.figures and alone.kept == both.kept
