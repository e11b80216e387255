"""Classify the capture (observed Gaussians, up, layout) and the view policy of each layout.

The first step of :func:`anigs.views.plan.plan_views`: :func:`classify_capture` gives the
:class:`CaptureFrame` (which Gaussians the photos observe, the world up, the capture layout);
:func:`layout_policy` turns its layout into a :class:`LayoutPolicy`, the few numbers that differ
between layouts (how yaw 0 is aimed, the base pitch, the field of view). The later steps
(candidates, score, place) are stateless functions of the policy.
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from anigs import geometry
from anigs.cameras import Camera
from anigs.gaussians import Gaussians
from anigs.views.config import ViewsConfig
from anigs.views.content import ContentCheck
from anigs.views.coverage import capture_pitch_deg, observation_counts

log = logging.getLogger("anigs.views")


@dataclass
class CaptureFrame:
    """What the plan knows of the capture before it places anything."""

    observed: np.ndarray                  # bool [N]: seen in >= min_observations photos
    up: np.ndarray                        # [3] world up
    up_report: dict[str, Any] | None      # geometry.estimate_up report (up: auto), else None
    layout: geometry.Layout               # the capture layout (or the configured one)


@dataclass(frozen=True)
class LayoutPolicy:
    """How a layout aims its views: ``forward`` (yaw 0 heading: best | centroid | camera, see
    :mod:`anigs.views`), the base ``pitch_deg`` of every direction and the ``fov_deg``."""

    forward: str
    pitch_deg: float
    fov_deg: float


def layout_policy(layout: geometry.Layout, cameras: Sequence[Camera], up: np.ndarray,
                  cfg: ViewsConfig) -> LayoutPolicy:
    """The policy of ``layout``: a ``walk`` keeps the paper's schedule (``cfg.forward``,
    ``cfg.pitch_deg``, ``cfg.fov_deg``); any other layout faces the ROI centroid at the capture's
    median pitch, with the photos' median FOV at most (``match_capture_fov``)."""
    if layout.kind == "walk":
        return LayoutPolicy(cfg.forward, float(cfg.pitch_deg), float(cfg.fov_deg))
    base_pitch = capture_pitch_deg(cameras, up)
    fov = float(cfg.fov_deg)
    if cfg.match_capture_fov:
        fov = min(fov, float(np.median([c.fov_x for c in cameras])))
    log.info("views: %s layout: yaw 0 faces the ROI centroid, pitch %.1f deg (capture median), FOV %.1f deg",
             layout.kind, base_pitch, fov)
    return LayoutPolicy("centroid", base_pitch, fov)


def observation_mask(g: Gaussians, cameras: Sequence[Camera], cfg: ViewsConfig, check: ContentCheck,
                     observations: np.ndarray | None) -> np.ndarray:
    """Bool [N]: Gaussians visible in >= ``cfg.min_observations`` capture photos (counted here
    when ``observations`` [N] is None; the content test's count under ``visibility: weight``)."""
    if observations is None and cfg.visibility == "weight":
        observations = check.sharp.observations  # the same test, counted in the same pass
    if observations is None:
        log.info("views: counting observations of %d Gaussians in %d capture photos", g.num, len(cameras))
        observations = observation_counts(g, cameras, cfg.visibility_config())
    observations = np.asarray(observations)
    if observations.shape != (g.num,):
        raise ValueError(f"views: observation counts must be [{g.num}], got {observations.shape}")
    return observations >= cfg.min_observations


def resolve_up(cameras: Sequence[Camera], means: np.ndarray, observed: np.ndarray,
               cfg: ViewsConfig) -> tuple[np.ndarray, dict[str, Any] | None]:
    """(up [3], report): +z for ``up: z`` (warning when the capture's estimate is far from it),
    else the estimate (:func:`anigs.geometry.estimate_up`) and its report."""
    est = geometry.estimate_up(cameras, means[observed] if observed.sum() >= 50 else None)
    if cfg.up == "z":
        up = np.array([0.0, 0.0, 1.0])
        if geometry.angle_deg(est.up, up) > 20 and not est.fallback:
            log.warning("views: the capture's up direction is %.0f deg from +z (%s); the views use +z "
                        "(views.up: auto uses the estimate)", geometry.angle_deg(est.up, up), est.method)
        return up, None
    up = est.up
    log.info("views: estimated up %s (%.1f deg from +z, %s)", np.round(up, 3),
             math.degrees(math.acos(np.clip(up[2], -1, 1))), est.method)
    return up, est.to_dict()


def classify_capture(g: Gaussians, means: np.ndarray, cameras: Sequence[Camera], cfg: ViewsConfig,
                     check: ContentCheck, observations: np.ndarray | None) -> CaptureFrame:
    """Observed Gaussians, up and layout (:func:`anigs.geometry.classify_layout`; ``cfg.layout``
    other than ``auto`` overrides the kind and records what it was classified as)."""
    observed = observation_mask(g, cameras, cfg, check, observations)
    up, up_report = resolve_up(cameras, means, observed, cfg)
    layout = geometry.classify_layout(cameras, up, means[observed] if observed.any() else None)
    if cfg.layout != "auto":
        layout = geometry.Layout(cfg.layout, {**layout.metrics, "classified_as": geometry.LAYOUTS.index(layout.kind)},
                                 layout.focus)
    log.info("views: capture layout %s (%s)", layout.kind,
             ", ".join(f"{k} {v:.2f}" for k, v in layout.metrics.items()))
    return CaptureFrame(observed, up, up_report, layout)
