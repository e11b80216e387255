"""A multi-view photometric loss for sparse captures: the render's depth must carry a neighbouring
training photo onto this one.

With few photos a fit can reproduce each training photo from splats at the wrong depth (a facade
drawn onto a needle a metre in front of it), and a photo it did not train on sees them smeared. The
render's expected depth of training photo ``i`` places each pixel in 3D; projected into a
neighbouring training photo ``j`` it picks up ``j``'s colour there, which must match photo ``i``'s
colour at the pixel when the depth is right. The loss is the mean L1 difference over the opaque pixels
that land inside ``j``, the per-pixel minimum over the neighbours (a pixel occluded in one neighbour
is usually seen by another: Monodepth2's minimum reprojection). Its gradient reaches the splats only
through the depth. Binocular3DGS (Han et al., NeurIPS 2024) trains sparse views with such a warp
between a photo and its nearest neighbour; this is the same loss without its learned matcher.
"""
from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F

from anigs.cameras import Camera
from anigs.static.evaluate import pixels

MIN_ALPHA = 0.5  # render alpha above which a pixel's depth is trusted


def nearest_views(cams: list[Camera], k: int, max_angle_deg: float = 60.0) -> list[list[int]]:
    """Per camera, its ``k`` nearest other cameras by centre whose viewing directions differ by at most
    ``max_angle_deg`` (fewer where fewer qualify)."""
    centres = np.stack([c.center for c in cams])
    fwd = np.stack([c.forward for c in cams])
    cos_max = np.cos(np.radians(max_angle_deg))
    out = []
    for i in range(len(cams)):
        d = np.linalg.norm(centres - centres[i], axis=1)
        out.append([int(j) for j in np.argsort(d, kind="stable") if j != i and fwd[i] @ fwd[j] >= cos_max][:k])
    return out


def _rays(cam: Camera, device: torch.device) -> torch.Tensor:
    """Camera-space rays [H*W,3] with z = 1 through the pixel centres (+0.5)."""
    v, u = torch.meshgrid(torch.arange(cam.height, device=device, dtype=torch.float32) + 0.5,
                          torch.arange(cam.width, device=device, dtype=torch.float32) + 0.5, indexing="ij")
    K = cam.K
    return torch.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], torch.ones_like(u)], -1).reshape(-1, 3)


class WarpLoss:
    """The warp loss of each training photo against its neighbours (images float [H,W,3] in [0,1] or
    uint8, all at the fit's size)."""

    def __init__(self, cams: list[Camera], neighbours: int, device: torch.device) -> None:
        self.cams, self.device = cams, device
        self.near = nearest_views(cams, neighbours)
        self.rays = [_rays(c, device) for c in cams]
        self.world = [torch.as_tensor(np.linalg.inv(c.viewmat), dtype=torch.float32, device=device) for c in cams]
        self.view = [torch.as_tensor(c.viewmat, dtype=torch.float32, device=device) for c in cams]
        self.K = [torch.as_tensor(c.K, dtype=torch.float32, device=device) for c in cams]

    def __call__(self, i: int, depth: torch.Tensor, alpha: torch.Tensor, target: torch.Tensor,
                 photos: list[torch.Tensor]) -> torch.Tensor:
        """The loss of training photo ``i`` (``target`` [H,W,3]) from its render's ``depth`` and ``alpha``
        [H,W]; ``photos``: every training photo as the fit keeps it. 0 (no gradient) without neighbours or
        opaque pixels."""
        if not self.near[i]:
            return depth.sum() * 0.0
        h, w = depth.shape
        pts = self.rays[i] * depth.reshape(-1, 1)  # camera i [P,3]
        world = pts @ self.world[i][:3, :3].T + self.world[i][:3, 3]
        opaque = (alpha.reshape(-1) > MIN_ALPHA) & (depth.reshape(-1) > 0)
        errs = []
        for j in self.near[i]:
            cam = self.cams[j]
            pj = world @ self.view[j][:3, :3].T + self.view[j][:3, 3]
            z = pj[:, 2]
            uv = (pj[:, :2] / z.clamp_min(1e-6)[:, None]) * torch.stack([self.K[j][0, 0], self.K[j][1, 1]]) + \
                torch.stack([self.K[j][0, 2], self.K[j][1, 2]])
            inside = (z > 1e-6) & (uv[:, 0] >= 0) & (uv[:, 0] <= cam.width) & (uv[:, 1] >= 0) & (uv[:, 1] <= cam.height)
            grid = torch.stack([2 * uv[:, 0] / cam.width - 1, 2 * uv[:, 1] / cam.height - 1], -1).reshape(1, h, w, 2)
            img = pixels(photos[j])
            warped = F.grid_sample(img.permute(2, 0, 1)[None], grid, mode="bilinear", padding_mode="border",
                                   align_corners=False)[0].permute(1, 2, 0).reshape(-1, 3)
            err = (warped - target.reshape(-1, 3)).abs().mean(-1)
            errs.append(torch.where(inside & opaque, err, torch.full_like(err, float("inf"))))
        best = torch.stack(errs).min(0).values
        ok = torch.isfinite(best)  # no host read: the fit reads the loss only every few steps
        return torch.where(ok, best, torch.zeros_like(best)).sum() / ok.sum().clamp_min(1)
