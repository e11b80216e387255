"""Procedural garden courtyard built directly as ground-truth 3D Gaussians: the label table, the
fixed layout, the scene config and the builder the layouts (:mod:`anigs.synth.garden`,
:mod:`anigs.synth.courtyard`, :mod:`anigs.synth.pond`) add their parts to. The layouts do not
import back: :func:`anigs.synth.build.build_scene` puts them together.

World convention: z up, ground plane z=0, metres. The courtyard spans
x in [-6.5, 6.5], y in [-5.5, 5.2]: a brick building facade closes the north side
(y=5.2, facing -y), a low brick wall the west side, wooden fences the south and east
sides. Inside: a lawn crossed by a cobbled path to the door, 2-4 trees, bushes, two
flower beds in front of the facade, a bench, a stone planter, rocks and grass tufts.

Every Gaussian carries a semantic label (``LABELS``) in ``extras["label"]`` [N] (int64)
and an anchor in ``extras["anchor"]`` [N,3]: the point it sways about (tree: trunk base,
bush: base centre, grass: tuft root, flower: stem base; static Gaussians: their own mean).
Everything is deterministic for a given seed (numpy ``default_rng``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np
import torch

from anigs.typed_config import check_in, from_dict
from anigs.gaussians import Gaussians, rgb_to_sh0
from anigs.geometry.quaternion import quat_from_matrix

# ---- label table -------------------------------------------------------------
LABELS: dict[int, str] = {0: "ground", 1: "building", 2: "clutter", 3: "trunk", 4: "foliage", 5: "grass", 6: "flowers"}
# the optional pond's label: not in LABELS, so the default garden's tables stay as they were
WATER_LABEL = 7
ALL_LABELS: dict[int, str] = {**LABELS, WATER_LABEL: "water"}
LABEL_IDS: dict[str, int] = {name: i for i, name in ALL_LABELS.items()}
LAYOUTS = ("garden", "courtyard")
SKY = (0.62, 0.76, 0.92)  # the demo scenes' sky colour (RGB in [0,1]): the capture is rendered onto it

# ---- fixed layout (metres) -------------------------------------------------------
X0, X1, Y0, Y1 = -6.5, 6.5, -5.5, 5.2  # courtyard; Y1 = facade plane
FACADE_H, WALL_H, FENCE_H = 4.6, 1.1, 1.3
PATH_W = 1.2
FINE_GROUND = (0.0, -0.3, 4.3, 3.4)  # ellipse (cx, cy, rx, ry) of finer ground around the walkable area
TREE_SITES = ((-4.6, 2.4), (4.6, 1.4), (-4.3, -3.6), (4.4, -3.8))
BUSH_SITES = ((-2.4, -4.7, 0.65), (2.2, -4.8, 0.7), (5.8, -0.7, 0.6), (-5.9, 0.9, 0.55), (-0.85, 4.5, 0.45))  # x, y, r
BEDS = ((-5.0, -1.4, 3.9, 4.9), (1.8, 5.0, 3.9, 4.9))  # flower beds (x0, x1, y0, y1)
BENCH = (-5.7, -1.0)  # centre; long axis along y, facing +x
PLANTER = (2.9, 2.9)
SURFACE_OPACITY = 0.98  # opacity of the flat Gaussians of solid surfaces
SUN = np.array([0.45, -0.55, 0.70]) / np.linalg.norm([0.45, -0.55, 0.70])

# share of the Gaussian budget per label
POND_BUDGET = 0.04  # extra share for the optional pond (water surface and its stone rim)
BUDGET = {"ground": 0.33, "building": 0.22, "clutter": 0.07, "trunk": 0.02, "foliage": 0.19,
          "grass": 0.11, "flowers": 0.06}


def path_x(y: np.ndarray) -> np.ndarray:
    """x of the path centre line at ``y`` (the path runs from the south fence to the door)."""
    return 0.6 * np.sin(0.45 * np.asarray(y) + 0.3)


@dataclass
class SceneConfig:
    """Scene parameters (config section ``synthetic.scene``)."""

    num_gaussians: int = 30000  # total budget (split over labels by fixed shares; actual count is close)
    num_trees: int = 4  # 2..4
    texture: float = 1.0  # strength of the high-frequency colour texture (0 = flat colours)
    layout: str = "garden"  # garden | courtyard (bare: walls, paving, a bench, no plants)
    pond: bool = False  # garden only: a pond (label ``water``, effect ``water_ripple``) in the lawn

    def __post_init__(self) -> None:
        if self.layout not in LAYOUTS:
            raise ValueError(f"scene.layout must be one of {list(LAYOUTS)}, got {self.layout!r}")
        if self.pond and self.layout != "garden":
            raise ValueError(f"scene.pond needs layout 'garden' (got layout {self.layout!r})")
        check_in("scene.num_gaussians", self.num_gaussians, 3000, 2000000)
        check_in("scene.num_trees", self.num_trees, 2, 4)
        check_in("scene.texture", self.texture, 0, 3)

    @staticmethod
    def from_dict(d: dict | None) -> "SceneConfig":
        return from_dict(SceneConfig, d, "synthetic.scene", check_types=True)


# ---- small geometry helpers ----------------------------------------------------
def frame_from_normal(n: np.ndarray, spin: np.ndarray | None = None) -> np.ndarray:
    """Rotations [N,3,3] whose local z is the unit normal ``n`` [N,3]; ``spin`` [N] turns about it."""
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    helper = np.where(np.abs(n[:, 2:3]) < 0.9, [[0.0, 0, 1]], [[1.0, 0, 0]])
    u = np.cross(helper, n)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = np.cross(n, u)
    if spin is not None:
        c, s = np.cos(spin)[:, None], np.sin(spin)[:, None]
        u, v = c * u + s * v, -s * u + c * v
    return np.stack([u, v, n], axis=2)


class Noise:
    """Smooth random field: a sum of sinusoids, std ~1. ``Noise(rng, dim, fmin, fmax)(x[N,dim]) -> [N]``."""

    def __init__(self, rng: np.random.Generator, dim: int, fmin: float, fmax: float, n: int = 24):
        dirs = rng.normal(size=(n, dim))
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        freqs = fmin * (fmax / fmin) ** (np.arange(n) / max(n - 1, 1))
        self.k = dirs * (2 * math.pi * freqs)[:, None]
        self.phase = rng.uniform(0, 2 * math.pi, n)
        amp = freqs**-0.5
        self.amp = amp / np.sqrt((amp**2).sum() / 2)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return np.sin(x @ self.k.T + self.phase) @ self.amp


def jittered_grid(rng, lo: tuple[float, float], hi: tuple[float, float], step: tuple[float, float]) -> np.ndarray:
    """Points [M,2] on a grid over [lo, hi] with +-0.3 step jitter (no holes, no clumps)."""
    us = np.arange(lo[0] + step[0] / 2, hi[0], step[0])
    vs = np.arange(lo[1] + step[1] / 2, hi[1], step[1])
    g = np.stack(np.meshgrid(us, vs, indexing="ij"), -1).reshape(-1, 2)
    return g + rng.uniform(-0.3, 0.3, g.shape) * np.asarray(step)


def shade(normals: np.ndarray) -> np.ndarray:
    """Soft sun + sky shading factor [N] for unit normals [N,3]."""
    return 0.62 + 0.38 * np.clip(normals @ SUN, 0, None) + 0.06 * normals[:, 2]


@dataclass
class Part:
    means: np.ndarray
    scales: np.ndarray
    quats: np.ndarray
    colors: np.ndarray
    opacity: np.ndarray
    label: int
    anchors: np.ndarray | None = None


class Builder:
    """Collects parts; ``texture`` scales the per-Gaussian colour jitter."""

    def __init__(self, rng: np.random.Generator, texture: float):
        self.rng, self.texture, self.parts = rng, texture, []

    def jitter(self, colors: np.ndarray, amount: float = 0.06) -> np.ndarray:
        n = colors.shape[0]
        lum = self.rng.normal(0, amount * self.texture, (n, 1))
        hue = self.rng.normal(0, 0.25 * amount * self.texture, (n, 3))
        return colors * (1 + lum) + hue

    def add(self, means, scales, quats, colors, opacity, label: str, anchors=None) -> None:
        n = means.shape[0]
        op = np.broadcast_to(np.asarray(opacity, np.float64), (n,)).copy()
        self.parts.append(Part(means, scales, quats, np.clip(colors, 0.02, 0.97), op, LABEL_IDS[label], anchors))

    def surface(self, origin, u, v, size, step, color_fn: Callable, label: str, thin: float = 0.004,
                opacity: float | None = None, scale_frac: float = 0.75) -> None:
        """Flat Gaussians on the rectangle origin + a*u + b*v, (a,b) in [0,size]; colour_fn(ab[M,2]) -> [M,3]."""
        u, v = np.asarray(u, float), np.asarray(v, float)
        ab = jittered_grid(self.rng, (0, 0), size, step)
        n = np.cross(u, v)
        R = np.broadcast_to(np.stack([u, v, n], 1), (len(ab), 3, 3))
        means = np.asarray(origin, float) + ab[:, :1] * u + ab[:, 1:] * v
        scales = np.column_stack([np.full(len(ab), scale_frac * step[0]), np.full(len(ab), scale_frac * step[1]),
                                  np.full(len(ab), thin)])
        colors = self.jitter(color_fn(ab)) * shade(np.broadcast_to(n, means.shape))[:, None]
        self.add(means, scales, quat_from_matrix(R), colors, SURFACE_OPACITY if opacity is None else opacity, label)

    def box(self, center, size, yaw: float, step: float, color_fn: Callable, label: str) -> None:
        """The 5 visible faces (not the bottom) of a box rotated by ``yaw`` about z."""
        c, s = math.cos(yaw), math.sin(yaw)
        ex, ey, ez = np.array([c, s, 0.0]), np.array([-s, c, 0.0]), np.array([0.0, 0, 1])
        sx, sy, sz = size
        base = np.asarray(center, float) - ex * sx / 2 - ey * sy / 2
        faces = [  # (origin, u, v, extent u, extent v)
            (base + ez * sz, ex, ey, sx, sy),
            (base, ex, ez, sx, sz), (base + ey * sy + ex * sx, -ex, ez, sx, sz),
            (base + ex * sx, ey, ez, sy, sz), (base + ey * sy, -ey, ez, sy, sz),
        ]
        for origin, u, v, a, b in faces:
            if a < 1e-6 or b < 1e-6:
                continue
            stp = (min(step, a / 1.5), min(step, b / 1.5))
            self.surface(origin, u, v, (a, b), stp, lambda ab, o=origin, u=u, v=v: color_fn(o + ab[:, :1] * u + ab[:, 1:] * v),
                         label, thin=0.002, scale_frac=0.72)

    def blob(self, spheres: list, count: int, base_color, label: str, anchor, leaf: float) -> None:
        """Foliage: ``count`` leaves in the shells of overlapping ellipsoids ``spheres`` [(centre, radii)],
        leaves hidden inside another ellipsoid dropped, plus a few large dark core Gaussians (no see-through)."""
        rng = self.rng
        centers = np.array([c for c, _ in spheres], float)
        radii = np.array([r for _, r in spheres], float)
        area = np.prod(radii, 1) ** (2 / 3)
        per = np.maximum(1, np.round(2.0 * count * area / area.sum()).astype(int))
        which = np.repeat(np.arange(len(spheres)), per)
        d = rng.normal(size=(len(which), 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        means = centers[which] + d * rng.uniform(0.8, 1.0, (len(which), 1)) * radii[which]
        rel = (means[:, None, :] - centers[None]) / radii[None]
        inner = (np.linalg.norm(rel, axis=2) < 0.8) & (np.arange(len(spheres))[None] != which[:, None])
        keep = np.flatnonzero(~inner.any(1) & (means[:, 2] > anchor[2] + 0.05))
        keep = np.sort(rng.permutation(keep)[:count])
        means, d, which = means[keep], d[keep], which[keep]
        count = len(keep)
        scales = np.column_stack([rng.uniform(0.8, 1.3, count) * leaf, rng.uniform(0.5, 0.9, count) * leaf,
                                  np.full(count, 0.12 * leaf)])
        q = rng.normal(size=(count, 4))
        light = 0.5 + 0.55 * (d[:, 2] + 1) / 2 * (0.75 + 0.45 * np.clip(d @ SUN, 0, 1))
        cols = np.asarray(base_color) * light[:, None] * rng.uniform(0.72, 1.28, (count, 1))
        cols *= rng.uniform(0.9, 1.1, (len(spheres), 3))[which]
        speck = rng.random(count) < 0.06
        cols[speck] = cols[speck] * np.array([1.5, 1.4, 0.7])  # sunlit yellowish leaves
        anc = np.broadcast_to(np.asarray(anchor, float), (count, 3)).copy()
        self.add(means, scales, q / np.linalg.norm(q, axis=1, keepdims=True), self.jitter(cols, 0.1), 0.9, label, anc)
        m = max(count // 30, 3 * len(spheres))
        wc = np.arange(m) % len(spheres)
        dc = rng.normal(size=(m, 3))
        dc /= np.linalg.norm(dc, axis=1, keepdims=True)
        cm = centers[wc] + dc * rng.uniform(0.15, 0.55, (m, 1)) * radii[wc]
        cm[:, 2] = np.maximum(cm[:, 2], anchor[2] + 0.1)
        sc = radii[wc] * 0.3
        self.add(cm, sc, np.tile([1.0, 0, 0, 0], (m, 1)), np.tile(np.asarray(base_color) * 0.4, (m, 1)),
                 0.95, label, np.broadcast_to(np.asarray(anchor, float), (m, 3)).copy())

    def cylinder(self, p0, p1, r0: float, r1: float, step: float, color_fn: Callable, label: str) -> None:
        """Bark-like surface of a tapered cylinder from p0 to p1 (flat Gaussians, long along the axis)."""
        p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
        axis = p1 - p0
        length = float(np.linalg.norm(axis))
        axis /= length
        e1 = np.cross(axis, [1.0, 0, 0] if abs(axis[0]) < 0.9 else [0, 1.0, 0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(axis, e1)
        circ = 2 * math.pi * max(r0, r1)
        ts = min(step, circ / 6)
        tv = jittered_grid(self.rng, (0, 0), (circ, length), (ts, step))
        s = tv[:, 1] / length
        r = r0 + (r1 - r0) * s
        th = tv[:, 0] / max(r0, r1)
        radial = np.cos(th)[:, None] * e1 + np.sin(th)[:, None] * e2
        means = p0 + tv[:, 1:2] * axis + r[:, None] * radial
        tang = np.cross(axis, radial)
        R = np.stack([tang, np.broadcast_to(axis, tang.shape), radial], axis=2)
        scales = np.column_stack([0.62 * ts * np.maximum(r / max(r0, r1), 0.3), np.full(len(s), 0.6 * step),
                                  np.full(len(s), 0.003)])
        cols = self.jitter(color_fn(np.column_stack([th * max(r0, r1), tv[:, 1]])), 0.08) * shade(radial)[:, None]
        self.add(means, scales, quat_from_matrix(R), cols, SURFACE_OPACITY, label)


def assemble(parts: list[Part]) -> Gaussians:
    means = np.concatenate([p.means for p in parts])
    colors = np.concatenate([p.colors for p in parts])
    anchors = np.concatenate([p.means if p.anchors is None else p.anchors for p in parts])
    labels = np.concatenate([np.full(len(p.means), p.label, np.int64) for p in parts])
    g = Gaussians(
        means=torch.from_numpy(means.astype(np.float32)),
        quats=torch.from_numpy(np.concatenate([p.quats for p in parts]).astype(np.float32)),
        log_scales=torch.from_numpy(np.log(np.clip(np.concatenate([p.scales for p in parts]), 1e-4, None)).astype(np.float32)),
        opacity_logits=torch.logit(torch.from_numpy(np.concatenate([p.opacity for p in parts]).astype(np.float32))),
        sh=rgb_to_sh0(torch.from_numpy(colors.astype(np.float32)))[:, None, :].contiguous(),
        extras={"label": torch.from_numpy(labels), "anchor": torch.from_numpy(anchors.astype(np.float32))},
    )
    g.check_finite("synthetic scene")
    return g
