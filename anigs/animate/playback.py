"""Playing the animated scene back: ping-pong loop times, a smooth camera path through the
capture cameras, and space-time slices of the most animated patch (the paper's x-t / y-t figures)."""
from __future__ import annotations

import numpy as np
import torch
from scipy.spatial.transform import Rotation, Slerp

from anigs.cameras import Camera


def pingpong_times(n: int, period: int, speed: float = 1.0) -> torch.Tensor:
    """n frame times in [0, period-1] that play forward then backward (a seamless loop: the
    DCT motion is even-symmetric in time, so wrapping from T-1 to 0 would jump)."""
    if period <= 1:
        return torch.zeros(n, dtype=torch.float64)
    u = torch.arange(n, dtype=torch.float64) * speed
    phase = torch.remainder(u, 2 * (period - 1))
    return torch.where(phase <= period - 1, phase, 2 * (period - 1) - phase)


def moving_camera_path(cameras: list[Camera], num_frames: int, num_keys: int = 6) -> list[Camera]:
    """Smooth path through ``num_keys`` evenly picked cameras (positions: Catmull-Rom-free linear
    interpolation in arc length, rotations: slerp). Returns ``num_frames`` cameras."""
    if not cameras:
        raise ValueError("moving_camera_path: no cameras")
    if num_frames < 1:
        raise ValueError(f"moving_camera_path: num_frames must be >= 1, got {num_frames}")
    idx = np.unique(np.linspace(0, len(cameras) - 1, max(2, min(num_keys, len(cameras)))).round().astype(int))
    keys = [cameras[i] for i in idx]
    if len(keys) == 1:
        return [keys[0]] * num_frames
    centers = np.stack([c.center for c in keys])
    seg = np.linalg.norm(np.diff(centers, axis=0), axis=1)
    s = np.concatenate([[0], np.cumsum(seg)])
    s = s / s[-1] if s[-1] > 0 else np.linspace(0, 1, len(keys))
    s = np.maximum.accumulate(s + np.arange(len(s)) * 1e-9)
    slerp = Slerp(s, Rotation.from_matrix(np.stack([c.R for c in keys])))
    out = []
    for u in np.linspace(0, 1, num_frames):
        c = np.array([np.interp(u, s, centers[:, k]) for k in range(3)])
        R = slerp([u]).as_matrix()[0]
        V = np.eye(4)
        V[:3, :3] = R
        V[:3, 3] = -R @ c
        out.append(Camera(keys[0].K.copy(), V, keys[0].width, keys[0].height, f"path{len(out):04d}"))
    return out


def most_animated_row_col(clip: np.ndarray, mask: np.ndarray | None = None) -> tuple[int, int, float]:
    """Row and column with the largest temporal standard deviation (inside ``mask`` when given).

    clip [T,H,W,3] -> (row, col, peak std)."""
    std = clip.std(axis=0).mean(-1)  # [H,W]
    if mask is not None and mask.any():
        std = np.where(mask, std, 0)
    row = int(std.sum(1).argmax())
    col = int(std.sum(0).argmax())
    return row, col, float(std.max())


def slice_images(clip: np.ndarray, row: int, col: int, upsample: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """x-t slice [T*up, W, 3] (row over time) and y-t slice [H, T*up, 3] (column over time)."""
    xt = np.repeat(clip[:, row], upsample, axis=0)
    yt = np.repeat(clip[:, :, col].transpose(1, 0, 2), upsample, axis=1)
    return xt, yt


def highlight(frame: np.ndarray, row: int, col: int, color=(1.0, 0.1, 0.1)) -> np.ndarray:
    """First frame with the sliced row and column drawn in."""
    out = frame.copy()
    out[row, :] = color
    out[:, col] = color
    return out


def static_change(clip: np.ndarray, mask: np.ndarray | None) -> float:
    """Largest absolute change from frame 0 outside the dynamic mask (0 = perfectly still)."""
    diff = np.abs(clip - clip[:1]).max(axis=(0, 3))  # [H,W]
    if mask is not None:
        diff = np.where(mask, 0, diff)
    return float(diff.max())

