"""Per-photo regions: foliage, grass, flowers and water masks of one capture photo.

Inputs per photo: the RGB photo, the fitted model's depth and alpha at its camera, and the
rendered per-Gaussian maps (surface variation, ``|normal . up|``, multi-view colour spread) of
:mod:`anigs.effects.geometry`. The rules:

1. *valid*: the model covers the pixel (alpha >= ``min_alpha``; sky and empty space are not);
2. *wall*: locally planar and vertical (walls, fences, pictures and screens on walls);
3. *vegetation*: green hue at any brightness (shaded foliage included) with a chroma above noise
   (``green_min_chroma``: not a dark stone's faint cast), not on a wall; green
   components that fill their bounding rectangle and are flat are pictures and are dropped;
4. *lawn*: vegetation lower than the ground cut (the flat ground sheet: static; the cut is how high
   the photos see the fitted ground reach, :func:`~anigs.effects.geometry.seen_ground_cut`); the rest
   is *plant*;
5. *flowers*: saturated colours of any hue outside the green band (red included) or white,
   blobs reaching within ``flower_radius_frac`` of plant pixels, surrounded by plants for at least
   ``flower_min_ring`` of their ring and not behind those plants (by more than
   ``flower_max_behind`` x their depth: a brick wall or a bench seen past a bush), closed into
   beds with the stems between blossoms; low plant components (below foliage) with blossoms on
   >= ``flower_bed_share`` of their area, and low plant pixels with that share of blossoms
   within ``flower_radius_frac``, are flower beds;
6. *foliage* / *grass*: plant pixels within ``foliage_reach_frac`` of a part of their component
   that rises above ``grass_max_height`` x camera height are foliage (trees and bushes down to
   their lowest leaves), the other plant pixels grass (all foliage without a ground plane);
7. *water*: low (near the ground plane), horizontal and planar, weakly textured cores with a
   bluish hue or a reflective (view-dependent) colour, grown over the same colour, not green.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import cv2
import numpy as np

from anigs.effects import cues
from anigs.effects.geometry import Ground
from anigs.effects.photo_maps import PhotoMaps
from anigs.geometry.ground import pixel_heights

if TYPE_CHECKING:
    from anigs.effects.config import CuesConfig, RegionsConfig

MIN_COMPONENT_PX = 4  # the smallest component kept is at least this many pixels, however small the photo (px)
PICTURE_MIN_AREA = 0.01  # a green component is tested for a picture from this share of the photo's pixels (fraction)
PICTURE_QUANTILE = 0.5  # a picture's flatness: this quantile of its pixels' surface variation (the median) ...
PICTURE_MAX_VARIATION = 2  # ... is below this x effects.cues.wall_max_variation (a factor)
MIN_FLOWER_PX = 2  # no blossom, and no flower component, is smaller than this (px)
FLOWER_SIZE_DIVISOR = 2  # a flower component may be this many times smaller than the smallest other one (a factor)
RIM_SATURATION = 0.5  # a blossom's rim: saturated at least this x effects.regions.flower_min_saturation (a factor)
WATER_HOLE_SIZE = 4  # holes in water up to this x the smallest component are filled (a factor)


@dataclass
class PhotoRegions:
    """Region masks bool [H,W] of one photo and what was set aside."""

    masks: dict[str, np.ndarray]
    rejected_wall_green: int = 0  # green pixels on flat vertical surfaces / rectangular pictures
    valid: int = 0                # pixels the model covers
    extra: dict = field(default_factory=dict)


def _px(frac: float, h: int, w: int) -> int:
    return max(int(round(frac * np.hypot(h, w))), 1)


def classify_photo(p: PhotoMaps, ground: Ground, cfg: RegionsConfig, cues_cfg: CuesConfig,
                   min_alpha: float) -> PhotoRegions:
    """Foliage, grass, flowers and water masks of one photo (see module docstring): ``cfg`` the thresholds
    of ``effects.regions``, ``cues_cfg`` the local shape's (``effects.cues``), ``min_alpha`` the photos' sky."""
    img = p.image
    h, w = img.shape[:2]
    min_px = max(int(round(cfg.min_component_frac * h * w)), MIN_COMPONENT_PX)
    valid = (p.alpha >= min_alpha) & (p.depth > 0)
    flat = p.variation < cues_cfg.wall_max_variation
    wall = valid & flat & (p.upness < cues_cfg.wall_max_upness)
    floor = valid & flat & (p.upness > cues_cfg.floor_min_upness)
    plane = ground.plane
    if plane is not None:
        height = p.height if p.height is not None else pixel_heights(p.depth.astype(np.float64), p.camera, plane)
        cam_h = plane.camera_height if plane.camera_height > 0 else 1.0
        low = valid & (height < ground.cut_height())
    else:
        height = np.full((h, w), np.nan)
        cam_h = 1.0
        low = np.zeros((h, w), bool)
    green_all = cues.green(img, cfg.green_hue, cfg.green_min_saturation, cfg.min_value,
                           cfg.green_min_chroma) & valid
    veg = green_all & ~wall
    # flat green rectangles are pictures, not plants
    n, lab, areas = cues.mask_components(veg)
    rect = cues.rectangularity(lab, n, areas, int(PICTURE_MIN_AREA * h * w))
    var_med = cues.component_quantile(lab, n, p.variation, PICTURE_QUANTILE)
    picture = ((rect >= cfg.max_rectangularity)
               & (np.nan_to_num(var_med, nan=1.0) < PICTURE_MAX_VARIATION * cues_cfg.wall_max_variation))
    picture[0] = False
    veg &= ~picture[lab]
    rejected = int((green_all & ~veg).sum())
    lawn = veg & low
    plant = veg & ~lawn
    # plants standing above grass height (trees, bushes) and the low plants (grass, flower beds):
    # a plant pixel is tall within foliage_reach_frac of a part of its component that rises above
    # grass_max_height (a bush's lower leaves included), so low plants that merely touch a bush in
    # the photo (a lawn's tufts, a flower bed in front of it) stay low (all tall without a plane)
    n_p, lab_p, _ = cues.mask_components(plant)
    if plane is not None:
        core = cues.clean(plant & (height >= cfg.grass_max_height * cam_h), min_px, 0)
        has_core = np.bincount(lab_p[core], minlength=n_p)[:n_p] > 0
        has_core[0] = False
        reach = cv2.dilate(core.astype(np.uint8), cues.disk(_px(cfg.foliage_reach_frac, h, w))) > 0
        tall_px = plant & has_core[lab_p] & reach
    else:
        tall_px = plant.copy()
    n_l, lab_l, _ = cues.mask_components(plant & ~tall_px)
    # flowers: saturated non-green (any hue) or white blobs next to plants
    r_f = _px(cfg.flower_radius_frac, h, w)
    col = cues.colourful(img, cfg.flower_green_hue, cfg.flower_min_saturation, cfg.flower_min_value,
                         cfg.white_flowers) & valid & ~wall & ~green_all
    near = cv2.dilate(plant.astype(np.uint8), cues.disk(r_f)) > 0
    # whole colourful blobs that reach within r_f of a plant: a large blossom's centre is farther
    # than r_f from any leaf, and belongs to the blossom all the same
    n, lab, areas = cues.mask_components(col)
    touches = np.bincount(lab[near], minlength=n)[:n] > 0
    ring = cues.ring_share(lab, n, r_f, plant)
    # a blossom sits on its plant or in front of it; a wall or a bench seen past a bush lies behind it
    behind = cues.ring_depth_gap(lab, n, r_f, p.depth, plant)
    keep = touches & (ring >= cfg.flower_min_ring) & (areas >= MIN_FLOWER_PX) & ~(behind > cfg.flower_max_behind)
    keep[0] = False
    blossom = keep[lab]
    flowers = blossom.copy()
    if blossom.any():
        # low plant components dotted with blossoms are flower beds (stems and leaves included)
        grown = cv2.dilate(lab_l.astype(np.float32), cues.disk(r_f)).astype(np.int64)
        hits = np.bincount(grown[blossom], minlength=n_l)[:n_l]
        area_l = np.bincount(lab_l.ravel(), minlength=n_l)[:n_l]
        bed_comp = hits >= cfg.flower_bed_share * np.maximum(area_l, 1)
        bed_comp[0] = False
        flowers |= bed_comp[lab_l]
        # ... and so are low plant pixels with that share of blossoms around them (a bed merged
        # in the photo with the lawn around it)
        k = 2 * r_f + 1
        share = cv2.blur(blossom.astype(np.float32), (k, k))
        flowers |= plant & ~tall_px & (share >= cfg.flower_bed_share)
        bed = cv2.morphologyEx(blossom.astype(np.uint8), cv2.MORPH_CLOSE,
                               cues.disk(_px(cfg.flower_bed_frac, h, w))) > 0
        flowers |= bed & (plant | col) & valid & ~wall
        # blossom edges blend with their surroundings: grow over the less saturated rim
        _, sat, _ = cues.hsv(img)
        rim = cv2.dilate(blossom.astype(np.uint8), cues.disk(_px(cfg.flower_rim_frac, h, w))) > 0
        flowers |= rim & valid & ~wall & ~green_all & (sat >= RIM_SATURATION * cfg.flower_min_saturation)
        flowers = cues.clean(flowers, max(min_px // FLOWER_SIZE_DIVISOR, MIN_FLOWER_PX), min_px)
    # foliage and grass: the rest of the plant components by how high they reach
    rest = cues.clean(plant & ~flowers, min_px, min_px) & plant & ~flowers
    foliage = rest & tall_px
    grass = rest & ~foliage
    # water: low, horizontal, planar, weakly textured, bluish or reflective
    water = np.zeros((h, w), bool)
    if plane is not None:
        hue, sat, _ = cues.hsv(img)
        reach = cfg.water_max_height * cam_h
        near_plane = valid & (height < max(ground.cut_height(), reach)) & (height > -reach)
        colour = (cues.in_band(hue, cfg.water_hue) & (sat >= cfg.water_min_saturation)) | \
                 (p.reflect >= cfg.reflect_min_spread)
        base = near_plane & floor & colour & ~green_all & ~flowers
        tex = cues.texture(img, _px(cfg.texture_frac, h, w))
        core = cues.clean(base & (tex < cfg.water_max_texture), min_px, min_px)
        if core.any():
            grow = cv2.dilate(core.astype(np.uint8), cues.disk(_px(cfg.texture_frac, h, w))) > 0
            water = cues.clean(core | (grow & base), min_px, WATER_HOLE_SIZE * min_px)
            water &= ~green_all & ~flowers & valid
    masks = {"foliage": foliage, "grass": grass, "flowers": flowers, "water": water}
    return PhotoRegions(masks, rejected, int(valid.sum()))
