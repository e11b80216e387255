"""Lifting 2D masks to 3D Gaussians: per Gaussian, votes among the views where it is visible
(:mod:`anigs.render.visibility`); dynamic when the fraction of positive votes is >=
``vote_threshold`` and it is visible in >= ``min_views`` views.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
import torch

from anigs.cameras import Camera
from anigs.typed_config import Section
from anigs.gaussians import Gaussians
from anigs.geometry.propagate import propagate_labels
from anigs.render.visibility import VisibilityConfig, as_means, blend_weights, check_mask, project_to_pixels, visibility


@dataclass
class LiftConfig(Section):
    """Parameters of the 2D-to-3D mask lifting (config key ``lift``)."""

    WHERE = "lift config"

    min_views: int = 1            # min views in which a Gaussian is visible to be dynamic
    vote_threshold: float = 0.5   # min fraction of those views whose mask covers it
    visibility: str = "weight"    # weight | depth | frustum
    rel_tol: float = 0.03         # depth test: relative tolerance
    scale_tol: float = 2.0        # depth test: tolerance in Gaussian max-scales
    min_alpha: float = 0.5        # depth test: pixels below this alpha occlude nothing
    min_weight: float = 0.05      # weight test: min summed blending weight (pixels)
    propagate_k: int = 8          # Gaussians seen in < min_views views take the majority of their
                                  # k nearest decided neighbours (0 = they stay static)
    weighted_votes: bool = True   # weight visibility: votes weighted by blending weight
    ground_cut: float = 0.5       # with a ground plane: static below this fraction of its min_height

    def validate(self) -> None:
        if self.ground_cut < 0:
            raise ValueError(f"lift.ground_cut must be >= 0, got {self.ground_cut}")
        if self.propagate_k < 0:
            raise ValueError(f"lift.propagate_k must be >= 0, got {self.propagate_k}")
        if self.min_views < 1:
            raise ValueError(f"lift.min_views must be >= 1, got {self.min_views}")
        if not 0.0 < self.vote_threshold <= 1.0:
            raise ValueError(f"lift.vote_threshold must be in (0, 1], got {self.vote_threshold}")
        self.visibility_config()


    def visibility_config(self) -> "VisibilityConfig":
        return VisibilityConfig(mode=self.visibility, rel_tol=self.rel_tol, scale_tol=self.scale_tol,
                                min_alpha=self.min_alpha, min_weight=self.min_weight)


def lift_votes(g: Gaussians | torch.Tensor | np.ndarray, cameras: Sequence[Camera], masks: Sequence[np.ndarray],
               cfg: VisibilityConfig | None = None, depths: Sequence[np.ndarray] | None = None,
               weighted: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Votes per Gaussian over the views: (positive [N], total [N], views seen [N int]).

    Per view a Gaussian that is visible votes 1 (positive when its pixel is in the mask). With
    ``weighted`` (``weight`` visibility only) it votes its blending weight, positive in
    proportion to the weight that falls inside the mask.
    """
    cfg = cfg or VisibilityConfig()
    if len(cameras) != len(masks):
        raise ValueError(f"lift: {len(cameras)} cameras but {len(masks)} masks")
    if depths is not None and len(depths) != len(cameras):
        raise ValueError(f"lift: {len(cameras)} cameras but {len(depths)} depth maps")
    means, gs = as_means(g)
    pos = np.zeros(len(means))
    tot = np.zeros(len(means))
    nvis = np.zeros(len(means), dtype=np.int64)
    for i, (cam, mask) in enumerate(zip(cameras, masks)):
        mask = check_mask(mask, cam)
        if cfg.mode == "weight":
            if gs is None:
                raise ValueError("lift: visibility 'weight' needs the full Gaussians, got only means")
            total, inside = blend_weights(gs, cam, mask)
            seen = total >= cfg.min_weight
            if weighted:
                pos += np.where(seen, inside, 0.0)
                tot += np.where(seen, total, 0.0)
            else:
                pos += seen & (inside >= 0.5 * np.maximum(total, 1e-12))
                tot += seen
        else:
            depth = None if depths is None else np.asarray(depths[i])
            seen = visibility(gs if gs is not None else means, cam, cfg, depth=depth)
            _, px, py, _ = project_to_pixels(means, cam, cfg.near)
            pos += seen & mask[py, px]
            tot += seen
        nvis += seen
    return pos, tot, nvis


def precision_recall(pred: np.ndarray, truth: np.ndarray) -> dict[str, float]:
    """Precision and recall of a lifted dynamic set ``pred`` [N] bool against ``truth`` [N] bool
    (0 when the denominator is empty)."""
    tp = int((pred & truth).sum())
    return {"precision": tp / max(int(pred.sum()), 1), "recall": tp / max(int(truth.sum()), 1)}


def lift_masks_report(g: Gaussians | torch.Tensor | np.ndarray, cameras: Sequence[Camera], masks: Sequence[np.ndarray],
                      cfg: LiftConfig | None = None, depths: Sequence[np.ndarray] | None = None,
                      ground=None) -> tuple[np.ndarray, dict]:
    """:func:`lift_masks` with a :class:`LiftConfig`; also returns counts (visible, voted, propagated).

    ``ground`` (a :class:`anigs.geometry.ground.GroundPlane`): Gaussians whose centre lies
    below ``cfg.ground_cut * ground.min_height`` above it are static (the 3D twin of the
    2D ground cue: a lawn does not move). The cut stays at the fixed margin, not at the
    measured ground layer (``ground.layer``) that the vegetation masks use: grass tufts,
    flower beds and bush bottoms that good masks do mark live in that layer (on the demo,
    cutting there took 0.1 of recall from the lifted ground-truth label masks).
    """
    cfg = cfg or LiftConfig()
    means, _ = as_means(g)
    pos, tot, nvis = lift_votes(g, cameras, masks, cfg.visibility_config(), depths, weighted=cfg.weighted_votes)
    decided = nvis >= cfg.min_views
    frac = np.where(tot > 0, pos / np.maximum(tot, 1e-12), 0.0)
    dyn = decided & (frac >= cfg.vote_threshold)
    out = propagate_labels(means, decided, dyn, cfg.propagate_k)
    low = np.zeros(len(means), bool)
    if ground is not None and cfg.ground_cut > 0:
        low = means @ np.asarray(ground.normal, float) - ground.offset < cfg.ground_cut * ground.min_height
        out &= ~low
    info = {"num_gaussians": int(len(means)), "num_views": len(cameras), "decided": int(decided.sum()),
            "undecided": int((~decided).sum()), "dynamic_voted": int(dyn.sum()),
            "dynamic_propagated": int((out & ~decided).sum()), "below_ground_cut": int(low.sum()),
            "dynamic": int(out.sum()), "visibility": cfg.visibility, "weighted_votes": cfg.weighted_votes}
    return out, info


def lift_masks(g: Gaussians | torch.Tensor | np.ndarray, cameras: Sequence[Camera], masks: Sequence[np.ndarray],
               min_views: int = 1, vote_threshold: float = 0.5, visibility: str = "depth",
               depths: Sequence[np.ndarray] | None = None, propagate_k: int = 0,
               cfg: LiftConfig | None = None) -> np.ndarray:
    """Lift 2D masks (bool [H,W] per camera) to a dynamic flag per Gaussian, bool [N].

    ``g`` is a :class:`Gaussians` (needed for the ``depth`` test unless ``depths`` are given,
    and for ``weight``) or means [N,3] (``frustum`` visibility, or ``depth`` with ``depths``).
    A Gaussian is dynamic when visible in >= ``min_views`` views and the fraction of those
    views whose mask covers it is >= ``vote_threshold``. With ``propagate_k`` > 0 the
    Gaussians seen in fewer views take the majority of their k nearest decided neighbours.
    ``cfg`` (a :class:`LiftConfig`) overrides the keyword parameters.
    """
    if cfg is None:
        cfg = LiftConfig(min_views=min_views, vote_threshold=vote_threshold, visibility=visibility,
                         propagate_k=propagate_k)
    return lift_masks_report(g, cameras, masks, cfg, depths)[0]
