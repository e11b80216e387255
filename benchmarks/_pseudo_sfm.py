"""Pseudo-SfM points of a synthetic capture, for the benchmarks that fit without running COLMAP.

    from _pseudo_sfm import pseudo_sfm_points   # benchmarks/ is on sys.path when a script runs
"""
from __future__ import annotations

import numpy as np


def pseudo_sfm_points(cap) -> tuple[np.ndarray, np.ndarray]:
    """(points float64 [P,3], colours float32 [P,3]) from the capture stage's ``Outputs`` ``cap``: every
    sixth ground-truth Gaussian's mean jittered by N(0, 0.02) (seed 0), and its colour in [0, 1]."""
    g = cap.gt_gaussians()
    rng = np.random.default_rng(0)
    pts = g.means.numpy()[::6].astype(np.float64)
    pts = pts + rng.normal(0, 0.02, pts.shape)
    return pts, g.rgb.clamp(0, 1).numpy()[::6]
