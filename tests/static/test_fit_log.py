"""The static fit's log names the SSIM path it trains with: the torch fallback gives other float bits
than the C++ kernel (so another canonical model), and a kept log must show when that happened."""
from __future__ import annotations

import torch

from anigs.ssim import kernel
from anigs.static.fit import _ssim_path


def test_ssim_path_names_the_kernel_or_the_fallback_and_why(monkeypatch):
    if kernel.available():
        assert _ssim_path(torch.device("cpu")) == "C++ kernel"
    monkeypatch.setattr(kernel, "_LIB", None)
    monkeypatch.setattr(kernel, "_FAILED", "building the fused SSIM kernel failed: no compiler")
    assert not kernel.available()
    assert _ssim_path(torch.device("cpu")) == "torch (the C++ kernel is unavailable: building the fused SSIM kernel failed: no compiler)"
