"""The baselines' one interface: same inputs as the model update, same output as the model update.

    result = fit_baseline("lifting", canonical, dynamic_mask, views, {"num_bases": 12})
    save_model("model.pt", result.deformation, result.canonical, ...)   # or run_baseline(...)

(the registry, :mod:`anigs.baselines.registry`, names the fits; this module holds what they share).

Inputs are exactly those of :func:`anigs.animate.update.run_update`: the canonical Gaussians
G^0 (N), the per-Gaussian dynamic mask [N] (bool, or integer effect labels with 0 = static),
the round's training views (:class:`anigs.animate.update.ViewData`: camera + refined target
clip [T,H,W,3]) and a config dict. Each baseline produces per-Gaussian 3D trajectories
``[T,D,3]`` of the D dynamic Gaussians; :func:`trajectories_to_deformation` projects them on the
paper's DCT basis, so the result is a :class:`~anigs.animate.deform.DCTDeformation` plus a
canonical scene, written with :func:`~anigs.animate.deform.save_model`. Rendering, export and
evaluation then read a baseline's ``model.pt`` exactly like ours (``load_model``), and static
Gaussians are bit-identical at every frame by construction.

DCT projection: the basis ``k = 1..K`` has zero temporal mean, so the dynamic Gaussians'
canonical positions become the temporal means of their trajectories and the coefficients are
the least-squares fit of the zero-mean remainder (exact for ``K = T-1``; a low-pass for smaller
K, the same function space as our model). The trajectories start at the canonical scene
(frame 0 of every target is the static render), so the model's t = 0 render matches it up to
the DCT truncation.
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import Any

import torch

from anigs.animate.deform import DCTDeformation, dynamic_index_from_mask, resolve_num_bases
from anigs.animate.update import ViewData
from anigs.device import get_device
from anigs.gaussians import Gaussians

log = logging.getLogger("anigs.baselines")

BASELINES = ("lifting", "physics")
MODEL_KIND = "baseline"


@dataclass
class BaselineResult:
    """What a baseline returns.

    canonical: G^0 with the dynamic rows' positions set to the temporal means of the trajectories;
    deformation: the DCT field [D,3,K] (no rotation offsets); trajectories: float64 [T,D,3] world
    positions before the DCT projection; info: JSON-able facts (visible counts, fitted parameters).
    """

    canonical: Gaussians
    deformation: DCTDeformation
    trajectories: torch.Tensor
    info: dict[str, Any] = field(default_factory=dict)
    seconds: float = 0.0


def prepare(cls: type, config: Any, canonical: Gaussians, dynamic_mask: torch.Tensor, views: list[ViewData],
            what: str) -> tuple[Any, torch.Tensor, int, Gaussians, Gaussians]:
    """The shared start of every baseline fit: (config of ``cls``, validated; dynamic index [D];
    T; the canonical scene on the CPU; a copy on the configured device for the visibility renders)."""
    cfg = config if isinstance(config, cls) else cls.from_dict(config)
    cfg.validate()
    idx, T = check_baseline_inputs(canonical, dynamic_mask, views, what)
    canonical = canonical.detach().to("cpu")
    return cfg, idx, T, canonical, canonical.to(get_device(cfg.device))


def check_baseline_inputs(canonical: Gaussians, dynamic_mask: torch.Tensor, views: list[ViewData], what: str
                 ) -> tuple[torch.Tensor, int]:
    """Validate the shared inputs; returns (dynamic index [D] long, T)."""
    if not views:
        raise ValueError(f"{what}: no views (refined target clips) given")
    mask = torch.as_tensor(dynamic_mask)
    idx = dynamic_index_from_mask(mask, canonical.num)
    T = int(views[0].clip.shape[0])
    for i, v in enumerate(views):
        c = v.clip
        if c.ndim != 4 or c.shape[-1] != 3 or c.shape[0] != T:
            raise ValueError(f"{what}: view {i} ({v.camera.name!r}) clip has shape {tuple(c.shape)}; "
                             f"expected [T={T},H,W,3] like view 0")
        if tuple(c.shape[1:3]) != (v.camera.height, v.camera.width):
            raise ValueError(f"{what}: view {i} clip is {c.shape[2]}x{c.shape[1]} but its camera is "
                             f"{v.camera.width}x{v.camera.height}")
        if not bool(torch.isfinite(torch.as_tensor(c)).all()):
            raise ValueError(f"{what}: view {i} ({v.camera.name!r}) clip has NaN or Inf values")
    return idx, T


def trajectories_to_deformation(canonical: Gaussians, dynamic_index: torch.Tensor, trajectories: torch.Tensor,
                                num_bases: int) -> tuple[Gaussians, DCTDeformation]:
    """Project world trajectories [T,D,3] of the dynamic rows onto the DCT basis.

    Returns (canonical with ``means[dynamic_index]`` = temporal mean of each trajectory, the
    field with K = min(num_bases, T-1) least-squares coefficients, rotation off). Static rows of
    the canonical scene are the input tensors' values, untouched.
    """
    traj = torch.as_tensor(trajectories, dtype=torch.float64)
    idx = torch.as_tensor(dynamic_index).long().reshape(-1)
    T = int(traj.shape[0])
    if traj.ndim != 3 or traj.shape[1:] != (idx.numel(), 3):
        raise ValueError(f"trajectories must be [T,D={idx.numel()},3], got {tuple(traj.shape)}")
    if not bool(torch.isfinite(traj).all()):
        raise ValueError("trajectories contain NaN or Inf")
    K = resolve_num_bases(num_bases, T, log)
    deformation = DCTDeformation(idx, T, K, rotation=False, num_gaussians=canonical.num)
    means = canonical.means.detach().clone()
    if idx.numel() == 0:
        return Gaussians(means, canonical.quats, canonical.log_scales, canonical.opacity_logits, canonical.sh,
                         extras=canonical.extras), deformation
    mean = traj.mean(0)  # [D,3]
    if K > 0:
        B = deformation.basis(torch.arange(T)).to(torch.float64)  # [T,K]
        rest = (traj - mean).reshape(T, -1)  # [T,D*3]
        coeffs = torch.linalg.lstsq(B, rest).solution  # [K,D*3]
        with torch.no_grad():
            deformation.pos_coeffs.copy_(coeffs.T.reshape(idx.numel(), 3, K).to(deformation.pos_coeffs.dtype))
    means[idx] = mean.to(means.dtype)
    deformation.pos_coeffs.requires_grad_(False)
    return Gaussians(means, canonical.quats, canonical.log_scales, canonical.opacity_logits, canonical.sh,
                     extras=canonical.extras), deformation


def finish(canonical: Gaussians, idx: torch.Tensor, traj: torch.Tensor, num_bases: int, info: dict[str, Any],
           t0: float) -> BaselineResult:
    """Project trajectories [T,D,3] to the DCT model and wrap everything in a :class:`BaselineResult`."""
    canon, deformation = trajectories_to_deformation(canonical, idx, traj, num_bases)
    if idx.numel():
        T = traj.shape[0]
        with torch.no_grad():
            fitted = deformation.trajectories(canon.means.double(), torch.arange(T)).double()
        disp = (traj - traj[:1]).norm(dim=-1)
        info["dct_residual_rms"] = float((fitted - traj).norm(dim=-1).pow(2).mean().sqrt())
        info["displacement_rms"] = float(disp.pow(2).mean().sqrt())
        info["displacement_max"] = float(disp.max())
    info["num_dynamic"] = int(idx.numel())
    info["num_bases"] = deformation.num_bases
    info["num_frames"] = deformation.num_frames
    return BaselineResult(canon, deformation, traj, info, time.perf_counter() - t0)
