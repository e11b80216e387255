"""The masks stage's method: segment each queued view's first frame, find the dynamic Gaussian set
(the effects stage's, or the masks lifted to 3D, voting over the capture photos too), complete the
masks with it, keep only the Gaussians contained in every view's mask, and label each one's effect.

:func:`segment_views` returns a :class:`MasksResult`; the stage writes it
(:mod:`anigs.stages.masks`) and compares it with the ground truth (:func:`anigs.masks.truth.compare`).
"""
from __future__ import annotations

import logging
import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from anigs.cameras import Camera
from anigs.gaussians import Gaussians
from anigs.masks import Frame, compute_masks
from anigs.masks.choose import EffectSets, capture_backend, choose_backend
from anigs.masks.lift import lift_masks_report
from anigs.masks.truth import GroundTruth
from anigs.geometry.ground import ground_plane as estimate_ground
from anigs.masks.capture import capture_frames
from anigs.masks.complete import complete_masks
from anigs.masks.contain import contain_dynamic
from anigs.masks.per_effect import add_effect_masks, label_dynamic

log = logging.getLogger("anigs.masks")


@dataclass
class MasksResult:
    """``masks``: per view {"dynamic": bool [H,W], effect: bool [H,W], ...}; ``dynamic``: bool [N] the
    Gaussians that move; ``effect_labels``: int8 [N] (with the effects stage's regions) or None;
    ``info``: the ``masks.json`` sections."""

    masks: list[dict]
    dynamic: np.ndarray
    effect_labels: np.ndarray | None
    info: dict


def _capture_votes(cfg, g: Gaussians, backend, veg, ground, images: str | Path,
                   capture_cams: Sequence[Camera] | None, info: dict) -> tuple[list[Camera], list[np.ndarray]]:
    """The capture photos segmented too: (their cameras, their dynamic masks) for the lifting."""

    if capture_cams is None:
        raise ValueError("--images needs --cameras (the cameras of the capture photos: the sfm stage's)")
    cap_frames = capture_frames(images, capture_cams, g)
    cap_masks = [r["dynamic"] for r in compute_masks(capture_backend(cfg, backend, veg, ground), cap_frames)]
    info["capture"] = {"images": len(cap_frames), "fraction": float(np.mean([m.mean() for m in cap_masks]))}
    log.info("masks: %d capture photos segmented (dynamic %.1f%%), lifting over them too",
             len(cap_frames), 100 * info["capture"]["fraction"])
    return [f.camera for f in cap_frames], cap_masks


def segment_views(cfg, g: Gaussians, frames: Sequence[Frame], up: np.ndarray, effects: EffectSets | None = None,
                  effects_source: str = "", truth: GroundTruth | None = None,
                  capture_cams: Sequence[Camera] | None = None, images: str | Path | None = None) -> MasksResult:
    """The masks of ``frames`` and the dynamic set of ``g`` (``cfg``: the ``masks`` section; ``up``
    [3] the scene's up; ``effects``: the effects stage's sets, ``effects_source`` naming them;
    ``capture_cams``/``images``: the capture photos, segmented too and voting in the lifting)."""
    veg = cfg.vegetation
    cams = [fr.camera for fr in frames]
    ground = estimate_ground(g.means.detach().double().numpy(), up, cams, veg.ground_margin) if veg.ground else None
    info: dict = {"backend": cfg.backend, "views": []}
    if ground is not None:
        info["ground_plane"] = ground.to_dict()
    backend = choose_backend(cfg, g, veg, ground, effects, truth, capture_cams)
    results = compute_masks(backend, frames)
    by_effects = cfg.backend == "effects"
    if by_effects:  # the region of interest is the effects stage's set, not lifted again
        dyn, lift_info = effects.dynamic, {"source": effects_source, "num_dynamic": int(effects.dynamic.sum())}
    else:  # the lifting votes over the queued views, and over the capture photos when given
        lift_cams, lift_in = list(cams), [r["dynamic"] for r in results]
        if images:
            more_cams, more_masks = _capture_votes(cfg, g, backend, veg, ground, images, capture_cams, info)
            lift_cams, lift_in = lift_cams + more_cams, lift_in + more_masks
        dyn, lift_info = lift_masks_report(g, lift_cams, lift_in, cfg.lift, ground=ground)
    info["lift"] = lift_info
    if cfg.complete_masks and cfg.backend not in ("labels", "effects"):  # those masks render the set itself

        info["completed_fraction"] = complete_masks(g, dyn, frames, results)
    if cfg.contain:  # a Gaussian moves only if its footprint stays inside the (dilated) masks of every view

        before = dyn
        kept = contain_dynamic(g, dyn, cams, [r["dynamic"] for r in results], cfg.contain_margin_px,
                               cfg.contain_max_outside_px)
        dyn = kept.dynamic
        info["containment"] = kept.info(before, [fr.name for fr in frames], cfg.contain_margin_px,
                                        cfg.contain_max_outside_px)
    labels = None
    if effects is not None:  # which effect each dynamic Gaussian belongs to; per-effect masks for every backend

        labels, info["effect_labels"] = label_dynamic(g, dyn, effects.chosen, effects.regions)
        if cfg.backend not in ("labels", "effects") and effects.chosen:
            add_effect_masks(g, labels, effects.chosen, frames, results, dataclasses.asdict(cfg.labels))
    return MasksResult(results, dyn, labels, info)
