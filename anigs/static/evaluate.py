"""Render the static fit's parameter dict and evaluate it (PSNR, SSIM) on posed images."""
from __future__ import annotations

from typing import Sequence

import numpy as np
import torch

from anigs.cameras import Camera
from anigs.ssim import fused_ssim
from anigs.render import rasterize
from anigs.ssim import psnr


def render_params(params: dict[str, torch.Tensor], cam: Camera, sh_degree: int, bg: torch.Tensor, backend: str,
            mats: tuple[torch.Tensor, torch.Tensor] | None = None, keep: torch.Tensor | None = None):
    """Render the parameter dict; only the SH bands up to ``sh_degree`` are passed on (the others
    get zero gradients, as when the rasterizer ignores them). ``mats``: cached (viewmat, K).
    ``keep`` [N]: per-Gaussian opacity factors (0: left out; DropGaussian's compensation above 1), the
    result clamped to 1."""
    dev = params["means"].device
    k = (sh_degree + 1) ** 2
    sh = torch.cat([params["sh_dc"], params["sh_rest"][:, :k - 1]], 1)
    viewmat, K = mats if mats is not None else (cam.torch_viewmat(dev), cam.torch_K(dev))
    opacity = torch.sigmoid(params["opacity_logits"])
    if keep is not None:
        opacity = (opacity * keep).clamp(max=1.0)
    return rasterize(params["means"], params["quats"], params["log_scales"].exp(), opacity, sh, viewmat, K,
                     cam.width, cam.height, sh_degree=sh_degree, background=bg, backend=backend)


def loss_fn(pred: torch.Tensor, target: torch.Tensor, ssim_weight: float) -> torch.Tensor:
    """``(1-w) L1 + w (1 - SSIM)`` for images [H,W,3] (SSIM: :func:`anigs.ssim.fused_ssim`)."""
    l1 = (pred - target).abs().mean()
    if ssim_weight == 0:
        return l1
    return (1 - ssim_weight) * l1 + ssim_weight * (1 - fused_ssim(pred, target))


@torch.no_grad()
def stored_image(img: torch.Tensor, device) -> torch.Tensor:
    """An input image as the fit keeps it: uint8 [H,W,3] stays uint8 (a quarter of the memory of
    float32: every photo is held for the whole fit), anything else float32 clamped to [0,1]."""
    if img.dtype == torch.uint8:
        return img.detach().to(device)
    return img.detach().float().clamp(0, 1).to(device)


def pixels(img: torch.Tensor) -> torch.Tensor:
    """Float32 [H,W,3] in [0,1] of a stored image (uint8 / 255: the values :func:`anigs.images.load_image` gives)."""
    return img.float() / 255.0 if img.dtype == torch.uint8 else img


def evaluate(params: dict[str, torch.Tensor], images: Sequence[torch.Tensor], cameras: Sequence[Camera],
             sh_degree: int, bg: torch.Tensor, backend: str) -> dict[str, float]:
    """Mean PSNR (dB) and SSIM over the given views (NaN when there are none)."""
    if not images:
        return {"psnr": float("nan"), "ssim": float("nan"), "views": 0}
    ps, ss = [], []
    for img, cam in zip(images, cameras):
        img = pixels(img)
        rgb, _, _ = render_params(params, cam, sh_degree, bg, backend)
        rgb = rgb.clamp(0, 1)
        ps.append(psnr(rgb, img))
        ss.append(float(fused_ssim(rgb, img)))
    return {"psnr": float(np.mean(ps)), "ssim": float(np.mean(ss)), "views": len(images)}
