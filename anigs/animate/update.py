"""Model update (paper, Model Update): fit the DCT deformation field (and, by default, the
canonical positions of the dynamic Gaussians) to a round's refined camera-fixed clips.

    result = run_update(canonical, dynamic_mask, views, UpdateConfig(...), init=prev_deformation)

Each step samples ``views_per_step`` training views, one random frame t per view, renders
them and minimises ``L_ani + lambda_cano * L_cano + lambda_sds * L_SDS`` (see
:mod:`anigs.animate.losses`). Parameter groups (Table 5 ablations):

- ``deformation+positions`` (paper default): DCT coefficients + canonical means of the
  dynamic Gaussians (static Gaussians are never touched).
- ``deformation``: DCT coefficients only.
- ``all``: DCT coefficients + every canonical attribute of every Gaussian.

Non-finite loss, gradients or parameters stop the update with :class:`UpdateDiverged`
naming the iteration; the last good state is written to ``failure_path`` first.
"""
from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import torch

from anigs.animate.adam import Adam
from anigs.animate.frames import render_frame
from anigs.cameras import Camera
from anigs.animate.config import UpdateConfig
from anigs.animate.deform import DCTDeformation, dynamic_index_from_mask, resolve_num_bases, save_model
from anigs.animate.limits import bases_from_config, limits_from_config
from anigs.animate.trainable import Trainable, first_non_finite, param_groups
from anigs.device import get_device, seed_everything
from anigs.geometry.extent import box_diagonal
from anigs.gaussians import Gaussians
from anigs.animate.losses import SDSContext, SDSHook, animation_loss, canonical_loss
from anigs.animate.target_frames import ClipFrames

log = logging.getLogger("anigs.animate.update")

__all__ = ["UpdateDiverged", "UpdateResult", "ViewData", "bases_from_config",
           "limits_from_config", "run_update", "static_references"]

@dataclass
class ViewData:
    """One training view: camera, target clip [T,H,W,3] in [0,1] (a tensor of any float dtype, or a
    :class:`~anigs.animate.target_frames.ClipFrames` read from disk; ``clip[t]`` is one frame), static
    reference [H,W,3] (optional)."""

    camera: Camera
    clip: torch.Tensor | ClipFrames
    reference: torch.Tensor | None = None


@dataclass
class UpdateResult:
    canonical: Gaussians
    deformation: DCTDeformation
    history: list[dict] = field(default_factory=list)
    steps: int = 0
    seconds: float = 0.0
    skipped: str = ""


class UpdateDiverged(RuntimeError):
    """Non-finite loss/gradients/parameters; ``iteration`` and ``saved_path`` (last good state)."""

    def __init__(self, message: str, iteration: int, saved_path: Path | None) -> None:
        super().__init__(message)
        self.iteration = iteration
        self.saved_path = saved_path


# ---------------------------------------------------------------------------------------
def static_references(canonical: Gaussians, cameras: list[Camera], background=None,
                      backend: str = "auto") -> list[torch.Tensor]:
    """Static reference images I_0 [H,W,3]: renders of the (undeformed) canonical scene."""
    with torch.no_grad():
        return [render_frame(canonical, None, cam, 0, background, backend) for cam in cameras]


def run_update(canonical: Gaussians, dynamic_mask: torch.Tensor, views: list[ViewData],
               config: UpdateConfig | dict | None = None, init: DCTDeformation | None = None,
               sds_fn: SDSHook | None = None, failure_path: str | Path | None = None,
               progress: bool = True) -> UpdateResult:
    """Train the deformation field on ``views`` (see module docstring).

    Args:
        canonical: the canonical scene G^0 (N Gaussians; with ``init`` from a previous round,
            pass the canonical with that round's trained positions applied).
        dynamic_mask: [N] bool (or integer effect labels, 0 = static).
        views: training views; all clips [T,H,W,3] share T; references default to renders of
            ``canonical`` without deformation.
        init: deformation of the previous round (coefficients kept for Gaussians that stay dynamic).
        sds_fn: optional SDS hook, used when ``lambda_sds > 0``.
        failure_path: where the last good state goes if the update diverges.
    Returns:
        :class:`UpdateResult` with the trained canonical Gaussians and deformation (on CPU).
    """
    cfg = config if isinstance(config, UpdateConfig) else UpdateConfig.from_dict(config)
    cfg.validate()
    T = _check_views(views)
    dev = get_device(cfg.device)
    gen = seed_everything(cfg.seed)
    mask = torch.as_tensor(dynamic_mask)
    idx = dynamic_index_from_mask(mask, canonical.num)
    K = resolve_num_bases(cfg.num_bases, T, log)
    max_off, max_ang = limits_from_config(canonical.means, mask, cfg)

    if init is not None:
        if init.num_frames != T:
            raise ValueError(f"run_update: init model has T={init.num_frames} frames, the targets have T={T}")
        if init.num_bases != K:
            raise ValueError(f"run_update: init model has K={init.num_bases} bases, config resolves to K={K}")
        if init.rotation != cfg.rotation:
            raise ValueError(f"run_update: init model rotation={init.rotation}, config rotation={cfg.rotation}")
        deformation = init.remapped(idx, max_off, max_ang)
    else:
        deformation = DCTDeformation(idx, T, K, cfg.rotation, max_off, max_ang, canonical.num)
    deformation.set_active_bases(bases_from_config(mask, cfg, K))  # this update's capacity (None: all K)
    deformation.num_gaussians = canonical.num

    if idx.numel() == 0:
        log.info("model update: the dynamic set is empty: nothing to animate, the update is a no-op")
        return UpdateResult(canonical.detach(), deformation, skipped="empty dynamic set")
    if cfg.steps == 0 or K == 0:
        why = "steps = 0" if cfg.steps == 0 else f"K = 0 bases (T={T} frames)"
        log.info("model update: %s: nothing to train, the update is a no-op", why)
        return UpdateResult(canonical.detach(), deformation, skipped=why)
    return _Update(canonical, deformation, idx, views, cfg, dev, sds_fn, failure_path).train(gen, progress)


def _check_views(views: list[ViewData]) -> int:
    """T, the frames of every view's clip [T,H,W,3] (sized as its camera); ValueError otherwise."""
    if not views:
        raise ValueError("run_update: no training views")
    T = views[0].clip.shape[0]
    for i, v in enumerate(views):
        if v.clip.ndim != 4 or v.clip.shape[-1] != 3 or v.clip.shape[0] != T:
            raise ValueError(f"run_update: view {i} ({v.camera.name!r}) clip has shape {tuple(v.clip.shape)}; "
                             f"expected [T={T},H,W,3] like view 0")
        if tuple(v.clip.shape[1:3]) != (v.camera.height, v.camera.width):
            raise ValueError(f"run_update: view {i} clip is {v.clip.shape[2]}x{v.clip.shape[1]} but its camera is "
                             f"{v.camera.width}x{v.camera.height}")
    return T


class _Update:
    """One model update's training: targets on the device, trainable state, optimiser, the steps."""

    def __init__(self, canonical: Gaussians, deformation: DCTDeformation, idx: torch.Tensor, views: list[ViewData],
                 cfg: UpdateConfig, dev: torch.device, sds_fn: SDSHook | None,
                 failure_path: str | Path | None) -> None:
        self.cfg, self.dev, self.sds_fn, self.failure_path = cfg, dev, sds_fn, failure_path
        self.T = views[0].clip.shape[0]
        self.bg = bg = torch.tensor(cfg.background, dtype=torch.float32, device=dev)
        canonical = canonical.to(dev)
        self.deformation = deformation = deformation.to(dev)
        self.clips = [v.clip for v in views]  # kept as given (on disk, float16, ...); a step's frames become float32
        refs: list[torch.Tensor | None] = [None if v.reference is None else v.reference.to(dev, torch.float32)
                                           for v in views]
        if cfg.lambda_cano > 0 and any(r is None for r in refs):
            computed = static_references(canonical, [v.camera for v in views], bg, cfg.backend)
            refs = [r if r is not None else c for r, c in zip(refs, computed)]
        self.refs = refs
        self.cams = [v.camera for v in views]

        self.tr = tr = Trainable(canonical, idx.to(dev), cfg.param_groups)
        spatial = cfg.spatial_lr_scale if cfg.spatial_lr_scale is not None else box_diagonal(canonical.means)
        gamma = cfg.lr_final_factor ** (1.0 / max(cfg.steps, 1))
        self.opt = Adam(param_groups(cfg, deformation, tr, spatial), eps=1e-15, gamma=gamma)  # torch.optim's, minus 2.7 s of import
        self.trainables = [("pos_coeffs", deformation.pos_coeffs), ("rot_coeffs", deformation.rot_coeffs)] + list(tr.params.items())
        log.info("model update: N=%d Gaussians, D=%d dynamic, %d views, T=%d, K=%d, group=%s, steps=%d, spatial lr scale %.3g",
                 canonical.num, idx.numel(), len(views), self.T, deformation.num_bases, cfg.param_groups, cfg.steps,
                 spatial)
        if deformation.active_bases is not None:
            ks, counts = torch.unique(deformation.active_bases.cpu(), return_counts=True)
            log.info("model update: per-effect capacity: %s", ", ".join(
                f"{int(c)} Gaussians with K={int(k)}" for k, c in zip(ks, counts)))

    def save_state(self, path: Path, it: int, params: dict[str, torch.Tensor] | None = None) -> None:
        cfg, deformation, tr = self.cfg, self.deformation, self.tr
        with torch.no_grad():
            d_state = deformation
            if params is not None:  # restore the snapshot into a copy
                d_state = DCTDeformation.from_state({**deformation.state(), **{
                    k: params[k].cpu() for k in ("pos_coeffs", "rot_coeffs") if k in params}})
                for k, v in params.items():
                    if k in tr.params:
                        tr.params[k].data.copy_(v)
            save_model(path, d_state.cpu(), tr.canonical().detach().to("cpu"), cfg.to_dict(),
                       store_all_attributes=cfg.param_groups == "all", extra={"iteration": it, "last_good": True})

    def diverged(self, it: int, what: str, snapshot=None) -> UpdateDiverged:
        path = Path(self.failure_path) if self.failure_path is not None else None
        if path is not None:
            self.save_state(path, it, snapshot)
        where = f"; last good state saved to {path}" if path else " (no failure_path given: state not saved)"
        return UpdateDiverged(f"model update diverged at iteration {it}: {what}{where}", it, path)

    def render_subclip(self, view: int, start: int, length: int, grad_frame: int | None = None) -> torch.Tensor:
        g0 = self.tr.canonical()
        frames = []
        for j in range(length):
            t = min(max(start + j, 0), self.T - 1)
            if grad_frame is not None and j == grad_frame:
                frames.append(render_frame(g0, self.deformation, self.cams[view], t, self.bg, self.cfg.backend))
            else:
                with torch.no_grad():
                    frames.append(render_frame(g0, self.deformation, self.cams[view], t, self.bg, self.cfg.backend))
        return torch.stack(frames)

    def step(self, it: int, gen: torch.Generator) -> dict[str, float]:
        """One optimisation step: sample views and frames, the losses, backward, Adam; the losses' record."""
        cfg, T, V, cams, bg = self.cfg, self.T, len(self.cams), self.cams, self.bg
        deformation, trainables = self.deformation, self.trainables
        perm = torch.randperm(V, generator=gen)
        sel = [int(perm[i % V]) for i in range(cfg.views_per_step)]
        ts = torch.randint(0, T, (len(sel),), generator=gen).tolist()
        g0 = self.tr.canonical()
        renders = torch.stack([render_frame(g0, deformation, cams[v], t, bg, cfg.backend) for v, t in zip(sel, ts)])
        targets = torch.stack([self.clips[v][t].to(torch.float32) for v, t in zip(sel, ts)]).to(self.dev)
        l_ani = animation_loss(renders, targets)
        loss = l_ani
        rec = {"step": it, "l_ani": l_ani.item()}
        if cfg.lambda_cano > 0 and cfg.cano_views_per_step > 0:
            cv = sel[: cfg.cano_views_per_step]
            r0 = torch.stack([render_frame(g0, deformation, cams[v], 0, bg, cfg.backend) for v in cv])
            l_cano = canonical_loss(r0, torch.stack([self.refs[v] for v in cv]))
            loss = loss + cfg.lambda_cano * l_cano
            rec["l_cano"] = l_cano.item()
        if cfg.lambda_sds > 0 and self.sds_fn is not None:
            l_sds = self.sds_fn(SDSContext(self.render_subclip, V, T, gen, it))
            loss = loss + cfg.lambda_sds * l_sds
            rec["l_sds"] = l_sds.item()
        rec["loss"] = loss.item()
        if cfg.nan_guard and not math.isfinite(rec["loss"]):
            raise self.diverged(it, f"non-finite loss ({rec})")
        self.opt.zero_grad()
        loss.backward()
        snapshot = None
        if cfg.nan_guard:
            bad = first_non_finite((n, p.grad) for n, p in trainables if p is not None)
            if bad:
                raise self.diverged(it, f"non-finite gradient of {bad!r}")
            snapshot = {n: p.detach().clone() for n, p in trainables if p is not None}
        self.opt.step()
        if cfg.nan_guard:
            bad = first_non_finite((n, p) for n, p in trainables if p is not None)
            if bad:
                raise self.diverged(it, f"parameter {bad!r} became non-finite after the optimiser step", snapshot)
        return rec

    def train(self, gen: torch.Generator, progress: bool) -> UpdateResult:
        """``cfg.steps`` steps; the result on the CPU with the logged history."""
        from tqdm import tqdm

        cfg = self.cfg
        history: list[dict] = []
        t_start = time.perf_counter()
        bar = tqdm(range(1, cfg.steps + 1), desc="update", disable=not progress, mininterval=1.0, leave=False)
        for it in bar:
            rec = self.step(it, gen)
            if it % cfg.log_every == 0 or it == cfg.steps or it == 1:
                history.append(rec)
                bar.set_postfix(loss=f"{rec['loss']:.4f}")
                log.debug("update step %d: %s", it, rec)
        bar.close()
        seconds = time.perf_counter() - t_start
        log.info("model update done: %d steps in %.1f s (%.2f steps/s), final loss %.4f",
                 cfg.steps, seconds, cfg.steps / max(seconds, 1e-9), history[-1]["loss"] if history else float("nan"))
        out_canonical = self.tr.canonical().detach().to("cpu")
        deformation = self.deformation.cpu()
        for p in deformation.parameters():
            p.requires_grad_(False)
        return UpdateResult(out_canonical, deformation, history, cfg.steps, seconds)
