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


def footprint_shares(g: Gaussians, maps: Sequence[PhotoMaps], regions: Sequence[PhotoRegions],
                     reach: int = 0) -> np.ndarray:
    """Per Gaussian and region: the share [N, R] of its blending weight, summed over the photos, that falls
    on the region's mask pixels or within ``reach`` px of them (its whole footprint,
    :func:`~anigs.render.visibility.blend_weights`; the reach forgives a splat's soft edge); 0 for a
    Gaussian no photo renders and for a region no photo shows."""
    total = np.zeros(g.num)
    inside = np.zeros((g.num, len(REGIONS)))
    grow = np.ones((2 * reach + 1, 2 * reach + 1), np.uint8)
    for p, reg in zip(maps, regions):
        shown = [k for k, name in enumerate(REGIONS) if reg.masks[name].any()]
        for j in range(0, max(len(shown), 1), 2):  # two masks per pass; one pass for the total at least
            pair = shown[j:j + 2]
            masks = [reg.masks[REGIONS[k]].astype(np.uint8) for k in pair]
            masks = [cv2.dilate(m, grow) if reach > 0 else m for m in masks]
            t, w = blend_weights(g, p.camera, np.stack(masks, -1) if masks else None)
            if pair:
                inside[:, pair] += w
            total += t if j == 0 else 0.0
    return inside / np.maximum(total, 1e-12)[:, None]


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
    foot = None
    if cfg.footprint_share > 0 and (region >= 0).any():
        foot = footprint_shares(g, maps, regions, cfg.footprint_reach_px)
        region[(region >= 0) & (foot[np.arange(n), best] < cfg.footprint_share)] = -1
    out = region.copy()
    for k in range(r):
        out[propagate_labels(means, decided, region == k, cfg.propagate_k) & ~decided] = k
    if foot is not None:  # a Gaussian no photo sees in the depth test but that renders elsewhere: its footprint too
        late = (out >= 0) & ~decided
        out[late & (foot[np.arange(n), np.maximum(out, 0)] < cfg.footprint_share) & (foot.sum(1) > 0)] = -1
    if ground.plane is not None:  # plants stop at the ground (water lies on it)
        hgt = means @ ground.plane.normal - ground.plane.offset
        below = hgt < PLANT_MIN_HEIGHT * ground.plane.min_height
        out[below & np.isin(out, [REGIONS.index(x) for x in ("foliage", "grass", "flowers")])] = -1
    return out, np.where(decided, top, 0.0)
