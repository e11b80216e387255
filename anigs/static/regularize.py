"""Needle and smear control for the static fit: Gaussians no photo resolves.

A sparse or one-sided capture leaves regions no photo sees sharply (the sky above a facade, the
surroundings of a close-up). Photometric loss alone fills them with long, blurry needles and
huge smooth blobs that every photo sees at a few pixels' blur; every novel view then shows them.
Two mechanisms, both cheap enough for every step (:class:`NeedleRegularizer`):

- **Needle limit** (a projection after each optimiser step): the largest scale of a Gaussian is
  at most ``max_needle_ratio`` times its middle scale. This is PhysGaussian's anisotropy
  regulariser (Xie et al., CVPR 2024, eq. 12: ``max(S)/min(S)`` hinged at a ratio ``r``) turned
  into a hard bound and measured against the *middle* scale: flat disks (two large axes, one
  thin) are how 3DGS represents surfaces and stay untouched; only one-axis needles shrink.
- **Unresolved decay** (at each densification step, and once at the end): a Gaussian is
  *unresolved* when, in every training photo where its centre projects inside the image, its
  largest standard deviation spans more than ``max_screen_fraction`` of the image width (the
  screen-size prune of 3DGS, Kerbl et al. 2023, whose ``max_radii2D > 20`` px prune removes
  splats too big for every view, measured here in the best photo instead of the worst), or it
  is larger than ``max_world_fraction`` of the scene extent (3DGS's world-space prune, 0.1 x
  extent there; off by default: the extent is the cameras' spread, far smaller than the scene
  in a forward-facing capture). Its opacity is multiplied by ``decay`` at each densification
  step, so a splat the photos need can win it back with gradients; one below the prune opacity
  is removed by densification's own opacity prune. At the last densification step what is still
  unresolved is pruned outright (``final_prune``: its opacity is zeroed before that step's
  prune), so the steps after it can fill what it covered; a fit with no densification step
  prunes after its last step instead. At most ``max_share`` of the Gaussians are flagged at a
  step, the least resolved first: in a coarse fit (a short or sparse one) nearly every splat is
  large, and pruning them all guts the model (the sparse 11-photo capture of
  ``benchmarks/needles.py``: 4882 -> 653 Gaussians, held-out PSNR -1.7 dB without this cap).

All sizes are tensors on the fit's device; nothing reads back to the host except counts logged
at the densification steps.
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Any, ClassVar, Sequence

import numpy as np
import torch

from anigs.cameras import Camera
from anigs.typed_config import Section

log = logging.getLogger(__name__)


@dataclass
class RegularizeConfig(Section):
    """Needle / unresolved-Gaussian control (config ``static.regularize``)."""

    enabled: bool = True               # bound needles and decay, then prune, Gaussians no photo resolves
    max_needle_ratio: float = 10.0     # largest scale <= this x the middle scale (0: no limit)
    max_screen_fraction: float = 0.08  # unresolved: largest std dev > this x image width in every photo it is in
    max_world_fraction: float = 0.0    # ... or largest std dev > this x the scene extent (0: no world limit; 3DGS: 0.1)
    decay: float = 0.5                 # opacity factor of unresolved Gaussians at each densification step
    final_prune: bool = True           # prune the Gaussians still unresolved at the last densification step
    #: at most this share of the Gaussians is decayed / pruned at a step, least resolved first
    max_share: float = 0.02
    #: after the fit, prune Gaussians whose blending weight summed over every training photo's pixels is
    #: below this (pixels): nothing the photos saw constrains them (0: keep them)
    min_seen_weight: float = 0.01

    WHERE: ClassVar[str] = "static.regularize config"

    def validate(self) -> None:
        if self.max_needle_ratio != 0 and self.max_needle_ratio < 1:
            raise ValueError(f"static.regularize.max_needle_ratio must be 0 (off) or >= 1, got {self.max_needle_ratio}")
        if self.max_screen_fraction <= 0 or self.max_world_fraction < 0:
            raise ValueError("static.regularize.max_screen_fraction must be > 0 and max_world_fraction >= 0")
        if not 0 < self.decay <= 1:
            raise ValueError(f"static.regularize.decay must be in (0, 1], got {self.decay}")
        if not 0 <= self.max_share <= 1:
            raise ValueError(f"static.regularize.max_share must be in [0, 1], got {self.max_share}")


def limit_needles(log_scales: torch.Tensor, ratio: float) -> None:
    """Clamp in place each row of ``log_scales`` [N,3] so its largest scale is <= ``ratio`` x its
    middle scale (no host read; ``ratio`` 0: nothing)."""
    if ratio <= 0 or log_scales.shape[0] == 0:
        return
    with torch.no_grad():
        mid = log_scales.median(dim=1).values.unsqueeze(1)  # the middle of three
        log_scales.copy_(torch.minimum(log_scales, mid + math.log(ratio)))


def prune_rows(params: dict[str, torch.Tensor], optimizer: torch.optim.Optimizer,
               keep: torch.Tensor) -> dict[str, torch.Tensor]:
    """The parameters restricted to the rows ``keep`` (bool [N]), Adam moments carried along."""
    from anigs.static.densify import gather, replace_rows

    src = torch.nonzero(keep, as_tuple=False).squeeze(1)
    return replace_rows(params, optimizer, gather(params, src), src, torch.zeros_like(src, dtype=torch.bool))


def last_densify_step(start: int, stop: int, every: int, iterations: int) -> int | None:
    """The last step in 1..``iterations`` at which densification runs (``start <= s < stop``,
    ``s % every == 0``), or None."""
    hi = min(stop - 1, iterations)
    last = hi - hi % every
    return last if last >= max(start, 1) else None


def min_screen_sigma(means: torch.Tensor, log_scales: torch.Tensor, cameras: Sequence[Camera],
                     mats: Sequence[tuple[torch.Tensor, torch.Tensor]]) -> torch.Tensor:
    """float [N]: the smallest, over the ``cameras`` whose image holds the centre (in front of
    it), of the largest std dev projected at the centre's depth, as a share of the image width
    (inf where no camera holds it). ``mats``: (viewmat [4,4], K [3,3]) per camera."""
    s = log_scales.detach().exp().max(1).values
    best = torch.full_like(s, float("inf"))
    x = means.detach()
    for cam, (vm, K) in zip(cameras, mats):
        pc = x @ vm[:3, :3].T + vm[:3, 3]
        z = pc[:, 2]
        zc = z.clamp_min(1e-6)
        u = pc[:, 0] / zc * K[0, 0] + K[0, 2]
        v = pc[:, 1] / zc * K[1, 1] + K[1, 2]
        inside = (z > 0.01) & (u >= 0) & (u < cam.width) & (v >= 0) & (v < cam.height)
        frac = s * torch.maximum(K[0, 0], K[1, 1]) / zc / cam.width
        best = torch.where(inside, torch.minimum(best, frac), best)
    return best


class NeedleRegularizer:
    """The per-step needle limit and the unresolved decay/prune of :mod:`anigs.static.regularize`."""

    def __init__(self, cfg: RegularizeConfig, extent: float, cameras: Sequence[Camera],
                 mats: Sequence[tuple[torch.Tensor, torch.Tensor]]):
        self.cfg, self.extent, self.cameras, self.mats = cfg, float(extent), list(cameras), list(mats)
        self.stats: dict[str, Any] = {"decayed": [], "final_pruned": 0}
        self.pruned_at_densify = False

    def after_step(self, params: dict[str, torch.Tensor]) -> None:
        """The needle limit (no host read)."""
        if self.cfg.enabled:
            limit_needles(params["log_scales"], self.cfg.max_needle_ratio)

    def unresolved(self, params: dict[str, torch.Tensor]) -> torch.Tensor:
        """bool [N]: Gaussians no training photo resolves (see the module docstring), at most
        ``max_share`` of them (the largest in their best photo first)."""
        ls = params["log_scales"].detach()
        best = min_screen_sigma(params["means"], ls, self.cameras, self.mats)
        if self.cfg.max_world_fraction > 0:
            best = torch.where(ls.exp().max(1).values > self.cfg.max_world_fraction * self.extent,
                               torch.full_like(best, float("inf")), best)
        bad = best > self.cfg.max_screen_fraction
        cap = int(self.cfg.max_share * bad.numel())
        if int(bad.sum()) > cap:  # a coarse fit: every splat is large; keep to its worst outliers
            worst = torch.argsort(best, descending=True, stable=True)[:cap]
            bad = torch.zeros_like(bad)
            bad[worst] = True
        return bad

    def decay(self, params: dict[str, torch.Tensor], step: int, last: bool = False) -> int:
        """Before a densification step: multiply the opacity of unresolved Gaussians by ``decay``
        (zero it at the ``last`` step with ``final_prune``, so that step's opacity prune removes
        them); returns their count."""
        prune = last and self.cfg.final_prune
        if not self.cfg.enabled or (self.cfg.decay >= 1 and not prune):
            return 0
        bad = self.unresolved(params)
        with torch.no_grad():
            op = params["opacity_logits"]
            p = torch.sigmoid(op[bad]) * (0.0 if prune else self.cfg.decay)
            op[bad] = torch.logit(p.clamp(1e-7, 1 - 1e-6))
        n = int(bad.sum())
        self.stats["decayed"].append({"iteration": step, "unresolved": n, "pruned": prune})
        if prune:
            self.stats["final_pruned"] = n
            self.pruned_at_densify = True
        if n:
            log.info("static fit: iteration %d: %d unresolved Gaussians (no photo sees them at <= %.0f%% of its "
                     "width%s): %s", step, n, 100 * self.cfg.max_screen_fraction,
                     f", or larger than {self.cfg.max_world_fraction:g} x extent" if self.cfg.max_world_fraction else "",
                     "pruned (the last densification step)" if prune else f"opacity x {self.cfg.decay:g}")
        return n

    def final_keep(self, params: dict[str, torch.Tensor]) -> torch.Tensor | None:
        """bool [N] rows to keep after the fit (None: keep all): not unresolved (when no densification
        step pruned them) and seen by the photos (:func:`unseen`)."""
        if not self.cfg.enabled:
            return None
        bad = torch.zeros(params["means"].shape[0], dtype=torch.bool, device=params["means"].device)
        if self.cfg.final_prune and not self.pruned_at_densify:
            bad = self.unresolved(params)
            self.stats["final_pruned"] = int(bad.sum())
        if self.cfg.min_seen_weight > 0:
            hidden = unseen(params, self.cameras, self.cfg.min_seen_weight).to(bad.device)
            self.stats["unseen_pruned"] = int((hidden & ~bad).sum())
            bad |= hidden
        n = int(bad.sum())
        if n == 0 or n == bad.numel():
            return None
        log.info("static fit: pruned %d Gaussians no photo resolves (%d of them unseen by every photo)", n,
                 self.stats.get("unseen_pruned", 0))
        return ~bad

    def report(self, params: dict[str, torch.Tensor]) -> dict[str, Any]:
        """Config and counts for the fit's metrics (``regularize``)."""
        ls = params["log_scales"].detach()
        srt = ls.sort(dim=1).values
        ratio = (srt[:, 2] - srt[:, 1]).exp()
        return {**self.cfg.__dict__, **self.stats,
                "max_needle_ratio_after": float(ratio.max()) if ratio.numel() else None}


def unseen(params: dict[str, torch.Tensor], cameras: Sequence[Camera], min_weight: float) -> torch.Tensor:
    """bool [N]: Gaussians whose blending weight, summed over the pixels of every camera, is below
    ``min_weight`` (hidden behind nearer surfaces or outside every photo: untrained)."""
    from anigs.render.visibility import blend_weights
    from anigs.static.init import params_to_gaussians

    g = params_to_gaussians(params)
    total = np.zeros(g.num)
    for cam in cameras:
        total += blend_weights(g, cam)[0]
    return torch.from_numpy(total < min_weight)
