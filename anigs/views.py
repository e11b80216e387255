"""Incremental viewpoint expansion: the queue of views the dataset-model loop adds.

Paper ("Incremental viewpoint expansion"): choose N camera locations with farthest-point
sampling among candidate positions, favouring those that see the regions of interest
(the dynamic Gaussians); order them counter-clockwise around the regions; at each location
three yaw directions 0, +90, -90 degrees with a fixed 95 degree FOV; the queue goes location
by location, directions 0 -> 90 -> -90.

Conventions: the world "up" is +z (``up="z"``) or estimated from the candidate cameras
(``up="auto"``: mean of their image-up axes). Yaw is measured counter-clockwise seen from
above (right-handed about up): +90 turns left. The forward direction (yaw 0) at a location
is, by ``forward``: ``best`` the heading whose views see the most ROI Gaussians (estimated
from a 4-view panorama rendered at the location), ``centroid`` the horizontal direction to
the ROI centroid, or ``camera`` the horizontal direction of the capture camera there.

Coverage counts a Gaussian as seen by a view when it is visible there
(:mod:`anigs.masks.lift`: ``weight`` = it contributes at least ``min_weight`` pixels of
blending weight to the rendered image; ``depth`` = its centre passes a depth test).
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from anigs.cameras import Camera, intrinsics_from_fov
from anigs.configs import reject_unknown_keys
from anigs.gaussians import Gaussians
from anigs.masks.lift import VisibilityConfig, visibility

log = logging.getLogger(__name__)


def config_from_dict(cls, d: dict | None, where: str):
    """Build dataclass ``cls`` from ``d``; unknown keys are an error naming them."""
    d = dict(d or {})
    reject_unknown_keys(cls, d, where, ValueError)
    return cls(**d)


@dataclass
class ViewsConfig:
    """Parameters of the view queue (config section ``views``)."""

    num_locations: int = 4            # N camera locations
    directions: list = field(default_factory=lambda: [0.0, 90.0, -90.0])  # yaw order per location (deg)
    fov_deg: float = 95.0             # horizontal field of view of every view
    width: int = 256                  # view image width
    height: int = 192                 # view image height
    pitch_deg: float = 0.0            # elevation of the views (negative looks down)
    up: str = "z"                     # "z" or "auto" (estimated from the candidate cameras)
    forward: str = "best"             # yaw-0 heading: best | centroid | camera
    heading_step_deg: float = 5.0     # resolution of the 'best' heading search
    jitter_std: float = 0.0           # std of horizontal jitter of extra candidates (world units)
    jitter_copies: int = 0            # jittered copies per camera centre
    visibility_power: float = 1.0     # FPS score = min distance * (visible fraction)^power
    max_candidates: int = 64          # more candidates are thinned by farthest-point sampling first
    visibility: str = "weight"        # coverage test: weight | depth | frustum
    min_weight: float = 0.05          # 'weight' test: min summed blending weight (pixels)
    rel_tol: float = 0.03             # 'depth' test: relative depth tolerance
    scale_tol: float = 2.0            # 'depth' test: tolerance in Gaussian max-scales
    min_overlap: float = 0.0          # warn when a view's overlap with previous views is <= this
    seed: int = 0                     # jitter seed

    def __post_init__(self) -> None:
        if self.num_locations < 1:
            raise ValueError(f"views.num_locations must be >= 1, got {self.num_locations}")
        if not self.directions:
            raise ValueError("views.directions must list at least one yaw")
        self.directions = [float(d) for d in self.directions]
        if self.width < 8 or self.height < 8:
            raise ValueError(f"views: resolution {self.width}x{self.height} is too small (min 8x8)")
        if self.up not in ("z", "auto"):
            raise ValueError(f"views.up must be 'z' or 'auto', got {self.up!r}")
        if self.forward not in ("best", "centroid", "camera"):
            raise ValueError(f"views.forward must be 'best', 'centroid' or 'camera', got {self.forward!r}")
        if self.jitter_copies < 0 or self.jitter_std < 0:
            raise ValueError("views.jitter_copies and views.jitter_std must be >= 0")
        if self.heading_step_deg <= 0:
            raise ValueError(f"views.heading_step_deg must be > 0, got {self.heading_step_deg}")
        VisibilityConfig(mode=self.visibility)  # validates the mode name

    @staticmethod
    def from_dict(d: dict | None) -> "ViewsConfig":
        return config_from_dict(ViewsConfig, d, "views config")

    def visibility_config(self) -> VisibilityConfig:
        return VisibilityConfig(mode=self.visibility, rel_tol=self.rel_tol, scale_tol=self.scale_tol,
                                min_weight=self.min_weight)


# ---- geometry helpers ---------------------------------------------------------------------
def estimate_up(cameras: Sequence[Camera]) -> np.ndarray:
    """World up [3] as the normalised mean image-up axis (-y of the camera) of ``cameras``."""
    ups = np.stack([-c.R[1] for c in cameras])
    u = ups.mean(0)
    n = np.linalg.norm(u)
    if n < 1e-6:
        raise ValueError("cannot estimate the up direction: the cameras' up axes cancel out; set views.up='z'")
    return u / n


def horizontal_basis(up: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors (e1, e2) spanning the plane orthogonal to ``up``, with e1 x e2 = up."""
    ref = np.array([1.0, 0, 0]) if abs(up[0]) < 0.9 else np.array([0, 1.0, 0])
    e1 = ref - up * (ref @ up)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(up, e1)
    return e1, e2


def view_camera(eye: np.ndarray, forward: np.ndarray, up: np.ndarray, yaw_deg: float, pitch_deg: float,
                fov_deg: float, width: int, height: int, name: str = "") -> Camera:
    """Camera at ``eye`` looking along horizontal ``forward`` rotated by ``yaw`` (CCW about up), tilted by ``pitch``."""
    f = forward - up * (forward @ up)
    n = np.linalg.norm(f)
    if n < 1e-9:
        raise ValueError(f"view {name!r}: forward direction is vertical, cannot define a yaw")
    f /= n
    left = np.cross(up, f)
    y, p = math.radians(yaw_deg), math.radians(pitch_deg)
    h = math.cos(y) * f + math.sin(y) * left          # yaw: +90 turns left (CCW seen from above)
    d = math.cos(p) * h + math.sin(p) * up            # pitch: positive looks up
    right = np.cross(d, up)
    right /= np.linalg.norm(right)
    down = np.cross(d, right)
    R = np.stack([right, down, d])
    V = np.eye(4)
    V[:3, :3] = R
    V[:3, 3] = -R @ eye
    return Camera(intrinsics_from_fov(fov_deg, width, height), V, width, height, name)


def farthest_point_order(points: np.ndarray, weights: np.ndarray, k: int, start: int, power: float = 1.0) -> list[int]:
    """Greedy farthest-point sampling of ``k`` indices from ``points`` [M,D] starting at ``start``.

    Score of a candidate = (distance to the chosen set) * weights**power. Ties break to the
    lowest index (deterministic).
    """
    chosen = [int(start)]
    dmin = np.linalg.norm(points - points[start], axis=1)
    w = np.power(np.clip(weights, 0.0, None), power)
    for _ in range(k - 1):
        score = dmin * w
        score[chosen] = -1.0
        nxt = int(np.argmax(score))
        if score[nxt] <= 0:  # nothing left that is both new and useful: fall back to pure distance
            score = dmin.copy()
            score[chosen] = -1.0
            nxt = int(np.argmax(score))
        chosen.append(nxt)
        dmin = np.minimum(dmin, np.linalg.norm(points - points[nxt], axis=1))
    return chosen


def ccw_order(points2d: np.ndarray, centre2d: np.ndarray, first: int = 0) -> list[int]:
    """Indices of ``points2d`` [K,2] sorted counter-clockwise around ``centre2d``, starting at ``first``."""
    ang = np.arctan2(points2d[:, 1] - centre2d[1], points2d[:, 0] - centre2d[0])
    rel = np.mod(ang - ang[first], 2 * math.pi)
    return [int(i) for i in np.lexsort((np.arange(len(rel)), rel))]


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

    def to_json(self) -> dict[str, Any]:
        return {
            "views": self.views,
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


def make_candidates(cameras: Sequence[Camera], up: np.ndarray, cfg: ViewsConfig) -> tuple[np.ndarray, np.ndarray]:
    """Candidate positions [M,3] (camera centres plus optional horizontal jitter copies) and the
    horizontal viewing direction [M,3] of the camera each comes from."""
    centres = np.stack([c.center for c in cameras])
    fwd = np.stack([c.forward - up * (c.forward @ up) for c in cameras])
    fwd /= np.maximum(np.linalg.norm(fwd, axis=1, keepdims=True), 1e-12)
    if cfg.jitter_copies == 0 or cfg.jitter_std == 0:
        return centres, fwd
    e1, e2 = horizontal_basis(up)
    rng = np.random.default_rng(cfg.seed)
    jit = rng.normal(0.0, cfg.jitter_std, size=(len(centres), cfg.jitter_copies, 2))
    extra = centres[:, None, :] + jit[..., :1] * e1 + jit[..., 1:] * e2
    extra_fwd = np.repeat(fwd[:, None], cfg.jitter_copies, 1)
    return np.concatenate([centres, extra.reshape(-1, 3)]), np.concatenate([fwd, extra_fwd.reshape(-1, 3)])


def _wrap_deg(a: np.ndarray) -> np.ndarray:
    return (np.asarray(a, float) + 180.0) % 360.0 - 180.0


def in_wedges(rel_az_deg: np.ndarray, directions: Sequence[float], fov_deg: float) -> np.ndarray:
    """bool [K]: relative azimuths (deg) inside any of the horizontal wedges ``yaw +- fov/2``."""
    rel = np.asarray(rel_az_deg, float)[:, None]
    return (np.abs(_wrap_deg(rel - np.asarray(directions, float)[None])) <= fov_deg / 2).any(1)


def azimuth_deg(vec: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Azimuth (deg) of vectors [...,3] in the horizontal basis of ``up``."""
    e1, e2 = horizontal_basis(up)
    return np.degrees(np.arctan2(np.asarray(vec) @ e2, np.asarray(vec) @ e1))


def location_cameras(pos: np.ndarray, heading_deg: float, up: np.ndarray, cfg: ViewsConfig,
                     directions: Sequence[float] | None = None, fov_deg: float | None = None) -> list[Camera]:
    """Cameras at ``pos`` for each yaw of ``directions`` (default ``cfg.directions``) relative to the
    azimuth ``heading_deg``."""
    e1, e2 = horizontal_basis(up)
    h = math.radians(heading_deg)
    fwd = math.cos(h) * e1 + math.sin(h) * e2
    dirs = cfg.directions if directions is None else directions
    return [view_camera(pos, fwd, up, yaw, cfg.pitch_deg, fov_deg or cfg.fov_deg, cfg.width, cfg.height,
                        f"{yaw:+.0f}") for yaw in dirs]


def score_candidate(g: Gaussians, pos: np.ndarray, roi_idx: np.ndarray, up: np.ndarray, cfg: ViewsConfig,
                    vcfg: VisibilityConfig, fixed_heading: float | None) -> tuple[float, np.ndarray]:
    """(heading in deg, bool [R] ROI Gaussians the location's views would see).

    Renders a 4-view panorama (FOV >= 92 deg) at ``pos``; a visible ROI Gaussian counts for a
    heading when its azimuth falls in one of the views' wedges. Without ``fixed_heading`` the
    heading that maximises the count is searched in ``cfg.heading_step_deg`` steps.
    """
    seen = np.zeros(len(roi_idx), dtype=bool)
    for cam in location_cameras(pos, 0.0, up, cfg, (0.0, 90.0, 180.0, -90.0), max(cfg.fov_deg, 92.0)):
        seen |= visibility(g, cam, vcfg)[roi_idx]
    heading = 0.0 if fixed_heading is None else float(fixed_heading)
    if not seen.any():
        return heading, seen
    az = azimuth_deg(g.means.detach().double().numpy()[roi_idx[seen]] - pos, up)
    headings = np.array([heading]) if fixed_heading is not None else np.arange(-180.0, 180.0, cfg.heading_step_deg)
    inside = [in_wedges(az - h, cfg.directions, cfg.fov_deg) for h in headings]
    k = int(np.argmax([m.sum() for m in inside]))
    out = np.zeros_like(seen)
    out[np.nonzero(seen)[0][inside[k]]] = True
    return float(headings[k]), out


def plan_views(gaussians: Gaussians, roi: np.ndarray, cameras: Sequence[Camera],
               cfg: ViewsConfig | None = None) -> ViewPlan:
    """Build the view queue.

    Args:
        gaussians: the canonical Gaussians (N) used for the visibility tests.
        roi: bool [N], the dynamic Gaussians (regions of interest).
        cameras: candidate cameras (the SfM cameras); their centres are the candidate positions.
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
    up = np.array([0.0, 0.0, 1.0]) if cfg.up == "z" else estimate_up(cameras)
    if cfg.up == "auto":
        log.info("views: estimated up %s (%.1f deg from +z)", np.round(up, 3),
                 math.degrees(math.acos(np.clip(up[2], -1, 1))))
    cand, cand_fwd = make_candidates(cameras, up, cfg)
    if len(cand) < cfg.num_locations:
        raise ValueError(f"views: {len(cand)} candidate positions but num_locations={cfg.num_locations}; "
                         "lower views.num_locations or add jittered candidates (views.jitter_copies)")
    means = gaussians.means.detach().double().numpy()
    centroid = means[roi].mean(0)
    if len(cand) > cfg.max_candidates:  # thin by pure farthest-point sampling first
        keep = sorted(farthest_point_order(cand, np.ones(len(cand)), cfg.max_candidates, 0))
        cand, cand_fwd = cand[keep], cand_fwd[keep]
    vcfg = cfg.visibility_config()
    roi_idx = np.nonzero(roi)[0]
    g = gaussians.detach()
    log.info("views: scoring %d candidate positions (4-view panorama each, %s visibility)", len(cand), cfg.visibility)

    heading = np.zeros(len(cand))
    cand_seen = np.zeros((len(cand), n_roi), dtype=bool)
    for m, pos in enumerate(cand):
        fixed = None
        if cfg.forward == "centroid":
            fixed = float(azimuth_deg(centroid - pos, up)) if np.linalg.norm(
                (centroid - pos) - up * ((centroid - pos) @ up)) > 1e-9 else 0.0
        elif cfg.forward == "camera":
            fixed = float(azimuth_deg(cand_fwd[m], up))
        heading[m], cand_seen[m] = score_candidate(g, pos, roi_idx, up, cfg, vcfg, fixed)
    cand_vis = cand_seen.mean(1)
    reachable = float(cand_seen.any(0).mean())
    log.info("views: candidates see %.1f%% of the ROI on average (best %.1f%%); all together %.1f%%",
             100 * cand_vis.mean(), 100 * cand_vis.max(), 100 * reachable)
    if cand_vis.max() == 0:
        raise ValueError(f"views: none of the {len(cand)} candidate positions sees any of the {n_roi} ROI Gaussians")

    start = int(np.argmax(cand_vis))
    chosen = farthest_point_order(cand, cand_vis, cfg.num_locations, start, cfg.visibility_power)
    e1, e2 = horizontal_basis(up)
    flat = lambda p: np.stack([p @ e1, p @ e2], -1)  # noqa: E731
    order = ccw_order(flat(cand[chosen]), flat(centroid), first=0)
    chosen = [chosen[i] for i in order]

    views: list[dict[str, Any]] = []
    cams: list[Camera] = []
    seen_by_view: list[np.ndarray] = []
    covered = np.zeros(gaussians.num, dtype=bool)
    any_seen = np.zeros(gaussians.num, dtype=bool)
    coverage_after: list[float] = []
    in_frustum = np.zeros(gaussians.num, dtype=bool)
    frustum_after: list[float] = []
    for loc, ci in enumerate(chosen):
        for cam, yaw in zip(location_cameras(cand[ci], heading[ci], up, cfg), cfg.directions):
            vid = f"v{len(views):02d}"
            cam.name = vid
            seen = visibility(g, cam, vcfg)
            n_seen = int(seen.sum())
            roi_seen = int((seen & roi).sum())
            entry: dict[str, Any] = {
                "id": vid, "location": loc, "candidate": int(ci), "yaw": float(yaw), "pitch": float(cfg.pitch_deg),
                "heading_deg": float(heading[ci]), "camera": cam.to_dict(),
                "roi_visible": roi_seen, "roi_visible_fraction": roi_seen / n_roi, "visible": n_seen,
            }
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
            cov = float(covered.sum() / n_roi)
            entry["coverage_after"] = cov
            in_frustum |= visibility(g, cam, VisibilityConfig(mode="frustum")) & roi
            frustum_after.append(float(in_frustum.sum() / n_roi))
            entry["frustum_coverage_after"] = frustum_after[-1]
            coverage_after.append(cov)
            views.append(entry)
            cams.append(cam)
            seen_by_view.append(seen)
    log.info("views: %d views at %d locations; ROI coverage after each view: %s (reachable from all "
             "candidates: %.1f%%)", len(views), len(chosen),
             " ".join(f"{100 * c:.1f}%" for c in coverage_after), 100 * reachable)
    return ViewPlan(views, cams, cand, cand_vis, heading, chosen, centroid, up, coverage_after, reachable, seen_by_view,
                    cand_seen, frustum_after)


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


__all__ = ["ViewsConfig", "ViewPlan", "plan_views", "view_camera", "farthest_point_order", "ccw_order",
           "estimate_up", "horizontal_basis", "make_candidates", "location_cameras", "score_candidate",
           "in_wedges", "azimuth_deg", "cameras_from_views", "config_from_dict"]
