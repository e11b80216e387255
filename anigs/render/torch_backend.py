"""Pure-PyTorch compositing: the readable reference the fast kernels are tested against.

Semantics (shared with the ``cpu`` kernel): Gaussians arrive sorted front to back; a
Gaussian touches the pixels whose centres lie in its box ``rect``; per pixel
``alpha = min(0.99, o * exp(-0.5 d^T Q d))`` with d = pixel centre - mean and Q the conic;
alpha < 1/255 is skipped; compositing stops before the splat that would push the
transmittance to <= 1e-4.
"""
from __future__ import annotations

import torch

from anigs.render.projection import ALPHA_MAX, ALPHA_MIN, T_MIN


def composite_torch(
    means2d: torch.Tensor, conics: torch.Tensor, feats: torch.Tensor, opacities: torch.Tensor,
    rects: torch.Tensor, width: int, height: int,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Front-to-back alpha compositing of M depth-sorted splats.

    Args: means2d [M,2], conics [M,3], feats [M,C], opacities [M], rects [M,4] int (x0,y0,x1,y1).
    Returns: accumulated features [H,W,C] (no background) and final transmittance [H,W].
    """
    dev, dtype = means2d.device, means2d.dtype
    M, C = feats.shape
    P = width * height
    rects = rects.long()
    w = (rects[:, 2] - rects[:, 0]).clamp_min(0)
    h = (rects[:, 3] - rects[:, 1]).clamp_min(0)
    n = w * h
    total = int(n.sum())
    if M == 0 or total == 0:
        # keep every input in the graph so callers get (zero) gradients, as from the cpu kernel
        link = 0 * (means2d.sum() + conics.sum() + feats.sum() + opacities.sum())
        return feats.new_zeros(height, width, C) + link, torch.ones(height, width, dtype=dtype, device=dev) + link

    # (pixel, gaussian) pairs for every pixel inside each Gaussian's box.
    g = torch.repeat_interleave(torch.arange(M, device=dev), n)
    start = torch.cumsum(n, 0) - n
    local = torch.arange(total, device=dev) - start[g]
    px = rects[g, 0] + local % w[g]
    py = rects[g, 1] + torch.div(local, w[g], rounding_mode="floor")
    pix = py * width + px
    order = torch.argsort(pix * M + g)  # by pixel, then depth rank
    g, px, py, pix = g[order], px[order], py[order], pix[order]
    counts = torch.bincount(pix, minlength=P)
    pos = torch.arange(total, device=dev) - (torch.cumsum(counts, 0) - counts)[pix]
    L = int(counts.max())

    dx = (px.to(dtype) + 0.5) - means2d[g, 0]
    dy = (py.to(dtype) + 0.5) - means2d[g, 1]
    a, b, c = conics[g].unbind(-1)
    power = -0.5 * (a * dx * dx + c * dy * dy) - b * dx * dy
    alpha = torch.clamp(opacities[g] * torch.exp(power), max=ALPHA_MAX)
    alpha = torch.where((alpha >= ALPHA_MIN) & (power <= 0), alpha, torch.zeros_like(alpha))

    A = torch.zeros(P, L, dtype=dtype, device=dev).index_put((pix, pos), alpha)
    T_incl = torch.cumprod(1 - A, dim=1)  # transmittance after each splat
    keep = T_incl > T_MIN  # a prefix of each row: stop before the splat crossing the floor
    T_excl = torch.cat([torch.ones_like(T_incl[:, :1]), T_incl[:, :-1]], dim=1)
    weights = (A * T_excl * keep)[pix, pos]  # [total]
    out = torch.zeros(P, C, dtype=dtype, device=dev).index_add(0, pix, weights[:, None] * feats[g])
    T_final = torch.cumprod(torch.where(keep, 1 - A, torch.ones_like(A)), dim=1)[:, -1]
    return out.reshape(height, width, C), T_final.reshape(height, width)
