"""``rasterize``: the flat-tensor rendering entry point (in the spirit of gsplat).

    rgb, alpha, meta = rasterize(means, quats, scales, opacities, colors_or_sh, viewmat, K,
                                 width, height, sh_degree=None, background=None, backend="auto")

Backends: ``torch`` (pure PyTorch reference), ``cpu`` (compiled tile kernel),
``gsplat`` (CUDA). ``auto`` picks gsplat on CUDA tensors when gsplat imports, else cpu
for CPU tensors, else torch. The torch path below is the readable reference: projection
(:mod:`anigs.render.projection`), colours (:mod:`anigs.geometry.sh`), depth sort and
compositing (:mod:`anigs.render.torch_backend`). The cpu backend
(:mod:`anigs.render.cpu_backend`) computes the same thing in fused C++ kernels.
"""
from __future__ import annotations

import warnings
from typing import Any

import torch

from anigs.render import gsplat_backend, kernel as render_kernel
from anigs.render.checks import validate, check_inputs
from anigs.render.cpu_backend import render_cpu
from anigs.render.projection import project_gaussians
from anigs.geometry.sh import sh_colors
from anigs.render.torch_backend import composite_torch

BACKENDS = ("auto", "torch", "cpu", "gsplat")


def select_backend(backend: str, device: torch.device) -> str:
    """Resolve ``auto`` to a concrete backend for tensors on ``device``."""
    if backend not in BACKENDS:
        raise ValueError(f"unknown rasterizer backend {backend!r}; choose one of {BACKENDS}")
    if backend != "auto":
        return backend
    if device.type == "cuda":
        if gsplat_backend.available():
            return "gsplat"
        warnings.warn("gsplat is not installed: rendering CUDA tensors with the torch backend "
                      "(install the 'gsplat' extra for speed)", stacklevel=3)
        return "torch"
    if device.type == "cpu":
        if render_kernel.available():
            return "cpu"
        warnings.warn("cpu rasterizer kernel could not be built; falling back to the slow torch backend", stacklevel=3)
    return "torch"


def rasterize(
    means: torch.Tensor, quats: torch.Tensor, scales: torch.Tensor, opacities: torch.Tensor,
    colors: torch.Tensor, viewmat: torch.Tensor, K: torch.Tensor, width: int, height: int,
    sh_degree: int | None = None, background: torch.Tensor | None = None, backend: str = "auto",
    near: float = 0.01, far: float = 1e10,
) -> tuple[torch.Tensor, torch.Tensor, dict[str, Any]]:
    """Render N Gaussians with one pinhole camera.

    Args:
        means [N,3]; quats [N,4] (w,x,y,z, any norm); scales [N,3] (activated std devs);
        opacities [N] (activated); colors [N,3] or SH [N,C,3] with ``sh_degree`` set;
        viewmat [4,4] world->camera (OpenCV); K [3,3]; background [3] (default black).
    Returns:
        rgb [H,W,3], alpha [H,W], meta with ``depth`` [H,W] (expected depth, 0 where empty),
        ``radii`` [N] int (0 = culled), ``means2d`` [N,2] (in the autograd graph: call
        ``retain_grad()`` for densification), ``visible`` [N] bool, ``backend`` str.
    """
    width, height, n = check_inputs("rasterize", means, quats, scales, opacities, width, height)
    if sh_degree is None:
        if colors.shape != (n, 3):
            raise ValueError(f"rasterize: colors must be [N,3] without sh_degree, got {tuple(colors.shape)}")
    elif colors.ndim != 3 or colors.shape[0] != n or colors.shape[1] < (sh_degree + 1) ** 2 or colors.shape[2] != 3:
        raise ValueError(f"rasterize: SH must be [N,>={(sh_degree + 1) ** 2},3] for degree {sh_degree}, "
                         f"got {tuple(colors.shape)}")
    if viewmat.shape != (4, 4) or K.shape != (3, 3):
        raise ValueError(f"rasterize: viewmat must be [4,4] and K [3,3], got {tuple(viewmat.shape)}, {tuple(K.shape)}")
    named = {"means": means, "quats": quats, "scales": scales, "opacities": opacities,
             "colors": colors, "viewmat": viewmat, "K": K}
    for name, t in named.items():
        if not torch.is_tensor(t):
            raise TypeError(f"rasterize: {name} must be a tensor, got {type(t).__name__}")
    device = means.device
    backend = select_backend(backend, device)
    if backend == "cpu":
        # One fused kernel path; it also validates the inputs (and defers to validate for
        # the error message), so no per-call torch ops run here.
        def on_invalid(_flags: int) -> None:
            validate(named)
            raise ValueError("rasterize: inputs are not finite in float32, or scales/opacities out of range")

        rgb, alpha, depth, means2d, radii, valid, num_visible = render_cpu(
            means, quats, scales, opacities, colors, viewmat, K, width, height, sh_degree,
            None if background is None else background.to(means), near, far, on_invalid)
        meta = {"depth": depth, "radii": radii, "means2d": means2d, "visible": valid,
                "backend": backend, "num_visible": num_visible}
        return rgb, alpha, meta

    validate(named)
    bg = torch.zeros(3, dtype=means.dtype, device=device) if background is None else background.to(means)

    if backend == "gsplat":
        rgb, alpha, meta = gsplat_backend.render(means, quats, scales, opacities, colors, viewmat, K,
                                                 width, height, sh_degree, bg, near, far)
        meta["backend"] = "gsplat"
        return rgb, alpha, meta

    p = project_gaussians(means, quats, scales, opacities, viewmat, K, width, height, near, far)
    means2d, conics, depths, rects, radii, valid = p.means2d, p.conics, p.depths, p.rects, p.radii, p.valid
    idx = torch.nonzero(valid, as_tuple=False).squeeze(1)
    # front-to-back order (stable, so equal depths keep input order)
    idx = idx[torch.argsort(depths.detach()[idx], stable=True)]
    if sh_degree is None:
        col = colors[idx]
    else:
        cam_center = -viewmat[:3, :3].T @ viewmat[:3, 3]
        col = sh_colors(sh_degree, colors[idx], means[idx], cam_center)
    feats = torch.cat([col, depths[idx, None]], dim=1)
    acc, T = composite_torch(means2d[idx], conics[idx], feats, opacities[idx], rects[idx], width, height)
    alpha = 1 - T
    rgb = acc[..., :3] + T[..., None] * bg
    depth = torch.where(alpha > 0, acc[..., 3] / alpha.clamp_min(1e-10), torch.zeros_like(alpha))
    meta = {"depth": depth, "radii": radii, "means2d": means2d, "visible": valid,
            "backend": backend, "num_visible": int(idx.numel())}
    return rgb, alpha, meta


def render_gaussians(gaussians, camera, background=None, backend: str = "auto", sh_degree: int | None = None):
    """Convenience: render a :class:`anigs.gaussians.Gaussians` with a :class:`anigs.cameras.Camera`."""
    dev = gaussians.device
    deg = gaussians.sh_degree if sh_degree is None else min(sh_degree, gaussians.sh_degree)
    return rasterize(gaussians.means, gaussians.quats, gaussians.scales, gaussians.opacities, gaussians.sh,
                     camera.torch_viewmat(dev), camera.torch_K(dev), camera.width, camera.height,
                     sh_degree=deg, background=background, backend=backend)
