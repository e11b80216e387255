"""Far points: starting Gaussians for what the photos show but SfM did not triangulate (the sky,
distant background).

SfM triangulates textured surfaces near the cameras. The sky over a street and the far background
of a facade have no points, so a fit started from SfM alone fills them late, with whatever
densification drags there: large smears near the cameras that every novel view shows (the castle's
sky, the street's blur). Outdoor 3DGS pipelines start such regions from a sphere of far points; here
the sphere is sampled only where it is needed: for each training photo, the cells of a coarse grid
that no SfM point projects into (nor next to) and that look up, or at most 3 degrees down, are
cast as rays onto a sphere around the scene,
coloured by the photo, deduplicated by direction. Cells whose colour is the fit's background
(within ``BG_TOL``) are left out: the background already shows there (the synthetic demo's sky).
Points that turn out hidden behind nearer surfaces get no gradient and are removed by the fit's
final visibility prune (:func:`anigs.static.init.prune_unseen`).
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from anigs.cameras import Camera

GRID = 64  # grid cells across a photo's width tested for SfM points (cells of at least 4 px)
BG_TOL = 0.06  # a cell within this (max abs, RGB in [0,1]) of the background is left to it
#: only rays at most 3 degrees below the horizon: what lies lower is ground near the cameras (a lawn SfM
#: found no texture on), not far away (on the demo, far points on its lawn cost 0.3 dB held out)
MIN_ELEVATION = -0.05


def far_radius(points: np.ndarray, cameras: Sequence[Camera]) -> tuple[np.ndarray, float]:
    """(centre [3], radius) of the far sphere: centred on the cameras, twice the 99th percentile of the
    SfM points' distance from that centre (and at least twice the cameras' own spread)."""
    centers = np.stack([c.center for c in cameras])
    mid = centers.mean(0)
    spread = float(np.linalg.norm(centers - mid, axis=1).max())
    d = np.linalg.norm(points - mid, axis=1) if len(points) else np.zeros(1)
    return mid, 2.0 * max(float(np.percentile(d, 99)), spread, 1e-3)


def cell_px(cam: Camera) -> int:
    """The grid cell's side in pixels of ``cam``'s photo."""
    return max(4, cam.width // GRID)


def _covered(points: np.ndarray, cam: Camera, gw: int, gh: int) -> np.ndarray:
    """bool [gh,gw]: grid cells holding a projected SfM point, dilated by one cell."""
    uv, z = cam.project(points)
    ok = (z > 1e-6) & np.isfinite(uv).all(1)
    cell = cell_px(cam)
    cx = np.floor(uv[ok, 0] / cell).astype(np.int64)
    cy = np.floor(uv[ok, 1] / cell).astype(np.int64)
    keep = (cx >= 0) & (cx < gw) & (cy >= 0) & (cy < gh)
    hit = np.zeros((gh + 2, gw + 2), bool)
    hit[cy[keep] + 1, cx[keep] + 1] = True
    out = np.zeros((gh, gw), bool)
    for dy in (0, 1, 2):
        for dx in (0, 1, 2):
            out |= hit[dy:dy + gh, dx:dx + gw]
    return out


def far_points(points: np.ndarray, cameras: Sequence[Camera], images: Sequence[np.ndarray],
               background: Sequence[float] | None, limit: int) -> tuple[np.ndarray, np.ndarray]:
    """Far points [F,3] and colours [F,3] in [0,1] (F <= ``limit``) where the photos show something
    no SfM point explains; ``images``: float or uint8 [H,W,3] per camera; ``background``: the fit's
    fixed background colour (None: a random one, nothing is left to it)."""
    if limit <= 0 or not cameras:
        return np.zeros((0, 3)), np.zeros((0, 3))
    points = np.asarray(points, np.float64).reshape(-1, 3)
    mid, radius = far_radius(points, cameras)
    bg = None if background is None else np.asarray(background, np.float64)
    # one direction cell per grid cell at the photos' median focal length: nearby photos see the same cell
    step = float(np.median([cell_px(c) / c.K[0, 0] for c in cameras]))
    cells: dict[tuple[int, int], list] = {}
    for cam, img in zip(cameras, images):
        im = np.asarray(img)
        im = im.astype(np.float64) / 255.0 if im.dtype == np.uint8 else im.astype(np.float64)
        cell = cell_px(cam)
        gw, gh = cam.width // cell, cam.height // cell
        if gw == 0 or gh == 0:
            continue
        free = ~_covered(points, cam, gw, gh)
        ys, xs = np.nonzero(free)
        if not len(ys):
            continue
        col = im[:gh * cell, :gw * cell].reshape(gh, cell, gw, cell, 3).mean((1, 3))[ys, xs]
        if bg is not None:
            far = np.abs(col - bg).max(1) > BG_TOL
            ys, xs, col = ys[far], xs[far], col[far]
        px = np.stack([(xs + 0.5) * cell, (ys + 0.5) * cell, np.ones(len(xs))], 1)
        rays = (np.linalg.inv(cam.K) @ px.T).T @ cam.R  # camera -> world directions
        rays /= np.linalg.norm(rays, axis=1, keepdims=True)
        o = cam.center - mid  # |o + t d| = R, t > 0
        b = rays @ o
        t = -b + np.sqrt(np.maximum(b * b - (o @ o - radius * radius), 0.0))
        up = rays[:, 2] > MIN_ELEVATION  # the SfM frame is z-up (anigs.sfm.align)
        rays, t, col = rays[up], t[up], col[up]
        hit = o + t[:, None] * rays
        u = hit / np.linalg.norm(hit, axis=1, keepdims=True)
        key_a = np.floor(np.arctan2(u[:, 1], u[:, 0]) / step).astype(np.int64)
        key_b = np.floor(np.arcsin(np.clip(u[:, 2], -1, 1)) / step).astype(np.int64)
        for a, bb, p, c in zip(key_a, key_b, hit, col):
            cells.setdefault((int(a), int(bb)), [p, c, 0])[2] += 1
    if not cells:
        return np.zeros((0, 3)), np.zeros((0, 3))
    keys = sorted(cells)
    if len(keys) > limit:  # evenly thinned, in a fixed order
        keys = [keys[i] for i in np.linspace(0, len(keys) - 1, limit).round().astype(int)]
    pts = np.stack([cells[k][0] for k in keys]) + mid
    cols = np.clip(np.stack([cells[k][1] for k in keys]), 0, 1)
    return pts, cols
