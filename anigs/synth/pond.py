"""Optional pond of the synthetic garden (``synthetic.scene.pond: true``).

An elliptic pond in the lawn south-east of the path: a flat, weakly textured, dark teal water
surface (label ``water``, effect ``water_ripple``) a centimetre below the lawn, inside a ring
of flat stones (label ``clutter``). The lawn and its specks inside the rim are removed; the
grass tufts and rocks keep out of it (``POND_KEEP_OUT``). Water Gaussians are their own anchors.
"""
from __future__ import annotations

import math

import numpy as np

from anigs.geometry.quaternion import quat_from_matrix
from anigs.synth.garden import stone_color
from anigs.synth.scene import LABEL_IDS, SURFACE_OPACITY, Noise, Builder, jittered_grid, shade, frame_from_normal

POND = (1.6, -1.3, 0.9, 0.65)  # ellipse (cx, cy, rx, ry) of the water, metres
RIM = 0.14  # width of the stone ring around the water (m)
WATER_Z = -0.012  # water level (the lawn lies at z in [0, 0.002])
WATER_COLOR = (0.15, 0.27, 0.31)
POND_KEEP_OUT = (POND[0], POND[1], max(POND[2], POND[3]) + RIM + 0.12)  # (x, y, r) disc for tufts and rocks


def in_pond(xy: np.ndarray, grow: float = 0.0) -> np.ndarray:
    """bool [M]: points ``xy`` [M,2] inside the water ellipse grown by ``grow`` metres."""
    cx, cy, rx, ry = POND
    xy = np.asarray(xy, float)
    return ((xy[:, 0] - cx) / (rx + grow)) ** 2 + ((xy[:, 1] - cy) / (ry + grow)) ** 2 < 1.0


def add_pond(B: "Builder", n: int) -> None:
    """Carve the lawn and add the water (75% of ``n``) and its stone rim (25%) to builder ``B``."""
    rng = B.rng
    cx, cy, rx, ry = POND
    for part in B.parts:  # the lawn (and its specks) ends at the outer edge of the rim
        if part.label == LABEL_IDS["ground"]:
            keep = ~in_pond(part.means[:, :2], RIM)
            for name in ("means", "scales", "quats", "colors", "opacity"):
                setattr(part, name, getattr(part, name)[keep])
            if part.anchors is not None:
                part.anchors = part.anchors[keep]
    up = np.array([0.0, 0, 1])
    # water: a flat sheet on a jittered grid inside the ellipse, smooth low-contrast colour
    n_water = max(int(0.75 * n), 16)
    s = math.sqrt(math.pi * rx * ry / n_water)
    grid = jittered_grid(rng, (cx - rx, cy - ry), (cx + rx, cy + ry), (s, s))
    grid = grid[in_pond(grid)]
    m = len(grid)
    swell = Noise(rng, 2, 0.3, 2.0)
    tone = 1 + 0.06 * swell(grid)
    sky = 0.08 * np.clip((grid[:, 1] - (cy - ry)) / (2 * ry), 0, 1)  # a faint sky reflection gradient
    cols = np.asarray(WATER_COLOR) * tone[:, None] + sky[:, None] * np.array([0.6, 0.8, 1.0])
    cols = cols + rng.normal(0, 0.008 * B.texture, (m, 3))
    R = frame_from_normal(np.tile(up, (m, 1)), rng.uniform(0, math.pi, m))
    means = np.column_stack([grid, np.full(m, WATER_Z)])
    B.add(means, np.column_stack([np.full(m, 0.8 * s), np.full(m, 0.7 * s), np.full(m, 0.002)]),
          quat_from_matrix(R), cols * shade(np.tile(up, (m, 1)))[:, None], SURFACE_OPACITY, "water", means.copy())
    # rim: flat stones on a ring between the water's edge and RIM outside it
    n_rim = max(n - n_water, 16)
    th = np.sort(rng.uniform(0, 2 * math.pi, n_rim))
    rad = rng.uniform(0.0, RIM, n_rim)
    xy = np.column_stack([cx + (rx + rad) * np.cos(th), cy + (ry + rad) * np.sin(th)])
    perim = math.pi * (3 * (rx + ry) - math.sqrt((3 * rx + ry) * (rx + 3 * ry)))
    step = math.sqrt((perim + 4 * RIM) * RIM / n_rim)
    stone = stone_color(rng, (cx, cy, 0.0), max(rx, ry) + RIM + 0.1, (0.6, 0.58, 0.55), cell=0.1)
    pts = np.column_stack([xy, rng.uniform(0.006, 0.02, n_rim)])
    R = frame_from_normal(np.tile(up, (n_rim, 1)), rng.uniform(0, math.pi, n_rim))
    B.add(pts, np.column_stack([np.full(n_rim, 0.9 * step), np.full(n_rim, 0.75 * step), np.full(n_rim, 0.003)]),
          quat_from_matrix(R), B.jitter(stone(pts)) * shade(np.tile(up, (n_rim, 1)))[:, None], SURFACE_OPACITY,
          "clutter")
