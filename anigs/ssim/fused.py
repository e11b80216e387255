"""Fused SSIM: the training-loss SSIM of :func:`anigs.ssim.reference.ssim` with a hand-written backward.

Same definition as the reference (Gaussian window of size 11 and sigma 1.5, zero-padded 'same'
filtering, ``C1 = 0.01^2``, ``C2 = 0.03^2``, mean over pixels and channels), computed with

* a separable blur (two 11-tap passes instead of an 11x11 depthwise convolution), either the
  compiled CPU kernel (``csrc/ssim.cpp`` via :mod:`anigs.ssim.kernel`: one pass per image for the
  forward and one for the backward, no temporaries beyond three saved maps) or, on other devices
  or without a compiler, banded matrix products in torch;
* an analytic backward. With ``u = G*x``, ``v = G*y``, ``s_xx = G*(x^2) - u^2``,
  ``s_xy = G*(xy) - uv``, ``s_yy = G*(y^2) - v^2`` and the SSIM map
  ``m = (2uv + C1)(2 s_xy + C2) / ((u^2 + v^2 + C1)(s_xx + s_yy + C2))``, the gradient of the mean
  is ``dmean/dx = (G*A + 2x G*B + y G*C) / n`` where ``A = dm/du``, ``B = dm/dG*(x^2)``,
  ``C = dm/dG*(xy)`` (partial derivatives holding the other blurred maps fixed) and ``n`` the
  number of map entries; ``G`` is symmetric, so the adjoint of the zero-padded blur is the blur.

Only the prediction gets a gradient (the target is data); a target that requires grad falls back
to the reference implementation. The reference stays the oracle in the tests.
"""
from __future__ import annotations

from functools import lru_cache

import torch
import torch.nn.functional as F

from anigs.ssim import kernel
from anigs.ssim.reference import C1, C2, SIGMA, WINDOW, ssim

_R = WINDOW // 2
_BLOCK = 16  # output columns per band block (the band matrix is [_BLOCK + 2*_R, _BLOCK])


@lru_cache(maxsize=16)
def _band(dtype: torch.dtype, device: str) -> torch.Tensor:
    """Band matrix T [_BLOCK + 2*_R, _BLOCK]: ``T[j + k, j] = g[k]``, with the window g [11] built
    in ``dtype`` as :func:`anigs.ssim.reference._window` builds it."""
    g = torch.exp(-((torch.arange(WINDOW, dtype=dtype) - _R) ** 2) / (2 * SIGMA**2))
    g = g / g.sum()
    T = torch.zeros(_BLOCK + 2 * _R, _BLOCK, dtype=dtype)
    for j in range(_BLOCK):
        T[j:j + WINDOW, j] = g
    return T.to(device)


def blur(x: torch.Tensor) -> torch.Tensor:
    """Zero-padded 'same' Gaussian blur (11 taps, sigma 1.5) of planes x [P,H,W] -> [P,H,W].

    Two banded matrix products: along W the padded rows are cut into overlapping blocks
    [P,H,nb,K] (K = _BLOCK + 10) times T [K,_BLOCK]; along H the same with T transposed.
    """
    P, H, W = x.shape
    T = _band(x.dtype, str(x.device))
    K = _BLOCK + 2 * _R
    nb = -(-W // _BLOCK)
    xp = F.pad(x, (_R, _R + nb * _BLOCK - W))
    u = xp.unfold(2, K, _BLOCK).reshape(-1, K)  # copies the overlapping blocks
    a = torch.mm(u, T).view(P, H, nb * _BLOCK)[..., :W]
    nb = -(-H // _BLOCK)
    ap = F.pad(a, (0, 0, _R, _R + nb * _BLOCK - H))  # [P,Hp,W], contiguous
    v = ap.as_strided((P, nb, K, W), (ap.stride(0), _BLOCK * W, W, 1))
    return torch.matmul(T.t(), v).view(P, nb * _BLOCK, W)[:, :H]


def _planes(t: torch.Tensor) -> torch.Tensor:
    """[H,W,C] or [B,H,W,C] -> contiguous planes [B*C,H,W] (autograd maps the gradient back)."""
    t = t if t.ndim == 4 else t[None]
    B, H, W, C = t.shape
    return t.permute(0, 3, 1, 2).reshape(B * C, H, W)


def _ssim_terms(mx: torch.Tensor, my: torch.Tensor, exx: torch.Tensor, eyy: torch.Tensor, exy: torch.Tensor,
                grad: bool) -> tuple[torch.Tensor, tuple[torch.Tensor, torch.Tensor, torch.Tensor] | None]:
    """SSIM map [P,H,W] from the blurred moments G*x, G*y, G*x^2, G*y^2, G*xy (each [P,H,W]) and,
    with ``grad``, the partials (A, B, C) of the map (each [P,H,W])."""
    mx2, my2, mxy = mx * mx, my * my, mx * my
    n1 = 2 * mxy + C1
    n2 = 2 * (exy - mxy) + C2
    d1 = mx2 + my2 + C1
    d2 = (exx - mx2) + (eyy - my2) + C2
    d = d1 * d2
    m = n1 * n2 / d
    if not grad:
        return m, None
    # A = dm/du = 2v (n2 - n1) / (d1 d2) + 2u m (1/d2 - 1/d1); B = -m/d2; C = 2 n1 / (d1 d2)
    A = 2 * my * (n2 - n1) / d + 2 * mx * m * (1 / d2 - 1 / d1)
    Bm = -m / d2
    Cm = 2 * n1 / d
    return m, (A, Bm, Cm)


class _FusedSSIMTorch(torch.autograd.Function):
    """Mean SSIM of planes x, y [P,H,W] with banded-matmul blurs (any device, any float dtype)."""

    @staticmethod
    def forward(ctx, x: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
        P = x.shape[0]
        moments = blur(torch.cat([x, y, x * x, y * y, x * y]))
        mx, my, exx, eyy, exy = moments.split(P)
        m, parts = _ssim_terms(mx, my, exx, eyy, exy, ctx.needs_input_grad[0])
        if parts is not None:
            ctx.save_for_backward(x, y, torch.cat(parts))
        return m.mean()

    @staticmethod
    def backward(ctx, g: torch.Tensor):
        x, y, parts = ctx.saved_tensors
        P = x.shape[0]
        bA, bB, bC = blur(parts).split(P)
        gx = (bA + 2 * x * bB + y * bC) * (g / x.numel())
        return gx, None


def _kernel_ok(x: torch.Tensor) -> bool:
    return x.device.type == "cpu" and x.dtype == torch.float32 and kernel.available()


def fused_ssim(pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Mean SSIM (scalar) of images [H,W,C] or [B,H,W,C] (channels last), differentiable in ``pred``.

    Equals :func:`anigs.ssim.reference.ssim` with its defaults (window 11, sigma 1.5, data range 1) to
    float rounding. float32 CPU tensors use the compiled kernel when it builds; everything else
    the torch path.
    """
    if pred.shape != target.shape:
        raise ValueError(f"fused_ssim: shapes differ: {tuple(pred.shape)} vs {tuple(target.shape)}")
    if pred.ndim not in (3, 4):
        raise ValueError(f"fused_ssim: images must be [H,W,C] or [B,H,W,C], got {tuple(pred.shape)}")
    if target.requires_grad:
        return ssim(pred, target)
    target = target.to(pred.dtype)
    if _kernel_ok(pred):
        return kernel.ssim_cpu(pred, target)
    return _FusedSSIMTorch.apply(_planes(pred), _planes(target.detach()))
