"""Adaptive density control for 3DGS training, kept separate from rendering (gsplat-style).

The strategy works on a dict of trainable per-Gaussian parameters (leaf tensors whose first
dimension is the Gaussian count N, e.g. ``means [N,3]``, ``quats [N,4]``, ``log_scales [N,3]``,
``opacity_logits [N]``, ``sh_dc [N,1,3]``, ``sh_rest [N,C-1,3]``) and one ``torch.optim.Adam``
whose param groups carry a ``"name"`` equal to the dict key. ``means``, ``quats``,
``log_scales`` and ``opacity_logits`` are required; every other entry is copied row-wise.

Usage, per training step::

    rgb, alpha, meta = rasterize(...)
    if stats_needed(cfg, step):           # False after the last scheduled densification
        meta["means2d"].retain_grad()
    loss.backward()
    if stats_needed(cfg, step):
        update_state(state, meta, width, height)
    optimizer.step(); optimizer.zero_grad()
    params = refine(params, optimizer, state, step, cfg, scene_extent, generator)

The optimizer may be fused (``torch.optim.Adam(fused=True)``): refinement moves each
parameter's state (moments and step count) to the new tensor, rows gathered like the
parameter's own.

Gradient threshold units follow the original 3DGS: the screen-space gradient is measured in
NDC units, i.e. the pixel-space gradient of ``means2d`` times ``(width/2, height/2)``.
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field, replace
from typing import Any, ClassVar

import torch

from anigs.typed_config import Section
from anigs.geometry.quaternion import quat_to_rotmat

log = logging.getLogger(__name__)

REQUIRED = ("means", "quats", "log_scales", "opacity_logits")
GROWTH = ("budget", "threshold")
BUDGET_FLOOR = 0.25  # budget growth: candidates need at least this share of grad_threshold


class AllPrunedError(RuntimeError):
    """Raised when a refinement step would remove every Gaussian."""


@dataclass
class DensifyConfig(Section):
    """Densification hyperparameters (iterations are 1-based training steps)."""

    start: int = 300  # first step that clones/splits/prunes
    stop: int | None = None  # no densification or opacity reset from this step on (null: stop_fraction of the steps)
    stop_fraction: float = 0.8  # ... nor after this fraction of the fit's iterations (new splats need steps to settle)
    every: int = 100  # refine interval
    grad_threshold: float = 0.0002  # mean NDC-space gradient norm of means2d that triggers densification
    dense_percent: float = 0.01  # clone if max scale <= this * scene extent, else split
    split_factor: float = 1.6  # split children have scales / this
    prune_opacity: float = 0.005  # prune below this opacity
    prune_screen_size: float = 0.15  # prune max radius above this fraction of max(W,H) (from prune_size_from)
    prune_world_size: float = 0.1  # prune max scale above this fraction of the scene extent (from prune_size_from)
    prune_size_from: int = 0  # first step of size-based pruning (0 = never: it punches holes in short schedules)
    reset_every: int = 0  # opacity reset interval (0 = never: short CPU schedules do better without)
    reset_opacity: float = 0.01  # opacities are clamped to at most this on reset
    max_gaussians: int | None = None  # densification never grows the set beyond this (null: from static.budget)
    #: "budget": each densification step grows the set along a straight line from its size at the first
    #: step to max_gaussians at the last, taking the candidates with the largest gradients (a rank, so
    #: the image size does not move it; grad_threshold / 4 is the floor); "threshold": every Gaussian
    #: above grad_threshold, up to max_gaussians (3DGS; what anigs 0.7 did)
    growth: str = "budget"

    WHERE: ClassVar[str] = "densify config"

    def validate(self) -> None:
        if self.every < 1:
            raise ValueError(f"densify.every must be >= 1, got {self.every}")
        if not 0 < self.stop_fraction <= 1:
            raise ValueError(f"densify.stop_fraction must be in (0, 1], got {self.stop_fraction}")
        if self.max_gaussians is not None and self.max_gaussians < 1:
            raise ValueError(f"densify.max_gaussians must be >= 1, got {self.max_gaussians}")
        if not 0 <= self.prune_opacity < 1:
            raise ValueError(f"densify.prune_opacity must be in [0,1), got {self.prune_opacity}")
        if not 0 < self.reset_opacity < 1:
            raise ValueError(f"densify.reset_opacity must be in (0,1), got {self.reset_opacity}")
        if self.growth not in GROWTH:
            raise ValueError(f"densify.growth must be one of {list(GROWTH)}, got {self.growth!r}")
        if self.split_factor <= 1:
            raise ValueError(f"densify.split_factor must be > 1, got {self.split_factor}")


@dataclass
class DensifyState:
    """Statistics accumulated between refinements, one row per Gaussian.

    grad_sum [N]: sum of NDC-space means2d gradient norms over the views that saw the Gaussian;
    count [N]: number of those views; max_radii [N]: largest screen radius seen, as a fraction of
    max(W,H). ``last`` holds the counts of the most recent refinement.
    """

    grad_sum: torch.Tensor
    count: torch.Tensor
    max_radii: torch.Tensor
    last: dict[str, int] = field(default_factory=dict)
    first_count: int | None = None  # the set's size at the first densification (budget growth starts there)

    @staticmethod
    def empty(n: int, device: torch.device | str = "cpu") -> "DensifyState":
        return DensifyState(torch.zeros(n, device=device), torch.zeros(n, device=device),
                            torch.zeros(n, device=device))

    @property
    def num(self) -> int:
        return self.grad_sum.shape[0]

    def reset(self, n: int | None = None) -> None:
        n = self.num if n is None else n
        dev = self.grad_sum.device
        self.grad_sum = torch.zeros(n, device=dev)
        self.count = torch.zeros(n, device=dev)
        self.max_radii = torch.zeros(n, device=dev)


@torch.no_grad()
def update_state(state: DensifyState, meta: dict[str, Any], width: int, height: int) -> None:
    """Accumulate screen-space gradient norms and radii after ``loss.backward()``.

    ``meta`` is the rasterizer's meta dict; ``meta["means2d"]`` [N,2] must have had
    ``retain_grad()`` called before backward. Gaussians with ``radii == 0`` (culled) are skipped.
    """
    means2d = meta["means2d"]
    grad = means2d.grad if (means2d.is_leaf or means2d.retains_grad) else None
    if grad is None:
        raise RuntimeError("densify.update_state: meta['means2d'].grad is None; call "
                           "meta['means2d'].retain_grad() before loss.backward()")
    radii = meta["radii"]
    n = grad.shape[0]
    if n != state.num:
        raise ValueError(f"densify.update_state: state has {state.num} rows but the render has {n} Gaussians")
    # one pass per statistic, no copy of the gradient: NDC norm, visible and finite -> sum,
    # visible -> count, radius fraction -> running max (all in place)
    norms = torch.linalg.vector_norm(grad * grad.new_tensor([width / 2.0, height / 2.0]), dim=-1)
    vis = radii > 0
    state.grad_sum.add_(torch.where(vis & torch.isfinite(norms), norms, 0.0))
    state.count.add_(vis)
    torch.maximum(state.max_radii, radii / float(max(width, height)), out=state.max_radii)


def _stop(cfg: DensifyConfig) -> int:
    if cfg.stop is None:
        raise ValueError("densify: stop is not set; resolve the schedule with schedule_for(cfg, iterations) first")
    return cfg.stop


def stats_needed(cfg: DensifyConfig, step: int) -> bool:
    """Whether :func:`update_state` at ``step`` can still matter: some densification step
    ``s >= step`` is scheduled (start <= s < stop, s a multiple of every). After the last one
    the statistics are never read, so the fit skips them (and ``retain_grad``)."""
    last = ((_stop(cfg) - 1) // cfg.every) * cfg.every
    return cfg.start <= last and step <= last


def _densify_due(cfg: DensifyConfig, step: int) -> bool:
    return cfg.start <= step < _stop(cfg) and step % cfg.every == 0


def _reset_due(cfg: DensifyConfig, step: int) -> bool:
    return cfg.reset_every > 0 and step < _stop(cfg) and step % cfg.reset_every == 0


def refine_due(cfg: DensifyConfig, step: int) -> bool:
    """Whether :func:`refine` changes anything at ``step`` (a densification or an opacity reset)."""
    return _densify_due(cfg, step) or _reset_due(cfg, step)


def replace_rows(params: dict[str, torch.Tensor], optimizer: torch.optim.Optimizer,
                  new_values: dict[str, torch.Tensor], src: torch.Tensor,
                  is_new: torch.Tensor) -> dict[str, torch.Tensor]:
    """Swap every parameter for its new rows and carry Adam moments: row i of the result takes
    the moments of old row ``src[i]``, or zeros where ``is_new[i]``."""
    out = {}
    by_name = {g.get("name"): g for g in optimizer.param_groups}
    for name, old in params.items():
        new = torch.nn.Parameter(new_values[name].detach().contiguous(), requires_grad=old.requires_grad)
        out[name] = new
        group = by_name.get(name)
        if group is None:
            continue
        if len(group["params"]) != 1 or group["params"][0] is not old:
            raise RuntimeError(f"densify: optimizer group {name!r} does not hold exactly the parameter being refined")
        st = optimizer.state.pop(old, None)
        group["params"][0] = new
        if st:
            for key in ("exp_avg", "exp_avg_sq", "max_exp_avg_sq"):
                if key in st and torch.is_tensor(st[key]) and st[key].shape[:1] == old.shape[:1]:
                    m = st[key][src]  # advanced indexing: already a copy
                    m[is_new] = 0
                    st[key] = m
            optimizer.state[new] = st
    return out


def gather(params: dict[str, torch.Tensor], src: torch.Tensor) -> dict[str, torch.Tensor]:
    return {k: v.detach()[src] for k, v in params.items()}


@torch.no_grad()
def reset_opacity(params: dict[str, torch.Tensor], optimizer: torch.optim.Optimizer, value: float) -> None:
    """Clamp opacities to at most ``value`` and zero the opacity Adam moments (in place)."""
    op = params["opacity_logits"]
    op.data = torch.minimum(op.data, torch.full_like(op.data, math.log(value / (1 - value))))
    st = optimizer.state.get(op)
    if st:
        for key in ("exp_avg", "exp_avg_sq"):
            if key in st:
                st[key].zero_()


def schedule_for(cfg: DensifyConfig, iterations: int) -> DensifyConfig:
    """``cfg`` with ``stop`` at most ``stop_fraction * iterations`` (``stop`` unset: exactly that): a
    fit of any length ends with steps free of densification (a split or clone at the last step
    would leave untrained splats: demo, 500 iterations with stop 1200: held-out 21.6 dB; stopping
    at 400: 26.3 dB)."""
    cap = int(cfg.stop_fraction * iterations)
    return replace(cfg, stop=cap if cfg.stop is None else min(cfg.stop, cap))


def growth_target(cfg: DensifyConfig, step: int, first_count: int) -> int:
    """Budget growth: the set's size after the densification at ``step``, on a straight line from
    ``first_count`` (before the first densification, at ``cfg.start`` rounded up to ``cfg.every``)
    to ``cfg.max_gaussians`` (after the last, before ``cfg.stop``)."""
    first = -(-max(cfg.start, 1) // cfg.every) * cfg.every
    last = ((_stop(cfg) - 1) // cfg.every) * cfg.every
    if last <= first:
        return int(cfg.max_gaussians)
    k = (step - first) // cfg.every + 1
    frac = min(1.0, k / ((last - first) // cfg.every + 1))
    return int(round(first_count + (cfg.max_gaussians - first_count) * frac))


@torch.no_grad()
def refine(params: dict[str, torch.Tensor], optimizer: torch.optim.Optimizer, state: DensifyState, step: int,
           cfg: DensifyConfig, scene_extent: float,
           generator: torch.Generator | None = None) -> dict[str, torch.Tensor]:
    """Clone, split, prune and reset opacity as scheduled for ``step``; return the (new) params.

    Call after ``optimizer.step()``. New rows start with zero Adam moments; pruned rows lose
    theirs. The state is reset after each densification. Raises :class:`AllPrunedError` when
    no Gaussian would survive.
    """
    missing = [k for k in REQUIRED if k not in params]
    if missing:
        raise KeyError(f"densify.refine: params lack {missing}")
    if _densify_due(cfg, step):
        params = _densify_and_prune(params, optimizer, state, step, cfg, scene_extent, generator)
    if _reset_due(cfg, step):
        reset_opacity(params, optimizer, cfg.reset_opacity)
        state.last["opacity_reset"] = 1
    return params


def _densify_and_prune(params, optimizer, state: DensifyState, step: int, cfg: DensifyConfig, extent: float,
                       generator: torch.Generator | None) -> dict[str, torch.Tensor]:
    means = params["means"].detach()
    n = means.shape[0]
    dev = means.device
    if state.num != n:
        raise ValueError(f"densify.refine: state has {state.num} rows but params have {n}")
    scales = params["log_scales"].detach().exp()
    max_scale = scales.max(dim=1).values
    avg_grad = state.grad_sum / state.count.clamp_min(1)
    budget_growth = cfg.growth == "budget" and cfg.max_gaussians is not None
    if state.first_count is None:
        state.first_count = n
    candidates = avg_grad >= cfg.grad_threshold * (BUDGET_FLOOR if budget_growth else 1.0)
    big = max_scale > cfg.dense_percent * extent
    opac = torch.sigmoid(params["opacity_logits"].detach())

    # prune mask on the existing rows
    low = opac < cfg.prune_opacity
    too_big = torch.zeros_like(low)
    if 0 < cfg.prune_size_from <= step:
        too_big = (state.max_radii > cfg.prune_screen_size) | (max_scale > cfg.prune_world_size * extent)
    prune = low | too_big
    candidates &= ~prune

    # budget: survivors + clones + split children (2 per split replacing one) <= max_gaussians
    survivors = int((~prune).sum())
    cap = n + int(candidates.sum()) if cfg.max_gaussians is None else cfg.max_gaussians
    if budget_growth:
        cap = min(cap, growth_target(cfg, step, state.first_count))
    room = max(0, cap - survivors)
    cand_idx = torch.nonzero(candidates, as_tuple=False).squeeze(1)
    if cand_idx.numel() > room:  # each candidate adds one row net
        order = torch.argsort(avg_grad[cand_idx], descending=True, stable=True)
        cand_idx = cand_idx[order[:room]]
    chosen = torch.zeros(n, dtype=torch.bool, device=dev)
    chosen[cand_idx] = True
    clone = chosen & ~big
    split = chosen & big
    clone_idx = torch.nonzero(clone, as_tuple=False).squeeze(1)
    split_idx = torch.nonzero(split, as_tuple=False).squeeze(1)

    keep = ~prune & ~split
    keep_idx = torch.nonzero(keep, as_tuple=False).squeeze(1)
    if keep_idx.numel() + clone_idx.numel() + 2 * split_idx.numel() == 0:
        raise AllPrunedError(
            f"densify: all {n} Gaussians would be pruned at step {step} ({int(low.sum())} with opacity < "
            f"{cfg.prune_opacity}, {int(too_big.sum())} too large on screen or in the world); the fit cannot "
            "continue. Check the images/cameras, or lower densify.prune_opacity")

    src = torch.cat([keep_idx, clone_idx, split_idx, split_idx])
    new_vals = gather(params, src)
    n_keep, n_clone, n_split = keep_idx.numel(), clone_idx.numel(), split_idx.numel()
    if n_split:
        # two children per split parent, sampled from the parent Gaussian, with shrunk scales
        s = scales[split_idx].repeat(2, 1)
        R = quat_to_rotmat(params["quats"].detach()[split_idx]).repeat(2, 1, 1)
        noise = torch.randn(2 * n_split, 3, generator=generator, device="cpu").to(dev)
        offsets = (R @ (noise * s)[..., None])[..., 0]
        a = n_keep + n_clone
        new_vals["means"][a:] = means[split_idx].repeat(2, 1) + offsets
        new_vals["log_scales"][a:] = torch.log(s / cfg.split_factor)
    is_new = torch.zeros(src.shape[0], dtype=torch.bool, device=dev)
    is_new[n_keep:] = True
    new_params = replace_rows(params, optimizer, new_vals, src, is_new)
    state.reset(src.shape[0])
    state.last = {"step": step, "cloned": n_clone, "split": n_split, "pruned": int(prune.sum()),
                  "num": int(src.shape[0])}
    log.debug("densify step %d: %s", step, state.last)
    return new_params
