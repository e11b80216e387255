"""Per-pixel helpers for RGB frames [H,W,3] and bool masks [H,W]: the frame check, colour
saturation, small-component morphology and the mask overlay of the contact sheets."""
from __future__ import annotations

import cv2
import numpy as np


def check_image(image: np.ndarray, name: str = "") -> np.ndarray:
    """Validate an RGB frame; return float32 [H,W,3] in [0,1]. NaN/Inf pixels are an error."""
    img = np.asarray(image)
    if img.ndim != 3 or img.shape[2] not in (3, 4) or img.shape[0] < 1 or img.shape[1] < 1:
        raise ValueError(f"frame {name!r}: expected an RGB image [H,W,3], got shape {img.shape}")
    if img.dtype == np.uint8:
        img = img.astype(np.float32) / 255.0
    img = img[..., :3].astype(np.float32)
    bad = ~np.isfinite(img)
    if bad.any():
        ys, xs = np.nonzero(bad.any(-1))
        raise ValueError(f"frame {name!r}: {len(ys)} pixels are NaN/Inf (first at x={xs[0]}, y={ys[0]}); "
                         "the rendered frame is broken, refusing to compute a mask")
    return np.clip(img, 0.0, 1.0)


def saturation(img: np.ndarray) -> np.ndarray:
    """HSV saturation (max-min)/max [H,W]."""
    mx, mn = img.max(-1), img.min(-1)
    return (mx - mn) / np.maximum(mx, 1e-6)


def remove_small(mask: np.ndarray, min_pixels: int) -> np.ndarray:
    """Drop 8-connected components with fewer than ``min_pixels`` pixels."""
    if min_pixels <= 1 or not mask.any():
        return mask
    n, lab, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
    keep = stats[:, cv2.CC_STAT_AREA] >= min_pixels
    keep[0] = False
    return keep[lab]


def fill_small_holes(mask: np.ndarray, max_pixels: int) -> np.ndarray:
    """Fill 4-connected background components not touching the border with <= ``max_pixels`` pixels."""
    if max_pixels <= 0 or mask.all():
        return mask
    inv = (~mask).astype(np.uint8)
    n, lab, stats, _ = cv2.connectedComponentsWithStats(inv, connectivity=4)
    h, w = mask.shape
    x, y, bw, bh = (stats[:, k] for k in (cv2.CC_STAT_LEFT, cv2.CC_STAT_TOP, cv2.CC_STAT_WIDTH, cv2.CC_STAT_HEIGHT))
    border = (x == 0) | (y == 0) | (x + bw == w) | (y + bh == h)
    fill = (stats[:, cv2.CC_STAT_AREA] <= max_pixels) & ~border
    fill[0] = False
    return mask | fill[lab]


def overlay(image: np.ndarray, mask: np.ndarray, colour=(1.0, 0.15, 0.6), strength: float = 0.5) -> np.ndarray:
    """RGB float [H,W,3]: the image with the mask tinted and its outline drawn."""
    img = check_image(image)
    m = np.asarray(mask, bool)
    out = img.copy()
    out[m] = (1 - strength) * out[m] + strength * np.asarray(colour, np.float32)
    edge = m.astype(np.uint8) - cv2.erode(m.astype(np.uint8), np.ones((3, 3), np.uint8))
    out[edge > 0] = colour
    return out


def dilate(mask: np.ndarray, px: int) -> np.ndarray:
    """Binary dilation of a boolean mask by ``px`` pixels (square structuring element)."""
    if px <= 0:
        return mask.astype(bool)
    k = np.ones((2 * px + 1, 2 * px + 1), np.uint8)
    return cv2.dilate(mask.astype(np.uint8), k) > 0
