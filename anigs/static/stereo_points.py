"""A dense start for sparse captures: depth maps of the training photos by plane-sweep stereo, kept where
neighbouring photos agree, as points.

SfM keeps a few thousand points on a street walk, each facade seen from two or three photos at a grazing
angle; the fit then fills the facades by densification from whatever lies nearest, and the photos it did not
train on show smears. With the poses known, each training photo's depth can be read from its neighbours
directly (Collins 1996; Gallup et al. 2007): for each of ``planes`` fronto-parallel planes between the nearest
and farthest SfM point the photo sees (even in inverse depth), each neighbour is warped onto the photo
through the plane's homography, and the depth whose warps match the photo best (zero-normalised
cross-correlation over a ``window``, the best neighbour of each pixel: one may not see it) is the pixel's,
refined between planes by a parabola. A plane sweep needs no rectification, so a walk whose camera moves
along its own axis works as a sideways one does. A pixel is kept where it matches well (``min_zncc``), has
texture (``min_texture``), and where a neighbour's own depth map puts the same point within ``max_rel_diff``
(geometric consistency). Only the training photos are read: the held-out photos judge the fit.

Weight-free and CPU-cheap: the sweep runs at ``max_side`` px (a 640 px street photo at 320: 48 planes x
2 neighbours of box filters).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass

import cv2
import numpy as np

from anigs.cameras import Camera
from anigs.static.pair_points import PairPoints
from anigs.static.warp import nearest_views

log = logging.getLogger("anigs.static.fit")

NEAR_QUANTILE, FAR_QUANTILE = 2.0, 98.0  # percentiles of the SfM points' depths in a photo that bound its sweep
NEAR_MARGIN, FAR_MARGIN = 0.7, 1.5  # ... widened by these factors (nearest x 0.7, farthest x 1.5)
BEYOND_FARTHEST = 1.2  # stereo points may lie this much beyond the farthest SfM point a photo sees (x its depth)
MIN_SEEN = 10  # a photo that sees fewer SfM points gets no depth map (no range to sweep)
INVALID = 2.0  # the cost (1 - ZNCC) of a pixel a warp leaves outside the neighbour
CENTRES = np.array([[1.0, 0.0, 0.5], [0.0, 1.0, 0.5], [0.0, 0.0, 1.0]])  # pixel index -> the cameras' coordinates


@dataclass(frozen=True)
class StereoConfig:
    """The plane sweep's settings (module docstring)."""

    neighbours: int = 2          # each training photo is matched against this many nearest training photos
    planes: int = 48             # depth planes, even in inverse depth between the photo's SfM range
    max_side: int = 320          # the sweep runs on the photos at most this size (px)
    window: int = 5              # ZNCC window (px at max_side)
    min_zncc: float = 0.7        # a pixel is kept when its best match correlates at least this well
    min_texture: float = 0.02    # ... and its window's grey std (grey in [0,1]) is at least this
    max_rel_diff: float = 0.02   # ... and a neighbour's depth map puts the point within this relative depth
    step: int = 2                # every step-th pixel (at max_side) of a photo becomes a point


def _scaled(img: np.ndarray, cam: Camera, max_side: int) -> tuple[np.ndarray, np.ndarray]:
    """Grey float32 [h,w] in [0,1] of ``img`` at most ``max_side`` px, and the camera's K at that size."""
    s = min(1.0, max_side / max(cam.width, cam.height))
    w, h = max(1, round(cam.width * s)), max(1, round(cam.height * s))
    grey = cv2.cvtColor(np.ascontiguousarray(img), cv2.COLOR_RGB2GRAY)
    grey = cv2.resize(grey, (w, h), interpolation=cv2.INTER_AREA).astype(np.float32)
    K = cam.K.astype(np.float64).copy()
    K[0] *= w / cam.width
    K[1] *= h / cam.height
    return grey / (255.0 if img.dtype == np.uint8 else 1.0), K


def _box(x: np.ndarray, window: int) -> np.ndarray:
    return cv2.boxFilter(x, -1, (window, window), normalize=True, borderType=cv2.BORDER_REFLECT)


def _depth_range(cam: Camera, points: np.ndarray) -> tuple[float, float] | None:
    """(near, far) of the sweep from the SfM points in front of ``cam`` and inside its image."""
    X = points @ cam.viewmat[:3, :3].T + cam.viewmat[:3, 3]
    z = X[:, 2]
    front = z > 1e-6
    uv = X[front, :2] / z[front, None] @ np.diag([cam.K[0, 0], cam.K[1, 1]]) + cam.K[:2, 2]
    inside = (uv[:, 0] >= 0) & (uv[:, 0] < cam.width) & (uv[:, 1] >= 0) & (uv[:, 1] < cam.height)
    z = z[front][inside]
    if len(z) < MIN_SEEN:
        return None
    return float(np.percentile(z, NEAR_QUANTILE)) * NEAR_MARGIN, float(np.percentile(z, FAR_QUANTILE)) * FAR_MARGIN


def _relative(ref: Camera, other: Camera) -> tuple[np.ndarray, np.ndarray]:
    """(R [3,3], t [3]) taking ``ref``'s camera frame to ``other``'s."""
    R = other.viewmat[:3, :3] @ ref.viewmat[:3, :3].T
    return R, other.viewmat[:3, 3] - R @ ref.viewmat[:3, 3]


def sweep(grey: np.ndarray, K: np.ndarray, others: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]],
          near: float, far: float, cfg: StereoConfig) -> tuple[np.ndarray, np.ndarray]:
    """Depth [h,w] (float32, camera z) and best ZNCC [h,w] of the photo ``grey`` (K at its size) against
    ``others``: (grey, K, R, t) of each neighbour, (R, t) from this camera's frame to its."""
    h, w = grey.shape
    mu = _box(grey, cfg.window)
    sd = np.sqrt(np.maximum(_box(grey * grey, cfg.window) - mu * mu, 0.0))
    inv = np.linspace(1.0 / near, 1.0 / far, cfg.planes)
    cost = np.full((cfg.planes, h, w), INVALID, np.float32)
    Kinv = np.linalg.inv(K)
    n = np.array([0.0, 0.0, 1.0])
    for og, oK, R, t in others:
        ones = np.ones_like(og)
        for k, q in enumerate(inv):
            # the plane z = 1/q of this camera: a pixel x here shows the neighbour's pixel H x (pixel centres at +0.5)
            H = np.linalg.inv(CENTRES) @ oK @ (R + np.outer(t, n) * q) @ Kinv @ CENTRES
            flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
            warped = cv2.warpPerspective(og, H, (w, h), flags=flags, borderValue=0.0)
            valid = cv2.warpPerspective(ones, H, (w, h), flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP,
                                        borderValue=0.0)
            mw = _box(warped, cfg.window)
            sw = np.sqrt(np.maximum(_box(warped * warped, cfg.window) - mw * mw, 0.0))
            zncc = (_box(grey * warped, cfg.window) - mu * mw) / np.maximum(sd * sw, 1e-6)
            c = np.where(valid > 0.5, 1.0 - zncc, INVALID).astype(np.float32)
            np.minimum(cost[k], c, out=cost[k])
    best = np.argmin(cost, 0)
    rows, cols = np.indices(best.shape)
    c0 = cost[best, rows, cols]
    lo, hi = np.clip(best - 1, 0, cfg.planes - 1), np.clip(best + 1, 0, cfg.planes - 1)
    cl, ch = cost[lo, rows, cols], cost[hi, rows, cols]
    denom = cl - 2 * c0 + ch
    shift = np.where((best > 0) & (best < cfg.planes - 1) & (denom > 1e-6), 0.5 * (cl - ch) / np.maximum(denom, 1e-6), 0)
    dq = inv[1] - inv[0] if cfg.planes > 1 else 0.0
    q = inv[best] + np.clip(shift, -0.5, 0.5) * dq
    depth = (1.0 / np.maximum(q, 1e-9)).astype(np.float32)
    zncc = (1.0 - c0).astype(np.float32)
    zncc[sd < cfg.min_texture] = -1.0
    return depth, zncc


def _backproject(depth: np.ndarray, K: np.ndarray, cam: Camera) -> np.ndarray:
    """World points [h,w,3] of a depth map [h,w] (camera z, K at its size) of ``cam``."""
    h, w = depth.shape
    v, u = np.indices((h, w), dtype=np.float64)
    x = np.stack([(u + 0.5 - K[0, 2]) / K[0, 0], (v + 0.5 - K[1, 2]) / K[1, 1], np.ones_like(u)], -1) * depth[..., None]
    R, t = cam.viewmat[:3, :3], cam.viewmat[:3, 3]
    return (x - t) @ R  # R^T (x - t)


def _consistent(X: np.ndarray, other: Camera, oK: np.ndarray, odepth: np.ndarray, max_rel: float) -> np.ndarray:
    """bool [h,w]: the world points X [h,w,3] land in ``other``'s depth map at a depth within ``max_rel`` of it."""
    Y = X @ other.viewmat[:3, :3].T + other.viewmat[:3, 3]
    z = Y[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.floor(oK[0, 0] * Y[..., 0] / z + oK[0, 2]).astype(np.int64)
        v = np.floor(oK[1, 1] * Y[..., 1] / z + oK[1, 2]).astype(np.int64)
    oh, ow = odepth.shape
    inside = (z > 1e-6) & (u >= 0) & (u < ow) & (v >= 0) & (v < oh)
    ok = np.zeros(z.shape, bool)
    d = odepth[v[inside], u[inside]]
    ok[inside] = np.abs(d - z[inside]) <= max_rel * z[inside]
    return ok


def consistent_depths(images: list[np.ndarray], cams: list[Camera], within: np.ndarray,
                      cfg: StereoConfig | None = None) -> list[np.ndarray | None]:
    """Per photo, the pixels of its plane-sweep depth that pass every test (module docstring) as rows
    (x, y, depth) [N,3] float32: (x, y) in the photo's pixels (the cameras' size; pixel centres at +0.5, COLMAP's
    convention, as SfM tracks), depth the camera-space z; None for a photo with no range to sweep. ``images``
    uint8 [H,W,3] (or float in [0,1]) with their ``cams`` at the same size; ``within`` [Q,3]: the SfM points,
    which bound each photo's sweep."""
    cfg = cfg or StereoConfig()
    near = nearest_views(cams, cfg.neighbours)
    scaled = [_scaled(im, cam, cfg.max_side) for im, cam in zip(images, cams)]
    ranges = [_depth_range(cam, within) for cam in cams]
    depths: list[np.ndarray | None] = []
    good: list[np.ndarray | None] = []
    for i, cam in enumerate(cams):
        if ranges[i] is None or not near[i]:
            depths.append(None)
            good.append(None)
            continue
        others = [(scaled[j][0], scaled[j][1], *_relative(cam, cams[j])) for j in near[i]]
        depth, zncc = sweep(scaled[i][0], scaled[i][1], others, ranges[i][0], ranges[i][1], cfg)
        depths.append(depth)
        # beyond SfM's farthest point (by a margin) is the far points' (the sky, distant background)
        good.append((zncc >= cfg.min_zncc) & (depth <= ranges[i][1] / FAR_MARGIN * BEYOND_FARTHEST))
    out: list[np.ndarray | None] = []
    for i, cam in enumerate(cams):
        if depths[i] is None:
            out.append(None)
            continue
        X = _backproject(depths[i], scaled[i][1], cam)
        agree = np.zeros_like(good[i])
        for j in near[i]:
            if depths[j] is not None:
                agree |= _consistent(X, cams[j], scaled[j][1], depths[j], cfg.max_rel_diff)
        v, u = np.nonzero(good[i] & agree)
        h, w = depths[i].shape
        out.append(np.c_[(u + 0.5) * cam.width / w, (v + 0.5) * cam.height / h, depths[i][v, u]].astype(np.float32))
    return out


def stereo_points(images: list[np.ndarray], cams: list[Camera], within: np.ndarray, max_points: int = 0,
                  cfg: StereoConfig | None = None) -> PairPoints:
    """Points of the training photos' consistent stereo depth (:func:`consistent_depths`), every ``cfg.step``-th
    pixel of the sweep's grid, coloured by their photo. At most ``max_points`` (0: all): an even subsample. The
    record counts the photos swept (``pairs``) and the pixels kept (``matches``)."""
    cfg = cfg or StereoConfig()
    rows = consistent_depths(images, cams, within, cfg)
    pts, cols, kept, swept = [], [], 0, 0
    for im, cam, r in zip(images, cams, rows):
        if r is None:
            continue
        swept += 1
        kept += len(r)
        s = max(cam.width, cam.height) / min(cfg.max_side, max(cam.width, cam.height))  # photo px per sweep px
        grid = np.floor(r[:, 0] / s) % cfg.step == 0
        grid &= np.floor(r[:, 1] / s) % cfg.step == 0
        r = r[grid]
        x = np.stack([(r[:, 0] - cam.K[0, 2]) / cam.K[0, 0], (r[:, 1] - cam.K[1, 2]) / cam.K[1, 1],
                      np.ones(len(r))], -1) * r[:, 2:3]
        pts.append((x - cam.viewmat[:3, 3]) @ cam.viewmat[:3, :3])
        u = np.clip(r[:, 0].astype(int), 0, cam.width - 1)
        v = np.clip(r[:, 1].astype(int), 0, cam.height - 1)
        c = np.asarray(im)[v, u].astype(np.float32)
        cols.append(c / 255.0 if np.asarray(im).dtype == np.uint8 else c)
    P = np.concatenate(pts) if pts else np.zeros((0, 3))
    C = np.concatenate(cols) if cols else np.zeros((0, 3), np.float32)
    if max_points and len(P) > max_points:
        idx = np.linspace(0, len(P) - 1, max_points).round().astype(int)
        P, C = P[idx], C[idx]
    log.info("static fit: %d points from the plane-sweep depth of %d training photos (%d consistent pixels)",
             len(P), swept, kept)
    return PairPoints(P.astype(np.float64), C.astype(np.float32), swept, kept)
