"""Planar structure of a point cloud: normals, plane costs of candidate up directions, observed points."""
from __future__ import annotations

import logging
import math
from typing import Sequence

import numpy as np

from anigs.cameras import Camera

log = logging.getLogger("anigs.geometry")


def point_normals(points: np.ndarray, max_points: int = 4000, k: int = 12,
                  seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(positions [M,3], local normals [M,3], planarity weights [M] in [0,1]) of a subsample of ``points`` [N,3].

    PCA of each point's ``k`` nearest neighbours: the normal is the smallest eigenvector and
    the weight ``(l2 - l3) / l1`` is high on planar patches (ground, walls), low on foliage.
    """
    from scipy.spatial import cKDTree

    P = np.asarray(points, np.float64)
    P = P[np.isfinite(P).all(1)]
    if len(P) < k + 1:
        return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0)
    rng = np.random.default_rng(seed)
    if len(P) > max_points:
        P = P[np.sort(rng.choice(len(P), max_points, replace=False))]
    _, idx = cKDTree(P).query(P, k=k)
    nb = P[idx] - P[idx].mean(1, keepdims=True)
    cov = np.einsum("mki,mkj->mij", nb, nb) / k
    w, v = np.linalg.eigh(cov)           # ascending eigenvalues
    normals = v[:, :, 0]
    planarity = (w[:, 1] - w[:, 0]) / np.maximum(w[:, 2], 1e-30)
    return P, normals, np.clip(planarity, 0.0, 1.0)


def plane_cost(dirs: np.ndarray, positions: np.ndarray, normals: np.ndarray, weights: np.ndarray,
               camera_centres: np.ndarray, tol_deg: float = 8.0, ground_share: float = 0.7) -> np.ndarray:
    """Cost [M] in [0,1] of candidate ups ``dirs`` [M,3] against planar patches.

    ``ground_share`` of it: 1 - the weight share of patches that are ground for that up (normal
    within ``tol_deg`` of it, below the lowest camera); the rest: 1 - the share of wall-like
    patches (normal horizontal); Gaussian kernels of width ``tol_deg``. The ground term is what tells up from a horizontal direction,
    and +up from -up, when the cameras cannot (sideways photos, all facing one way).
    """
    if len(normals) == 0 or weights.sum() <= 0:
        return np.zeros(len(dirs))
    c = np.clip(np.abs(dirs @ normals.T), 0.0, 1.0)                # [M,P]
    below = (dirs @ positions.T) < (dirs @ camera_centres.T).min(1, keepdims=True)
    tol = math.radians(tol_deg)
    ground = (np.exp(-(np.arccos(c) / tol) ** 2) * below) @ weights    # smooth: peaks at the exact normal
    wall = np.exp(-(np.arcsin(c) / tol) ** 2) @ weights
    W = weights.sum()
    return 1.0 - (ground_share * ground + (1 - ground_share) * wall) / W


def observed_points(points: np.ndarray, cameras: Sequence[Camera], min_views: int = 2) -> np.ndarray:
    """Bool [N]: points inside the image of at least ``min_views`` cameras (frustum only, no occlusion)."""
    P = np.asarray(points, np.float64)
    count = np.zeros(len(P), dtype=np.int64)
    for cam in cameras:
        uv, z = cam.project(P)
        with np.errstate(invalid="ignore"):
            count += ((z > 1e-6) & (uv[:, 0] >= 0) & (uv[:, 0] < cam.width) & (uv[:, 1] >= 0)
                      & (uv[:, 1] < cam.height))
    return count >= min_views
