"""Losses of the model update (paper, Model Update).

    L = L_ani + lambda_cano * L_cano + lambda_sds * L_SDS
    L_ani  = |R_t - A_t|_1 + (1 - SSIM(R_t, A_t))      rendered frame t vs refined target frame t
    L_cano = |R_0 - I_0|_1 + (1 - SSIM(R_0, I_0))      rendered frame 0 vs static reference image

The SDS term comes from the video prior through a hook (:data:`SDSHook`): the update hands
it an :class:`SDSContext` whose ``render_subclip`` renders a short camera-fixed clip of a
training view with gradients through one chosen frame (the paper back-propagates through a
single frame of the 4m+1 rendered frames for memory).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Protocol

import torch

from anigs.ssim import fused_ssim


def photometric_loss(render: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Mean-absolute L1 plus (1 - SSIM) for images [H,W,3] or batches [B,H,W,3] (scalar)."""
    if render.shape != target.shape:
        raise ValueError(f"photometric_loss: render {tuple(render.shape)} vs target {tuple(target.shape)}")
    return (render - target).abs().mean() + (1.0 - fused_ssim(render, target))


def animation_loss(renders: torch.Tensor, targets: torch.Tensor) -> torch.Tensor:
    """L_ani over a batch of sampled (view, t) frames [B,H,W,3] (mean over the batch)."""
    return photometric_loss(renders, targets)


def canonical_loss(renders_t0: torch.Tensor, references: torch.Tensor) -> torch.Tensor:
    """L_cano: frame-0 renders vs the static reference images [B,H,W,3]."""
    return photometric_loss(renders_t0, references)


class SubclipRenderer(Protocol):
    def __call__(self, view: int, start: int, length: int, grad_frame: int | None = None) -> torch.Tensor:
        """Frames start..start+length-1 of training view ``view`` -> [L,H,W,3] in [0,1];
        gradients flow only through frame ``start + grad_frame`` (None: through none)."""


@dataclass
class SDSContext:
    """What the update hands the SDS hook at each step.

    render_subclip: see :class:`SubclipRenderer`; num_views / num_frames: the training set;
    generator: the update's seeded CPU generator (use it for every random draw so the
    update stays deterministic); step: the iteration.
    """

    render_subclip: SubclipRenderer
    num_views: int
    num_frames: int
    generator: torch.Generator
    step: int


# The video-prior hook: returns a differentiable scalar (the SDS loss, unweighted).
SDSHook = Callable[[SDSContext], torch.Tensor]


def largest_4m1(n: int) -> int:
    """Largest 4m+1 <= n (at least 1)."""
    return max(1, ((int(n) - 1) // 4) * 4 + 1)


def prior_sds_hook(prior, prompt: str = "", frames: int = 9) -> SDSHook:
    """SDS hook from a video prior with a score (``prior.sds_loss(clip, prompt, generator, grad_frame)``).

    Each call samples a training view, a start frame and a sub-clip of ``4m+1 <= min(frames, T)``
    frames, renders it with gradients through one random frame, and returns the prior's SDS loss.
    """
    if not getattr(prior, "has_score", False):
        raise ValueError(f"video prior {getattr(prior, 'name', prior)!r} has no score: it cannot provide an SDS "
                         "loss (set lambda_sds: 0, or use a prior with a score such as ltx)")

    def hook(ctx: SDSContext) -> torch.Tensor:
        g = ctx.generator
        length = largest_4m1(min(frames, ctx.num_frames))
        view = int(torch.randint(ctx.num_views, (1,), generator=g))
        start = int(torch.randint(ctx.num_frames - length + 1, (1,), generator=g))
        j = int(torch.randint(length, (1,), generator=g))
        clip = ctx.render_subclip(view, start, length, j)
        return prior.sds_loss(clip, prompt, g, grad_frame=j)

    return hook
