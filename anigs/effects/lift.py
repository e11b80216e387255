"""Step ``lift`` of :func:`anigs.effects.detect_effects`: the photos' regions voted onto the Gaussians."""
from __future__ import annotations

from typing import Sequence

import cv2
import numpy as np

from anigs.effects.config import REGIONS, LiftConfig
from anigs.effects.photo_maps import PhotoMaps
from anigs.effects.regions import PhotoRegions
from anigs.effects.scene_cues import Cues
from anigs.gaussians import Gaussians
from anigs.geometry.propagate import propagate_labels
from anigs.render.visibility import VisibilityConfig, blend_weights, project_to_pixels, visible_depth

#: plants stop at the ground: a plant Gaussian lower than this x the ground plane's layer height is ground
PLANT_MIN_HEIGHT = 0.5
#: a photo has a say on a Gaussian's region (``effects.lift.photo_min_share``) where the Gaussian carries at least
#: this much blending weight in it (px of the analysed photo: a splat that shows, not one hidden or off its edge)
PHOTO_MIN_WEIGHT = 5.0


def footprint_shares(g: Gaussians, maps: Sequence[PhotoMaps], regions: Sequence[PhotoRegions], reach: int = 0,
                     min_weight: float = PHOTO_MIN_WEIGHT, least_k: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Per Gaussian and region: (the share [N, R] of its blending weight, summed over the photos, that falls
    on the region's mask pixels or within ``reach`` px of them; the ``least_k`` least such shares [N, R, k],
    ascending, in the photos where the Gaussian carries at least ``min_weight`` px of weight). Its whole
    footprint counts (:func:`~anigs.render.visibility.blend_weights`; the reach forgives a splat's soft edge).
    The sum is 0 for a Gaussian no photo renders and for a region no photo shows; a least share is 1 where
    fewer photos count."""
    total = np.zeros(g.num)
    inside = np.zeros((g.num, len(REGIONS)))
    least = np.ones((g.num, len(REGIONS), least_k))
    grow = np.ones((2 * reach + 1, 2 * reach + 1), np.uint8)
    for p, reg in zip(maps, regions):
        shown = [k for k, name in enumerate(REGIONS) if reg.masks[name].any()]
        here = np.zeros((g.num, len(REGIONS)))  # this photo's shares: none of the weight is on a region it does not show
        for j in range(0, max(len(shown), 1), 2):  # two masks per pass; one pass for the total at least
            pair = shown[j:j + 2]
            masks = [reg.masks[REGIONS[k]].astype(np.uint8) for k in pair]
            masks = [cv2.dilate(m, grow) if reach > 0 else m for m in masks]
            t, w = blend_weights(g, p.camera, np.stack(masks, -1) if masks else None)
            if pair:
                inside[:, pair] += w
                here[:, pair] = w / np.maximum(t, 1e-12)[:, None]
            if j == 0:
                total += t
                counts = t >= min_weight
        merged = np.concatenate([least[counts], here[counts][..., None]], 2)
        least[counts] = np.sort(merged, 2)[..., :least_k]
    return inside / np.maximum(total, 1e-12)[:, None], least


def footprint_agrees(foot: np.ndarray, least: np.ndarray, region: np.ndarray, cfg: LiftConfig) -> np.ndarray:
    """Whether each Gaussian's footprint bears out its ``region`` [N]: over all the photos together
    (``footprint_share``; ``foot`` [N, R]) and in all but fewer than ``photo_vetoes`` of the photos where it
    shows (``photo_min_share``; ``least`` [N, R, >= photo_vetoes], :func:`footprint_shares`)."""
    rows = np.arange(len(region))
    return (foot[rows, region] >= cfg.footprint_share) & \
        (least[rows, region, cfg.photo_vetoes - 1] >= cfg.photo_min_share)


def lift(g: Gaussians, cues: Cues, regions: Sequence[PhotoRegions], cfg: LiftConfig) -> tuple[np.ndarray, np.ndarray]:
    """Step ``lift``: region id [N] (-1 none) and vote share [N] of every Gaussian (module docstring)."""
    means, maps, ground = cues.means, cues.maps, cues.ground
    n, r = len(means), len(REGIONS)
    votes = np.zeros((n, r + 1))
    seen_n = np.zeros(n)
    vis = VisibilityConfig(mode="depth")
    for p, reg in zip(maps, regions):
        ids = np.zeros(p.depth.shape, np.int64)
        for k, name in enumerate(REGIONS):
            ids[reg.masks[name]] = k + 1
        seen = visible_depth(means, p.camera, p.depth, p.alpha, cues.max_scale, vis)
        _, px, py, _ = project_to_pixels(means, p.camera, vis.near)
        np.add.at(votes, (np.flatnonzero(seen), ids[py[seen], px[seen]]), 1.0)
        seen_n += seen
    share = votes[:, 1:] / np.maximum(seen_n, 1)[:, None]
    best = np.argmax(share, 1)
    top = share[np.arange(n), best]
    region = np.where(top >= cfg.vote_threshold, best, -1)
    decided = seen_n > 0
    foot = least = None
    if (cfg.footprint_share > 0 or cfg.photo_min_share > 0) and (region >= 0).any():
        foot, least = footprint_shares(g, maps, regions, cfg.footprint_reach_px, least_k=cfg.photo_vetoes)
        region[(region >= 0) & ~footprint_agrees(foot, least, best, cfg)] = -1
    out = region.copy()
    for k in range(r):
        out[propagate_labels(means, decided, region == k, cfg.propagate_k) & ~decided] = k
    if foot is not None:  # a Gaussian no photo sees in the depth test but that renders elsewhere: its footprint too
        late = (out >= 0) & ~decided & (foot.sum(1) > 0)
        out[late & ~footprint_agrees(foot, least, np.maximum(out, 0), cfg)] = -1
    if ground.plane is not None:  # plants stop at the ground (water lies on it)
        hgt = means @ ground.plane.normal - ground.plane.offset
        below = hgt < PLANT_MIN_HEIGHT * ground.plane.min_height
        out[below & np.isin(out, [REGIONS.index(x) for x in ("foliage", "grass", "flowers")])] = -1
    return out, np.where(decided, top, 0.0)
