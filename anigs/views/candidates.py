"""Candidate locations and directions of the view queue: view cameras, farthest-point and
counter-clockwise orders, heading wedges, candidate scores."""
from __future__ import annotations

import logging
import math
from typing import Sequence

import numpy as np


from anigs.cameras import Camera, intrinsics_from_fov
from anigs.gaussians import Gaussians
from anigs.geometry import horizontal_basis
from anigs.views.config import ViewsConfig
from anigs.render.visibility import VisibilityConfig, visibility

log = logging.getLogger("anigs.views")


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


def wrap_deg(a: np.ndarray) -> np.ndarray:
    return (np.asarray(a, float) + 180.0) % 360.0 - 180.0


def in_wedges(rel_az_deg: np.ndarray, directions: Sequence[float], fov_deg: float) -> np.ndarray:
    """bool [K]: relative azimuths (deg) inside any of the horizontal wedges ``yaw +- fov/2``."""
    rel = np.asarray(rel_az_deg, float)[:, None]
    return (np.abs(wrap_deg(rel - np.asarray(directions, float)[None])) <= fov_deg / 2).any(1)


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


def roi_azimuth(pos: np.ndarray, centroid: np.ndarray, up: np.ndarray) -> float | None:
    """Azimuth (deg, horizontal basis of ``up``) from ``pos`` to the ROI ``centroid``; None when
    the centroid is straight above or below."""
    d = centroid - pos
    if np.linalg.norm(d - up * (d @ up)) <= 1e-9:
        return None
    return float(azimuth_deg(d, up))


def candidate_positions(cameras: Sequence[Camera], up: np.ndarray, cfg: ViewsConfig) -> tuple[np.ndarray, np.ndarray]:
    """Candidate positions [M,3] and forwards [M,3] (:func:`make_candidates`), at least
    ``cfg.num_locations`` of them, thinned to ``cfg.max_candidates`` by farthest-point sampling."""
    cand, cand_fwd = make_candidates(cameras, up, cfg)
    if len(cand) < cfg.num_locations:
        raise ValueError(f"views: {len(cand)} candidate positions but num_locations={cfg.num_locations}; "
                         "lower views.num_locations or add jittered candidates (views.jitter_copies)")
    if len(cand) > cfg.max_candidates:  # thin by pure farthest-point sampling first
        keep = sorted(farthest_point_order(cand, np.ones(len(cand)), cfg.max_candidates, 0))
        cand, cand_fwd = cand[keep], cand_fwd[keep]
    return cand, cand_fwd
