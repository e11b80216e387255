"""gsplat backend (CUDA only): calls ``gsplat.rasterization``.

Only selected when the tensors live on a CUDA device: on a machine with ``nvcc`` but no
GPU, gsplat would try to JIT-compile and fail (see NOTES.md). Note gsplat clamps alpha at
0.999 and culls at 3 sigma, so it agrees with the cpu/torch backends to ~1e-3, not 1e-5.
"""
from __future__ import annotations

import torch


def available() -> bool:
    if not torch.cuda.is_available():
        return False
    try:
        import gsplat  # noqa: F401
    except Exception:
        return False
    return True


def render(means, quats, scales, opacities, colors, viewmat, K, width, height, sh_degree, bg, near, far):
    if means.device.type != "cuda":
        raise ValueError("the gsplat backend needs CUDA tensors; use backend='cpu' or 'auto' on the CPU")
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
    return rgb, alpha, {"depth": out[..., 3], "radii": radii.int(), "means2d": meta["means2d"][0],
                        "visible": radii > 0, "num_visible": int((radii > 0).sum())}
