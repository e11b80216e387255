"""Render the animated scene: canonical Gaussians + DCT deformation -> frames and clips.

``deformation=None`` (round 0: the static canonical model) renders the canonical scene at
every frame.
"""
from __future__ import annotations

import torch

from anigs.cameras import Camera
from anigs.animate.deform import DCTDeformation
from anigs.gaussians import Gaussians
from anigs.render import render_gaussians


def _background(background, device) -> torch.Tensor | None:
    if background is None:
        return None
    bg = torch.as_tensor(background, dtype=torch.float32, device=device).reshape(-1)
    if bg.shape != (3,):
        raise ValueError(f"background must have 3 values, got {tuple(bg.shape)}")
    return bg


def deformed(canonical: Gaussians, deformation: DCTDeformation | None, t: float | int | torch.Tensor) -> Gaussians:
    """Gaussians at frame t (the canonical set itself without a deformation)."""
    return canonical if deformation is None else deformation(canonical, t)


def render_frame(canonical: Gaussians, deformation: DCTDeformation | None, camera: Camera,
                 t: float | int | torch.Tensor, background=None, backend: str = "auto") -> torch.Tensor:
    """Frame t (fractional allowed) seen by ``camera``: rgb [H,W,3] (differentiable)."""
    g = deformed(canonical, deformation, t)
    rgb, _, _ = render_gaussians(g, camera, background=_background(background, g.device), backend=backend)
    return rgb


def render_clip(canonical: Gaussians, deformation: DCTDeformation | None, camera: Camera, num_frames: int,
                background=None, backend: str = "auto", times: torch.Tensor | None = None) -> torch.Tensor:
    """Camera-fixed clip [T,H,W,3] (no gradient) at frames 0..T-1 (or at ``times`` [T]).

    Without a deformation, or with no dynamic Gaussians, the canonical render is computed once
    and repeated.
    """
    if times is None:
        if deformation is not None and deformation.num_dynamic and deformation.num_frames != num_frames:
            raise ValueError(f"render_clip: the model has T={deformation.num_frames} frames, asked for {num_frames} "
                             "(pass explicit fractional times to resample)")
        if num_frames < 1:
            raise ValueError(f"render_clip: num_frames must be >= 1, got {num_frames}")
        times = torch.arange(num_frames)
    with torch.no_grad():
        if deformation is None or deformation.num_dynamic == 0:
            frame = render_frame(canonical, None, camera, 0, background, backend)
            return frame[None].expand(len(times), -1, -1, -1).contiguous()
        return torch.stack([render_frame(canonical, deformation, camera, t, background, backend) for t in times])
