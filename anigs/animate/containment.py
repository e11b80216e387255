"""Containment of a trained model's motion in the masks (model surgery after an update).

After training, the dynamic Gaussians whose motion carries their footprint out of a view's mask
(dilated by ``contain_margin_px``) in any frame move less (half, then a quarter) until they stay
inside, or else stay still: their DCT coefficients are dropped and their canonical position is
the static fit's again. :func:`anigs.masks.contain.contain_motion` finds the factors; this module
applies them to an :class:`anigs.animate.update.UpdateResult`.
"""
from __future__ import annotations

import time

import numpy as np
import torch

from anigs.cameras import Camera
from anigs.gaussians import Gaussians
from anigs.masks.contain import contain_motion, scaled_motion


def contain_result(result, static: Gaussians, cameras: list[Camera], masks: list[np.ndarray], cfg) -> dict:
    """Shrink or stop, in ``result`` (its ``deformation`` and ``canonical``), the motion that leaves the
    dilated ``masks`` (bool [H,W], one per camera) of ``cameras``. ``static``: the static fit (frozen
    Gaussians get its positions back with ``param_groups: deformation+positions``); ``cfg``: the
    update config (``contain_margin_px``, ``contain_max_outside_px``, ``param_groups``). Returns the
    counts that ``update.json`` reports under ``containment``."""
    t0 = time.perf_counter()
    d = result.deformation
    factor, _, worst = contain_motion(result.canonical, d, cameras, masks, cfg.contain_margin_px,
                                      cfg.contain_max_outside_px)
    keep = factor > 0
    info = {"margin_px": cfg.contain_margin_px, "max_outside_px": cfg.contain_max_outside_px,
            "dynamic_before": int(len(keep)), "dynamic_after": int(keep.sum()),
            "attenuated": {str(f): int((factor == f).sum()) for f in sorted(set(factor.tolist())) if 0 < f < 1},
            "frozen": int((~keep).sum()),
            "frozen_by_view": {c.name: int(((worst == k) & ~keep).sum()) for k, c in enumerate(cameras)}}
    if (factor < 1).any():
        d = scaled_motion(d, factor)
        k = torch.from_numpy(keep)
        frozen = d.dynamic_index[~k]
        sub = lambda lim: None if lim is None else lim[k]  # noqa: E731
        result.deformation = d.remapped(d.dynamic_index[k], sub(d.max_offset), sub(d.max_angle))
        for p in result.deformation.parameters():
            p.requires_grad_(False)
        if cfg.param_groups == "deformation+positions":  # a frozen Gaussian is the static fit's again
            c = result.canonical
            c.means = c.means.index_copy(0, frozen, static.means.detach()[frozen].to(c.means.dtype))
    info["seconds"] = round(time.perf_counter() - t0, 3)
    return info
