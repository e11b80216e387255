"""Place the queue's directions at the chosen locations: the first direction per requested yaw
that passes the coverage and content tests (:func:`anigs.views.coverage.replacement_directions`
gives the order of the replacements), then extra locations for the yaws nowhere placed."""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from anigs.cameras import Camera
from anigs.gaussians import Gaussians
from anigs.geometry import horizontal_basis
from anigs.views.candidates import roi_azimuth, view_camera
from anigs.views.config import ViewsConfig
from anigs.views.content import ContentCheck
from anigs.views.coverage import rel_deg, replacement_directions, scene_coverage
from anigs.views.policy import LayoutPolicy

log = logging.getLogger("anigs.views")

def _angle_deg(yaw0: float, pitch0: float, yaw1: float, pitch1: float) -> float:
    """Angle (deg) between two view directions given as yaw and pitch (deg) about the same heading."""
    p0, p1, dy = math.radians(pitch0), math.radians(pitch1), math.radians(rel_deg(yaw0 - yaw1))
    c = math.sin(p0) * math.sin(p1) + math.cos(p0) * math.cos(p1) * math.cos(dy)
    return math.degrees(math.acos(min(max(c, -1.0), 1.0)))


class Placed(NamedTuple):
    """A direction that passed: its camera, scene coverage, and yaw and pitch (deg)."""

    camera: Camera
    coverage: float
    yaw: float
    pitch: float


class Slot(NamedTuple):
    """A queued direction: the location (queue order), its candidate index, the yaw it was asked
    for (deg) and what was placed for it."""

    location: int
    candidate: int
    requested_yaw: float
    placed: Placed


@dataclass
class Placer:
    """Places directions at candidate locations; remembers what it tried.

    ``g_obs``: the observed Gaussians (scene coverage); ``cand`` [M,3] and ``heading`` [M] (deg):
    the scored candidates. ``rejected`` lists every direction that failed a test, ``figures`` the
    content figures of each placed camera (by ``id``).
    """

    g_obs: Gaussians
    check: ContentCheck
    cand: np.ndarray
    heading: np.ndarray
    centroid: np.ndarray
    up: np.ndarray
    policy: LayoutPolicy
    cfg: ViewsConfig
    rejected: list[dict[str, Any]] = field(default_factory=list)
    figures: dict[int, dict[str, float]] = field(default_factory=dict)
    used: dict[int, list[tuple[float, float]]] = field(default_factory=dict)
    cov_cache: dict[tuple, tuple[float, dict[str, float] | None]] = field(default_factory=dict)
    missing: list[float] = field(default_factory=list)  # yaws placed nowhere (after place_all)
    motion_failed: list[tuple[Camera, dict[str, Any]]] = field(default_factory=list)  # (camera, figures) of the
    # directions tried for those that failed min_motion_sharpness

    def heading_vec(self, h_deg: float) -> np.ndarray:
        e1, e2 = horizontal_basis(self.up)
        h = math.radians(h_deg)
        return math.cos(h) * e1 + math.sin(h) * e2

    def coverage_of(self, ci: int, yaw: float, pitch: float) -> tuple[Camera, float, dict[str, float] | None]:
        """The view's camera, scene coverage and content figures (None when the coverage fails)."""
        cfg = self.cfg
        cam = view_camera(self.cand[ci], self.heading_vec(self.heading[ci]), self.up, yaw, pitch,
                          self.policy.fov_deg, cfg.width, cfg.height)
        key = (ci, round(rel_deg(yaw), 6), round(pitch, 6))
        if key not in self.cov_cache:
            cov = scene_coverage(self.g_obs, cam, cfg.coverage_alpha)
            self.cov_cache[key] = cov, (self.check.measure(cam) if cov >= cfg.min_coverage else None)
        return cam, *self.cov_cache[key]

    def place(self, ci: int, loc: int, yaw: float) -> Placed | None:
        """First direction at candidate ``ci`` for requested ``yaw`` that passes the coverage test."""
        roi_az = roi_azimuth(self.cand[ci], self.centroid, self.up)
        roi_rel = None if roi_az is None else rel_deg(roi_az - self.heading[ci])
        blurred: list[tuple[Camera, dict[str, Any]]] = []
        for y, p in replacement_directions(yaw, self.policy.pitch_deg, roi_rel, self.cfg):
            if any(abs(rel_deg(y - uy)) < 1e-6 and abs(p - up_) < 1e-6 for uy, up_ in self.used.get(ci, [])):
                continue
            if any(_angle_deg(y, p, uy, up_) < self.cfg.min_separation_deg for uy, up_ in self.used.get(ci, [])):
                continue  # a near-copy of a view queued here (not tested, not drawn)
            cam, cov, fig = self.coverage_of(ci, y, p)
            why = (f"coverage {cov:.2f} < min_coverage {self.cfg.min_coverage:g}" if fig is None
                   else self.check.failure(fig))
            if why is None:
                self.used.setdefault(ci, []).append((y, p))
                self.figures[id(cam)] = fig
                return Placed(cam, cov, y, p)
            self.rejected.append({"location": loc, "candidate": int(ci), "requested_yaw": float(yaw), "yaw": float(y),
                                  "pitch": float(p), "coverage": cov, **(fig or {}), "reason": why,
                                  "position": self.cand[ci].tolist(), "forward": cam.forward.tolist()})
            if "motion sharpness" in why:
                blurred.append((cam, fig or {}))
        self.motion_failed.extend(blurred)
        return None

    def place_all(self, chosen: list[int], extra: list[int]) -> tuple[list[Slot], list[int]]:
        """(slots in queue order, locations used): every ``cfg.directions`` yaw at each ``chosen``
        location, then the yaws no location placed at the ``extra`` candidates (a location joins
        ``chosen``, returned extended, when it places one)."""
        cfg = self.cfg
        chosen = list(chosen)
        slots: list[Slot] = []
        missing: list[float] = []
        for loc, ci in enumerate(chosen):
            for yaw in cfg.directions:
                got = self.place(ci, loc, yaw)
                if got is None:
                    missing.append(yaw)
                else:
                    slots.append(Slot(loc, ci, yaw, got))
        loc_ids = list(range(len(chosen)))
        for ci in extra:  # directions no location passed: other locations
            if not missing:
                break
            loc = len(loc_ids)
            placed_here = False
            for yaw in list(missing):
                got = self.place(ci, loc, yaw)
                if got is not None:
                    missing.remove(yaw)
                    slots.append(Slot(loc, ci, yaw, got))
                    placed_here = True
            if placed_here:
                loc_ids.append(loc)
                chosen.append(ci)
        self.missing = missing
        if missing:
            log.warning("views: %d direction(s) (yaw %s) pass the coverage test (>= %.0f%% of pixels on Gaussians "
                        "seen in >= %d photos) and the content test (>= %.0f%% of pixels on sharp Gaussians, the "
                        "moving region >= %g x as sharp as the photos show it, <= %.0f%% unobserved) nowhere",
                        len(missing), ", ".join(f"{y:+.0f}" for y in missing), 100 * cfg.min_coverage,
                        cfg.min_observations, 100 * cfg.min_content, cfg.min_motion_sharpness, 100 * cfg.max_unobserved)
        if self.rejected:
            log.info("views: %d direction(s) rejected by the coverage test and replaced", len(self.rejected))
        return slots, chosen
