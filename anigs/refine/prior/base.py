"""Video prior interface.

A prior turns a camera-fixed clip into an animated one. Clips are float32 numpy arrays
[T,H,W,3] in [0,1]; masks are [H,W] in [0,1] (0 = static) or a dict ``{effect: [H,W]}``
when a scene lists several effect types.

- ``refine(clip, mask, prompt, seed, strength) -> clip``: video-to-video refinement
  (``strength`` 0 keeps the clip, 1 replaces its motion / fully re-noises it).
- ``generate(first_frame, mask, prompt, seed, num_frames) -> clip``: image-to-video.
- ``sds_loss(rendered_subclip, prompt, generator) -> scalar``: only for backends with a
  score (``has_score = True``); ``rendered_subclip`` is a torch tensor [T,H,W,3] that
  carries gradients to the renderer.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Mapping, Union

import numpy as np

MaskLike = Union[np.ndarray, Mapping[str, np.ndarray]]


def check_prior_mask(mask: np.ndarray, height: int, width: int, what: str = "mask") -> np.ndarray:
    """Validate a mask against a frame size; return float32 [H,W] in [0,1]."""
    m = np.asarray(mask)
    if m.ndim == 3 and m.shape[-1] in (1, 3, 4):
        m = m[..., 0]
    if m.ndim != 2:
        raise ValueError(f"{what}: expected [H,W], got shape {m.shape}")
    if m.shape != (height, width):
        raise ValueError(f"{what}: size {m.shape[1]}x{m.shape[0]} (WxH) does not match the clip "
                         f"{width}x{height}")
    m = m.astype(np.float32)
    if m.size and m.max() > 1.0:
        m = m / 255.0
    if not np.isfinite(m).all():
        raise ValueError(f"{what}: contains NaN or Inf")
    return np.clip(m, 0.0, 1.0)


def union_mask(mask: MaskLike, height: int, width: int) -> np.ndarray:
    """One [H,W] mask from a mask or a dict of per-effect masks (pixel-wise max)."""
    if isinstance(mask, Mapping):
        out = np.zeros((height, width), np.float32)
        for name, m in mask.items():
            out = np.maximum(out, check_prior_mask(m, height, width, f"mask[{name!r}]"))
        return out
    return check_prior_mask(mask, height, width)


class VideoPrior(ABC):
    """Base class of the video priors (see module docstring for shapes)."""

    name: str = "base"
    has_score: bool = False

    @abstractmethod
    def refine(self, clip: np.ndarray, mask: MaskLike, prompt: str, seed: int, strength: float) -> np.ndarray:
        """Refine a clip [T,H,W,3] -> [T,H,W,3] (same shape, float32 in [0,1])."""

    @abstractmethod
    def generate(self, first_frame: np.ndarray, mask: MaskLike, prompt: str, seed: int,
                 num_frames: int) -> np.ndarray:
        """Animate one frame [H,W,3] -> clip [num_frames,H,W,3] whose frame 0 is the input."""

    def sds_loss(self, rendered_subclip, prompt: str, generator=None):
        """Score-distillation loss of a rendered clip (torch [T,H,W,3]) -> scalar tensor."""
        raise NotImplementedError(f"video prior {self.name!r} has no score: it cannot provide an SDS loss "
                                  "(set lambda_sds: 0 or use prior: ltx)")


def check_strength(strength: float) -> float:
    s = float(strength)
    if not (0.0 <= s <= 1.0) or not np.isfinite(s):
        raise ValueError(f"strength must be in [0, 1], got {strength!r}")
    return s
