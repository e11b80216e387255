"""The trainable state of a model update: the canonical parameters its group trains
(:class:`Trainable`), the optimiser's parameter groups and the finite-value check."""
from __future__ import annotations

from typing import TYPE_CHECKING

import torch

from anigs.animate.deform import DCTDeformation
from anigs.gaussians import Gaussians

if TYPE_CHECKING:
    from anigs.animate.config import UpdateConfig


class Trainable:
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


def param_groups(cfg: UpdateConfig, deformation: DCTDeformation, tr: Trainable, spatial: float) -> list[dict]:
    """Optimiser groups (``name``, ``lr``): the DCT coefficients and ``tr``'s parameters (lengths times ``spatial``)."""
    groups = [{"params": [deformation.pos_coeffs], "lr": cfg.lr_position_coeffs * spatial, "name": "pos_coeffs"}]
    if deformation.rot_coeffs is not None:
        groups.append({"params": [deformation.rot_coeffs], "lr": cfg.lr_rotation_coeffs, "name": "rot_coeffs"})
    lrs = {"dyn_means": cfg.lr_means * spatial, "means": cfg.lr_means * spatial, "quats": cfg.lr_quats,
           "log_scales": cfg.lr_scales, "opacity_logits": cfg.lr_opacity, "sh": cfg.lr_sh}
    for k, p in tr.params.items():
        groups.append({"params": [p], "lr": lrs[k], "name": k})
    return groups


def first_non_finite(tensors) -> str | None:
    """Name of the first (name, tensor) pair with a non-finite entry (None tensors skipped), else None."""
    for name, t in tensors:
        if t is not None and not bool(torch.isfinite(t).all()):
            return name
    return None
