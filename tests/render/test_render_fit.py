"""The rasterizer trains: a random Gaussian set learns to reproduce a target image."""
from __future__ import annotations

import torch

from anigs.render import rasterize
from anigs.ssim import psnr
from tests._scenes import random_scene


def test_fit_reaches_30db():
    W, H = 64, 48
    gt = random_scene(300, W, H, 0, seed=11)
    viewmat, K = gt[5], gt[6]
    with torch.no_grad():
        target, _, _ = rasterize(*gt[:5], viewmat, K, W, H)
    init = random_scene(600, W, H, 0, seed=12)
    means = init[0].clone().requires_grad_()
    quats = init[1].clone().requires_grad_()
    log_s = init[2].log().clone().requires_grad_()
    logit_o = torch.logit(init[3]).clone().requires_grad_()
    colors = torch.logit(init[4].clamp(0.05, 0.95)).clone().requires_grad_()
    opt = torch.optim.Adam([
        {"params": [means], "lr": 2e-3}, {"params": [quats], "lr": 1e-2}, {"params": [log_s], "lr": 1e-2},
        {"params": [logit_o], "lr": 5e-2}, {"params": [colors], "lr": 5e-2}])
    start = None
    for _ in range(600):
        rgb, _, _ = rasterize(means, quats, log_s.exp(), torch.sigmoid(logit_o), torch.sigmoid(colors), viewmat, K, W, H)
        loss = (rgb - target).abs().mean()
        if start is None:
            start = psnr(rgb, target)
        opt.zero_grad()
        loss.backward()
        opt.step()
    with torch.no_grad():
        rgb, _, _ = rasterize(means, quats, log_s.exp(), torch.sigmoid(logit_o), torch.sigmoid(colors), viewmat, K, W, H)
    final = psnr(rgb, target)
    assert final >= 30.0, (start, final)
    assert final > start + 10
