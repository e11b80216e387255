"""Optical flow and backward warping helpers (OpenCV DIS + ``cv2.remap``).

Convention used everywhere in anigs: a *displacement field* ``d`` [H,W,2] (x, y in pixels)
is a **backward** map: the warped image is ``out(p) = src(p + d(p))``. With this convention
``d = 0`` is the identity and a frame ``t`` of an animated clip is ``frame_0`` sampled at
``p + d_t(p)``. :func:`backward_flow` estimates exactly this field between two frames.
"""
from __future__ import annotations

import cv2
import numpy as np

PRESETS = {"ultrafast": cv2.DISOPTICAL_FLOW_PRESET_ULTRAFAST,
            "fast": cv2.DISOPTICAL_FLOW_PRESET_FAST,
            "medium": cv2.DISOPTICAL_FLOW_PRESET_MEDIUM}


def _gray_u8(image: np.ndarray) -> np.ndarray:
    img = np.asarray(image, dtype=np.float32)
    if img.ndim == 3:
        img = cv2.cvtColor(np.ascontiguousarray(img[..., :3]), cv2.COLOR_RGB2GRAY)
    return (np.clip(img, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


def backward_flow(frame_t: np.ndarray, frame_0: np.ndarray, preset: str = "medium") -> np.ndarray:
    """DIS flow [H,W,2] such that ``frame_t(p) ≈ frame_0(p + d(p))``.

    Frames are float [H,W,3] (or [H,W]) in [0,1]. ``preset``: ultrafast | fast | medium.
    """
    if preset not in PRESETS:
        raise ValueError(f"unknown DIS preset {preset!r}; choose one of {sorted(PRESETS)}")
    a, b = _gray_u8(frame_t), _gray_u8(frame_0)
    if a.shape != b.shape:
        raise ValueError(f"frame sizes differ: {a.shape} vs {b.shape}")
    dis = cv2.DISOpticalFlow_create(PRESETS[preset])
    flow = dis.calc(a, b, None)
    return flow.astype(np.float32)


def clip_backward_flow(clip: np.ndarray, preset: str = "medium") -> np.ndarray:
    """Displacement of every frame w.r.t. frame 0: [T,H,W,2], ``d[0] = 0``.

    ``clip[t](p) ≈ clip[0](p + d[t](p))``.
    """
    T, H, W, _ = clip.shape
    out = np.zeros((T, H, W, 2), np.float32)
    for t in range(1, T):
        out[t] = backward_flow(clip[t], clip[0], preset)
    return out


def identity_grid(height: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    """Pixel coordinate maps (x [H,W], y [H,W]) as float32, integer pixel indices."""
    xs = np.arange(width, dtype=np.float32)
    ys = np.arange(height, dtype=np.float32)
    gx, gy = np.meshgrid(xs, ys)
    return gx, gy


def warp(image: np.ndarray, disp: np.ndarray, grid: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """Backward warp: ``out(p) = image(p + disp(p))`` with bilinear sampling, border replicated.

    image [H,W,C] float32, disp [H,W,2]. Where ``disp`` is exactly 0 the output equals the
    input bit for bit (integer sample positions).
    """
    H, W = image.shape[:2]
    if disp.shape != (H, W, 2):
        raise ValueError(f"displacement shape {disp.shape} does not match image {image.shape[:2]} (+2)")
    gx, gy = grid if grid is not None else identity_grid(H, W)
    mx = (gx + disp[..., 0]).astype(np.float32)
    my = (gy + disp[..., 1]).astype(np.float32)
    return cv2.remap(np.ascontiguousarray(image, dtype=np.float32), mx, my, cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_REPLICATE)


def field_gradient_max(disp: np.ndarray) -> float:
    """Largest spatial finite difference (px per px) of a displacement field [...,H,W,2]."""
    gx = np.abs(np.diff(disp, axis=-2)).max() if disp.shape[-2] > 1 else 0.0
    gy = np.abs(np.diff(disp, axis=-3)).max() if disp.shape[-3] > 1 else 0.0
    return float(max(gx, gy))
