"""Captures the sfm tests build: a textured scene rendered from a ring of cameras, in chosen orders.

:func:`split_ring_capture` names the photos of one orbit so that COLMAP's sequential pairs
(i, i+1 with ``sequential_overlap: 1``) join only runs of neighbours: the orbit falls into three
groups that sequential matching cannot join (10, 6 and 4 photos; see ``SPLIT_ORDER``), while
every photo overlaps its ring neighbours, so matching every pair joins them into one model.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import torch

from anigs.cameras import Camera, intrinsics_from_fov, look_at, save_cameras
from anigs.gaussians import Gaussians
from anigs.render import render_gaussians
from anigs.video import save_png

W, H = 320, 240
# quaternions (w,x,y,z) turning a disc's thin local z axis onto the world x, y, z normals
_Q_NORMAL = np.array([[math.sqrt(.5), 0, math.sqrt(.5), 0], [math.sqrt(.5), -math.sqrt(.5), 0, 0], [1, 0, 0, 0]])
# ring positions in file-name order: 0..9 (one group), then 14..19 (joins 0 only on the ring),
# then 10..13 (joins 9 only on the ring): neighbours in the order are ring neighbours inside a
# group and 5 or 9 positions (90 or 162 degrees) apart at the group boundaries
SPLIT_ORDER = list(range(10)) + list(range(14, 20)) + list(range(10, 14))
SPLIT_GROUPS = [list(range(10)), list(range(10, 16)), list(range(16, 20))]  # in file-name positions


BOXES = [((-0.9, -0.5), (0.7, 0.6, 0.9)), ((0.9, 0.7), (0.5, 0.8, 0.6)), ((0.3, -1.2), (0.6, 0.4, 1.2)),
         ((-0.6, 1.1), (0.4, 0.5, 0.7)), ((1.3, -0.3), (0.3, 0.3, 0.5))]


def textured_discs(seed: int, half: float, boxes: list, n_ground: int, n_box: int) -> Gaussians:
    """Small flat discs of random colour on the ground plane z=0 (``n_ground`` in [-half, half]^2) and
    ``n_box`` on the faces of each box ``((cx, cy), (sx, sy, sz))`` standing on it (a SIFT-rich scene)."""
    rng = np.random.default_rng(seed)
    pts = [np.c_[rng.uniform(-half, half, (n_ground, 2)), np.zeros(n_ground)]]
    normals = [np.full(n_ground, 2)]
    for (cx, cy), size in boxes:
        size = np.array(size)
        u = rng.uniform(-0.5, 0.5, (n_box, 3))
        axis = rng.choice(3, n_box, p=[0.4, 0.4, 0.2])
        u[np.arange(n_box), axis] = rng.choice([-0.5, 0.5], n_box)
        pts.append(np.array([cx, cy, size[2] / 2]) + u * size)
        normals.append(axis)
    pts, normals = np.concatenate(pts), np.concatenate(normals)
    colors = rng.uniform(0, 1, (len(pts), 3)) * rng.uniform(0.1, 1, (len(pts), 1))
    g = Gaussians.from_points(torch.tensor(pts), torch.tensor(colors), 0.01, opacity=0.99)
    g.quats = torch.tensor(_Q_NORMAL[normals], dtype=torch.float32)
    discs = np.c_[np.exp(rng.uniform(math.log(0.02), math.log(0.07), (len(pts), 2))), np.full(len(pts), 0.003)]
    g.log_scales = torch.tensor(np.log(discs), dtype=torch.float32)
    return g


def textured_boxes(seed: int = 0, n_ground: int = 4000, n_box: int = 900) -> Gaussians:
    """Discs on a 6 m ground and on five boxes' faces (:func:`textured_discs`)."""
    return textured_discs(seed, 3.0, BOXES, n_ground, n_box)


def ring_positions(n: int = 20, seed: int = 0) -> list[np.ndarray]:
    """[4,4] world-to-camera matrices of ``n`` cameras on an orbit around the boxes."""
    rng = np.random.default_rng(seed + 1)
    out = []
    for i in range(n):
        a = 2 * math.pi * i / n + 0.03 * rng.standard_normal()
        eye = [3.6 * math.cos(a), 3.6 * math.sin(a), 2.2 + 0.2 * rng.standard_normal()]
        out.append(look_at(eye, [0, 0, 0.3]))
    return out


def render(folder: Path, cams: list[Camera], g: Gaussians) -> tuple[Path, Path]:
    """PNG per camera into ``folder/images`` and the cameras into ``folder/gt_cameras.json``."""
    images = folder / "images"
    bg = torch.tensor([0.5, 0.5, 0.5])
    with torch.no_grad():
        for c in cams:
            rgb, _, _ = render_gaussians(g, c, background=bg)
            save_png(images / c.name, rgb)
    save_cameras(folder / "gt_cameras.json", cams)
    return images, folder / "gt_cameras.json"


def split_ring_capture(folder: Path, seed: int = 0) -> tuple[Path, Path]:
    """The orbit of :func:`ring_positions` named in ``SPLIT_ORDER`` (``photo_00.png`` ...)."""
    K = intrinsics_from_fov(60, W, H)
    views = ring_positions(len(SPLIT_ORDER), seed)
    cams = [Camera(K, views[pos], W, H, f"photo_{k:02d}.png") for k, pos in enumerate(SPLIT_ORDER)]
    return render(folder, cams, textured_boxes(seed))


def ring_capture(folder: Path, n: int = 12, seed: int = 0) -> tuple[Path, Path]:
    """A plain orbit of ``n`` photos in ring order (``ring_00.png`` ...)."""
    K = intrinsics_from_fov(60, W, H)
    cams = [Camera(K, v, W, H, f"ring_{k:02d}.png") for k, v in enumerate(ring_positions(n, seed))]
    return render(folder, cams, textured_boxes(seed))
