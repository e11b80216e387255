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
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

import torch

from anigs.animate.adam import Adam
from anigs.animate.frames import render_frame
from anigs.cameras import Camera
from anigs.typed_config import from_dict
from anigs.animate.deform import DCTDeformation, dynamic_index_from_mask, resolve_num_bases, save_model
from anigs.animate.limits import bases_from_config, effect_labels, limits_from_config
from anigs.animate.trainable import Trainable, first_non_finite, param_groups
from anigs.device import get_device, seed_everything
from anigs.geometry.extent import box_diagonal
from anigs.gaussians import Gaussians
from anigs.animate.losses import SDSContext, SDSHook, animation_loss, canonical_loss
from anigs.animate.target_frames import ClipFrames

log = logging.getLogger("anigs.animate.update")

__all__ = ["PARAM_GROUPS", "UpdateConfig", "UpdateDiverged", "UpdateResult", "ViewData", "bases_from_config",
           "effect_labels", "limits_from_config", "run_update", "static_references"]

PARAM_GROUPS = ("deformation+positions", "deformation", "all")


@dataclass
class UpdateConfig:
    """Hyper-parameters of one model update (the ``update`` config section)."""

    steps: int = 600  # optimisation steps per round
    views_per_step: int = 2  # (view, t) samples per step for the animation loss
    cano_views_per_step: int = 1  # views per step for the canonical loss (frame 0 vs the static render)
    num_bases: int = 16  # K: DCT bases per motion channel (clamped to T-1)
    rotation: bool = True  # learn per-Gaussian rotation offsets as well as position offsets
    #: trainable parameters: deformation+positions (paper) | deformation | all
    param_groups: str = "deformation+positions"
    lr_position_coeffs: float = 2e-3  # learning rate of the position DCT coefficients (times spatial_lr_scale)
    lr_rotation_coeffs: float = 5e-3  # learning rate of the rotation DCT coefficients
    lr_means: float = 2e-4  # learning rate of the canonical positions (times spatial_lr_scale)
    lr_quats: float = 1e-3  # learning rate of the rotations
    lr_scales: float = 5e-3  # learning rate of the log-scales
    lr_opacity: float = 2.5e-2  # learning rate of the opacity logits
    lr_sh: float = 2.5e-3  # learning rate of the SH coefficients (param_groups all)
    lr_final_factor: float = 0.1  # learning rates decay exponentially to this fraction at the last step
    #: length scale of position learning rates (null = 1-99 percentile scene extent)
    spatial_lr_scale: float | None = None
    lambda_cano: float = 0.1  # weight of the canonical loss
    lambda_sds: float = 0.0  # weight of the SDS loss (needs a prior with a score: ltx)
    sds_frames: int = 9  # frames of the SDS sub-clip (4m+1)
    #: smooth limit on offsets as a fraction of the height above the ground (null = none)
    max_offset_frac: float | None = None
    max_offset_abs: float | None = None  # smooth absolute limit on offsets in world units (null = none)
    max_angle_deg: float | None = None  # smooth limit on rotation offsets in degrees (null = none)
    effect_limits: dict = field(default_factory=dict)  # per-effect-label overrides of the three limits
    #: per-effect capacity, {key: K_e <= num_bases}: the Gaussians of that effect use only the first K_e DCT bases (the
    #: rest stay zero); key = a label of the masks stage's effect labels ("1", "2", ...; without them every dynamic Gaussian
    #: is "1") or an effect name (foliage_sway, leaf_flutter: label 1, grass_wave 2, flower_bob 3, water_ripple 4 = 1 +
    #: the effects stage's region index; effects sharing a label take their largest K_e, unnamed ones count as
    #: num_bases); {} = all use num_bases. Default: grass and flowers 6 (demo, labels from the masks stage: their
    #: amplitude W1 2.1x / 2.7x and frequency W1 1.8x / 1.9x lower than at 12, foliage unchanged, the same time:
    #: benchmarks/README.md)
    effect_num_bases: dict = field(default_factory=lambda: {"grass_wave": 6, "flower_bob": 6})
    background: list = field(default_factory=lambda: [0.0, 0.0, 0.0])  # background colour (RGB in [0,1])
    seed: int = 0  # random seed (the workflow passes the global seed)
    device: str = "auto"  # torch device: auto picks CUDA when present (the workflow passes the global device)
    backend: str = "auto"  # rasterizer backend: auto | cpu | torch | gsplat
    log_every: int = 25  # log the loss every this many steps
    nan_guard: bool = True  # stop on NaN loss or gradients, saving the last good state
    #: with the masks: after training, a Gaussian whose motion carries its footprint out of a view's dilated mask moves
    #: less (1/2, 1/4) or stays still
    contain: bool = True
    #: containment: each view's mask is dilated by this many pixels first (the still-pixel metric forgives 5)
    contain_margin_px: int = 3
    #: containment: most blending weight (in pixels) a moving Gaussian may put outside, in any frame and view (0.05
    #: left 1-3 levels of change on flower-llff)
    contain_max_outside_px: float = 0.01
    #: which rounds' updates contain the motion (the update stage decides from --round/--rounds): final (the model that is
    #: rendered, exported and evaluated; an earlier round's model only renders the next round's clips, whose static
    #: pixels ComposedV2V pastes back from frame 0) or every
    contain_rounds: str = "final"

    @staticmethod
    def from_dict(d: dict[str, Any] | None) -> "UpdateConfig":
        cfg = from_dict(UpdateConfig, d, "update config", KeyError)
        cfg.validate()
        return cfg

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        if not d["effect_num_bases"]:  # opt-in key: unused, the recorded config is the one before it existed
            del d["effect_num_bases"]
        return d

    def validate(self) -> None:
        if self.param_groups not in PARAM_GROUPS:
            raise ValueError(f"update config: param_groups={self.param_groups!r}; choose one of {PARAM_GROUPS}")
        if self.steps < 0 or self.views_per_step < 1 or self.cano_views_per_step < 0:
            raise ValueError("update config: steps >= 0, views_per_step >= 1, cano_views_per_step >= 0 required")
        if self.num_bases < 0:
            raise ValueError(f"update config: num_bases must be >= 0, got {self.num_bases}")
        for k in ("lambda_cano", "lambda_sds"):
            if getattr(self, k) < 0:
                raise ValueError(f"update config: {k} must be >= 0")
        if self.sds_frames < 1 or self.sds_frames % 4 != 1:
            raise ValueError(f"update config: sds_frames must be 4m+1 (1, 5, 9, ...), got {self.sds_frames}")
        for f in fields(self):
            if f.name.startswith("lr_") and not (math.isfinite(getattr(self, f.name)) and getattr(self, f.name) > 0):
                raise ValueError(f"update config: {f.name} must be a finite positive number, got {getattr(self, f.name)}")
        if self.contain_margin_px < 0 or not self.contain_max_outside_px >= 0:
            raise ValueError("update config: contain_margin_px and contain_max_outside_px must be >= 0")
        if not 0 < self.lr_final_factor <= 1:
            raise ValueError("update config: lr_final_factor must be in (0, 1]")
        if len(self.background) != 3:
            raise ValueError("update config: background must be 3 numbers")
        if self.contain_rounds not in ("final", "every"):
            raise ValueError(f"update config: contain_rounds={self.contain_rounds!r}; choose final or every")
        for key, lim in self.effect_limits.items():
            bad = set(lim) - {"max_offset_frac", "max_offset_abs", "max_angle_deg"}
            if bad:
                raise KeyError(f"update config: effect_limits[{key!r}] has unknown key(s) {sorted(bad)}")
        if self.effect_num_bases:
            names = effect_labels()
            for key, k in self.effect_num_bases.items():
                if not (str(key) in names or (str(key).isdigit() and int(key) > 0)):
                    raise KeyError(f"update config: effect_num_bases key {key!r} is unknown: give an effect label "
                                   f"(1, 2, ... as a string) or an effect name ({', '.join(names)})")
                if isinstance(k, bool) or not isinstance(k, int) or k < 1:
                    raise ValueError(f"update config: effect_num_bases[{key!r}] = {k!r}: must be an integer >= 1 "
                                     f"(above num_bases = {self.num_bases} it changes nothing)")
            twice = {names[k] for k in self.effect_num_bases if k in names} & {
                int(k) for k in self.effect_num_bases if k not in names}
            if twice:
                raise ValueError(f"update config: effect_num_bases gives label(s) {sorted(twice)} both by number "
                                 "and by effect name")


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
