"""The view queue (:func:`plan_views`), its :class:`ViewPlan` and the cameras of a ``views.json``."""
from __future__ import annotations

import logging
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Sequence

import numpy as np

import torch

from anigs import geometry
from anigs.cameras import Camera
from anigs.gaussians import Gaussians
from anigs.views.candidates import candidate_positions
from anigs.views.config import ViewsConfig
from anigs.views.coverage import DYNAMIC_ALPHA, DYNAMIC_SHARE, dynamic_fraction
from anigs.views.content import ContentCheck, sharp_gaussians
from anigs.views.entries import queue_entries
from anigs.views.fallback import motion_advice, photo_pose_slots
from anigs.views.motion import MotionSharpness
from anigs.views.place import Placer, Slot
from anigs.views.policy import classify_capture, layout_policy
from anigs.views.score import choose_locations, score_candidates

log = logging.getLogger("anigs.views")


# ---- the queue ----------------------------------------------------------------------------
@dataclass
class ViewPlan:
    """Result of :func:`plan_views`."""

    views: list[dict[str, Any]]
    cameras: list[Camera]
    candidates: np.ndarray          # [M,3] candidate positions
    candidate_visible: np.ndarray   # [M] estimated fraction of ROI Gaussians a location there would see
    candidate_heading: np.ndarray   # [M] yaw-0 azimuth (deg) in the horizontal basis of ``up``
    chosen: list[int]               # candidate index per location, in queue (CCW) order
    roi_centroid: np.ndarray        # [3]
    up: np.ndarray                  # [3]
    coverage_after: list[float]     # fraction of ROI Gaussians seen by the first k views
    reachable: float                # fraction of ROI Gaussians seen from any candidate panorama
    seen_by_view: list[np.ndarray] = field(repr=False, default_factory=list)  # bool [N] per view
    candidate_seen: np.ndarray | None = field(repr=False, default=None)  # bool [M,R] ROI seen per candidate
    frustum_coverage_after: list[float] = field(default_factory=list)  # same, ignoring occlusion
    layout: geometry.Layout | None = None          # capture layout used for the schedule
    rejected: list[dict[str, Any]] = field(default_factory=list)  # directions that failed the coverage test
    coverage_rule: dict[str, Any] = field(default_factory=dict)   # the test (min, alpha, min_observations)
    up_estimate: dict[str, Any] | None = None      # geometry.estimate_up report (up: auto)
    dropped: list[dict[str, Any]] = field(default_factory=list)   # views left out: negligible dynamic region
    dynamic_rule: dict[str, Any] | None = None     # the negligible-view test (None: min_dynamic_fraction 0)
    content_rule: dict[str, Any] | None = None     # the content test (anigs.views.content.ContentCheck.to_json)
    motion: dict[str, Any] | None = None           # photo-pose fallback and advice (anigs.views.fallback)

    def dynamic_json(self) -> dict[str, Any]:
        """The ``dynamic_fraction`` section of ``views.json`` (see :func:`drop_negligible`)."""
        return {**(self.dynamic_rule or {}), "per_view": [v.get("dynamic_fraction") for v in self.views],
                "dropped": self.dropped}

    def to_json(self) -> dict[str, Any]:
        return {
            "views": self.views,
            "layout": None if self.layout is None else self.layout.to_dict(),
            "scene_coverage": {**self.coverage_rule, "per_view": [v.get("coverage") for v in self.views],
                               "rejected": self.rejected},
            **({} if self.dynamic_rule is None else {"dynamic_fraction": self.dynamic_json()}),
            **({} if self.content_rule is None else {"content": {
                **self.content_rule, "per_view": [v.get("content") for v in self.views],
                "edge_share_per_view": [v.get("edge_share") for v in self.views]}}),
            **({} if self.content_rule is None or self.content_rule.get("motion") is None else {"motion": {
                **(self.motion or {"advice": None}),
                "per_view": [v.get("motion_sharpness") for v in self.views],
                "unobserved_per_view": [v.get("unobserved") for v in self.views]}}),
            "up_estimate": self.up_estimate,
            "coverage_after": self.coverage_after,
            "frustum_coverage_after": self.frustum_coverage_after,
            "roi_reachable_fraction": self.reachable,
            "locations": [{"index": i, "candidate": int(c), "position": self.candidates[c].tolist(),
                           "heading_deg": float(self.candidate_heading[c]),
                           "roi_visible_fraction": float(self.candidate_visible[c])}
                          for i, c in enumerate(self.chosen)],
            "roi_centroid": self.roi_centroid.tolist(),
            "up": self.up.tolist(),
            "num_candidates": int(len(self.candidates)),
            "convention": ("yaw in degrees, counter-clockwise about up, relative to the location's heading; "
                           "camera = OpenCV world-to-camera"),
        }


DYNAMIC_DEFINITION = ("share of the view's width x height pixels in the dynamic mask of the ROI: all Gaussians "
                      "rendered, a pixel counts when its alpha is >= alpha and the ROI Gaussians carry >= share "
                      "of it (the masks stage's render of a dynamic set)")


def drop_negligible(g: Gaussians, roi: np.ndarray, cams: Sequence[Camera], cfg: ViewsConfig,
                    keep_all: str | None = None) -> tuple[list[int], list[float | None], dict[str, Any] | None]:
    """Which of the placed views ``cams`` to queue: (kept indices, dynamic fraction per view, rule).

    A view is negligible when its dynamic fraction (:func:`~anigs.views.coverage.dynamic_fraction`)
    is < ``cfg.min_dynamic_fraction``; negligible views are not queued. When every view is
    negligible the one with the largest fraction is kept (ties: the earliest). With
    ``min_dynamic_fraction`` 0 nothing is computed and the rule is None; with ``keep_all`` (a
    reason, e.g. the whole-scene ROI fallback) nothing is dropped and the reason is recorded.
    """
    n = len(cams)
    if cfg.min_dynamic_fraction <= 0:
        return list(range(n)), [None] * n, None
    rule: dict[str, Any] = {"min": cfg.min_dynamic_fraction, "share": DYNAMIC_SHARE, "alpha": DYNAMIC_ALPHA,
                            "definition": DYNAMIC_DEFINITION, "applied": keep_all is None, "not_applied": keep_all,
                            "kept_below_min": None}
    if keep_all is not None:
        log.info("views: min_dynamic_fraction not applied (%s): every view is queued", keep_all)
        return list(range(n)), [None] * n, rule
    fractions: list[float | None] = [dynamic_fraction(g, roi, c) for c in cams]
    keep = [i for i, f in enumerate(fractions) if f >= cfg.min_dynamic_fraction]
    if n and not keep:
        best = int(np.argmax(fractions))
        keep = [best]
        rule["kept_below_min"] = (f"all {n} views are below min_dynamic_fraction {cfg.min_dynamic_fraction:g}: "
                                  f"kept the one with the largest dynamic fraction ({fractions[best]:.5f}) rather "
                                  "than an empty queue")
        log.warning("views: %s", rule["kept_below_min"])
    return keep, fractions, rule


def plan_views(gaussians: Gaussians, roi: np.ndarray, cameras: Sequence[Camera],
               cfg: ViewsConfig | None = None, observations: np.ndarray | None = None,
               keep_all: str | None = None, points: np.ndarray | None = None,
               images: str | Path | None = None) -> ViewPlan:
    """Build the view queue: classify the capture (:mod:`anigs.views.policy`) -> candidate
    positions -> score them and choose locations (:mod:`anigs.views.score`) -> place the
    directions (:mod:`anigs.views.place`) -> drop negligible views -> the queue's entries.

    Args:
        gaussians: the canonical Gaussians (N) used for the visibility tests.
        roi: bool [N], the dynamic Gaussians (regions of interest).
        cameras: the capture cameras (SfM): candidate positions, layout, observation counts.
        observations: int [N] capture photos each Gaussian is visible in (computed from
            ``cameras`` with the configured visibility test when None).
        keep_all: a reason to queue every placed view, whatever its dynamic fraction (the
            stage passes its whole-scene ROI fallback); None applies ``min_dynamic_fraction``.
        points: the SfM points [P,3] (the content test's ``near_points``; None skips that part).
        images: the folder of the photos ``cameras`` describe: the moving region's sharpness is
            judged against them (:mod:`anigs.views.motion`); None skips that test (and the
            photo-pose fallback, :mod:`anigs.views.fallback`).
    """
    cfg = cfg or ViewsConfig()
    roi = np.asarray(roi)
    if roi.dtype != bool or roi.shape != (gaussians.num,):
        raise ValueError(f"views: region-of-interest mask must be bool [{gaussians.num}], got {roi.dtype} {roi.shape}")
    n_roi = int(roi.sum())
    if n_roi == 0:
        raise ValueError(f"views: no region of interest: 0 of {gaussians.num} Gaussians are marked dynamic "
                         "(check the labels / masks that define the dynamic regions)")
    if len(cameras) == 0:
        raise ValueError("views: no candidate cameras given")
    means = gaussians.means.detach().double().numpy()
    g = gaussians.detach()
    vcfg = cfg.visibility_config()
    motion = None if images is None else MotionSharpness(g, roi, cameras, images, 2 * max(cfg.width, cfg.height))
    # the whole-scene fallback (nothing moves): no moving region to judge, the holes still count
    check = content_check(g, cameras, cfg if keep_all is None else replace(cfg, min_motion_sharpness=0.0), points,
                          motion)
    frame = classify_capture(g, means, cameras, cfg, check, observations)
    observed, up, layout = frame.observed, frame.up, frame.layout
    g_obs = g.subset(torch.from_numpy(np.nonzero(observed)[0]))
    policy = layout_policy(layout, cameras, up, cfg)

    cand, cand_fwd = candidate_positions(cameras, up, cfg)
    centroid = means[roi].mean(0)
    roi_idx = np.nonzero(roi)[0]
    log.info("views: scoring %d candidate positions (4-view panorama each, %s visibility)", len(cand), cfg.visibility)
    heading, cand_seen = score_candidates(g, cand, cand_fwd, roi_idx, centroid, up, policy, cfg, vcfg)
    cand_vis = cand_seen.mean(1)
    reachable = float(cand_seen.any(0).mean())
    log.info("views: candidates see %.1f%% of the ROI on average (best %.1f%%); all together %.1f%%",
             100 * cand_vis.mean(), 100 * cand_vis.max(), 100 * reachable)
    if cand_vis.max() == 0:
        raise ValueError(f"views: none of the {len(cand)} candidate positions sees any of the {n_roi} ROI Gaussians")
    chosen, extra = choose_locations(cand, cand_vis, centroid, up, cfg)

    placer = Placer(g_obs, check, cand, heading, centroid, up, policy, cfg)
    slots, chosen = placer.place_all(chosen, extra)
    motion_json = None
    if motion is not None and placer.missing and placer.motion_failed:
        fb_figs: dict[int, dict[str, Any]] = {}
        if cfg.photo_pose_fallback:
            fb, fb_figs = photo_pose_slots(motion, check, g_obs, cand, heading, up, placer.missing, len(chosen),
                                           cfg.width, cfg.height, cfg.coverage_alpha)
            slots += fb
            placer.figures.update(fb_figs)
        motion_json = motion_advice(motion, placer.motion_failed, len(placer.missing), cfg.min_motion_sharpness,
                                    list(fb_figs.values()))
        if motion_json is not None:
            log.warning("views: %s", motion_json["advice"])
    slots, fractions, dropped, dyn_rule = _drop_slots(g, roi, slots, cfg, keep_all)
    views, cams, seen_by_view, coverage_after, frustum_after = queue_entries(
        g, roi, slots, fractions, heading, placer.figures, policy, cfg)
    log.info("views: %d views at %d locations (layout %s); scene coverage per view: %s; content: %s; edge share: "
             "%s; ROI coverage after each view: %s (reachable from all candidates: %.1f%%)", len(views), len(chosen),
             layout.kind, " ".join(f"{v['coverage']:.2f}" for v in views),
             " ".join(f"{v['content']:.2f}" for v in views),
             " ".join(f"{v['edge_share']:.2f}" for v in views),
             " ".join(f"{100 * c:.1f}%" for c in coverage_after), 100 * reachable)
    rule = {"min": cfg.min_coverage, "alpha": cfg.coverage_alpha, "min_observations": cfg.min_observations,
            "observed_gaussians": int(observed.sum())}
    return ViewPlan(views=views, cameras=cams, candidates=cand, candidate_visible=cand_vis, candidate_heading=heading,
                    chosen=chosen, roi_centroid=centroid, up=up, coverage_after=coverage_after, reachable=reachable,
                    seen_by_view=seen_by_view, candidate_seen=cand_seen, frustum_coverage_after=frustum_after,
                    layout=layout, rejected=placer.rejected, coverage_rule=rule, up_estimate=frame.up_report,
                    dropped=dropped, dynamic_rule=dyn_rule, content_rule=check.to_json(), motion=motion_json)


def _drop_slots(g: Gaussians, roi: np.ndarray, slots: list[Slot], cfg: ViewsConfig, keep_all: str | None
                ) -> tuple[list[Slot], list[float | None], list[dict[str, Any]], dict[str, Any] | None]:
    """(kept slots, their dynamic fractions, dropped entries, rule): :func:`drop_negligible` on
    the placed views, with a ``views.json`` entry per dropped view."""
    keep, fractions, dyn_rule = drop_negligible(g, roi, [s.placed.camera for s in slots], cfg, keep_all)
    dropped: list[dict[str, Any]] = []
    if dyn_rule is not None and dyn_rule["applied"]:
        log.info("views: dynamic fraction of the %d placed views (queue order before dropping): %s", len(slots),
                 " ".join(f"{100 * f:.2f}%" for f in fractions))
        for i, ((loc, ci, req_yaw, (cam, cov, yaw, pitch)), f) in enumerate(zip(slots, fractions)):
            if i in keep:
                continue
            dropped.append({"slot": i, "location": loc, "candidate": int(ci), "requested_yaw": float(req_yaw),
                            "yaw": float(yaw), "pitch": float(pitch), "coverage": cov, "dynamic_fraction": f,
                            "reason": f"negligible dynamic region: {f:.5f} of the pixels < min_dynamic_fraction "
                                      f"{cfg.min_dynamic_fraction:g}",
                            "position": cam.center.tolist(), "forward": cam.forward.tolist(),
                            "camera": cam.to_dict()})
        if dropped:
            log.warning("views: %d of %d views not queued, their dynamic region covers < %.2f%% of the pixels: %s; "
                        "the %d others are numbered v00..v%02d", len(dropped), len(slots),
                        100 * cfg.min_dynamic_fraction,
                        ", ".join(f"slot {d['slot']} (location {d['location']}, yaw {d['requested_yaw']:+.0f}) "
                                  f"{100 * d['dynamic_fraction']:.3f}%" for d in dropped), len(keep), len(keep) - 1)
    return [slots[i] for i in keep], [fractions[i] for i in keep], dropped, dyn_rule


def content_check(g: Gaussians, cameras: Sequence[Camera], cfg: ViewsConfig, points: np.ndarray | None,
                  motion: MotionSharpness | None = None) -> ContentCheck:
    """The content test of the plan (:mod:`anigs.views.content`): its sharp Gaussians from the capture,
    and the moving region's sharpness against the photos (``motion``, None: not judged)."""
    sharp = sharp_gaussians(g, cameras, cfg.content_rule(), points)
    return ContentCheck(g, sharp, cfg.content_rule(), cfg.background, cfg.min_edge_share, motion)


def cameras_from_views(data: dict) -> list[Camera]:
    """The queue's cameras from a loaded ``views.json`` (named by view id)."""
    if "views" not in data:
        raise KeyError("the views stage's queue lacks key 'views'")
    cams = []
    for v in data["views"]:
        cam = Camera.from_dict(v["camera"])
        cam.name = v["id"]
        cams.append(cam)
    return cams
