"""Quaternions (w, x, y, z), the one home of the library's rotation helpers.

torch: :func:`quat_to_rotmat` (any norm; zero -> identity), :func:`quat_multiply` (Hamilton
product), :func:`axis_angle_to_quat` (exponential map, exact identity at zero); numpy:
:func:`quat_from_matrix`.
"""
from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F


def quat_to_rotmat(quats: torch.Tensor) -> torch.Tensor:
    """Rotation matrices [N,3,3] from quaternions [N,4] (w,x,y,z, any norm).

    A zero quaternion maps to the identity, with a finite (zero) gradient.
    """
    q = F.normalize(quats, dim=-1, eps=1e-12)
    w, x, y, z = q.unbind(-1)
    R = torch.stack([
        1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
        2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
        2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
    ], dim=-1)
    return R.reshape(quats.shape[:-1] + (3, 3))


def quat_multiply(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Hamilton product a (x) b of quaternions [...,4] (w,x,y,z)."""
    aw, ax, ay, az = a.unbind(-1)
    bw, bx, by, bz = b.unbind(-1)
    return torch.stack([
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    ], -1)


def axis_angle_to_quat(w: torch.Tensor) -> torch.Tensor:
    """Exponential map so(3) -> unit quaternion (w,x,y,z): [...,3] -> [...,4].

    Exactly (1,0,0,0) at w = 0, with finite gradients there (Taylor branch).
    """
    th2 = (w * w).sum(-1, keepdim=True)
    small = th2 < 1e-8
    th = torch.sqrt(torch.where(small, torch.ones_like(th2), th2))
    c = torch.where(small, 1.0 - th2 / 8.0, torch.cos(th / 2))
    s = torch.where(small, 0.5 - th2 / 48.0, torch.sin(th / 2) / th)
    return torch.cat([c, w * s], -1)


def quat_from_matrix(R: np.ndarray) -> np.ndarray:
    """Rotation matrices [N,3,3] -> unit quaternions [N,4] (w,x,y,z)."""
    R = np.asarray(R, np.float64).reshape(-1, 3, 3)
    w = np.sqrt(np.clip(1 + R[:, 0, 0] + R[:, 1, 1] + R[:, 2, 2], 0, None)) / 2
    x = np.sqrt(np.clip(1 + R[:, 0, 0] - R[:, 1, 1] - R[:, 2, 2], 0, None)) / 2
    y = np.sqrt(np.clip(1 - R[:, 0, 0] + R[:, 1, 1] - R[:, 2, 2], 0, None)) / 2
    z = np.sqrt(np.clip(1 - R[:, 0, 0] - R[:, 1, 1] + R[:, 2, 2], 0, None)) / 2
    x = np.copysign(x, R[:, 2, 1] - R[:, 1, 2])
    y = np.copysign(y, R[:, 0, 2] - R[:, 2, 0])
    z = np.copysign(z, R[:, 1, 0] - R[:, 0, 1])
    q = np.stack([w, x, y, z], 1)
    return q / np.linalg.norm(q, axis=1, keepdims=True)
