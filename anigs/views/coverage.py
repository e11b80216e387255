"""Scene coverage of a view (pixels that see Gaussians observed by enough photos), and the
directions that replace one that fails."""
from __future__ import annotations

import logging
from typing import Sequence

import numpy as np


from anigs.cameras import Camera
from anigs.gaussians import Gaussians
from anigs.render.labels import dynamic_masks
from anigs.views.candidates import wrap_deg
from anigs.views.config import ViewsConfig
from anigs.render.visibility import VisibilityConfig, render_depth, visibility

log = logging.getLogger("anigs.views")


# ---- geometry helpers ---------------------------------------------------------------------
def observation_counts(g: Gaussians, cameras: Sequence[Camera], vcfg: VisibilityConfig | None = None) -> np.ndarray:
    """int [N]: in how many of the capture ``cameras`` each Gaussian is visible."""
    vcfg = vcfg or VisibilityConfig(mode="weight")
    count = np.zeros(g.num, dtype=np.int64)
    for cam in cameras:
        count += visibility(g, cam, vcfg)
    return count


def scene_coverage(g_observed: Gaussians, cam: Camera, alpha_min: float = 0.5) -> float:
    """Fraction of ``cam``'s pixels with accumulated alpha >= ``alpha_min`` (render of ``g_observed``)."""
    if g_observed.num == 0:
        return 0.0
    _, alpha = render_depth(g_observed, cam)
    return float((alpha >= alpha_min).mean())


DYNAMIC_SHARE = 0.5   # a pixel is dynamic when the ROI carries >= this share of its alpha ...
DYNAMIC_ALPHA = 0.3   # ... and its alpha is >= this (the labels/effects mask backends' defaults)


def dynamic_fraction(g: Gaussians, roi: np.ndarray, cam: Camera) -> float:
    """Share of ``cam``'s pixels in the dynamic mask of the ROI (bool [N]).

    The mask is the render the masks stage makes of a dynamic Gaussian set
    (:func:`anigs.render.labels.dynamic_masks`): every Gaussian of ``g`` is rasterised, and a
    pixel is dynamic when its alpha is >= ``DYNAMIC_ALPHA`` and the ROI Gaussians carry
    >= ``DYNAMIC_SHARE`` of it (occluded ROI Gaussians do not count).
    """
    return float(dynamic_masks(g, roi, [cam], DYNAMIC_SHARE, DYNAMIC_ALPHA)[0].mean())


def capture_pitch_deg(cameras: Sequence[Camera], up: np.ndarray) -> float:
    """Median pitch (deg, positive looks up) of the capture cameras."""
    f = np.stack([c.forward for c in cameras])
    return float(np.median(np.degrees(np.arcsin(np.clip(f @ up, -1, 1)))))


def rel_deg(a: float) -> float:
    return float(wrap_deg(np.array([a]))[0])


def replacement_directions(yaw: float, pitch: float, roi_rel: float | None, cfg: ViewsConfig) -> list[tuple[float, float]]:
    """(yaw, pitch) pairs to try for a requested direction, in order: itself, pitched down in
    ``pitch_step_deg`` steps, then yaws moved ``yaw_steps`` of the way towards ``roi_rel`` (deg,
    relative to the heading) with the same pitches. Duplicates dropped."""
    pitches = [pitch - k * cfg.pitch_step_deg for k in range(int(cfg.max_pitch_drop_deg // cfg.pitch_step_deg) + 1)]
    pitches = [p for p in pitches if p >= -89.0]
    yaws = [yaw]
    if roi_rel is not None:
        d = rel_deg(roi_rel - yaw)
        yaws += [yaw + t * d for t in cfg.yaw_steps]
    out: list[tuple[float, float]] = []
    for y in yaws:
        for p in pitches:
            key = (round(rel_deg(y), 6), round(p, 6))
            if key not in [(round(rel_deg(a), 6), round(b, 6)) for a, b in out]:
                out.append((float(y), float(p)))
    return out
