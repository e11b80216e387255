"""The opt-in island rule (anigs.effects.rules.islands, ``effects.rules.islands.min_share``): green Gaussians
lifted onto a surface that is not a plant (moss on a stone between leaves, a painted gate) do not move; a
plant is a volume of plant Gaussians, and its Gaussians keep their region.

On the flower capture (0.8's default fit) 31 of the foliage Gaussians seen in a marked stone had a median
of 31% plant Gaussians among their 16 nearest, the moving leaves' and blossoms' 94-100%.
"""
from __future__ import annotations

import numpy as np
import pytest

from anigs.effects.config import REGIONS, EffectsConfig
from anigs.effects.rules import check_candidates, drop_islands

FOLIAGE = REGIONS.index("foliage")


def _scene(seed: int = 0):
    """A stone (a 1 x 1 grid of 400 unlabelled Gaussians at z = 0) with 6 green specks on it lifted as
    foliage, and a bush (300 foliage Gaussians in a ball of radius 0.3 above it). Returns means [N,3],
    region [N], the specks' indices and the bush's."""
    rng = np.random.default_rng(seed)
    gx, gy = np.meshgrid(np.linspace(0, 1, 20), np.linspace(0, 1, 20))
    stone = np.column_stack([gx.ravel(), gy.ravel(), rng.normal(0, 0.005, gx.size)])
    bush = rng.normal(0, 1, (300, 3))
    bush = bush / np.linalg.norm(bush, axis=1, keepdims=True) * 0.3 * rng.uniform(0, 1, (300, 1)) ** (1 / 3)
    bush += [0.5, 0.5, 1.0]
    means = np.vstack([stone, bush])
    region = np.full(len(means), -1)
    specks = rng.choice(len(stone), 6, replace=False)
    region[specks] = FOLIAGE
    region[len(stone):] = FOLIAGE
    return means, region, specks, np.arange(len(stone), len(means))


@pytest.mark.parametrize("seed", range(5))
def test_green_specks_on_a_stone_do_not_move_and_the_bush_does(seed):
    means, region, specks, bush = _scene(seed)
    counts = {}
    out = drop_islands(means, region, 16, 0.35, counts)
    assert (out[specks] == -1).all()
    assert (out[bush] == FOLIAGE).mean() >= 0.95  # a bush's rim is still a plant
    assert counts == {"foliage": int((out == -1).sum() - (region == -1).sum())}


def test_the_rule_is_off_by_default_and_runs_inside_check_candidates():
    means, region, specks, bush = _scene()
    colours = np.tile([0.2, 0.6, 0.2], (len(means), 1))
    assert EffectsConfig().rules.islands.min_share == 0
    on, _, fragments = check_candidates(means, colours, region, None, 1.0, 0.1, EffectsConfig.from_dict({"rules": {"islands": {"min_share": 0.35}}}), None)
    assert (on[specks] == -1).all() and (on[bush] == FOLIAGE).mean() >= 0.95
    assert fragments.get("foliage", 0) >= len(specks)


def test_a_bad_share_is_refused():
    with pytest.raises(ValueError, match="islands.min_share"):
        EffectsConfig.from_dict({"rules": {"islands": {"min_share": 1.5}}})
