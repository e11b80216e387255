"""Step ``cues`` of :func:`anigs.effects.detect_effects`: the fitted model's 3D cues (up, the ground plane and how
high the photos see it reach, the local shape) and, per photo, its renders at the photo's camera."""
from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from anigs.cameras import Camera
from anigs.effects.config import CuesConfig
from anigs.effects.geometry import (Ground, colour_spread, local_shape, render_features, scene_ground, seen_ground_cut,
                                   world_up)
from anigs.effects.photo_maps import PhotoMaps
from anigs.gaussians import Gaussians
from anigs.render.visibility import project_to_pixels

log = logging.getLogger("anigs.effects")


@dataclass
class Cues:
    """Step ``cues``: the model's 3D cues and, per photo, its renders (:class:`PhotoMaps`)."""

    means: np.ndarray       # [N,3] Gaussian centres
    max_scale: np.ndarray   # [N] largest scale of each Gaussian
    up: np.ndarray          # [3] world up
    ground: Ground
    radius: float           # neighbourhood radius of the local shape (world units)
    flat: np.ndarray        # bool [N]: locally planar Gaussians
    maps: list[PhotoMaps]


def _median_depth(means: np.ndarray, cams: Sequence[Camera]) -> float:
    zs = []
    for cam in cams:
        inside, _, _, z = project_to_pixels(means, cam)
        if inside.any():
            zs.append(float(np.median(z[inside])))
    if not zs:
        raise ValueError("detect_effects: no Gaussian lies in front of any photo's camera")
    return float(np.median(zs))


def scene_cues(g: Gaussians, photos: Sequence[np.ndarray], cams: Sequence[Camera], cfg: CuesConfig,
               min_alpha: float) -> Cues:
    """Step ``cues``: up, the ground plane (and how high the photos see it reach), the local shape and the
    per-photo renders of the depth, alpha, shape, colour spread and height."""
    means = g.means.double().numpy()
    max_scale = g.scales.max(1).values.double().numpy()
    up = world_up(cams, cfg.up, means)
    ground = scene_ground(means, cams, up, cfg.ground_margin, cfg.ground_min_support, cfg.ground_max_below)
    if ground.note:
        log.info("effects: %s", ground.note)
    radius = cfg.neighbour_radius * _median_depth(means, cams)
    variation, upness = local_shape(means, up, radius, cfg.neighbours)
    shape = np.column_stack([variation, upness])
    renders = [render_features(g, shape, cam) for cam in cams]
    spread = colour_spread(g, photos, cams, [r[2] for r in renders])
    second = [spread]
    if ground.plane is not None:
        second.append(means @ ground.plane.normal - ground.plane.offset)
    second = np.column_stack(second)
    maps = []
    for img, cam, (m, a, d) in zip(photos, cams, renders):
        m2 = render_features(g, second, cam)[0]
        height = m2[..., 1] if ground.plane is not None else None
        maps.append(PhotoMaps(img, cam, d, a, m[..., 0], m[..., 1], m2[..., 0], height, cam.name))
    if ground.plane is not None:
        seen = [np.where((p.alpha >= min_alpha) & (p.depth > 0), p.height, np.nan) for p in maps]
        ground.cut = seen_ground_cut(ground.plane, seen, cfg.ground_seen_quantile)
        log.info("effects: ground cut %.3g above the plane (seen ground; the centres' layer reaches %.3g)",
                 ground.cut, ground.plane.cut_height())
    return Cues(means, max_scale, up, ground, radius, variation < cfg.wall_max_variation, maps)
