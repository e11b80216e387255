"""The view queue (:func:`plan_views`), its :class:`ViewPlan` and the cameras of a ``views.json``."""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

import torch

from anigs import geometry
from anigs.cameras import Camera
from anigs.gaussians import Gaussians
from anigs.geometry import horizontal_basis
from anigs.views.candidates import azimuth_deg, ccw_order, farthest_point_order, make_candidates, score_candidate, view_camera
from anigs.views.config import ViewsConfig
from anigs.views.coverage import (DYNAMIC_ALPHA, DYNAMIC_SHARE, _rel_deg, capture_pitch_deg, dynamic_fraction,
                                  observation_counts, replacement_directions, scene_coverage)
from anigs.render.visibility import VisibilityConfig, visibility
from anigs.views.content import ContentCheck, sharp_gaussians

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
               keep_all: str | None = None, points: np.ndarray | None = None) -> ViewPlan:
    """Build the view queue.

    Args:
        gaussians: the canonical Gaussians (N) used for the visibility tests.
        roi: bool [N], the dynamic Gaussians (regions of interest).
        cameras: the capture cameras (SfM): candidate positions, layout, observation counts.
        observations: int [N] capture photos each Gaussian is visible in (computed from
            ``cameras`` with the configured visibility test when None).
        keep_all: a reason to queue every placed view, whatever its dynamic fraction (the
            stage passes its whole-scene ROI fallback); None applies ``min_dynamic_fraction``.
        points: the SfM points [P,3] (the content test's ``near_points``; None skips that part).
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
    check = content_check(g, cameras, cfg, points)
    if observations is None and cfg.visibility == "weight":
        observations = check.sharp.observations  # the same test, counted in the same pass
    if observations is None:
        log.info("views: counting observations of %d Gaussians in %d capture photos", g.num, len(cameras))
        observations = observation_counts(g, cameras, vcfg)
    observations = np.asarray(observations)
    if observations.shape != (g.num,):
        raise ValueError(f"views: observation counts must be [{g.num}], got {observations.shape}")
    observed = observations >= cfg.min_observations
    g_obs = g.subset(torch.from_numpy(np.nonzero(observed)[0]))
    up_report = None
    if cfg.up == "z":
        up = np.array([0.0, 0.0, 1.0])
        est = geometry.estimate_up(cameras, means[observed] if observed.sum() >= 50 else None)
        if geometry.angle_deg(est.up, up) > 20 and not est.fallback:
            log.warning("views: the capture's up direction is %.0f deg from +z (%s); the views use +z "
                        "(views.up: auto uses the estimate)", geometry.angle_deg(est.up, up), est.method)
    else:
        est = geometry.estimate_up(cameras, means[observed] if observed.sum() >= 50 else None)
        up = est.up
        up_report = est.to_dict()
        log.info("views: estimated up %s (%.1f deg from +z, %s)", np.round(up, 3),
                 math.degrees(math.acos(np.clip(up[2], -1, 1))), est.method)
    layout = geometry.classify_layout(cameras, up, means[observed] if observed.any() else None)
    if cfg.layout != "auto":
        layout = geometry.Layout(cfg.layout, {**layout.metrics, "classified_as": geometry.LAYOUTS.index(layout.kind)},
                                 layout.focus)
    log.info("views: capture layout %s (%s)", layout.kind,
             ", ".join(f"{k} {v:.2f}" for k, v in layout.metrics.items()))
    walk = layout.kind == "walk"
    forward_mode = cfg.forward if walk else "centroid"
    base_pitch = float(cfg.pitch_deg) if walk else capture_pitch_deg(cameras, up)
    fov = float(cfg.fov_deg)
    if not walk and cfg.match_capture_fov:
        fov = min(fov, float(np.median([c.fov_x for c in cameras])))
    if not walk:
        log.info("views: %s layout: yaw 0 faces the ROI centroid, pitch %.1f deg (capture median), FOV %.1f deg",
                 layout.kind, base_pitch, fov)
    cand, cand_fwd = make_candidates(cameras, up, cfg)
    if len(cand) < cfg.num_locations:
        raise ValueError(f"views: {len(cand)} candidate positions but num_locations={cfg.num_locations}; "
                         "lower views.num_locations or add jittered candidates (views.jitter_copies)")
    centroid = means[roi].mean(0)
    if len(cand) > cfg.max_candidates:  # thin by pure farthest-point sampling first
        keep = sorted(farthest_point_order(cand, np.ones(len(cand)), cfg.max_candidates, 0))
        cand, cand_fwd = cand[keep], cand_fwd[keep]
    roi_idx = np.nonzero(roi)[0]
    log.info("views: scoring %d candidate positions (4-view panorama each, %s visibility)", len(cand), cfg.visibility)

    def roi_azimuth(pos: np.ndarray) -> float | None:
        d = centroid - pos
        if np.linalg.norm(d - up * (d @ up)) <= 1e-9:
            return None
        return float(azimuth_deg(d, up))

    heading = np.zeros(len(cand))
    cand_seen = np.zeros((len(cand), n_roi), dtype=bool)
    for m, pos in enumerate(cand):
        fixed = None
        if forward_mode == "centroid":
            az = roi_azimuth(pos)
            fixed = 0.0 if az is None else az
        elif forward_mode == "camera":
            fixed = float(azimuth_deg(cand_fwd[m], up))
        heading[m], cand_seen[m] = score_candidate(g, pos, roi_idx, up, cfg, vcfg, fixed)
    cand_vis = cand_seen.mean(1)
    reachable = float(cand_seen.any(0).mean())
    log.info("views: candidates see %.1f%% of the ROI on average (best %.1f%%); all together %.1f%%",
             100 * cand_vis.mean(), 100 * cand_vis.max(), 100 * reachable)
    if cand_vis.max() == 0:
        raise ValueError(f"views: none of the {len(cand)} candidate positions sees any of the {n_roi} ROI Gaussians")

    start = int(np.argmax(cand_vis))
    n_extra = min(cfg.extra_locations, len(cand) - cfg.num_locations)
    fps = farthest_point_order(cand, cand_vis, cfg.num_locations + n_extra, start, cfg.visibility_power)
    chosen, extra = fps[:cfg.num_locations], fps[cfg.num_locations:]
    e1, e2 = horizontal_basis(up)
    flat = lambda p: np.stack([p @ e1, p @ e2], -1)  # noqa: E731
    order = ccw_order(flat(cand[chosen]), flat(centroid), first=0)
    chosen = [chosen[i] for i in order]

    cov_cache: dict[tuple, tuple[float, dict[str, float] | None]] = {}

    def coverage_of(ci: int, yaw: float, pitch: float) -> tuple[Camera, float, dict[str, float] | None]:
        """The view's camera, scene coverage and content figures (None when the coverage fails)."""
        cam = view_camera(cand[ci], _heading_vec(heading[ci]), up, yaw, pitch, fov, cfg.width, cfg.height)
        key = (ci, round(_rel_deg(yaw), 6), round(pitch, 6))
        if key not in cov_cache:
            cov = scene_coverage(g_obs, cam, cfg.coverage_alpha)
            cov_cache[key] = cov, (check.measure(cam) if cov >= cfg.min_coverage else None)
        return cam, *cov_cache[key]

    def _heading_vec(h_deg: float) -> np.ndarray:
        h = math.radians(h_deg)
        return math.cos(h) * e1 + math.sin(h) * e2

    rejected: list[dict[str, Any]] = []
    used: dict[int, list[tuple[float, float]]] = {}
    figures: dict[int, dict[str, float]] = {}  # content figures of the placed cameras (by id)

    def place(ci: int, loc: int, yaw: float) -> tuple[Camera, float, float, float] | None:
        """First direction at candidate ``ci`` for requested ``yaw`` that passes the coverage test."""
        roi_az = roi_azimuth(cand[ci])
        roi_rel = None if roi_az is None else _rel_deg(roi_az - heading[ci])
        for y, p in replacement_directions(yaw, base_pitch, roi_rel, cfg):
            if any(abs(_rel_deg(y - uy)) < 1e-6 and abs(p - up_) < 1e-6 for uy, up_ in used.get(ci, [])):
                continue
            cam, cov, fig = coverage_of(ci, y, p)
            why = (f"coverage {cov:.2f} < min_coverage {cfg.min_coverage:g}" if fig is None
                   else check.failure(fig))
            if why is None:
                used.setdefault(ci, []).append((y, p))
                figures[id(cam)] = fig
                return cam, cov, y, p
            rejected.append({"location": loc, "candidate": int(ci), "requested_yaw": float(yaw), "yaw": float(y),
                             "pitch": float(p), "coverage": cov, **(fig or {}), "reason": why,
                             "position": cand[ci].tolist(), "forward": cam.forward.tolist()})
        return None

    slots: list[tuple[int, int, float, tuple]] = []   # (location, candidate, requested yaw, placed)
    missing: list[float] = []
    for loc, ci in enumerate(chosen):
        for yaw in cfg.directions:
            got = place(ci, loc, yaw)
            if got is None:
                missing.append(yaw)
            else:
                slots.append((loc, ci, yaw, got))
    loc_ids = list(range(len(chosen)))
    for ci in extra:  # directions no location passed: other locations
        if not missing:
            break
        loc = len(loc_ids)
        placed_here = False
        for yaw in list(missing):
            got = place(ci, loc, yaw)
            if got is not None:
                missing.remove(yaw)
                slots.append((loc, ci, yaw, got))
                placed_here = True
        if placed_here:
            loc_ids.append(loc)
            chosen.append(ci)
    if missing:
        log.warning("views: %d direction(s) (yaw %s) pass the coverage test (>= %.0f%% of pixels on Gaussians "
                    "seen in >= %d photos) and the content test (>= %.0f%% of pixels on sharp Gaussians) nowhere: "
                    "left out of the queue", len(missing), ", ".join(f"{y:+.0f}" for y in missing),
                    100 * cfg.min_coverage, cfg.min_observations, 100 * cfg.min_content)
    if rejected:
        log.info("views: %d direction(s) rejected by the coverage test and replaced", len(rejected))
    keep, fractions, dyn_rule = drop_negligible(g, roi, [s[3][0] for s in slots], cfg, keep_all)
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
    fractions = [fractions[i] for i in keep]
    slots = [slots[i] for i in keep]

    views: list[dict[str, Any]] = []
    cams: list[Camera] = []
    seen_by_view: list[np.ndarray] = []
    covered = np.zeros(gaussians.num, dtype=bool)
    any_seen = np.zeros(gaussians.num, dtype=bool)
    coverage_after: list[float] = []
    in_frustum = np.zeros(gaussians.num, dtype=bool)
    frustum_after: list[float] = []
    for (loc, ci, req_yaw, (cam, cov, yaw, pitch)), dyn in zip(slots, fractions):
        vid = f"v{len(views):02d}"
        cam.name = vid
        seen = visibility(g, cam, vcfg)
        n_seen = int(seen.sum())
        roi_seen = int((seen & roi).sum())
        entry: dict[str, Any] = {
            "id": vid, "location": loc, "candidate": int(ci), "yaw": float(yaw), "pitch": float(pitch),
            "heading_deg": float(heading[ci]), "camera": cam.to_dict(),
            "roi_visible": roi_seen, "roi_visible_fraction": roi_seen / n_roi, "visible": n_seen,
            "coverage": cov, "requested_yaw": float(req_yaw), "fov_deg": fov,
            "replaced": bool(abs(yaw - req_yaw) > 1e-9 or abs(pitch - base_pitch) > 1e-9 or loc >= cfg.num_locations),
            **figures[id(cam)],
        }
        if dyn is not None:
            entry["dynamic_fraction"] = dyn
        if views:
            ov = float((seen & any_seen).sum() / n_seen) if n_seen else 0.0
            ov_roi = float((seen & roi & covered).sum() / roi_seen) if roi_seen else 0.0
            entry["overlap_prev"] = ov
            entry["overlap_prev_roi"] = ov_roi
            if ov <= cfg.min_overlap:
                log.warning("views: %s (location %d, yaw %+.0f) overlaps none of the previous views: "
                            "%d of its %d visible Gaussians were seen before (%.1f%%, min_overlap %.2f)",
                            vid, loc, yaw, int((seen & any_seen).sum()), n_seen, 100 * ov, cfg.min_overlap)
        else:
            entry["overlap_prev"] = None
            entry["overlap_prev_roi"] = None
        covered |= seen & roi
        any_seen |= seen
        c_after = float(covered.sum() / n_roi)
        entry["coverage_after"] = c_after
        in_frustum |= visibility(g, cam, VisibilityConfig(mode="frustum")) & roi
        frustum_after.append(float(in_frustum.sum() / n_roi))
        entry["frustum_coverage_after"] = frustum_after[-1]
        coverage_after.append(c_after)
        views.append(entry)
        cams.append(cam)
        seen_by_view.append(seen)
    log.info("views: %d views at %d locations (layout %s); scene coverage per view: %s; content: %s; edge share: "
             "%s; ROI coverage after each view: %s (reachable from all candidates: %.1f%%)", len(views), len(chosen),
             layout.kind, " ".join(f"{v['coverage']:.2f}" for v in views),
             " ".join(f"{v['content']:.2f}" for v in views),
             " ".join(f"{v['edge_share']:.2f}" for v in views),
             " ".join(f"{100 * c:.1f}%" for c in coverage_after), 100 * reachable)
    rule = {"min": cfg.min_coverage, "alpha": cfg.coverage_alpha, "min_observations": cfg.min_observations,
            "observed_gaussians": int(observed.sum())}
    return ViewPlan(views, cams, cand, cand_vis, heading, chosen, centroid, up, coverage_after, reachable, seen_by_view,
                    cand_seen, frustum_after, layout, rejected, rule, up_report, dropped, dyn_rule, check.to_json())


def content_check(g: Gaussians, cameras: Sequence[Camera], cfg: ViewsConfig,
                  points: np.ndarray | None) -> ContentCheck:
    """The content test of the plan (:mod:`anigs.views.content`): its sharp Gaussians from the capture."""
    sharp = sharp_gaussians(g, cameras, cfg.content_rule(), points)
    return ContentCheck(g, sharp, cfg.content_rule(), cfg.background, cfg.min_edge_share)


def cameras_from_views(data: dict) -> list[Camera]:
    """The queue's cameras from a loaded ``views.json`` (named by view id)."""
    if "views" not in data:
        raise KeyError("views.json lacks key 'views'")
    cams = []
    for v in data["views"]:
        cam = Camera.from_dict(v["camera"])
        cam.name = v["id"]
        cams.append(cam)
    return cams
