"""Per-Gaussian limits and capacity of a model update, resolved from its config: offset and angle
limits [D] (:func:`limits_from_config`) and DCT bases per dynamic Gaussian [D]
(:func:`bases_from_config`), per effect label of the dynamic mask."""
from __future__ import annotations

import logging
import math
from typing import TYPE_CHECKING

import torch

from anigs.animate.deform import dynamic_index_from_mask, offset_limits
from anigs.effects.labels import effect_label_ids

if TYPE_CHECKING:
    from anigs.animate.config import UpdateConfig

log = logging.getLogger("anigs.animate.update")

_UNLIMITED = 1e18  # stands for "no limit" in per-Gaussian limit tensors (finite: checkpoints refuse Inf)


def bases_from_config(mask: torch.Tensor, cfg: UpdateConfig, num_bases: int) -> torch.Tensor | None:
    """Bases K_d [D] long each dynamic Gaussian uses, from ``effect_num_bases`` (None when it is empty).

    ``mask`` [N] is bool or integer effect labels (0 = static); keys are labels (as strings) or
    effect names (:func:`anigs.effects.labels.effect_label_ids`; several effects on one label: the largest K_e, an effect
    not named counting as ``cfg.num_bases``). Values are clamped to ``num_bases`` (the K resolved for T).
    """
    if not cfg.effect_num_bases:
        return None
    mask = torch.as_tensor(mask)
    idx = dynamic_index_from_mask(mask)
    labels = mask[idx].long() if mask.dtype != torch.bool else torch.ones_like(idx)
    names = effect_label_ids()
    per_label: dict[int, int] = {}
    by_name = {k: v for k, v in cfg.effect_num_bases.items() if k in names}
    if by_name and mask.dtype == torch.bool:
        log.warning("update: effect_num_bases names effects %s but the dynamic mask is bool (no per-Gaussian effect "
                    "labels: the masks stage wrote none, run it with the effects stage's folder): every "
                    "dynamic Gaussian uses %d bases", sorted(by_name), num_bases)
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
