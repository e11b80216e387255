"""The reference SSIM (Gaussian window, sigma 1.5, size 11) for images [...,H,W,C] in [0,1], and PSNR.

Readable and differentiable through autograd; the oracle of the fused SSIM in the tests."""
from __future__ import annotations

import torch
import torch.nn.functional as F

C1, C2 = 0.01**2, 0.03**2  # stabilising constants for data range 1 (K1 = 0.01, K2 = 0.03)
WINDOW = 11  # the Gaussian window's size (pixels) and standard deviation, the 3DGS loss defaults
SIGMA = 1.5


def _window(size: int, sigma: float, channels: int, dtype, device) -> torch.Tensor:
    x = torch.arange(size, dtype=dtype, device=device) - (size - 1) / 2
    g = torch.exp(-(x**2) / (2 * sigma**2))
    g = g / g.sum()
    return (g[:, None] * g[None, :]).expand(channels, 1, size, size).contiguous()


def ssim(a: torch.Tensor, b: torch.Tensor, window: int = WINDOW, sigma: float = SIGMA, data_range: float = 1.0,
         reduce: bool = True) -> torch.Tensor:
    """SSIM between images a, b of shape [H,W,C] or [B,H,W,C] (channels last).

    Uses zero-padded 'same' convolution (the 3DGS training loss convention). For the
    evaluation metric use :func:`skimage.metrics.structural_similarity` semantics via
    ``anigs.metrics`` (valid window, explicit data range). This is the readable reference;
    the training loop uses :func:`anigs.ssim.fused.fused_ssim` (same value, hand-written
    backward, a fraction of the time).
    """
    if a.shape != b.shape:
        raise ValueError(f"ssim: shapes differ: {tuple(a.shape)} vs {tuple(b.shape)}")
    x = a if a.ndim == 4 else a[None]
    y = b if b.ndim == 4 else b[None]
    x, y = x.permute(0, 3, 1, 2), y.permute(0, 3, 1, 2)
    C = x.shape[1]
    w = _window(window, sigma, C, x.dtype, x.device)
    pad = window // 2
    mu_x = F.conv2d(x, w, padding=pad, groups=C)
    mu_y = F.conv2d(y, w, padding=pad, groups=C)
    sxx = F.conv2d(x * x, w, padding=pad, groups=C) - mu_x**2
    syy = F.conv2d(y * y, w, padding=pad, groups=C) - mu_y**2
    sxy = F.conv2d(x * y, w, padding=pad, groups=C) - mu_x * mu_y
    c1, c2 = C1 * data_range**2, C2 * data_range**2
    m = ((2 * mu_x * mu_y + c1) * (2 * sxy + c2)) / ((mu_x**2 + mu_y**2 + c1) * (sxx + syy + c2))
    return m.mean() if reduce else m.permute(0, 2, 3, 1)


def psnr(a: torch.Tensor, b: torch.Tensor, data_range: float = 1.0) -> float:
    """PSNR in dB (inf for identical images)."""
    mse = float(torch.mean((a.detach().double() - b.detach().double()) ** 2))
    return float("inf") if mse == 0 else 10.0 * float(torch.log10(torch.tensor(data_range**2 / mse)))
