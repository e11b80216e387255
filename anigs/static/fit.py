"""Static 3DGS fit: SfM points + posed images -> canonical Gaussians.

Adam with the usual 3DGS per-parameter learning rates (position lr decaying exponentially and
scaled by the scene extent), loss ``(1-w) L1 + w (1 - SSIM)``, SH degree raised progressively,
densification by :mod:`anigs.static.densify`, every ``holdout_every``-th image held out for evaluation.

A step is the rasterizer plus as little as possible around it: the fused SSIM
(:mod:`anigs.ssim.fused`), a fused Adam, densification statistics only while a densification
is still to come, and no host reads except every ``LOG_EVERY`` steps and before checkpoints,
evaluations and refinements (a non-finite step is recorded on the device and skipped by the
optimizer, then reported with its iteration at the next read). ``benchmarks/static_fit.py``
compares the step with the rasterizer's own forward+backward.
"""
from __future__ import annotations

import logging
import math
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch

from anigs.cameras import Camera
from anigs.static.config import StaticConfig
from anigs.static.planning import (StaticPlan, check_inputs, downscaled, eval_background, fit_side, flat_curve,
                                   plan_static, start)
from anigs.static.report import accuracy_record, held_out_text, log_accuracy
from anigs.static.densify import (DensifyState, refine, refine_due, schedule_for, stats_needed,
                                  update_state)
from anigs.static.divergence import DivergenceGuard, FitDivergedError, raise_diverged
from anigs.static.depth import DepthTarget, depth_loss, depth_record, depth_targets, depth_weight
from anigs.static.exposure import Exposure
from anigs.static.evaluate import evaluate, loss_fn, pixels, render_params, stored_image
from anigs.static.sparse import added_points, dropout
from anigs.static.warp import WarpLoss
from anigs.static.init import init_gaussians, make_optimizer, params_to_gaussians, split_holdout, to_params
from anigs.static.regularize import NeedleRegularizer, last_densify_step, prune_rows
from anigs.sfm.tracks import Tracks, check_tracks
from anigs.device import get_device, seed_everything
from anigs.render.rasterize import select_backend
from anigs.ssim import kernel as ssim_kernel
from anigs.gaussians import Gaussians
from anigs.ssim import psnr

__all__ = ["LOG_EVERY", "DivergenceGuard", "FitDivergedError", "StaticConfig", "StaticPlan", "evaluate", "fit_static",
           "init_gaussians", "loss_fn", "make_optimizer", "params_to_gaussians", "plan_static", "render_params",
           "split_holdout", "to_params", "train_step"]

log = logging.getLogger(__name__)

LOG_EVERY = 10  # steps between host reads of the loss (progress) and of the divergence record


# ---------------------------------------------------------------------------- helpers
def train_step(params: dict[str, torch.nn.Parameter], optimizer: torch.optim.Optimizer, cam: Camera,
               target: torch.Tensor, sh_degree: int, bg: torch.Tensor, backend: str, ssim_weight: float,
               mats: tuple[torch.Tensor, torch.Tensor] | None = None, stats: DensifyState | None = None,
               guard: DivergenceGuard | None = None, step: int = 0, depth: DepthTarget | None = None,
               depth_w: float = 0.0, depth_tol: float = 0.0, colour: tuple[Exposure, int] | None = None,
               keep: torch.Tensor | None = None, warp: tuple[WarpLoss, int, list, float] | None = None
               ) -> tuple[torch.Tensor, torch.Tensor]:
    """One optimisation step on view ``cam`` with image ``target`` [H,W,3]: render, loss (plus
    ``depth_w`` times the depth loss at ``depth``'s SfM points, :mod:`anigs.static.depth`; with
    ``colour`` = (exposure, photo) the render is colour-mapped first, :mod:`anigs.static.exposure`), backward,
    densification statistics into ``stats`` (None: skipped), divergence record, Adam step. ``keep`` [N]:
    DropGaussian's per-Gaussian opacity factors for this step (None: every Gaussian as it is). ``warp``:
    (the warp loss, this photo's index among ``photos``, the training photos, its weight), :mod:`anigs.static.warp`.

    Returns the detached loss (0-dim, on the device; not read here) and rendered rgb [H,W,3].
    """
    rgb, alpha, meta = render_params(params, cam, sh_degree, bg, backend, mats, keep)
    if stats is not None:
        meta["means2d"].retain_grad()
    if colour is not None:
        rgb = colour[0].apply(rgb, colour[1])
    loss = loss_fn(rgb, target, ssim_weight)
    if depth is not None and depth_w > 0:
        loss = loss + depth_w * depth_loss(meta["depth"], alpha, depth, depth_tol)
    if warp is not None:
        loss = loss + warp[3] * warp[0](warp[1], meta["depth"], alpha, target, warp[2])
    loss.backward()
    if guard is not None:
        guard.record(step, loss, params)
    if stats is not None:
        update_state(stats, meta, cam.width, cam.height)
    optimizer.step()
    optimizer.zero_grad(set_to_none=True)
    if colour is not None:
        colour[0].step()
    return loss.detach(), rgb.detach()


def _lr_means(step: int, total: int, lr0: float, lr1: float) -> float:
    t = min(max(step / max(total, 1), 0.0), 1.0)
    return math.exp((1 - t) * math.log(lr0) + t * math.log(lr1))


# ---------------------------------------------------------------------------- the fit
def fit_static(images: list[torch.Tensor], cameras: list[Camera], init_points, init_colors, cfg: StaticConfig,
               progress: bool = True, checkpoint_path: str | Path | None = None,
               tracks: Tracks | None = None, plan: StaticPlan | None = None) -> tuple[Gaussians, dict[str, Any]]:
    """Fit 3D Gaussians to posed images.

    Args:
        images: float images [H,W,3] in [0,1] (or uint8 [H,W,3], 0..255: kept as uint8), one per camera.
        cameras: the matching :class:`Camera` list (image ``i`` seen by ``cameras[i]``).
        init_points [P,3], init_colors [P,3] in [0,1]: the SfM point cloud.
        cfg: :class:`StaticConfig`.
        progress: show a tqdm bar with loss and PSNR.
        checkpoint_path: where to keep the last good PLY (written atomically every
            ``cfg.checkpoint_every`` steps and kept when the fit diverges).
        tracks: the SfM tracks (:mod:`anigs.sfm.tracks`: image name -> rows (x, y, depth) [N,3] in the
            photo's pixels as given): the training photos' rows feed the depth loss
            (``cfg.depth_weight``), and the render's depth error at every photo's rows is reported;
            None: neither (a synthetic scene).
        plan: the fit's plan, :func:`anigs.static.planning.plan_static` of these arguments (None: planned here
            first); the fit runs with ``plan.config``.
    Returns:
        (Gaussians on CPU at SH degree ``cfg.sh_degree``, metrics dict).
    Raises:
        FitDivergedError when the loss or a gradient turns non-finite (names the iteration and
        the last good checkpoint); anigs.static.densify.AllPrunedError when every Gaussian is pruned.
    """
    cfg.validate()
    plan = plan if plan is not None else plan_static(images, cameras, init_points, init_colors, cfg)
    if not plan.made_for(cfg):
        raise ValueError("static fit: the plan was made for another config")
    return _fit(images, cameras, init_points, init_colors, plan, progress, checkpoint_path, tracks)


def _fit(images: list[torch.Tensor], cameras: list[Camera], init_points, init_colors, plan: StaticPlan,
         progress: bool, checkpoint_path: str | Path | None, tracks: Tracks | None) -> tuple[Gaussians, dict[str, Any]]:
    """:func:`fit_static` following ``plan`` (its config: the schedule's keys concrete)."""
    cfg, fit_plan = plan.config, plan.schedule
    check_inputs(images, cameras)
    device = get_device(cfg.device)
    gen = seed_everything(cfg.seed)
    t_start, c_start = time.perf_counter(), time.process_time()
    train_idx, test_idx = split_holdout(len(images), cfg.holdout_every)
    sizes = [(c.width, c.height) for c in cameras]
    images, cameras = downscaled(list(images), list(cameras), fit_side(cfg))
    tracks = None if tracks is None else check_tracks(tracks, "depth tracks")
    train_depth, test_depth = ((depth_targets(tracks, sizes, cameras, ix, device) for ix in (train_idx, test_idx))
                               if tracks is not None else (None, None))
    imgs = [stored_image(im, device) for im in images]
    train_imgs, train_cams = [imgs[i] for i in train_idx], [cameras[i] for i in train_idx]
    test_imgs, test_cams = [imgs[i] for i in test_idx], [cameras[i] for i in test_idx]

    pts, cols, extent, g0 = start(cameras, init_points, init_colors, cfg)
    params = to_params(g0, device)
    random_bg = cfg.background == "random"
    bg = eval_background(cfg, device)
    lr = {"means": cfg.lr_means * extent, "quats": cfg.lr_quats, "log_scales": cfg.lr_scales,
          "opacity_logits": cfg.lr_opacity, "sh_dc": cfg.lr_sh_dc, "sh_rest": cfg.lr_sh_rest}
    if g0.num != plan.start_gaussians:
        raise ValueError(f"static fit: the plan was made for {plan.start_gaussians} initial Gaussians, not {g0.num}")
    added, paired, n_far = added_points(cfg, pts, cols, train_imgs, train_cams, random_bg)
    if added is not None:
        g0 = init_gaussians(added[0], added[1], extent, cfg.sh_degree, cfg.init_opacity)
        params = to_params(g0, device)
    optimizer = make_optimizer(params, lr)
    dstate = DensifyState.empty(g0.num, device)
    _log_start(cfg, fit_plan, optimizer, device, (len(train_idx), len(test_idx)), g0.num, extent, train_cams[0])

    run = _FitRun(cfg, params, bg, test_imgs, test_cams, checkpoint_path, t_start, c_start)
    curve = [run.checkpoint(0, 0)]
    guard = DivergenceGuard(optimizer, list(params), device, on_failure=lambda step, what: run.diverged(step, what))
    run.save_checkpoint(0)
    if progress:
        import sys

        from tqdm import tqdm

        # in a log file (no terminal) refresh rarely, so Snakemake logs stay readable
        run.bar = tqdm(total=cfg.iterations, desc="static fit", unit="it", dynamic_ncols=True,
                       mininterval=0.1 if sys.stderr.isatty() else 10.0)
    deg, reg, step_seconds, last_refine, steps = _train(run, optimizer, guard, gen, train_imgs, train_cams, extent,
                                                        dstate, curve, device, train_depth)
    if run.bar is not None:
        run.bar.close()
    guard.check()

    params = run.params
    keep = reg.final_keep(params)
    if keep is not None:
        params = run.params = prune_rows(params, optimizer, keep)
    final_deg = min(cfg.sh_degree, max(deg, 0))
    if steps > 0 and (keep is not None or curve[-1]["iteration"] != steps):  # not yet evaluated as it is now
        curve.append(run.checkpoint(steps, final_deg))
    train_seconds = curve[-1]["train_seconds"]
    tr = evaluate(params, train_imgs, train_cams, final_deg, bg, cfg.backend)
    te = curve[-1]
    gaussians = params_to_gaussians(params)
    gaussians.check_finite("static fit result")
    if final_deg < cfg.sh_degree:  # SH bands above the active degree were never trained
        gaussians = gaussians.with_sh_degree(final_deg).with_sh_degree(cfg.sh_degree)
    metrics = {
        "train_psnr": tr["psnr"], "train_ssim": tr["ssim"], "train_views": tr["views"],
        "test_psnr": te["test_psnr"], "test_ssim": te["test_ssim"], "test_views": len(test_idx),
        "init_test_psnr": curve[0]["test_psnr"], **({"pair_points": paired.as_dict()} if paired else {}),
        "num_gaussians": gaussians.num, "init_gaussians": g0.num, "far_points": n_far, "iterations": steps,
        "plan": {**fit_plan.as_dict(), "stopped_early": steps < cfg.iterations},
        "seconds": time.perf_counter() - t_start, "train_seconds": train_seconds, "eval_seconds": run.eval_seconds,
        "train_cpu_seconds": curve[-1]["train_cpu_seconds"], "torch_threads": torch.get_num_threads(),
        "scene_extent": extent, "image_size": [train_cams[0].width, train_cams[0].height], "sh_degree": cfg.sh_degree, "active_sh_degree": final_deg,
        "holdout": [cameras[i].name for i in test_idx], "curve": curve, "regularize": reg.report(params),
        **_step_summary(step_seconds, last_refine),
    }
    if run.exposure is not None:
        metrics["exposure"] = {"lr": cfg.exposure_lr, **run.exposure.report()}
    if train_depth is not None:
        metrics["depth"] = depth_record(cfg, params, (train_cams, train_depth), (test_cams, test_depth), final_deg, bg)
    log.info("static fit done: %d Gaussians, %s, train PSNR %.2f dB, %.1f s",
             gaussians.num, held_out_text(te["test_psnr"], te["test_ssim"]), tr["psnr"], metrics["seconds"])
    metrics["plan"]["estimate_ratio"] = round(train_seconds / max(fit_plan.estimated_seconds, 1e-9), 3)
    metrics["accuracy"] = log_accuracy(accuracy_record(metrics, fit_plan, plan.size, plan.cost, g0.num))
    return gaussians, metrics


def _log_start(cfg: StaticConfig, fit_plan, optimizer, device, views: tuple[int, int], num: int, extent: float,
               cam: Camera) -> None:
    """The fit's set-up and plan, in the log before the first step."""
    log.info("static fit: %d train / %d held-out views, %d initial Gaussians, scene extent %.3f, %s Adam, "
             "rasterizer %s, SSIM %s", *views, num, extent, "fused" if optimizer.defaults.get("fused") else "foreach",
             select_backend(cfg.backend, device), _ssim_path(device))
    log.info("static fit plan (budget %s%s): photos at %dx%d, at most %d steps, at most %d Gaussians (densifying "
             "until step %d), held-out PSNR every %d steps; estimated %.1f min of training on this machine",
             fit_plan.level, f"; set: {', '.join(fit_plan.pinned)}" if fit_plan.pinned else "", cam.width,
             cam.height, fit_plan.iterations,
             fit_plan.max_gaussians, fit_plan.densify_stop, fit_plan.eval_every, fit_plan.estimated_seconds / 60)


class _FitRun:
    """What the fit's loop, evaluations and checkpoints share: the current parameter dict
    (replaced by each refinement), the evaluation time to leave out of the training time, the
    last good checkpoint and the progress bar."""

    def __init__(self, cfg: StaticConfig, params: dict[str, torch.nn.Parameter], bg: torch.Tensor,
                 test_imgs: list[torch.Tensor], test_cams: list[Camera], checkpoint_path: str | Path | None,
                 t_start: float, c_start: float) -> None:
        self.cfg, self.params, self.bg = cfg, params, bg
        self.test_imgs, self.test_cams, self.checkpoint_path = test_imgs, test_cams, checkpoint_path
        self.t_start, self.c_start = t_start, c_start
        self.eval_seconds = self.eval_cpu = 0.0
        self.last_good: dict[str, Any] = {"iteration": None, "path": None}
        self.bar = None
        self.exposure: Exposure | None = None  # the training photos' colour maps (static.exposure_lr)

    def checkpoint(self, step: int, deg: int) -> dict[str, Any]:
        """A row of the accuracy-versus-time curve: held-out PSNR and SSIM at ``step``."""
        t0, c0 = time.perf_counter(), time.process_time()
        ev = evaluate(self.params, self.test_imgs, self.test_cams, deg, self.bg, self.cfg.backend)
        self.eval_seconds += time.perf_counter() - t0
        self.eval_cpu += time.process_time() - c0
        row = {"iteration": step, "train_seconds": time.perf_counter() - self.t_start - self.eval_seconds,
               "train_cpu_seconds": time.process_time() - self.c_start - self.eval_cpu,
               "test_psnr": ev["psnr"], "test_ssim": ev["ssim"], "num_gaussians": int(self.params["means"].shape[0])}
        log.info("iteration %d: %s, %d Gaussians, %.1f s (cpu %.1f s)", step,
                 held_out_text(row["test_psnr"], row["test_ssim"]), row["num_gaussians"], row["train_seconds"],
                 row["train_cpu_seconds"])
        return row

    def save_checkpoint(self, step: int) -> None:
        """Write the parameters as the last good PLY (kept as they were when not finite)."""
        if self.checkpoint_path is None:
            return
        g = params_to_gaussians(self.params)
        try:
            g.check_finite(f"parameters at iteration {step}")
        except ValueError as exc:  # keep the previous (good) checkpoint
            self.diverged(step, str(exc))
        g.save_ply(self.checkpoint_path)
        self.last_good.update(iteration=step, path=str(self.checkpoint_path))

    def diverged(self, step: int, what: str) -> None:
        raise_diverged(what, step, self.last_good, self.bar)


def _ssim_path(device: torch.device) -> str:
    """Which SSIM the fit trains with, for its log: the C++ kernel, or the torch path and why (its
    float bits differ from the kernel's, so the fit differs too)."""
    if device.type != "cpu":
        return "torch"
    return "C++ kernel" if ssim_kernel.available() else f"torch (the C++ kernel is unavailable: {ssim_kernel.failure()})"


def _train(run: _FitRun, optimizer: torch.optim.Optimizer, guard: DivergenceGuard, gen: torch.Generator,
           train_imgs: list[torch.Tensor], train_cams: list[Camera], extent: float, dstate: DensifyState,
           curve: list[dict[str, Any]], device: torch.device, depth: list[DepthTarget | None] | None = None
           ) -> tuple[int, NeedleRegularizer, list[float], int, int]:
    """The optimisation loop (``run.params`` is replaced by each refinement; held-out rows are
    appended to ``curve``; ``depth``: the training photos' depth targets, or None). Returns (last active SH degree, the regulariser, seconds per step,
    the last step whose refinement changed the set, the steps run: fewer than ``cfg.iterations``
    when the held-out curve flattened, :func:`anigs.static.planning.flat_curve`)."""
    cfg, bar = run.cfg, run.bar
    order: list[int] = []
    ema_loss = ema_psnr = None
    deg = 0
    densify_cfg = schedule_for(cfg.densify, cfg.iterations)
    means_group = next(g for g in optimizer.param_groups if g["name"] == "means")  # refine keeps the groups
    train_mats = [(c.torch_viewmat(device), c.torch_K(device)) for c in train_cams]
    reg = NeedleRegularizer(cfg.regularize, extent, train_cams, train_mats)
    run.exposure = Exposure(len(train_cams), cfg.exposure_lr, device) if cfg.exposure_lr > 0 else None
    warp = WarpLoss(train_cams, cfg.sparse.warp_neighbours, device) if cfg.sparse.warp_weight > 0 else None
    last_densify = last_densify_step(densify_cfg.start, densify_cfg.stop, densify_cfg.every, cfg.iterations)
    step_seconds: list[float] = []  # per step, checkpoints and evaluations excluded
    last_refine = 0  # last step whose refinement changed the set
    for step in range(1, cfg.iterations + 1):
        t_step = time.perf_counter()
        deg = min(cfg.sh_degree, (step - 1) // cfg.sh_increase_every)
        means_group["lr"] = _lr_means(step - 1, cfg.iterations, cfg.lr_means * extent, cfg.lr_means_final * extent)
        if not order:
            order = torch.randperm(len(train_cams), generator=gen).tolist()
        v = order.pop()
        cam, target = train_cams[v], pixels(train_imgs[v])
        if run.params["means"].shape[0] == 0:
            raise RuntimeError(f"static fit: no Gaussians left at iteration {step}")
        stats = dstate if stats_needed(densify_cfg, step) else None
        keep = dropout(run.params["means"].shape[0], cfg.sparse.drop_rate * step / cfg.iterations, gen, device)
        step_bg = torch.rand(3, generator=gen).to(device) if cfg.background == "random" else run.bg
        dw = depth_weight(step - 1, cfg.iterations, cfg.depth_weight, cfg.depth_weight_final) if depth else 0.0
        loss, rgb = train_step(run.params, optimizer, cam, target, deg, step_bg, cfg.backend, cfg.ssim_weight,
                               mats=train_mats[v], stats=stats, guard=guard, step=step,
                               depth=depth[v] if dw > 0 else None, depth_w=dw, depth_tol=cfg.depth_tolerance,
                               colour=None if run.exposure is None else (run.exposure, v), keep=keep,
                               warp=None if warp is None else (warp, v, train_imgs, cfg.sparse.warp_weight))

        ckpt_due = cfg.checkpoint_every > 0 and step % cfg.checkpoint_every == 0
        eval_due = cfg.eval_every > 0 and step % cfg.eval_every == 0 and step != cfg.iterations
        due = refine_due(densify_cfg, step)
        log_due = step % LOG_EVERY == 0 or step == cfg.iterations
        if log_due or ckpt_due or eval_due or due:
            guard.check()  # the one host read: raises naming the first non-finite step
        if log_due and bar is not None:
            lv, pv = float(loss), psnr(rgb.clamp(0, 1), target)
            ema_loss = lv if ema_loss is None else 0.9 * ema_loss + 0.1 * lv
            ema_psnr = pv if ema_psnr is None else 0.9 * ema_psnr + 0.1 * pv
        aside = time.perf_counter()
        if ckpt_due:
            run.save_checkpoint(step)
        if eval_due:
            curve.append(run.checkpoint(step, deg))  # before refinement: an opacity reset would hide the progress
        aside = time.perf_counter() - aside
        if eval_due and flat_curve(curve, last_densify, cfg.plateau_db):
            log.info("static fit: the held-out curve is flat after step %d (%+.3f dB since step %d < %.3f dB): "
                     "stopping", step, curve[-1]["test_psnr"] - curve[-2]["test_psnr"], curve[-2]["iteration"],
                     cfg.plateau_db)
            step_seconds.append(time.perf_counter() - t_step - aside)
            return deg, reg, step_seconds, last_refine, step
        reg.after_step(run.params)
        if due and step % densify_cfg.every == 0 and step >= densify_cfg.start:
            reg.decay(run.params, step, last=step == last_densify)
        run.params = refine(run.params, optimizer, dstate, step, densify_cfg, extent, gen)
        if due:
            last_refine = step
        step_seconds.append(time.perf_counter() - t_step - aside)
        if bar is not None:
            bar.update(1)
            if log_due:
                bar.set_postfix(loss=f"{ema_loss:.4f}", psnr=f"{ema_psnr:.2f}", n=int(run.params["means"].shape[0]))
    return deg, reg, step_seconds, last_refine, cfg.iterations


def _step_summary(step_seconds: list[float], last_refine: int) -> dict[str, Any]:
    """Median step time (ms) over the fit and over its steps after the last refinement (constant
    Gaussian count: what ``benchmarks/static_fit.py`` compares with the rasterizer)."""
    final = step_seconds[last_refine:]
    med = lambda xs: round(float(np.median(xs)) * 1e3, 3) if xs else None
    return {"step_ms_median": med(step_seconds), "step_ms_median_final": med(final),
            "final_steps_from": last_refine + 1 if final else None}
