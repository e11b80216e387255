"""The compiled CPU kernel of the fused SSIM loss (``csrc/ssim.cpp``) and its autograd Function.

Built like the rasterizer kernel (:mod:`anigs.render.kernel`: same compiler, flags, instruction-set
level and cache folder; its own library ``anigs_ssim_<hash>.so``, keyed by the source and
flags, written atomically) on first use. When it cannot be built, :func:`available` is False
and :func:`anigs.ssim.fused.fused_ssim` takes its torch path; when it builds but does not load,
:func:`available` raises instead (the torch path has other numerics).
"""
from __future__ import annotations

import ctypes
import hashlib
import os
import platform
import threading
from pathlib import Path

import torch

from anigs.render import kernel as render_kernel
from anigs.ssim.reference import C1, C2, SIGMA, WINDOW

SRC = Path(__file__).with_name("csrc") / "ssim.cpp"
ABI_VERSION = 1
_LIB: ctypes.CDLL | None = None
_FAILED: str | None = None
_LOCK = threading.Lock()


def library_path() -> Path:
    flags = " ".join(render_kernel.FLAGS + render_kernel.arch_flags() + render_kernel.thread_flags())
    key = hashlib.sha256(SRC.read_bytes() + flags.encode() + platform.machine().encode()).hexdigest()[:16]
    return render_kernel.cache_dir() / f"anigs_ssim_{key}.so"


def build(verbose: bool = False) -> Path:
    """Compile the kernel if it is not cached; return the library path."""
    return render_kernel.compile_cached(SRC, library_path(), "the fused SSIM kernel", verbose)


def load() -> ctypes.CDLL:
    """Load (building first if needed) the kernel library, with typed signatures."""
    global _LIB
    if _LIB is not None:
        return _LIB
    with _LOCK:
        if _LIB is None:
            if render_kernel.thread_flags():
                os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")  # as anigs.render.kernel.load
            path = build()
            lib = render_kernel.open_library(path, "the fused SSIM kernel")
            render_kernel.check_abi(lib, "anigs_ssim_abi_version", ABI_VERSION, path)
            P, I, Fl = ctypes.c_void_p, ctypes.c_int, ctypes.c_float
            lib.anigs_ssim_forward.argtypes = [I, I, I, I, P, P, P, Fl, Fl, P, P, P, I]
            lib.anigs_ssim_forward.restype = ctypes.c_double
            lib.anigs_ssim_backward.argtypes = [I, I, I, I, P, P, P, P, P, P, Fl, P, I]
            lib.anigs_ssim_backward.restype = None
            _LIB = lib
    return _LIB


def available() -> bool:
    """Whether the kernel builds and loads here. False only when it cannot be built on this machine
    (remembered, not retried); a library that does not load raises (see :func:`anigs.render.kernel.unavailable_reason`)."""
    global _FAILED
    if _LIB is not None:
        return True
    if _FAILED is None:
        _FAILED = render_kernel.unavailable_reason(load)
    return _FAILED is None


def failure() -> str | None:
    """Why the kernel is unavailable (the error :func:`available` met), or None."""
    return _FAILED


def _taps() -> torch.Tensor:
    """The float32 window [11], computed as :func:`anigs.ssim.reference._window` does."""
    x = torch.arange(WINDOW, dtype=torch.float32) - (WINDOW - 1) / 2
    g = torch.exp(-(x**2) / (2 * SIGMA**2))
    return (g / g.sum()).contiguous()


_TAPS: torch.Tensor | None = None


class _SSIMCpu(torch.autograd.Function):
    """Mean SSIM of float32 CPU images [B,H,W,C]; gradient w.r.t. the first only."""

    @staticmethod
    def forward(ctx, pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        global _TAPS
        lib = load()
        if _TAPS is None:
            _TAPS = _taps()
        x, y = pred.detach().contiguous(), target.detach().contiguous()
        B, H, W, C = x.shape
        need = ctx.needs_input_grad[0]
        parts = torch.empty((3, *x.shape)) if need else None
        ptr = (lambda i: parts[i].data_ptr()) if need else (lambda i: None)
        total = lib.anigs_ssim_forward(B, H, W, C, x.data_ptr(), y.data_ptr(), _TAPS.data_ptr(), C1, C2,
                                       ptr(0), ptr(1), ptr(2), max(1, torch.get_num_threads()))
        if need:
            ctx.save_for_backward(x, y, parts)
        return torch.tensor(total / x.numel(), dtype=torch.float32)

    @staticmethod
    def backward(ctx, g: torch.Tensor):
        lib = load()
        x, y, parts = ctx.saved_tensors
        B, H, W, C = x.shape
        gx = torch.empty_like(x)
        lib.anigs_ssim_backward(B, H, W, C, x.data_ptr(), y.data_ptr(), _TAPS.data_ptr(), parts[0].data_ptr(),
                                parts[1].data_ptr(), parts[2].data_ptr(), float(g) / x.numel(), gx.data_ptr(),
                                max(1, torch.get_num_threads()))
        return gx, None


def ssim_cpu(pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Mean SSIM (0-dim float32) of float32 CPU images [H,W,C] or [B,H,W,C], differentiable in ``pred``."""
    if pred.ndim == 3:
        return _SSIMCpu.apply(pred[None], target[None])
    return _SSIMCpu.apply(pred, target)
