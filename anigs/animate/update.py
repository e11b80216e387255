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
from anigs.animate.deform import DCTDeformation, dynamic_index_from_mask, offset_limits, resolve_num_bases, save_model
from anigs.device import get_device, seed_everything
from anigs.geometry.extent import box_diagonal
from anigs.gaussians import Gaussians
from anigs.animate.losses import SDSContext, SDSHook, animation_loss, canonical_loss

log = logging.getLogger("anigs.animate.update")

PARAM_GROUPS = ("deformation+positions", "deformation", "all")
_UNLIMITED = 1e18  # stands for "no limit" in per-Gaussian limit tensors (finite: checkpoints refuse Inf)


@dataclass
class UpdateConfig:
    """Hyper-parameters of one model update (the ``update`` config section)."""

    steps: int = 600
    views_per_step: int = 2
    cano_views_per_step: int = 1
    num_bases: int = 16
    rotation: bool = True
    param_groups: str = "deformation+positions"
    lr_position_coeffs: float = 2e-3
    lr_rotation_coeffs: float = 5e-3
    lr_means: float = 2e-4
    lr_quats: float = 1e-3
    lr_scales: float = 5e-3
    lr_opacity: float = 2.5e-2
    lr_sh: float = 2.5e-3
    lr_final_factor: float = 0.1
    spatial_lr_scale: float | None = None
    lambda_cano: float = 0.1
    lambda_sds: float = 0.0
    sds_frames: int = 9
    max_offset_frac: float | None = None
    max_offset_abs: float | None = None
    max_angle_deg: float | None = None
    effect_limits: dict = field(default_factory=dict)
    effect_num_bases: dict = field(default_factory=lambda: {"grass_wave": 6, "flower_bob": 6})  # per-effect capacity, {key: K_e <= num_bases}: the Gaussians of that effect use only the first K_e DCT bases (the rest stay zero); key = a label of an int --dynamic mask ("1", "2", ...; with a bool mask every dynamic Gaussian is "1") or an effect name (foliage_sway, leaf_flutter: label 1, grass_wave 2, flower_bob 3, water_ripple 4 = 1 + the effects stage's region index; effects sharing a label take their largest K_e, unnamed ones count as num_bases); {} = all use num_bases. Default: grass and flowers 6 (demo, labels from the masks stage: their amplitude W1 2.1x / 2.7x and frequency W1 1.8x / 1.9x lower than at 12, foliage unchanged, the same time: benchmarks/README.md)
    background: list = field(default_factory=lambda: [0.0, 0.0, 0.0])
    seed: int = 0
    device: str = "auto"
    backend: str = "auto"
    log_every: int = 25
    nan_guard: bool = True
    contain: bool = True  # with the masks: after training, a Gaussian whose motion carries its footprint out of a view's dilated mask moves less (1/2, 1/4) or stays still
    contain_margin_px: int = 3  # containment: each view's mask is dilated by this many pixels first (the still-pixel metric forgives 5)
    contain_max_outside_px: float = 0.01  # containment: most blending weight (in pixels) a moving Gaussian may put outside, in any frame and view (0.05 left 1-3 levels of change on flower-llff)
    contain_rounds: str = "final"  # which rounds' updates contain the motion (the workflow passes --masks to them): final (the model that is rendered, exported and evaluated; an earlier round's model only renders the next round's clips, whose static pixels ComposedV2V pastes back from frame 0) or every

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


def effect_labels() -> dict[str, int]:
    """Effect name -> its label in an int dynamic mask (:func:`anigs.masks.effect_labels.effect_label_ids`)."""
    from anigs.effects.labels import effect_label_ids

    return effect_label_ids()


def bases_from_config(mask: torch.Tensor, cfg: UpdateConfig, num_bases: int) -> torch.Tensor | None:
    """Bases K_d [D] long each dynamic Gaussian uses, from ``effect_num_bases`` (None when it is empty).

    ``mask`` [N] is bool or integer effect labels (0 = static); keys are labels (as strings) or
    effect names (:func:`effect_labels`; several effects on one label: the largest K_e, an effect
    not named counting as ``cfg.num_bases``). Values are clamped to ``num_bases`` (the K resolved for T).
    """
    if not cfg.effect_num_bases:
        return None
    mask = torch.as_tensor(mask)
    idx = dynamic_index_from_mask(mask)
    labels = mask[idx].long() if mask.dtype != torch.bool else torch.ones_like(idx)
    names = effect_labels()
    per_label: dict[int, int] = {}
    by_name = {k: v for k, v in cfg.effect_num_bases.items() if k in names}
    if by_name and mask.dtype == torch.bool:
        log.warning("update: effect_num_bases names effects %s but the dynamic mask is bool (no per-Gaussian effect "
                    "labels: pass --effect-labels, the masks stage's effect_labels.npy): every dynamic Gaussian uses "
                    "%d bases", sorted(by_name), num_bases)
        by_name = {}
        if not any(k not in names for k in cfg.effect_num_bases):
            return None
    for name in by_name:
        lab = names[name]
        shared = [e for e, lb in names.items() if lb == lab]
        per_label[lab] = max(int(cfg.effect_num_bases.get(e, cfg.num_bases)) for e in shared)
    for key, k in cfg.effect_num_bases.items():
        if key not in names:
            per_label[int(key)] = int(k)
    kd = torch.full((idx.numel(),), int(num_bases), dtype=torch.long)
    for lab, k in per_label.items():
        kd[labels.cpu() == lab] = min(k, int(num_bases))
    return kd


@dataclass
class ViewData:
    """One training view: camera, target clip [T,H,W,3] in [0,1], static reference [H,W,3] (optional)."""

    camera: Camera
    clip: torch.Tensor
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


def limits_from_config(canonical_means: torch.Tensor, mask: torch.Tensor, cfg: UpdateConfig
                       ) -> tuple[torch.Tensor | None, torch.Tensor | None]:
    """Per-dynamic-Gaussian offset [D] and angle [D] limits from the config (None = unlimited).

    ``mask`` [N] is bool or integer effect labels (0 = static); ``effect_limits`` keys are
    labels (as strings) whose entries override the global limits.
    """
    mask = torch.as_tensor(mask)
    idx = dynamic_index_from_mask(mask, canonical_means.shape[0])
    labels = mask[idx].long() if mask.dtype != torch.bool else torch.ones_like(idx)
    d = idx.numel()
    off = torch.full((d,), _UNLIMITED)
    ang = torch.full((d,), _UNLIMITED)
    any_off = any_ang = False
    for lab in torch.unique(labels).tolist():
        spec = {"max_offset_frac": cfg.max_offset_frac, "max_offset_abs": cfg.max_offset_abs,
                "max_angle_deg": cfg.max_angle_deg}
        spec.update(cfg.effect_limits.get(str(lab), {}))
        sel = labels == lab
        lim = offset_limits(canonical_means, idx[sel], spec["max_offset_frac"], spec["max_offset_abs"])
        if lim is not None:
            off[sel] = lim.float().cpu()
            any_off = True
        if spec["max_angle_deg"] is not None:
            if spec["max_angle_deg"] <= 0:
                raise ValueError(f"max_angle_deg must be > 0, got {spec['max_angle_deg']}")
            ang[sel] = math.radians(spec["max_angle_deg"])
            any_ang = True
    return (off if any_off else None), (ang if any_ang else None)


class _Trainable:
    """The trainable canonical state for a parameter group; builds G^0 each step."""

    def __init__(self, canonical: Gaussians, idx: torch.Tensor, group: str) -> None:
        self.group = group
        self.idx = idx
        base = canonical.detach()
        self.base = base
        self.params: dict[str, torch.Tensor] = {}
        if group == "deformation+positions":
            self.params["dyn_means"] = base.means[idx].clone().requires_grad_(True)
        elif group == "all":
            for k, v in base.params().items():
                self.params[k] = v.clone().requires_grad_(True)

    def canonical(self) -> Gaussians:
        b = self.base
        if self.group == "deformation+positions":
            return Gaussians(b.means.index_copy(0, self.idx, self.params["dyn_means"]), b.quats, b.log_scales,
                             b.opacity_logits, b.sh, extras=b.extras)
        if self.group == "all":
            return Gaussians(**self.params, extras=b.extras)
        return b


def _param_groups(cfg: UpdateConfig, deformation: DCTDeformation, tr: _Trainable, spatial: float) -> list[dict]:
    groups = [{"params": [deformation.pos_coeffs], "lr": cfg.lr_position_coeffs * spatial, "name": "pos_coeffs"}]
    if deformation.rot_coeffs is not None:
        groups.append({"params": [deformation.rot_coeffs], "lr": cfg.lr_rotation_coeffs, "name": "rot_coeffs"})
    lrs = {"dyn_means": cfg.lr_means * spatial, "means": cfg.lr_means * spatial, "quats": cfg.lr_quats,
           "log_scales": cfg.lr_scales, "opacity_logits": cfg.lr_opacity, "sh": cfg.lr_sh}
    for k, p in tr.params.items():
        groups.append({"params": [p], "lr": lrs[k], "name": k})
    return groups


def _all_finite(tensors) -> str | None:
    for name, t in tensors:
        if t is not None and not bool(torch.isfinite(t).all()):
            return name
    return None


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

    bg = torch.tensor(cfg.background, dtype=torch.float32, device=dev)
    canonical = canonical.to(dev)
    deformation = deformation.to(dev)
    clips = [v.clip.to(torch.float32) for v in views]  # kept where they are; sampled frames move per step
    refs: list[torch.Tensor | None] = [None if v.reference is None else v.reference.to(dev, torch.float32)
                                       for v in views]
    if cfg.lambda_cano > 0 and any(r is None for r in refs):
        computed = static_references(canonical, [v.camera for v in views], bg, cfg.backend)
        refs = [r if r is not None else c for r, c in zip(refs, computed)]
    cams = [v.camera for v in views]

    tr = _Trainable(canonical, idx.to(dev), cfg.param_groups)
    spatial = cfg.spatial_lr_scale if cfg.spatial_lr_scale is not None else box_diagonal(canonical.means)
    gamma = cfg.lr_final_factor ** (1.0 / max(cfg.steps, 1))
    opt = Adam(_param_groups(cfg, deformation, tr, spatial), eps=1e-15, gamma=gamma)  # torch.optim's, minus 2.7 s of import
    trainables = [("pos_coeffs", deformation.pos_coeffs), ("rot_coeffs", deformation.rot_coeffs)] + list(tr.params.items())
    log.info("model update: N=%d Gaussians, D=%d dynamic, %d views, T=%d, K=%d, group=%s, steps=%d, spatial lr scale %.3g",
             canonical.num, idx.numel(), len(views), T, K, cfg.param_groups, cfg.steps, spatial)
    if deformation.active_bases is not None:
        ks, counts = torch.unique(deformation.active_bases.cpu(), return_counts=True)
        log.info("model update: per-effect capacity: %s", ", ".join(
            f"{int(c)} Gaussians with K={int(k)}" for k, c in zip(ks, counts)))

    def save_state(path: Path, it: int, params: dict[str, torch.Tensor] | None = None) -> None:
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

    def diverged(it: int, what: str, snapshot=None) -> UpdateDiverged:
        path = Path(failure_path) if failure_path is not None else None
        if path is not None:
            save_state(path, it, snapshot)
        where = f"; last good state saved to {path}" if path else " (no failure_path given: state not saved)"
        return UpdateDiverged(f"model update diverged at iteration {it}: {what}{where}", it, path)

    def render_subclip(view: int, start: int, length: int, grad_frame: int | None = None) -> torch.Tensor:
        g0 = tr.canonical()
        frames = []
        for j in range(length):
            t = min(max(start + j, 0), T - 1)
            if grad_frame is not None and j == grad_frame:
                frames.append(render_frame(g0, deformation, cams[view], t, bg, cfg.backend))
            else:
                with torch.no_grad():
                    frames.append(render_frame(g0, deformation, cams[view], t, bg, cfg.backend))
        return torch.stack(frames)

    history: list[dict] = []
    t_start = time.perf_counter()
    from tqdm import tqdm

    bar = tqdm(range(1, cfg.steps + 1), desc="update", disable=not progress, mininterval=1.0, leave=False)
    V = len(views)
    for it in bar:
        perm = torch.randperm(V, generator=gen)
        sel = [int(perm[i % V]) for i in range(cfg.views_per_step)]
        ts = torch.randint(0, T, (len(sel),), generator=gen).tolist()
        g0 = tr.canonical()
        renders = torch.stack([render_frame(g0, deformation, cams[v], t, bg, cfg.backend) for v, t in zip(sel, ts)])
        targets = torch.stack([clips[v][t] for v, t in zip(sel, ts)]).to(dev)
        l_ani = animation_loss(renders, targets)
        loss = l_ani
        rec = {"step": it, "l_ani": l_ani.item()}
        if cfg.lambda_cano > 0 and cfg.cano_views_per_step > 0:
            cv = sel[: cfg.cano_views_per_step]
            r0 = torch.stack([render_frame(g0, deformation, cams[v], 0, bg, cfg.backend) for v in cv])
            l_cano = canonical_loss(r0, torch.stack([refs[v] for v in cv]))
            loss = loss + cfg.lambda_cano * l_cano
            rec["l_cano"] = l_cano.item()
        if cfg.lambda_sds > 0 and sds_fn is not None:
            l_sds = sds_fn(SDSContext(render_subclip, V, T, gen, it))
            loss = loss + cfg.lambda_sds * l_sds
            rec["l_sds"] = l_sds.item()
        rec["loss"] = loss.item()
        if cfg.nan_guard and not math.isfinite(rec["loss"]):
            raise diverged(it, f"non-finite loss ({rec})")
        opt.zero_grad()
        loss.backward()
        snapshot = None
        if cfg.nan_guard:
            bad = _all_finite((n, p.grad) for n, p in trainables if p is not None)
            if bad:
                raise diverged(it, f"non-finite gradient of {bad!r}")
            snapshot = {n: p.detach().clone() for n, p in trainables if p is not None}
        opt.step()
        if cfg.nan_guard:
            bad = _all_finite((n, p) for n, p in trainables if p is not None)
            if bad:
                raise diverged(it, f"parameter {bad!r} became non-finite after the optimiser step", snapshot)
        if it % cfg.log_every == 0 or it == cfg.steps or it == 1:
            history.append(rec)
            bar.set_postfix(loss=f"{rec['loss']:.4f}")
            log.debug("update step %d: %s", it, rec)
    bar.close()
    seconds = time.perf_counter() - t_start
    log.info("model update done: %d steps in %.1f s (%.2f steps/s), final loss %.4f",
             cfg.steps, seconds, cfg.steps / max(seconds, 1e-9), history[-1]["loss"] if history else float("nan"))
    out_canonical = tr.canonical().detach().to("cpu")
    deformation = deformation.cpu()
    for p in deformation.parameters():
        p.requires_grad_(False)
    return UpdateResult(out_canonical, deformation, history, cfg.steps, seconds)
