"""Fréchet distance between two Gaussians fitted to feature sets (the FID/FVD core).

``FD = |mu1 - mu2|^2 + tr(S1 + S2 - 2 (S1 S2)^{1/2})``, computed in float64.

Guards (the usual ones of FID/FVD code):

- the matrix square root of ``S1 @ S2`` is taken with :func:`scipy.linalg.sqrtm`; when it
  fails, is not finite, or comes back complex with a non-negligible imaginary part, the
  computation is retried with ``eps * I`` added to both covariances (``eps`` growing by 10x
  up to ``max_eps``); the offset actually used is reported;
- a negligible imaginary part (``|imag| <= imag_tol * max(1, |real|)`` on the diagonal) is
  dropped;
- fewer than 2 samples on either side is an error (the covariance is undefined);
- fewer samples than feature dimensions makes the covariance singular and the value
  biased upward: the result carries ``n1``, ``n2``, ``dim`` and ``undersampled = True``, and
  the value must never be reported without the sample counts.
"""
from __future__ import annotations

import warnings
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
import scipy.linalg


@dataclass
class FrechetResult:
    """A Fréchet distance with the facts needed to read it."""

    value: float
    n1: int
    n2: int
    dim: int
    undersampled: bool  # min(n1, n2) < dim: covariance rank-deficient, value biased upward
    eps_used: float = 0.0  # diagonal offset added to both covariances (0 = none needed)
    warnings: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def feature_stats(features: np.ndarray, what: str = "features") -> tuple[np.ndarray, np.ndarray, int]:
    """Mean [D] and unbiased covariance [D,D] (float64) of features [N,D]; N >= 2 required."""
    f = np.asarray(features, dtype=np.float64)
    if f.ndim != 2:
        raise ValueError(f"{what}: expected a 2-D array [N, D], got shape {f.shape}")
    n = f.shape[0]
    if n < 2:
        raise ValueError(f"{what}: a Fréchet distance needs at least 2 samples per set, got {n}")
    if not np.isfinite(f).all():
        raise ValueError(f"{what}: contains NaN or Inf")
    mu = f.mean(axis=0)
    sigma = np.atleast_2d(np.cov(f, rowvar=False))
    return mu, sigma, n


def _trace_sqrt_product(s1: np.ndarray, s2: np.ndarray, imag_tol: float) -> float | None:
    """tr((s1 s2)^{1/2}) or None when sqrtm fails / is non-finite / materially complex."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            root = scipy.linalg.sqrtm(s1 @ s2)
    except (ValueError, np.linalg.LinAlgError, scipy.linalg.LinAlgError):
        return None
    root = np.asarray(root)
    if not np.isfinite(root).all():
        return None
    if np.iscomplexobj(root):
        diag = np.diagonal(root)
        if np.max(np.abs(diag.imag)) > imag_tol * max(1.0, float(np.max(np.abs(diag.real)))):
            return None
        root = root.real
    return float(np.trace(root))


def frechet_distance_from_stats(mu1: np.ndarray, sigma1: np.ndarray, mu2: np.ndarray, sigma2: np.ndarray,
                                n1: int = 0, n2: int = 0, eps: float = 1e-6, max_eps: float = 1e-2,
                                imag_tol: float = 1e-3) -> FrechetResult:
    """Fréchet distance between N(mu1, sigma1) and N(mu2, sigma2) (float64, guarded).

    ``n1``/``n2`` are the sample counts behind the statistics (reported, used for the
    ``undersampled`` flag; 0 = unknown). Raises ValueError on shape mismatch and
    RuntimeError when even ``max_eps`` does not give a usable square root.
    """
    mu1 = np.atleast_1d(np.asarray(mu1, dtype=np.float64))
    mu2 = np.atleast_1d(np.asarray(mu2, dtype=np.float64))
    s1 = np.atleast_2d(np.asarray(sigma1, dtype=np.float64))
    s2 = np.atleast_2d(np.asarray(sigma2, dtype=np.float64))
    d = mu1.shape[0]
    if mu2.shape != (d,) or s1.shape != (d, d) or s2.shape != (d, d):
        raise ValueError(f"frechet: inconsistent shapes mu1 {mu1.shape}, mu2 {mu2.shape}, "
                         f"sigma1 {s1.shape}, sigma2 {s2.shape}")
    for name, arr in (("mu1", mu1), ("mu2", mu2), ("sigma1", s1), ("sigma2", s2)):
        if not np.isfinite(arr).all():
            raise ValueError(f"frechet: {name} contains NaN or Inf")
    notes: list[str] = []
    diff = mu1 - mu2
    tr_sqrt = _trace_sqrt_product(s1, s2, imag_tol)
    eps_used = 0.0
    if tr_sqrt is None:
        e = eps
        while e <= max_eps * (1 + 1e-9):
            off = e * np.eye(d)
            tr_sqrt = _trace_sqrt_product(s1 + off, s2 + off, imag_tol)
            if tr_sqrt is not None:
                eps_used = e
                break
            e *= 10.0
        if tr_sqrt is None:
            raise RuntimeError(f"frechet: matrix square root failed even with a diagonal offset of {max_eps:g} "
                               f"(dim {d}, samples {n1}/{n2})")
        notes.append(f"sqrtm(S1 S2) was singular or complex; retried with {eps_used:g} * I added to both covariances")
    value = float(diff @ diff + np.trace(s1) + np.trace(s2) - 2.0 * tr_sqrt)
    if value < 0 and value > -1e-6 * max(1.0, float(np.trace(s1) + np.trace(s2))):
        value = 0.0  # round-off around identical distributions
    undersampled = bool(n1 and n2 and min(n1, n2) < d)
    if undersampled:
        notes.append(f"fewer samples ({min(n1, n2)}) than feature dimensions ({d}): covariance is rank-deficient "
                     "and the distance is biased upward; compare only values with the same sample counts")
    return FrechetResult(value=value, n1=int(n1), n2=int(n2), dim=int(d), undersampled=undersampled,
                         eps_used=eps_used, warnings=notes)


def frechet_distance(features1: np.ndarray, features2: np.ndarray, **kwargs: Any) -> FrechetResult:
    """Fréchet distance between feature sets [N1,D] and [N2,D] (each N >= 2)."""
    mu1, s1, n1 = feature_stats(features1, "features1")
    mu2, s2, n2 = feature_stats(features2, "features2")
    if mu1.shape != mu2.shape:
        raise ValueError(f"frechet: feature dimensions differ: {mu1.shape[0]} vs {mu2.shape[0]}")
    return frechet_distance_from_stats(mu1, s1, mu2, s2, n1=n1, n2=n2, **kwargs)
