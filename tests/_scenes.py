"""Random Gaussian scenes shared by the rasterizer tests and benchmarks."""
from __future__ import annotations

import math

import torch

from anigs.cameras import intrinsics_from_fov


def random_scene(n: int, width: int, height: int, sh_degree: int = 0, seed: int = 0, fov: float = 60.0,
                 dtype=torch.float32):
    """n Gaussians in a 2x2x2 cube 4 units in front of an identity camera.

    Returns (means, quats, scales, opacities, colors_or_sh, viewmat, K).
    """
    g = torch.Generator().manual_seed(seed)
    means = torch.rand(n, 3, generator=g) * 2 - 1
    means[:, 2] += 4
    quats = torch.randn(n, 4, generator=g)
    scales = torch.exp(torch.empty(n, 3).uniform_(math.log(0.01), math.log(0.05), generator=g))
    opac = torch.empty(n).uniform_(0.1, 0.9, generator=g)
    if sh_degree is None or sh_degree == 0:
        colors = torch.rand(n, 3, generator=g)
    else:
        colors = torch.randn(n, (sh_degree + 1) ** 2, 3, generator=g) * 0.3
    K = torch.tensor(intrinsics_from_fov(fov, width, height))
    out = (means, quats, scales, opac, colors, torch.eye(4, dtype=torch.float64), K)
    return tuple(t.to(dtype) for t in out)
