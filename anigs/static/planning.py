"""Planning one static fit: its schedule from ``static.budget`` and the capture, the time estimate
calibrated on this machine, and the plateau test that ends it early (:mod:`anigs.static.budget`
holds the levels and the cost model)."""
from __future__ import annotations

import time
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np
import torch

from anigs.cameras import Camera
from anigs.static.budget import LEVELS, CaptureSize, FitPlan, StepCost, fit_scale, parse_budget, plan
from anigs.static.evaluate import _render, loss_fn, pixels

if TYPE_CHECKING:
    from anigs.static.fit import FitConfig


def flat_curve(curve: list[dict[str, Any]], last_densify: int | None, plateau_db: float) -> bool:
    """Whether the last two held-out evaluations, both after the last densification, differ by
    less than ``plateau_db`` dB (a fall counts as flat)."""
    if plateau_db <= 0 or len(curve) < 2:
        return False
    prev, cur = curve[-2], curve[-1]
    after = prev["iteration"] > (last_densify or 0)
    return after and cur["test_psnr"] - prev["test_psnr"] < plateau_db


def plan_fit(cfg: "FitConfig", params: dict[str, torch.nn.Parameter], imgs: list[torch.Tensor],
             cams: list[Camera], bg: torch.Tensor, start: int, size: CaptureSize) -> tuple[FitPlan, StepCost]:
    """The fit's schedule from ``cfg.budget`` and the capture's ``size`` (the training photos as
    captured), its time estimate calibrated by timing forward+backward passes of the initial
    Gaussians on ``imgs``/``cams`` (the photos at the fit's size; parameters unchanged). Returns the
    plan and the calibrated cost model."""
    times = []
    for _ in range(3):
        t0 = time.perf_counter()
        rgb, _, _ = _render(params, cams[0], 0, bg, cfg.backend)
        loss_fn(rgb, pixels(imgs[0]), cfg.ssim_weight).backward()
        if rgb.is_cuda:
            torch.cuda.synchronize()
        times.append(time.perf_counter() - t0)
    for p in params.values():
        p.grad = None
    # a whole step is the render and loss plus the optimizer and densification statistics: 1.25x
    # (benchmarks/README.md, "The static fit's step": training step / rasterizer 1.21-1.32)
    cost = StepCost().calibrated(1.25 * min(times[1:]), cams[0].width * cams[0].height, start)
    fit_plan = plan(cfg.budget, size, cost, start, iterations=cfg.iterations, max_gaussians=cfg.densify.max_gaussians,
                    densify_stop=cfg.densify.stop, stop_fraction=cfg.densify.stop_fraction, eval_every=cfg.eval_every,
                    max_side=cfg.max_side)
    return fit_plan, cost


def resolved(cfg: "FitConfig", fit_plan: FitPlan) -> "FitConfig":
    """``cfg`` with the plan's concrete steps, Gaussian budget, densification stop and evaluation interval."""
    densify = replace(cfg.densify, max_gaussians=fit_plan.max_gaussians, stop=fit_plan.densify_stop)
    return replace(cfg, iterations=fit_plan.iterations, eval_every=fit_plan.eval_every, densify=densify)


def fit_side(cfg: "FitConfig") -> int:
    """The fit's largest photo side: ``static.max_side``, else its budget level's (a minutes budget: auto's)."""
    if cfg.max_side is not None:
        return cfg.max_side
    b = parse_budget(cfg.budget)
    return LEVELS[b if isinstance(b, str) else "auto"].max_side


def downscale(image: np.ndarray, cam: Camera, max_side: int) -> tuple[np.ndarray, Camera]:
    """``image`` [H,W,3] (uint8 or float) and ``cam`` at most ``max_side`` px on the longest side (area
    interpolation; 0 or already smaller: the same objects back)."""
    f = fit_scale(cam.width, cam.height, max_side)
    if f >= 1.0:
        return image, cam
    w, h = max(1, round(cam.width * f)), max(1, round(cam.height * f))
    return cv2.resize(np.ascontiguousarray(image), (w, h), interpolation=cv2.INTER_AREA), cam.scaled(w, h)


def downscaled(images: list[torch.Tensor], cameras: list[Camera], max_side: int
               ) -> tuple[list[torch.Tensor], list[Camera]]:
    """Images [H,W,3] (uint8 or float) and cameras at most ``max_side`` on the longest side
    (:func:`downscale` each; 0 or already smaller: unchanged)."""
    out_i, out_c = [], []
    for img, cam in zip(images, cameras):
        if fit_scale(cam.width, cam.height, max_side) >= 1.0:
            out_i.append(img)
            out_c.append(cam)
            continue
        arr, small = downscale(img.cpu().numpy(), cam, max_side)
        out_i.append(torch.from_numpy(arr).to(img.device))
        out_c.append(small)
    return out_i, out_c
