"""SSIM for images [H,W,C] or [B,H,W,C] in [0,1] (channels last), and PSNR.

=============  ==================================================================================
``reference``  :func:`ssim`: the readable definition (Gaussian window 11, sigma 1.5, zero-padded
               'same' filtering), differentiable through autograd; :func:`psnr`
``fused``      :func:`fused_ssim`: the training loss, the same value with a hand-written backward
``kernel``     the compiled CPU kernel of the fused SSIM (``csrc/ssim.cpp``), built on first use or
               by ``anigs build-kernel``
=============  ==================================================================================

The evaluation metric (valid window, explicit data range) is :mod:`anigs.metrics.image`'s.
"""
from anigs.ssim.fused import fused_ssim
from anigs.ssim.reference import psnr, ssim

__all__ = ["fused_ssim", "psnr", "ssim"]
