"""Which effect each dynamic Gaussian belongs to: the per-Gaussian labels the update's per-effect
settings (``update.effect_num_bases``, ``update.effect_limits``) read.

Label = 1 + the index of the effect's region in :data:`anigs.effects.config.REGIONS` (foliage 1,
grass 2, flowers 3, water 4), 0 = static: the labels of :func:`anigs.animate.update.effect_labels`.
A dynamic Gaussian takes its region from the effects stage (``regions.npy``) when that region is
one of the chosen effects'; the others (the masks backend found them, the effects stage gave them
no chosen region) take the label of the nearest labelled dynamic Gaussian, or foliage's when none
is labelled.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.spatial import cKDTree

from anigs.effects.config import EFFECTS, EFFECT_REGION, REGIONS


def effect_label_ids() -> dict[str, int]:
    """Effect name -> its label: 1 + the index of its region in the effects stage's ``REGIONS``
    (foliage_sway and leaf_flutter 1, grass_wave 2, flower_bob 3, water_ripple 4; 0 = static)."""
    return {e: 1 + REGIONS.index(EFFECT_REGION[e]) for e in EFFECTS}


def effect_labels(dynamic: np.ndarray, regions: np.ndarray, chosen_regions: Sequence[int],
                  means: np.ndarray) -> tuple[np.ndarray, dict[str, int]]:
    """Per-Gaussian effect labels.

    Args:
        dynamic: bool [N], the dynamic set.
        regions: int [N], the effects stage's region index per Gaussian (-1 = none).
        chosen_regions: the region indices of the chosen effects.
        means: float [N,3] Gaussian centres (for the nearest-neighbour fill).

    Returns:
        (int8 [N]: 0 static, else 1 + region index; counts: ``from_regions``, ``nearest``, ``default``).
    """
    dynamic = np.asarray(dynamic, bool)
    regions = np.asarray(regions)
    means = np.asarray(means, np.float64)
    n = dynamic.shape[0]
    if regions.shape != (n,) or means.shape != (n, 3):
        raise ValueError(f"effect_labels: dynamic [{n}], regions {regions.shape} and means {means.shape} must agree")
    out = np.zeros(n, np.int8)
    own = dynamic & np.isin(regions, np.asarray(list(chosen_regions), dtype=regions.dtype))
    out[own] = (regions[own] + 1).astype(np.int8)
    rest = dynamic & ~own
    counts = {"from_regions": int(own.sum()), "nearest": 0, "default": 0}
    if rest.any():
        if own.any():
            _, j = cKDTree(means[own]).query(means[rest], k=1)
            out[rest] = out[own][j]
            counts["nearest"] = int(rest.sum())
        else:
            out[rest] = 1
            counts["default"] = int(rest.sum())
    return out, counts
