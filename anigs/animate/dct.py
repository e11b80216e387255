"""The paper's DCT basis over T frames and the smooth amplitude limits of the deformation
(:mod:`anigs.animate.deform` has the formulas and why)."""
from __future__ import annotations

import math

import torch

_MIN_LIMIT = 1e-6


def max_num_bases(num_frames: int) -> int:
    """Largest usable K for T frames: T - 1 (k = T vanishes on integer frames)."""
    return max(int(num_frames) - 1, 0)


def dct_basis(t: torch.Tensor | float | int, num_frames: int, num_bases: int,
              dtype: torch.dtype = torch.float32, device: torch.device | str | None = None) -> torch.Tensor:
    """The paper's DCT basis.

    Args:
        t: frame index (scalar, or tensor [B]); fractional values allowed.
        num_frames: T; num_bases: K.
    Returns:
        [K] for scalar t, [B,K] for t of shape [B]:
        ``sqrt(2/(K+1)) * cos(pi/(2T) * (2t+1) * k)`` for k = 1..K.
    """
    t = torch.as_tensor(t, dtype=torch.float64, device=device)
    k = torch.arange(1, num_bases + 1, dtype=torch.float64, device=t.device)
    b = math.sqrt(2.0 / (num_bases + 1)) * torch.cos(math.pi / (2 * num_frames) * (2 * t[..., None] + 1) * k)
    return b.to(dtype)


def _safe_norm_sq(x: torch.Tensor) -> torch.Tensor:
    return (x * x).sum(-1, keepdim=True)


def soft_limit(x: torch.Tensor, limit: torch.Tensor) -> torch.Tensor:
    """Smoothly squash vectors x [...,3] to norm < limit [...] (``L tanh(|x|/L) x/|x|``).

    Identity to first order for |x| << L, exactly 0 at x = 0, finite gradients everywhere.
    """
    L = limit.clamp_min(_MIN_LIMIT)[..., None]
    u2 = _safe_norm_sq(x) / (L * L)
    small = u2 < 1e-6
    u = torch.sqrt(torch.where(small, torch.ones_like(u2), u2))
    scale = torch.where(small, 1.0 - u2 / 3.0, torch.tanh(u) / u)
    return x * scale


def offset_limits(canonical_means: torch.Tensor, dynamic_index: torch.Tensor,
                  max_offset_frac: float | None = None, max_offset_abs: float | None = None,
                  anchors: torch.Tensor | None = None) -> torch.Tensor | None:
    """Per-dynamic-Gaussian offset limit [D] (None when no limit is configured).

    ``L = min(frac * |mu - anchor|, abs)``; anchors [D,3] default to the ground points (x, y, 0).
    """
    if max_offset_frac is None and max_offset_abs is None:
        return None
    mu = canonical_means.detach()[dynamic_index]
    lim = torch.full((mu.shape[0],), float("inf"), dtype=mu.dtype, device=mu.device)
    if max_offset_frac is not None:
        if max_offset_frac <= 0:
            raise ValueError(f"max_offset_frac must be > 0, got {max_offset_frac}")
        if anchors is None:
            anchors = torch.cat([mu[:, :2], torch.zeros_like(mu[:, :1])], 1)
        lim = torch.minimum(lim, max_offset_frac * (mu - anchors).norm(dim=1))
    if max_offset_abs is not None:
        if max_offset_abs <= 0:
            raise ValueError(f"max_offset_abs must be > 0, got {max_offset_abs}")
        lim = lim.clamp_max(float(max_offset_abs))
    return lim.clamp_min(_MIN_LIMIT)
