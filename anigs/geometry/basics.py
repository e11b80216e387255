"""Vector basics of scene geometry: unit vectors, angles, horizontal bases, camera axes."""
from __future__ import annotations

import logging
import math
from typing import Sequence

import numpy as np

from anigs.cameras import Camera

log = logging.getLogger("anigs.geometry")

Z_UP = np.array([0.0, 0.0, 1.0])


def unit(v: np.ndarray, eps: float = 1e-12) -> np.ndarray:
    """``v`` [...,3] normalised along the last axis (zero vectors stay zero)."""
    v = np.asarray(v, np.float64)
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.maximum(n, eps)


def angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    """Angle in degrees between directions ``a`` [3] and ``b`` [3]."""
    return math.degrees(math.acos(float(np.clip(unit(a) @ unit(b), -1.0, 1.0))))


def horizontal_basis(up: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors (e1, e2) spanning the plane orthogonal to ``up``, with e1 x e2 = up."""
    up = np.asarray(up, np.float64)
    ref = np.array([1.0, 0, 0]) if abs(up[0]) < 0.9 else np.array([0, 1.0, 0])
    e1 = ref - up * (ref @ up)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(up, e1)
    return e1, e2


def fibonacci_sphere(n: int) -> np.ndarray:
    """``n`` nearly uniform unit directions [n,3] (deterministic)."""
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    r = np.sqrt(np.clip(1 - z * z, 0, None))
    phi = math.pi * (3 - math.sqrt(5)) * i
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], 1)


def camera_axes(cameras: Sequence[Camera]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(x [C,3], y [C,3], forward [C,3]) world directions of the cameras' image axes."""
    R = np.stack([c.R for c in cameras]).astype(np.float64)
    return R[:, 0], R[:, 1], R[:, 2]


def roll_axes(cameras: Sequence[Camera]) -> tuple[np.ndarray, np.ndarray]:
    """Per camera and roll k (0, 90, 180, 270 deg): image-up axis [C,4,3] and horizontal axis [C,4,3].

    Roll k means the world up appears along image -y (k=0), +x (1), +y (2), -x (3).
    """
    x, y, _ = camera_axes(cameras)
    a = np.stack([-y, x, y, -x], 1)
    h = np.stack([x, y, x, y], 1)
    return a, h
