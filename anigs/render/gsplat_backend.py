"""gsplat backend (CUDA only): calls ``gsplat.rasterization``.

Only selected when the tensors live on a CUDA device: on a machine with ``nvcc`` but no
GPU, gsplat would try to JIT-compile and fail (see NOTES.md). Note gsplat clamps alpha at
0.999 and culls at 3 sigma, so it agrees with the cpu/torch backends to ~1e-3, not 1e-5.
"""
from __future__ import annotations

import weakref

import torch


def available() -> bool:
    if not torch.cuda.is_available():
        return False
    try:
        import gsplat  # noqa: F401
    except Exception:
        return False
    return True


def _means2d_view(batched: torch.Tensor) -> torch.Tensor:
    """``batched[0]`` ([N,2]) whose ``retain_grad()`` + ``.grad`` work like the other backends'.

    gsplat's rasterizer consumes the batched [1,N,2] tensor, so the loss does not pass
    through the view and autograd would never fill the view's retained gradient. A hook on
    the batched tensor hands it over: once autograd has the batched tensor's total gradient
    (which includes any gradient that reached it through the view), the view's ``.grad`` is
    set to its row 0 when ``retain_grad()`` was called on the view.
    """
    view = batched[0]
    if batched.requires_grad:
        ref = weakref.ref(view)  # no reference cycle through the hook

        def _to_view(grad: torch.Tensor) -> None:
            v = ref()
            if v is not None and v.retains_grad:
                v.grad = grad[0].detach().clone()

        batched.register_hook(_to_view)
    return view


def render(means, quats, scales, opacities, colors, viewmat, K, width, height, sh_degree, bg, near, far):
    if means.device.type != "cuda":
        raise ValueError("the gsplat backend needs CUDA tensors; use backend='cpu' or 'auto' on the CPU")
    return _render(means, quats, scales, opacities, colors, viewmat, K, width, height, sh_degree, bg, near, far)


def _render(means, quats, scales, opacities, colors, viewmat, K, width, height, sh_degree, bg, near, far):
    try:
        from gsplat import rasterization
    except ImportError as exc:  # pragma: no cover - depends on the extra
        raise ImportError("backend='gsplat' needs the 'gsplat' extra: pip install 'anigs[gsplat]'") from exc
    out, alphas, meta = rasterization(
        means, quats, scales, opacities, colors, viewmat[None], K[None], width, height,
        near_plane=near, far_plane=far, sh_degree=sh_degree, render_mode="RGB+ED", eps2d=0.3, packed=False,
    )
    out, alpha = out[0], alphas[0, ..., 0]
    rgb = out[..., :3] + (1 - alpha)[..., None] * bg
    radii = meta["radii"][0]
    if radii.ndim == 2:  # gsplat >= 1.5 returns per-axis radii
        radii = radii.max(-1).values
    return rgb, alpha, {"depth": out[..., 3], "radii": radii.int(), "means2d": _means2d_view(meta["means2d"]),
                        "visible": radii > 0, "num_visible": int((radii > 0).sum())}
