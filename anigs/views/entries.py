"""The queue's ``views.json`` entries: one per placed view, numbered v00, v01, ... in queue
order, with what it sees, its overlap with the views before it and the ROI coverage so far."""
from __future__ import annotations

import logging
from typing import Any, Sequence

import numpy as np

from anigs.cameras import Camera
from anigs.gaussians import Gaussians
from anigs.render.visibility import VisibilityConfig, visibility
from anigs.views.config import ViewsConfig
from anigs.views.place import Slot
from anigs.views.policy import LayoutPolicy

log = logging.getLogger("anigs.views")


def queue_entries(g: Gaussians, roi: np.ndarray, slots: Sequence[Slot], fractions: Sequence[float | None],
                  heading: np.ndarray, figures: dict[int, dict[str, float]], policy: LayoutPolicy, cfg: ViewsConfig
                  ) -> tuple[list[dict[str, Any]], list[Camera], list[np.ndarray], list[float], list[float]]:
    """(entries, cameras named by id, bool [N] seen per view, ROI coverage after each view, the same
    ignoring occlusion) for the queued ``slots`` (their dynamic ``fractions``; ``heading`` [M] deg
    per candidate; ``figures``: content figures by camera ``id``)."""
    vcfg = cfg.visibility_config()
    n_roi = int(roi.sum())
    views: list[dict[str, Any]] = []
    cams: list[Camera] = []
    seen_by_view: list[np.ndarray] = []
    covered = np.zeros(g.num, dtype=bool)
    any_seen = np.zeros(g.num, dtype=bool)
    coverage_after: list[float] = []
    in_frustum = np.zeros(g.num, dtype=bool)
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
            "coverage": cov, "requested_yaw": float(req_yaw), "fov_deg": policy.fov_deg,
            "replaced": bool(abs(yaw - req_yaw) > 1e-9 or abs(pitch - policy.pitch_deg) > 1e-9
                             or loc >= cfg.num_locations),
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
    return views, cams, seen_by_view, coverage_after, frustum_after
