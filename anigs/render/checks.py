"""Input checks shared by the rasterizer front and its backends: shapes, finite values, ranges."""
from __future__ import annotations

import torch


def _check_inputs(named: dict[str, torch.Tensor]) -> None:
    for name, t in named.items():
        if not torch.is_tensor(t):
            raise TypeError(f"rasterize: {name} must be a tensor, got {type(t).__name__}")
        if t.numel() and not torch.isfinite(t).all():
            bad = int((~torch.isfinite(t.detach())).sum())
            raise ValueError(f"rasterize: input {name!r} contains {bad} non-finite values (NaN or Inf)")


def validate(named: dict[str, torch.Tensor]) -> None:
    """Finite inputs, scales >= 0, opacities in [0,1]; raises a ValueError naming the culprit."""
    _check_inputs(named)
    scales, opacities = named["scales"], named["opacities"]
    if bool((scales < 0).any()) or bool((opacities < 0).any()) or bool((opacities > 1).any()):
        raise ValueError("rasterize: scales must be >= 0 and opacities in [0,1] (pass activated values)")


def check_inputs(what: str, means: torch.Tensor, quats: torch.Tensor, scales: torch.Tensor,
                 opacities: torch.Tensor, width, height) -> tuple[int, int, int]:
    """Check the image size and the shapes of a splat set (means [N,3], quats [N,4], scales [N,3],
    opacities [N]); returns (width, height, N). ``what`` names the caller in the error."""
    width, height = int(width), int(height)
    if width < 1 or height < 1:
        raise ValueError(f"{what}: image size must be >= 1x1, got {width}x{height}")
    n = means.shape[0]
    if means.shape != (n, 3) or quats.shape != (n, 4) or scales.shape != (n, 3) or opacities.shape != (n,):
        raise ValueError(f"{what}: shape mismatch: means {tuple(means.shape)}, quats {tuple(quats.shape)}, "
                         f"scales {tuple(scales.shape)}, opacities {tuple(opacities.shape)} (N={n})")
    return width, height, n
