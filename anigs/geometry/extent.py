"""How big a scene is: the two length scales the library uses.

:func:`scene_extent` (the 3DGS convention, from the cameras) scales the static fit's learning rates
and densification; :func:`box_diagonal` (a robust box of the positions) scales the model update's.
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np
import torch

from anigs.cameras import Camera


def scene_extent(cameras: Sequence[Camera], points: np.ndarray | None = None) -> float:
    """3DGS scene radius (the static fit's length scale): 1.1 x the largest camera distance from the
    mean camera centre.

    Falls back to the point cloud's radius (then 1.0) when the cameras all coincide.
    """
    centers = np.stack([c.center for c in cameras])
    r = float(np.linalg.norm(centers - centers.mean(0), axis=1).max()) * 1.1
    if r < 1e-6 and points is not None and len(points) > 1:
        r = float(np.linalg.norm(points - points.mean(0), axis=1).max())
    return r if r > 1e-6 else 1.0


def box_diagonal(means: torch.Tensor) -> float:
    """Robust size of a set of positions [N,3]: the diagonal of their 1-99 percentile box (the
    length scale of the model update's position learning rates)."""
    if means.shape[0] < 2:
        return 1.0
    m = means.detach().float().cpu()
    lo, hi = torch.quantile(m, 0.01, dim=0), torch.quantile(m, 0.99, dim=0)
    ext = float((hi - lo).norm())
    return ext if math.isfinite(ext) and ext > 0 else 1.0
