"""The spread of a Fréchet distance over bootstrap resamples of the clips.

Each resample draws, with replacement, as many *groups* (clips of one camera-fixed view: their
windows overlap in time, so they are not independent) as there are, takes every clip of the
drawn groups on both sides (the method's clips and the reference clips of the same views:
paired), and recomputes the distance. The same ``seed`` draws the same groups for every
method, so the resamples of two methods compare like with like.

Per resample the distance uses the exact low-rank form of the trace term: with centred
feature matrices ``A`` [n,D] and ``B`` [m,D], ``S1 = A^T A / (n-1)`` and ``S2 = B^T B / (m-1)``,
the non-zero eigenvalues of ``S1 S2`` are the squared singular values of
``C = A B^T / sqrt((n-1)(m-1))`` [n,m], so ``tr((S1 S2)^{1/2}) = ||C||_*`` (nuclear norm), which
is exact for any n, m (no square root of a singular D x D matrix, no diagonal offset) and
costs an n x m SVD instead of a D x D ``sqrtm``. :func:`frechet_lowrank` equals
:func:`anigs.metrics.frechet.frechet_distance` where the latter needs no offset (tested).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any, Sequence

import numpy as np


def frechet_lowrank(f1: np.ndarray, f2: np.ndarray) -> float:
    """Fréchet distance of feature sets [n,D] and [m,D] (float64; n, m >= 2) through the nuclear norm."""
    a = np.asarray(f1, dtype=np.float64)
    b = np.asarray(f2, dtype=np.float64)
    if a.ndim != 2 or b.ndim != 2 or a.shape[1] != b.shape[1]:
        raise ValueError(f"frechet_lowrank: expected [n,D] and [m,D], got {a.shape} and {b.shape}")
    n, m = a.shape[0], b.shape[0]
    if n < 2 or m < 2:
        raise ValueError(f"frechet_lowrank: at least 2 samples per set, got {n} and {m}")
    if not (np.isfinite(a).all() and np.isfinite(b).all()):
        raise ValueError("frechet_lowrank: features contain NaN or Inf")
    mu1, mu2 = a.mean(0), b.mean(0)
    ac, bc = a - mu1, b - mu2
    tr1 = float((ac * ac).sum()) / (n - 1)
    tr2 = float((bc * bc).sum()) / (m - 1)
    c = (ac @ bc.T) / np.sqrt((n - 1) * (m - 1))
    nuc = float(np.linalg.svd(c, compute_uv=False).sum())
    d = mu1 - mu2
    return max(0.0, float(d @ d) + tr1 + tr2 - 2.0 * nuc)


@dataclass
class BootstrapSpread:
    """Bootstrap figures of one Fréchet distance."""

    resamples: int
    seed: int
    unit: str  # what was resampled
    groups: int
    mean: float
    std: float
    interval: tuple[float, float]  # central 90%: 5th and 95th percentiles
    level: float = 0.90

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["interval"] = [float(x) for x in self.interval]
        return d


def resample_groups(num_groups: int, resamples: int, seed: int) -> np.ndarray:
    """Group indices [resamples, num_groups], drawn with replacement (numpy PCG64 from ``seed``)."""
    if num_groups < 2:
        raise ValueError(f"bootstrap: at least 2 groups (views) are needed, got {num_groups}")
    if resamples < 2:
        raise ValueError(f"bootstrap: at least 2 resamples, got {resamples}")
    return np.random.default_rng(int(seed)).integers(0, num_groups, size=(int(resamples), int(num_groups)))


def bootstrap_frechet(f1: np.ndarray, f2: np.ndarray, groups: Sequence[int], resamples: int = 200,
                      seed: int = 0, level: float = 0.90) -> BootstrapSpread:
    """Spread of FD(f1, f2) over paired resamples of the groups.

    ``f1`` [n,D] and ``f2`` [n,D] are paired row by row (clip i of the method and clip i of the
    reference show the same view and frames); ``groups`` [n] names each row's view.
    """
    a = np.asarray(f1, dtype=np.float64)
    b = np.asarray(f2, dtype=np.float64)
    g = np.asarray(groups)
    if a.shape != b.shape or g.shape != (a.shape[0],):
        raise ValueError(f"bootstrap_frechet: paired features and groups must agree, got {a.shape}, {b.shape}, {g.shape}")
    return _over_group_resamples(g, lambda rows: frechet_lowrank(a[rows], b[rows]), resamples, seed, level,
                                 "views (all windows of a drawn view, both sides)")


def bootstrap_gap(f_a: np.ndarray, f_b: np.ndarray, f_ref: np.ndarray, groups: Sequence[int], resamples: int = 200,
                  seed: int = 0, level: float = 0.90) -> BootstrapSpread:
    """Spread of ``FD(f_a, f_ref) - FD(f_b, f_ref)`` over paired resamples of the groups: the same
    drawn views for both (paired rows, as :func:`bootstrap_frechet`). An interval that excludes 0
    tells a real gap between two methods from the noise of the views drawn."""
    a, b, r = (np.asarray(x, dtype=np.float64) for x in (f_a, f_b, f_ref))
    g = np.asarray(groups)
    if not (a.shape == b.shape == r.shape) or g.shape != (a.shape[0],):
        raise ValueError(f"bootstrap_gap: paired features and groups must agree, got {a.shape}, {b.shape}, "
                         f"{r.shape}, {g.shape}")
    return _over_group_resamples(g, lambda rows: frechet_lowrank(a[rows], r[rows]) - frechet_lowrank(b[rows], r[rows]),
                                 resamples, seed, level, "views (paired: the same drawn views for both sets)")


def _over_group_resamples(groups: np.ndarray, stat, resamples: int, seed: int, level: float,
                          unit: str) -> BootstrapSpread:
    """``stat(rows)`` over resamples of whole groups (every row of a drawn group; :func:`resample_groups`)."""
    names, inverse = np.unique(groups, return_inverse=True)
    rows_of = [np.flatnonzero(inverse == i) for i in range(len(names))]
    draws = resample_groups(len(names), resamples, seed)
    vals = np.empty(len(draws))
    for k, pick in enumerate(draws):
        vals[k] = stat(np.concatenate([rows_of[i] for i in pick]))
    lo, hi = np.percentile(vals, [50 * (1 - level), 50 * (1 + level)])
    return BootstrapSpread(int(resamples), int(seed), unit, len(names),
                           float(vals.mean()), float(vals.std(ddof=1)), (float(lo), float(hi)), float(level))
