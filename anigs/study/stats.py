"""Binomial statistics of a preference rate: Wilson and Clopper-Pearson intervals, exact test."""
from __future__ import annotations

import math
from typing import Sequence

CI_METHODS = ("wilson", "clopper-pearson")


def _check(k: int, n: int, level: float) -> None:
    if n < 1 or not 0 <= k <= n:
        raise ValueError(f"need 0 <= k <= n and n >= 1, got k={k}, n={n}")
    if not 0 < level < 1:
        raise ValueError(f"confidence level must be in (0, 1), got {level}")


def wilson(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    """Wilson score interval (Wilson 1927) for k successes in n trials."""
    from scipy.stats import norm

    _check(k, n, level)
    z = float(norm.ppf(0.5 + level / 2))
    p = k / n
    den = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return max(0.0, centre - half), min(1.0, centre + half)


def clopper_pearson(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    """Exact (Clopper-Pearson 1934) interval from beta quantiles; conservative."""
    from scipy.stats import beta

    _check(k, n, level)
    a = (1 - level) / 2
    lo = 0.0 if k == 0 else float(beta.ppf(a, k, n - k + 1))
    hi = 1.0 if k == n else float(beta.ppf(1 - a, k + 1, n - k))
    return lo, hi


def interval(k: int, n: int, method: str = "wilson", level: float = 0.95) -> tuple[float, float]:
    if method == "wilson":
        return wilson(k, n, level)
    if method == "clopper-pearson":
        return clopper_pearson(k, n, level)
    raise ValueError(f"unknown interval {method!r}; choose one of {CI_METHODS}")


def binomial_p(k: int, n: int) -> float:
    """Two-sided exact binomial test of k of n against a rate of 0.5 (no preference)."""
    from scipy.stats import binomtest

    _check(k, n, 0.95)
    return float(binomtest(k, n, 0.5).pvalue)


def cluster_bootstrap(k: Sequence[int], n: Sequence[int], level: float = 0.95, reps: int = 4000,
                      seed: int = 0) -> tuple[float, float]:
    """Percentile interval of the pooled rate sum(k)/sum(n) when whole participants are resampled.

    ``k[i]`` of ``n[i]`` answers of participant i prefer ours. Answers of one participant are
    correlated; resampling participants (not answers) keeps that, so the interval widens when
    participants disagree. Seeded: the same answers give the same interval.
    """
    import numpy as np

    k_arr, n_arr = np.asarray(k, dtype=float), np.asarray(n, dtype=float)
    if k_arr.shape != n_arr.shape or k_arr.size == 0 or (n_arr < 1).any() or (k_arr > n_arr).any() or (k_arr < 0).any():
        raise ValueError("cluster_bootstrap: need one (k <= n, n >= 1) per participant, at least one participant")
    _check(int(k_arr.sum()), int(n_arr.sum()), level)
    idx = np.random.default_rng(seed).integers(0, k_arr.size, size=(reps, k_arr.size))
    rates = k_arr[idx].sum(1) / n_arr[idx].sum(1)
    a = (1 - level) / 2
    return float(np.quantile(rates, a)), float(np.quantile(rates, 1 - a))
