"""Planning one static fit before it starts: :func:`plan_static` gives its :class:`StaticPlan` (the schedule
from ``static.budget`` and the capture, the time estimate calibrated on this machine, the config with the
schedule's keys concrete), which :func:`anigs.static.fit.fit_static` follows; and the plateau test that
ends the fit early (:mod:`anigs.static.budget` holds the levels and the cost model)."""
from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Any, Sequence

import numpy as np
import torch

from anigs.cameras import Camera
from anigs.device import get_device
from anigs.gaussians import Gaussians
from anigs.geometry.extent import scene_extent
from anigs.images import downscale, fit_scale
from anigs.static.budget import LEVELS, CaptureSize, FitPlan, StepCost, parse_budget, plan
from anigs.static.config import StaticConfig
from anigs.static.evaluate import loss_fn, pixels, render_params, stored_image
from anigs.static.init import init_gaussians, split_holdout, to_params

EVAL_BACKGROUND = (0.5, 0.5, 0.5)  # behind the evaluation renders of a fit trained on random backgrounds


@dataclass(frozen=True)
class StaticPlan:
    """One static fit's plan, decided before it starts (:func:`plan_static`)."""

    schedule: FitPlan  # steps, Gaussian budget, densification stop, evaluation interval, estimated seconds
    cost: StepCost  # the step cost model calibrated on this machine
    size: CaptureSize  # the training photos as captured
    start_gaussians: int  # the initial Gaussians (the SfM points, duplicates merged)
    #: the config the fit runs with: the requested one with ``iterations``, ``eval_every``,
    #: ``densify.max_gaussians`` and ``densify.stop`` from the schedule
    config: StaticConfig

    def made_for(self, cfg: StaticConfig) -> bool:
        """Whether this is a plan of ``cfg`` (its keys other than the scheduled ones the same)."""
        return resolved(cfg, self.schedule) == self.config

    def as_dict(self) -> dict[str, Any]:
        """The schedule, the capture and the start (JSON-ready)."""
        fit = self.size.limited(self.schedule.max_side)
        return {**self.schedule.as_dict(), "training_photos": self.size.photos,
                "photo_size": [self.size.width, self.size.height], "fit_size": [fit.width, fit.height],
                "start_gaussians": self.start_gaussians}

    def text(self) -> str:
        """The plan in one line (as the fit logs it before its first step)."""
        s, fit = self.schedule, self.size.limited(self.schedule.max_side)
        pinned = f"; set: {', '.join(s.pinned)}" if s.pinned else ""
        return (f"static fit plan (budget {s.level}{pinned}): {self.size.photos} training photos at {fit.width}x"
                f"{fit.height}, at most {s.iterations} steps, at most {s.max_gaussians} Gaussians (densifying until "
                f"step {s.densify_stop}; {self.start_gaussians} at the start), held-out PSNR every {s.eval_every} "
                f"steps; estimated {s.estimated_seconds / 60:.1f} min of training on this machine")


def check_inputs(images: Sequence[torch.Tensor], cameras: Sequence[Camera]) -> None:
    """One [H,W,3] image per camera, each of its camera's size; else a ValueError naming the photo."""
    if len(images) != len(cameras):
        raise ValueError(f"static fit: {len(images)} images but {len(cameras)} cameras")
    if not images:
        raise ValueError("static fit: no images")
    for i, (img, cam) in enumerate(zip(images, cameras)):
        if img.ndim != 3 or img.shape[2] != 3:
            raise ValueError(f"static fit: image {i} ({cam.name!r}) must be [H,W,3], got {tuple(img.shape)}")
        if (img.shape[0], img.shape[1]) != (cam.height, cam.width):
            raise ValueError(f"static fit: image {i} ({cam.name!r}) is {img.shape[1]}x{img.shape[0]} but its "
                             f"camera is {cam.width}x{cam.height}")


def plan_static(images: Sequence[torch.Tensor], cameras: Sequence[Camera], init_points, init_colors,
                cfg: StaticConfig) -> StaticPlan:
    """The plan of a fit of ``cfg`` on ``images``/``cameras`` (as :func:`anigs.static.fit.fit_static` takes
    them) from ``init_points``/``init_colors``: the schedule from ``cfg.budget`` and the training photos as
    captured, its time estimate calibrated by timing a few forward+backward passes of the initial Gaussians on
    the first training photo at the fit's size (nothing is fitted)."""
    cfg.validate()
    check_inputs(images, cameras)
    device = get_device(cfg.device)
    train_idx, _ = split_holdout(len(images), cfg.holdout_every)
    size = CaptureSize.of([(cameras[i].width, cameras[i].height) for i in train_idx])  # as captured
    (img,), (cam,) = downscaled([images[train_idx[0]]], [cameras[train_idx[0]]], fit_side(cfg))
    _, _, _, g0 = start(cameras, init_points, init_colors, cfg)
    cost = _calibrated(cfg, to_params(g0, device), stored_image(img, device), cam, eval_background(cfg, device), g0.num)
    schedule = plan(cfg.budget, size, cost, g0.num, iterations=cfg.iterations,
                    max_gaussians=cfg.densify.max_gaussians, densify_stop=cfg.densify.stop,
                    stop_fraction=cfg.densify.stop_fraction, eval_every=cfg.eval_every, max_side=cfg.max_side)
    return StaticPlan(schedule, cost, size, g0.num, resolved(cfg, schedule))


def start(cameras: Sequence[Camera], init_points, init_colors, cfg: StaticConfig
          ) -> tuple[np.ndarray, np.ndarray, float, Gaussians]:
    """The fit's start, shared by the plan and the fit: the SfM points [P,3] and colours [P,3] as numpy, the
    scene extent of ``cameras`` and the points, and the initial Gaussians."""
    pts = init_points.detach().cpu().numpy() if torch.is_tensor(init_points) else np.asarray(init_points)
    cols = init_colors.detach().cpu().numpy() if torch.is_tensor(init_colors) else np.asarray(init_colors)
    extent = scene_extent(cameras, np.asarray(pts, dtype=np.float64).reshape(-1, 3))
    return pts, cols, extent, init_gaussians(pts, cols, extent, cfg.sh_degree, cfg.init_opacity)


def eval_background(cfg: StaticConfig, device: torch.device) -> torch.Tensor:
    """[3] the background of the evaluation renders (grey behind a fit trained on random backgrounds)."""
    return torch.tensor(EVAL_BACKGROUND if cfg.background == "random" else cfg.background, dtype=torch.float32,
                        device=device)


def _calibrated(cfg: StaticConfig, params: dict[str, torch.nn.Parameter], img: torch.Tensor, cam: Camera,
                bg: torch.Tensor, start: int) -> StepCost:
    """The step cost model scaled to this machine: forward+backward passes of ``params`` on ``img``
    (the photo at the fit's size) timed (parameters unchanged)."""
    times = []
    for _ in range(3):
        t0 = time.perf_counter()
        rgb, _, _ = render_params(params, cam, 0, bg, cfg.backend)
        loss_fn(rgb, pixels(img), cfg.ssim_weight).backward()
        if rgb.is_cuda:
            torch.cuda.synchronize()
        times.append(time.perf_counter() - t0)
    for p in params.values():
        p.grad = None
    # a whole step is the render and loss plus the optimizer and densification statistics: 1.25x
    # (benchmarks/README.md, "The static fit's step": training step / rasterizer 1.21-1.32)
    return StepCost().calibrated(1.25 * min(times[1:]), cam.width * cam.height, start)


def resolved(cfg: StaticConfig, schedule: FitPlan) -> StaticConfig:
    """``cfg`` with the schedule's concrete steps, Gaussian budget, densification stop and evaluation interval."""
    densify = replace(cfg.densify, max_gaussians=schedule.max_gaussians, stop=schedule.densify_stop)
    return replace(cfg, iterations=schedule.iterations, eval_every=schedule.eval_every, densify=densify)


def fit_side(cfg: StaticConfig) -> int:
    """The fit's largest photo side: ``static.max_side``, else its budget level's (a minutes budget: auto's)."""
    if cfg.max_side is not None:
        return cfg.max_side
    b = parse_budget(cfg.budget)
    return LEVELS[b if isinstance(b, str) else "auto"].max_side


def downscaled(images: list[torch.Tensor], cameras: list[Camera], max_side: int
               ) -> tuple[list[torch.Tensor], list[Camera]]:
    """Images [H,W,3] (uint8 or float) and cameras at most ``max_side`` on the longest side
    (:func:`anigs.images.downscale` each; 0 or already smaller: unchanged)."""
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


def flat_curve(curve: list[dict[str, Any]], last_densify: int | None, plateau_db: float) -> bool:
    """Whether the last two held-out evaluations, both after the last densification, differ by
    less than ``plateau_db`` dB (a fall counts as flat)."""
    if plateau_db <= 0 or len(curve) < 2:
        return False
    prev, cur = curve[-2], curve[-1]
    after = prev["iteration"] > (last_densify or 0)
    return after and cur["test_psnr"] - prev["test_psnr"] < plateau_db
