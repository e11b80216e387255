"""Label propagation over Gaussian centres: undecided points take the majority of their nearest decided ones."""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree


def propagate_labels(means: np.ndarray, decided: np.ndarray, value: np.ndarray, k: int) -> np.ndarray:
    """Fill undecided entries of bool ``value`` [N] by majority over the ``k`` nearest decided Gaussians."""
    out = value.copy()
    und = ~decided
    if k <= 0 or not und.any() or not decided.any():
        return out
    k = min(k, int(decided.sum()))
    _, idx = cKDTree(means[decided]).query(means[und], k=k)
    idx = np.asarray(idx).reshape(int(und.sum()), k)
    out[und] = value[decided][idx].mean(1) > 0.5
    return out
