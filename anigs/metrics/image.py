"""Image metrics for evaluation: PSNR and SSIM with scikit-image semantics.

SSIM here is the evaluation metric (Wang et al. 2004 settings, as scikit-image documents
them): Gaussian window sigma 1.5, population covariance, explicit ``data_range``, mean over
the valid interior of every channel. The training loss SSIM lives in :mod:`anigs.ssim`.
"""
from __future__ import annotations

import math

import numpy as np


def _pair(a, b, what: str) -> tuple[np.ndarray, np.ndarray]:
    a = np.asarray(a.detach().cpu() if hasattr(a, "detach") else a, dtype=np.float64)
    b = np.asarray(b.detach().cpu() if hasattr(b, "detach") else b, dtype=np.float64)
    if a.shape != b.shape:
        raise ValueError(f"{what}: image shapes differ: {a.shape} vs {b.shape}")
    if not (np.isfinite(a).all() and np.isfinite(b).all()):
        raise ValueError(f"{what}: images contain NaN or Inf")
    return a, b


def psnr(a, b, data_range: float = 1.0) -> float:
    """PSNR in dB between images of equal shape (+inf when identical)."""
    a, b = _pair(a, b, "psnr")
    mse = float(np.mean((a - b) ** 2))
    return math.inf if mse == 0 else 10.0 * math.log10(data_range**2 / mse)


def ssim(a, b, data_range: float = 1.0) -> float:
    """SSIM of images [H,W,C] or [H,W] (skimage: gaussian_weights, sigma 1.5, population covariance)."""
    from skimage.metrics import structural_similarity

    a, b = _pair(a, b, "ssim")
    if min(a.shape[:2]) < 7:
        raise ValueError(f"ssim: images of {a.shape[:2]} are smaller than the 7x7 minimum")
    return float(structural_similarity(a, b, data_range=data_range, gaussian_weights=True, sigma=1.5,
                                       use_sample_covariance=False,
                                       channel_axis=-1 if a.ndim == 3 else None))


def mean_finite(values: list[float]) -> float:
    """Mean of values; +inf entries (identical images) are capped at 100 dB so the mean stays finite."""
    if not values:
        return math.nan
    return float(np.mean([min(v, 100.0) for v in values]))
