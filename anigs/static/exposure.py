"""Per-training-photo exposure of the static fit: an affine colour map (3x3 + 3) learned per photo.

Photos of a walk differ in exposure and white balance; a fit without a per-photo correction bakes
the differences into the splats (view-dependent colour, floaters in front of the brighter photos).
Each training photo ``v`` gets ``A_v`` [3,4] (identity at the start), the loss compares
``A_v [rgb, 1]`` with the photo, and the held-out evaluation and every render downstream use the
splats alone (the identity). Off unless ``static.exposure_lr`` > 0.
"""
from __future__ import annotations

from typing import Any

import torch


class Exposure:
    """The affine colour maps of ``n`` training photos, each its own parameter [3,4] (a photo not
    rendered in a step has no gradient and Adam leaves it as it is)."""

    def __init__(self, n: int, lr: float, device: torch.device | str = "cpu") -> None:
        eye = torch.cat([torch.eye(3), torch.zeros(3, 1)], 1).to(device)
        self.maps = [torch.nn.Parameter(eye.clone()) for _ in range(n)]
        self.optimizer = torch.optim.Adam(self.maps, lr=lr, eps=1e-15)

    def apply(self, rgb: torch.Tensor, v: int) -> torch.Tensor:
        """Photo ``v``'s colour map applied to a render [H,W,3] -> [H,W,3]."""
        a = self.maps[v]
        return rgb @ a[:, :3].T + a[:, 3]

    def step(self) -> None:
        """Adam step of the maps that received a gradient; clears them."""
        self.optimizer.step()
        self.optimizer.zero_grad(set_to_none=True)

    @torch.no_grad()
    def report(self) -> dict[str, Any]:
        """How far the maps moved: per training photo (in order), the mean gain (the diagonal) and offset."""
        return {"gains": [round(float(a[:, :3].diagonal().mean()), 4) for a in self.maps],
                "offsets": [round(float(a[:, 3].mean()), 4) for a in self.maps]}
