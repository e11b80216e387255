"""A tiny random-weight 3D-conv network with the I3D TorchScript call convention
(``net(x, rescale=..., resize=..., return_features=True)``, x float [B,3,T,H,W] -> [B,400]):
the tests' stand-in for the Kinetics-400 I3D (no weights offline in tests)."""
from __future__ import annotations

import torch
from torch import nn


class TinyI3D(nn.Module):
    """Two strided 3D convolutions, global average pooling and a linear layer to ``dim`` features."""

    def __init__(self, dim: int = 400, seed: int = 0):
        super().__init__()
        torch.manual_seed(seed)
        self.c1 = nn.Conv3d(3, 8, (3, 7, 7), stride=(1, 4, 4), padding=(1, 3, 3))
        self.c2 = nn.Conv3d(8, 16, 3, stride=2, padding=1)
        self.fc = nn.Linear(32, dim)
        self.eval()

    def forward(self, x: torch.Tensor, rescale: bool = False, resize: bool = False,
                return_features: bool = True) -> torch.Tensor:
        if rescale:
            x = x / 127.5 - 1.0
        h = torch.relu(self.c2(torch.relu(self.c1(x))))
        pooled = torch.cat([h.mean(dim=(2, 3, 4)), h.std(dim=(2, 3, 4))], 1)  # [B,32]
        return self.fc(pooled)
