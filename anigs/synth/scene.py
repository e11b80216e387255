"""Procedural garden courtyard built directly as ground-truth 3D Gaussians.

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

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np
import torch
from scipy.spatial import cKDTree

from anigs.gaussians import Gaussians, rgb_to_sh0

# ---- label table -------------------------------------------------------------
LABELS: dict[int, str] = {0: "ground", 1: "building", 2: "clutter", 3: "trunk", 4: "foliage", 5: "grass", 6: "flowers"}
LABEL_IDS: dict[str, int] = {name: i for i, name in LABELS.items()}

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
BUDGET = {"ground": 0.33, "building": 0.22, "clutter": 0.07, "trunk": 0.02, "foliage": 0.19,
          "grass": 0.11, "flowers": 0.06}


def path_x(y: np.ndarray) -> np.ndarray:
    """x of the path centre line at ``y`` (the path runs from the south fence to the door)."""
    return 0.6 * np.sin(0.45 * np.asarray(y) + 0.3)


def dataclass_from_dict(cls, d: dict | None, where: str):
    """Build dataclass ``cls`` from ``d``; unknown keys and mistyped values raise ValueError naming them."""
    d = {} if d is None else d
    if not isinstance(d, dict):
        raise ValueError(f"{where}: expected a mapping, got {type(d).__name__}")
    fields = {f.name: f for f in dataclasses.fields(cls)}
    unknown = sorted(set(d) - set(fields))
    if unknown:
        raise ValueError(f"{where}: unknown key(s) {unknown}; allowed: {sorted(fields)}")
    kwargs: dict[str, Any] = {}
    defaults = cls()
    for key, value in d.items():
        ref = getattr(defaults, key)
        if isinstance(ref, bool):
            ok = isinstance(value, bool)
        elif isinstance(ref, int):
            ok = isinstance(value, int) and not isinstance(value, bool)
        elif isinstance(ref, float):
            ok = isinstance(value, (int, float)) and not isinstance(value, bool)
            value = float(value) if ok else value
        elif isinstance(ref, tuple):
            ok = isinstance(value, (list, tuple)) and len(value) == len(ref)
            value = tuple(float(v) for v in value) if ok else value
        else:
            ok = True
        if not ok:
            raise ValueError(f"{where}.{key}: expected {type(ref).__name__} like {ref!r}, got {value!r}")
        kwargs[key] = value
    return cls(**kwargs)


@dataclass
class SceneConfig:
    """Scene parameters (config section ``synthetic.scene``)."""

    num_gaussians: int = 30000  # total budget (split over labels by fixed shares; actual count is close)
    num_trees: int = 4  # 2..4
    texture: float = 1.0  # strength of the high-frequency colour texture (0 = flat colours)

    def __post_init__(self) -> None:
        if not 3000 <= self.num_gaussians <= 2_000_000:
            raise ValueError(f"scene.num_gaussians must be in [3000, 2000000], got {self.num_gaussians}")
        if not 2 <= self.num_trees <= 4:
            raise ValueError(f"scene.num_trees must be in [2, 4], got {self.num_trees}")
        if not 0.0 <= self.texture <= 3.0:
            raise ValueError(f"scene.texture must be in [0, 3], got {self.texture}")

    @staticmethod
    def from_dict(d: dict | None) -> "SceneConfig":
        return dataclass_from_dict(SceneConfig, d, "synthetic.scene")


# ---- small geometry helpers ----------------------------------------------------
def quat_from_matrix(R: np.ndarray) -> np.ndarray:
    """Rotation matrices [N,3,3] -> unit quaternions [N,4] (w,x,y,z)."""
    R = np.asarray(R, np.float64).reshape(-1, 3, 3)
    w = np.sqrt(np.clip(1 + R[:, 0, 0] + R[:, 1, 1] + R[:, 2, 2], 0, None)) / 2
    x = np.sqrt(np.clip(1 + R[:, 0, 0] - R[:, 1, 1] - R[:, 2, 2], 0, None)) / 2
    y = np.sqrt(np.clip(1 - R[:, 0, 0] + R[:, 1, 1] - R[:, 2, 2], 0, None)) / 2
    z = np.sqrt(np.clip(1 - R[:, 0, 0] - R[:, 1, 1] + R[:, 2, 2], 0, None)) / 2
    x = np.copysign(x, R[:, 2, 1] - R[:, 1, 2])
    y = np.copysign(y, R[:, 0, 2] - R[:, 2, 0])
    z = np.copysign(z, R[:, 1, 0] - R[:, 0, 1])
    q = np.stack([w, x, y, z], 1)
    return q / np.linalg.norm(q, axis=1, keepdims=True)


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


def _jittered_grid(rng, lo: tuple[float, float], hi: tuple[float, float], step: tuple[float, float]) -> np.ndarray:
    """Points [M,2] on a grid over [lo, hi] with +-0.3 step jitter (no holes, no clumps)."""
    us = np.arange(lo[0] + step[0] / 2, hi[0], step[0])
    vs = np.arange(lo[1] + step[1] / 2, hi[1], step[1])
    g = np.stack(np.meshgrid(us, vs, indexing="ij"), -1).reshape(-1, 2)
    return g + rng.uniform(-0.3, 0.3, g.shape) * np.asarray(step)


def _shade(normals: np.ndarray) -> np.ndarray:
    """Soft sun + sky shading factor [N] for unit normals [N,3]."""
    return 0.62 + 0.38 * np.clip(normals @ SUN, 0, None) + 0.06 * normals[:, 2]


@dataclass
class _Part:
    means: np.ndarray
    scales: np.ndarray
    quats: np.ndarray
    colors: np.ndarray
    opacity: np.ndarray
    label: int
    anchors: np.ndarray | None = None


class _Builder:
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
        self.parts.append(_Part(means, scales, quats, np.clip(colors, 0.02, 0.97), op, LABEL_IDS[label], anchors))

    def surface(self, origin, u, v, size, step, color_fn: Callable, label: str, thin: float = 0.004,
                opacity: float | None = None, scale_frac: float = 0.75) -> None:
        """Flat Gaussians on the rectangle origin + a*u + b*v, (a,b) in [0,size]; colour_fn(ab[M,2]) -> [M,3]."""
        u, v = np.asarray(u, float), np.asarray(v, float)
        ab = _jittered_grid(self.rng, (0, 0), size, step)
        n = np.cross(u, v)
        R = np.broadcast_to(np.stack([u, v, n], 1), (len(ab), 3, 3))
        means = np.asarray(origin, float) + ab[:, :1] * u + ab[:, 1:] * v
        scales = np.column_stack([np.full(len(ab), scale_frac * step[0]), np.full(len(ab), scale_frac * step[1]),
                                  np.full(len(ab), thin)])
        colors = self.jitter(color_fn(ab)) * _shade(np.broadcast_to(n, means.shape))[:, None]
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
        tv = _jittered_grid(self.rng, (0, 0), (circ, length), (ts, step))
        s = tv[:, 1] / length
        r = r0 + (r1 - r0) * s
        th = tv[:, 0] / max(r0, r1)
        radial = np.cos(th)[:, None] * e1 + np.sin(th)[:, None] * e2
        means = p0 + tv[:, 1:2] * axis + r[:, None] * radial
        tang = np.cross(axis, radial)
        R = np.stack([tang, np.broadcast_to(axis, tang.shape), radial], axis=2)
        scales = np.column_stack([0.62 * ts * np.maximum(r / max(r0, r1), 0.3), np.full(len(s), 0.6 * step),
                                  np.full(len(s), 0.003)])
        cols = self.jitter(color_fn(np.column_stack([th * max(r0, r1), tv[:, 1]])), 0.08) * _shade(radial)[:, None]
        self.add(means, scales, quat_from_matrix(R), cols, SURFACE_OPACITY, label)


# ---- parts -----------------------------------------------------------------------
def _brick_color(rng: np.random.Generator, palette_base, mortar=(0.72, 0.70, 0.66)):
    """Running-bond bricks 0.42 x 0.19 m with 2.5 cm mortar; returns f(a[M], b[M]) -> [M,3]."""
    palette = np.asarray(palette_base) * rng.uniform(0.72, 1.18, (997, 1)) + rng.normal(0, 0.025, (997, 3))
    noise = Noise(rng, 2, 0.5, 12.0)

    def f(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        bh, bl, m = 0.19, 0.42, 0.025
        row = np.floor(b / bh).astype(np.int64)
        x = a / bl + 0.5 * (row % 2)
        col = np.floor(x).astype(np.int64)
        in_mortar = ((b - row * bh) < m) | ((x - col) * bl < m)
        c = palette[(row * 7919 + col * 104729) % 997].copy()
        c *= (1 + 0.08 * noise(np.column_stack([a, b])))[:, None]
        c[in_mortar] = np.asarray(mortar) * (1 + 0.05 * noise(np.column_stack([a, b])[in_mortar] * 3))[:, None]
        return c
    return f


def _ground(B: _Builder, n: int, trees: list) -> None:
    rng = B.rng
    length = Y1 - Y0
    cx, cy, rx, ry = FINE_GROUND
    a_path = PATH_W * length * 1.03
    a_fine = math.pi * rx * ry - PATH_W * 2 * ry
    a_lawn = (X1 - X0) * length - a_path - a_fine
    n_speck = int(0.3 * n)  # small high-contrast details (daisies, pebbles, leaves) on top of the lawn
    s = math.sqrt((a_lawn + a_fine / 0.36 + a_path / 0.36) / (n - n_speck))
    # lawn: coarse outside, finer inside the walkable ellipse (seen from close by); then the path
    coarse = _jittered_grid(rng, (X0, Y0), (X1, Y1), (s, s))
    fine = _jittered_grid(rng, (cx - rx, cy - ry), (cx + rx, cy + ry), (0.6 * s, 0.6 * s))
    in_fine = lambda q: ((q[:, 0] - cx) / rx) ** 2 + ((q[:, 1] - cy) / ry) ** 2 < 1
    lawn = np.concatenate([coarse[~in_fine(coarse)], fine[in_fine(fine)]])
    lawn_s = np.concatenate([np.full((~in_fine(coarse)).sum(), s), np.full(in_fine(fine).sum(), 0.6 * s)])
    off_path = np.abs(lawn[:, 0] - path_x(lawn[:, 1])) > PATH_W / 2 - 0.15 * s
    lawn, lawn_s = lawn[off_path], lawn_s[off_path]
    sp = 0.6 * s
    loc = _jittered_grid(rng, (-PATH_W / 2, Y0), (PATH_W / 2, Y1), (sp, sp))
    path = np.column_stack([path_x(loc[:, 1]) + loc[:, 0], loc[:, 1]])
    big, small = Noise(rng, 2, 0.12, 1.0), Noise(rng, 2, 1.0, 7.0)
    # lawn colour: patchy green, tree shade, clover/daisy specks, bare soil spots
    p = lawn
    c = np.tile([0.30, 0.45, 0.16], (len(p), 1))
    nb, ns = big(p), small(p)
    c *= (1 + 0.13 * nb + 0.09 * ns)[:, None]
    c[:, 0] += 0.035 * np.clip(nb, 0, None)
    for tx, ty, rad in trees:
        d = np.hypot(p[:, 0] - tx, p[:, 1] - ty)
        c *= (1 - 0.3 * np.clip(1.2 - d / rad, 0, 1))[:, None]
    u = rng.random(len(p))
    c[u < 0.025] = [0.92, 0.9, 0.82]
    c[(u >= 0.025) & (u < 0.04)] = [0.9, 0.8, 0.2]
    c[(u >= 0.04) & (u < 0.07)] *= 0.55
    for x0, x1, y0, y1 in BEDS:  # soil with a stone edging
        inside = (p[:, 0] > x0) & (p[:, 0] < x1) & (p[:, 1] > y0) & (p[:, 1] < y1)
        edge = inside & ((p[:, 0] < x0 + 0.12) | (p[:, 0] > x1 - 0.12) | (p[:, 1] < y0 + 0.12) | (p[:, 1] > y1 - 0.12))
        c[inside] = np.array([0.33, 0.23, 0.15]) * (1 + 0.15 * ns[inside] + rng.normal(0, 0.08, inside.sum()))[:, None]
        c[edge] = np.array([0.62, 0.6, 0.56]) * rng.uniform(0.8, 1.1, (edge.sum(), 1))
    lawn_c = c
    # cobbles: Voronoi cells with dark joints, a dark curb along the edges
    seeds = _jittered_grid(rng, (-PATH_W / 2, Y0), (PATH_W / 2, Y1), (0.2, 0.2))
    stone = np.array([0.66, 0.62, 0.55]) * rng.uniform(0.72, 1.15, (len(seeds), 1)) + rng.normal(0, 0.03, (len(seeds), 3))
    d, idx = cKDTree(seeds).query(loc, k=2)
    c = stone[idx[:, 0]] * (1 + 0.06 * small(path))[:, None]
    c[(d[:, 1] - d[:, 0]) < 0.035] = [0.27, 0.25, 0.22]
    c[np.abs(loc[:, 0]) > PATH_W / 2 - 0.06] = [0.42, 0.41, 0.4]
    pts = np.concatenate([lawn, path])
    cols = np.concatenate([lawn_c, c])
    steps = np.concatenate([lawn_s, np.full(len(path), sp)])
    m = len(pts)
    means = np.column_stack([pts, rng.uniform(0, 0.002, m)])
    scales = np.column_stack([0.8 * steps, 0.68 * steps, np.full(m, 0.003)])
    R = frame_from_normal(np.tile([0.0, 0, 1], (m, 1)), rng.uniform(0, math.pi, m))
    B.add(means, scales, quat_from_matrix(R), B.jitter(cols, 0.1) * _shade(np.tile([0.0, 0, 1], (m, 1)))[:, None],
          SURFACE_OPACITY, "ground")
    _specks(B, n_speck, in_fine)


def _specks(B: _Builder, n: int, inside: Callable) -> None:
    """Daisies, dandelions, soil spots, dead leaves and light blades on the lawn: 70% near the walk."""
    rng = B.rng
    cand = np.column_stack([rng.uniform(X0 + 0.1, X1 - 0.1, 8 * n), rng.uniform(Y0 + 0.1, Y1 - 0.1, 8 * n)])
    ok = np.abs(cand[:, 0] - path_x(cand[:, 1])) > PATH_W / 2 + 0.02
    for x0, x1, y0, y1 in BEDS:
        ok &= ~((cand[:, 0] > x0) & (cand[:, 0] < x1) & (cand[:, 1] > y0) & (cand[:, 1] < y1))
    near = cand[ok & inside(cand)][: int(0.7 * n)]
    far = cand[ok & ~inside(cand)][: n - len(near)]
    p = np.concatenate([near, far])
    m = len(p)
    palette = np.array([[0.93, 0.92, 0.85], [0.92, 0.8, 0.2], [0.2, 0.16, 0.1], [0.5, 0.35, 0.18], [0.55, 0.7, 0.3]])
    cols = palette[rng.choice(len(palette), size=m, p=[0.15, 0.1, 0.25, 0.2, 0.3])]
    scales = np.column_stack([rng.uniform(0.025, 0.045, m), rng.uniform(0.015, 0.03, m), np.full(m, 0.002)])
    R = frame_from_normal(np.tile([0.0, 0, 1], (m, 1)), rng.uniform(0, math.pi, m))
    B.add(np.column_stack([p, np.full(m, 0.005)]), scales, quat_from_matrix(R), B.jitter(cols, 0.1), 0.95, "ground")


def _facade_color(rng: np.random.Generator):
    brick = _brick_color(rng, (0.62, 0.30, 0.21))
    door_x = float(path_x(Y1))
    win_x = [door_x + k * 2.3 for k in (-2, -1, 1, 2)]
    glass_noise = Noise(rng, 2, 0.5, 4.0)
    wood = Noise(rng, 2, 2.0, 20.0)

    def f(ab: np.ndarray) -> np.ndarray:
        x, z = X0 + ab[:, 0], ab[:, 1]
        c = brick(ab[:, 0], z)
        c[z < 0.4] = np.array([0.55, 0.54, 0.52]) * (1 + 0.1 * glass_noise(ab[z < 0.4] * 4))[:, None]
        top = z > FACADE_H - 0.3
        c[top] = np.array([0.8, 0.78, 0.72]) * (1 - 0.25 * (z[top] < FACADE_H - 0.24))[:, None]
        rows = [(0.9, 2.15, win_x), (2.85, 4.05, win_x + [door_x])]
        for z0, z1, xs in rows:
            for xc in xs:
                w = 1.1
                inside = (np.abs(x - xc) < w / 2) & (z > z0) & (z < z1)
                fr = inside & ((np.abs(x - xc) > w / 2 - 0.09) | (z < z0 + 0.09) | (z > z1 - 0.09)
                               | (np.abs(x - xc) < 0.035) | (np.abs(z - (z0 + z1) / 2 - 0.15) < 0.035))
                sky = 0.25 + 0.25 * np.clip((z - z0) / (z1 - z0), 0, 1)
                g = np.column_stack([0.16 + 0.5 * sky, 0.2 + 0.55 * sky, 0.28 + 0.6 * sky])
                g *= (1 + 0.15 * glass_noise(ab))[:, None]
                c[inside] = g[inside]
                c[fr] = [0.9, 0.9, 0.86]
                sill = (np.abs(x - xc) < w / 2 + 0.08) & (z > z0 - 0.1) & (z <= z0)
                c[sill] = [0.7, 0.68, 0.64]
        door = (np.abs(x - door_x) < 0.6) & (z < 2.3)
        plank = np.floor((x - door_x + 0.6) / 0.15)
        dc = np.array([0.38, 0.22, 0.12]) * (1 + 0.12 * np.sin(plank * 2.7))[:, None] * (1 + 0.1 * wood(ab))[:, None]
        c[door] = dc[door]
        dframe = door & ((np.abs(x - door_x) > 0.52) | (z > 2.22))
        c[dframe] = [0.85, 0.84, 0.8]
        c[door & (np.abs(x - door_x - 0.4) < 0.04) & (np.abs(z - 1.05) < 0.04)] = [0.9, 0.8, 0.3]
        return c
    return f


def _building(B: _Builder, n: int) -> None:
    rng = B.rng
    area = (X1 - X0) * FACADE_H + (Y1 - Y0) * (WALL_H + 0.25)
    s = math.sqrt(area / n)
    B.surface((X0, Y1, 0), (1, 0, 0), (0, 0, 1), (X1 - X0, FACADE_H), (s, s), _facade_color(rng), "building")
    wall = _brick_color(rng, (0.55, 0.33, 0.25))
    coping = Noise(rng, 2, 1.0, 8.0)
    B.surface((X0, Y0, 0), (0, 1, 0), (0, 0, 1), (Y1 - Y0, WALL_H), (s, s),
              lambda ab: wall(ab[:, 0], ab[:, 1]), "building")
    B.surface((X0 - 0.25, Y0, WALL_H), (1, 0, 0), (0, 1, 0), (0.25, Y1 - Y0), (0.125, s),
              lambda ab: np.array([0.6, 0.58, 0.55]) * (1 + 0.12 * coping(ab))[:, None], "building")


def _stone(rng: np.random.Generator, center, extent: float, base=(0.6, 0.58, 0.54), cell: float = 0.12):
    """3D Voronoi stones around ``center`` (cube of half-size ``extent``): f(points[M,3]) -> colours [M,3]."""
    count = int(min(4000, max(50, (2 * extent / cell) ** 3)))
    seeds = np.asarray(center, float) + rng.uniform(-extent, extent, (count, 3))
    tree = cKDTree(seeds)
    tone = rng.uniform(0.75, 1.15, (count, 1)) * np.asarray(base) + rng.normal(0, 0.02, (count, 3))

    def f(p: np.ndarray) -> np.ndarray:
        d, idx = tree.query(p, k=2)
        c = tone[idx[:, 0]].copy()
        c[(d[:, 1] - d[:, 0]) < 0.15 * cell] *= 0.55
        return c
    return f


def _clutter(B: _Builder, n: int, keep_out: list) -> None:
    rng = B.rng
    # wooden fences on the south and east sides (planks with dark gaps, grain)
    grain = Noise(rng, 2, 1.0, 25.0)
    planks = np.array([0.52, 0.40, 0.28]) * rng.uniform(0.6, 1.3, (400, 1)) + rng.normal(0, 0.03, (400, 3))

    def fence(ab: np.ndarray) -> np.ndarray:
        k = np.floor(ab[:, 0] / 0.16).astype(int)
        c = planks[k % 400] * (1 + 0.12 * grain(ab * np.array([4.0, 0.3])))[:, None]
        c[(ab[:, 0] - k * 0.16) > 0.135] = [0.18, 0.14, 0.1]
        c[np.abs(ab[:, 1] - 0.3) < 0.03] *= 0.7
        c[np.abs(ab[:, 1] - 1.05) < 0.03] *= 0.7
        return c
    fence_area = (X1 - X0 + Y1 - Y0) * FENCE_H
    s = math.sqrt(fence_area / (0.6 * n))  # shares of n: fences 0.6, bench 0.17, planter 0.1, rocks 0.12
    B.surface((X1, Y0, 0), (-1, 0, 0), (0, 0, 1), (X1 - X0, FENCE_H), (0.8 * s, 1.25 * s), fence, "clutter")
    B.surface((X1, Y1, 0), (0, -1, 0), (0, 0, 1), (Y1 - Y0, FENCE_H), (0.8 * s, 1.25 * s), fence, "clutter")
    # bench along the west wall, facing +x: seat slats, backrest, dark metal legs
    bx, by = BENCH
    wood = Noise(rng, 3, 2.0, 30.0)
    woodc = lambda p: np.array([0.58, 0.38, 0.22]) * (1 + 0.15 * wood(p * np.array([0.2, 1.0, 1.0])))[:, None]
    metal = lambda p: np.tile([0.16, 0.16, 0.17], (len(p), 1)) * (1 + 0.3 * (np.sin(p[:, 2] * 40) > 0.6))[:, None]
    step = math.sqrt(2.6 / (0.17 * n))
    for i in range(4):
        B.box((bx - 0.2 + 0.135 * i, by, 0.43), (0.11, 1.7, 0.035), 0.0, step, woodc, "clutter")
    for j in range(3):
        B.box((bx - 0.29, by, 0.55 + 0.13 * j), (0.035, 1.7, 0.095), 0.0, step, woodc, "clutter")
    for dx, dy, h in ((-0.22, -0.72, 0.9), (-0.22, 0.72, 0.9), (0.2, -0.72, 0.43), (0.2, 0.72, 0.43)):
        B.box((bx + dx, by + dy, 0.0), (0.05, 0.05, h), 0.0, step, metal, "clutter")
    # stone planter
    B.box((PLANTER[0], PLANTER[1], 0.0), (0.8, 0.8, 0.55), 0.35, math.sqrt(2.4 / (0.1 * n)),
          _stone(rng, (PLANTER[0], PLANTER[1], 0.3), 0.7, cell=0.12), "clutter")
    # rocks: half-buried ellipsoid shells
    for _ in range(6):
        for _try in range(100):
            c = np.array([rng.uniform(X0 + 0.8, X1 - 0.8), rng.uniform(Y0 + 0.8, 3.4)])
            if _free(c, 0.5, keep_out):
                break
        keep_out.append((c[0], c[1], 0.45))
        radii = np.array([rng.uniform(0.2, 0.35), rng.uniform(0.18, 0.3), rng.uniform(0.12, 0.22)])
        m = int(0.02 * n)
        d = rng.normal(size=(3 * m, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        d = d[d[:, 2] > -0.15][:m]
        means = np.array([c[0], c[1], 0.0]) + d * radii
        spacing = math.sqrt(2.6 * math.pi * radii.mean() ** 2 / len(d))
        sc = np.tile([0.7 * spacing, 0.7 * spacing, 0.003], (len(d), 1))
        nrm = d / radii
        nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
        R = frame_from_normal(nrm, rng.uniform(0, math.pi, len(d)))
        rock = _stone(rng, (c[0], c[1], 0.1), 0.4, (0.5, 0.49, 0.47), cell=0.09)
        B.add(means, sc, quat_from_matrix(R), B.jitter(rock(means)) * _shade(nrm)[:, None], SURFACE_OPACITY, "clutter")


def _free(p: np.ndarray, r: float, keep_out: list) -> bool:
    """True when a disc of radius r at p avoids path, beds and every keep-out disc."""
    if abs(p[0] - path_x(p[1])) < PATH_W / 2 + r:
        return False
    for x0, x1, y0, y1 in BEDS:
        if x0 - r < p[0] < x1 + r and y0 - r < p[1] < y1 + r:
            return False
    return all(math.hypot(p[0] - x, p[1] - y) > r + rr for x, y, rr in keep_out)


def _trees(B: _Builder, n_trunk: int, n_leaves: int, num_trees: int, keep_out: list) -> list:
    """Trunks (+3 branches) and crowns; returns [(x, y, crown radius)] for ground shading."""
    rng = B.rng
    bark_noise = Noise(rng, 2, 0.5, 10.0)
    greens = np.array([[0.22, 0.40, 0.13], [0.28, 0.42, 0.12], [0.18, 0.35, 0.15], [0.30, 0.45, 0.17]])
    out = []
    for k in range(num_trees):
        x, y = np.asarray(TREE_SITES[k]) + rng.uniform(-0.15, 0.15, 2)
        H, r0 = rng.uniform(1.8, 2.2), rng.uniform(0.16, 0.21)
        step = math.sqrt((2 * math.pi * 0.8 * r0 * (H + 0.5) + 0.7) / (n_trunk / num_trees))

        def bark(tv, shift=rng.uniform(0, 10)):
            c = np.array([0.30, 0.22, 0.15]) * (1 + 0.3 * bark_noise((tv + shift) * np.array([5.0, 0.6])))[:, None]
            c[bark_noise(tv * 2.0 + shift) > 1.6] = [0.45, 0.5, 0.38]  # lichen
            return c
        B.cylinder((x, y, 0.0), (x, y, H + 0.5), r0, 0.6 * r0, step, bark, "trunk")
        for a in rng.uniform(0, 2 * math.pi, 2):
            tip = np.array([x + 0.8 * math.cos(a), y + 0.8 * math.sin(a), H + 0.9])
            B.cylinder((x, y, H - 0.1), tip, 0.05, 0.025, step, bark, "trunk")
        Rh, Rv = rng.uniform(1.35, 1.6), rng.uniform(1.15, 1.35)
        c = np.array([x, y, H + 0.85 + rng.uniform(0, 0.2)])
        spheres = [(c, (0.8 * Rh, 0.8 * Rh, 0.8 * Rv))]
        for az in np.linspace(0, 2 * math.pi, 6, endpoint=False) + rng.uniform(0, 1, 6):
            off = np.array([0.5 * Rh * math.cos(az), 0.5 * Rh * math.sin(az), rng.uniform(-0.3, 0.4) * Rv])
            k = rng.uniform(0.45, 0.65)
            spheres.append((c + off, (k * Rh, k * Rh, 0.9 * k * Rv)))
        count = n_leaves // num_trees
        leaf = 0.75 * math.sqrt(4 * math.pi * Rh * Rh / count)
        B.blob(spheres, count, greens[rng.integers(len(greens))], "foliage", (x, y, 0.0), leaf)
        keep_out.append((x, y, 0.35))
        out.append((x, y, Rh))
    return out


def _bushes(B: _Builder, n: int, keep_out: list) -> None:
    rng = B.rng
    sites = [(x, y, r, 0.0) for x, y, r in BUSH_SITES] + [(PLANTER[0], PLANTER[1], 0.38, 0.55)]
    area = np.array([r * r for _, _, r, _ in sites])
    for (x, y, r, z0), a in zip(sites, area):
        rv = r * rng.uniform(0.8, 0.95)
        c = np.array([x, y, z0 + 0.75 * rv])
        spheres = [(c, (r, r, rv))]
        for az in rng.uniform(0, 2 * math.pi, 2):
            spheres.append((c + [0.45 * r * math.cos(az), 0.45 * r * math.sin(az), 0.1 * rv], (0.7 * r, 0.7 * r, 0.75 * rv)))
        count = int(n * a / area.sum())
        base = np.array([0.2, 0.36, 0.14]) * rng.uniform(0.8, 1.15, 3)
        B.blob(spheres, count, base, "foliage", (x, y, z0), 0.7 * math.sqrt(4 * math.pi * r * r / count))
        if z0 == 0.0:
            keep_out.append((x, y, r))


def _grass(B: _Builder, n: int, keep_out: list) -> None:
    """Tufts of 6 curved blades, 3 elongated Gaussians per blade; anchor = tuft root on the ground."""
    rng = B.rng
    nt, nb = max(n // 18, 1), 6
    roots = []
    for _ in range(1000 * nt):
        if len(roots) == nt:
            break
        p = np.array([rng.uniform(X0 + 0.3, X1 - 0.3), rng.uniform(Y0 + 0.3, Y1 - 0.4)])
        if _free(p, 0.12, keep_out):
            roots.append(p)
    if not roots:
        raise RuntimeError("synthetic scene: no free lawn left for grass tufts")
    roots = np.repeat(np.array(roots), nb, 0)
    m = len(roots)
    base = roots + rng.normal(0, 0.035, (m, 2))
    h = rng.uniform(0.1, 0.28, m)
    az = rng.uniform(0, 2 * math.pi, m)
    ld = np.column_stack([np.cos(az), np.sin(az), np.zeros(m)])
    lean = rng.uniform(0.15, 0.55, m)
    green = np.array([0.30, 0.50, 0.15]) * rng.uniform(0.75, 1.2, (m, 1)) + rng.normal(0, 0.02, (m, 3))
    w = np.column_stack([-ld[:, 1], ld[:, 0], np.zeros(m)])
    for s in (1 / 6, 1 / 2, 5 / 6):
        means = np.column_stack([base, np.zeros(m)]) + ld * (lean * h * s * s)[:, None]
        means[:, 2] = h * s
        tan = ld * (2 * lean * s)[:, None] + np.array([0.0, 0, 1])
        tan /= np.linalg.norm(tan, axis=1, keepdims=True)
        R = np.stack([w, tan, np.cross(w, tan)], 2)
        scales = np.column_stack([np.full(m, 0.009), 0.19 * h, np.full(m, 0.003)])
        col = green * (0.62 + 0.55 * s) + np.array([0.06, 0.04, 0.0]) * s
        B.add(means, scales, quat_from_matrix(R), B.jitter(col), 0.95, "grass",
              np.column_stack([roots, np.zeros(m)]))


FLOWER_COLORS = np.array([[0.88, 0.15, 0.15], [0.95, 0.82, 0.15], [0.94, 0.93, 0.9], [0.58, 0.3, 0.78],
                          [0.95, 0.5, 0.12], [0.95, 0.55, 0.72], [0.3, 0.42, 0.88]])


def _flowers(B: _Builder, n: int) -> None:
    """Flowers in the beds: 3 stem + 2 leaf + 1 centre + 5 petal Gaussians; anchor = stem base."""
    rng = B.rng
    beds = [(x0 + 0.16, x1 - 0.16, y0 + 0.16, y1 - 0.16) for x0, x1, y0, y1 in BEDS]
    area = sum((x1 - x0) * (y1 - y0) for x0, x1, y0, y1 in beds)
    s = math.sqrt(area / max(n // 11, 1))
    pts = np.concatenate([_jittered_grid(rng, (x0, y0), (x1, y1), (s, s)) for x0, x1, y0, y1 in beds])
    m = len(pts)
    anchor = np.column_stack([pts, np.zeros(m)])
    h = rng.uniform(0.25, 0.5, m)
    az = rng.uniform(0, 2 * math.pi, m)
    ld = np.column_stack([np.cos(az), np.sin(az), np.zeros(m)])
    lean = rng.uniform(0.0, 0.25, m)
    w = np.column_stack([-ld[:, 1], ld[:, 0], np.zeros(m)])
    stem_c = np.array([0.22, 0.42, 0.14]) * rng.uniform(0.8, 1.15, (m, 1))
    for t in (1 / 6, 1 / 2, 5 / 6):
        means = anchor + ld * (lean * h * t * t)[:, None]
        means[:, 2] = h * t
        tan = ld * (2 * lean * t)[:, None] + np.array([0.0, 0, 1])
        tan /= np.linalg.norm(tan, axis=1, keepdims=True)
        R = np.stack([w, tan, np.cross(w, tan)], 2)
        B.add(means, np.column_stack([np.full(m, 0.007), 0.19 * h, np.full(m, 0.003)]), quat_from_matrix(R),
              B.jitter(stem_c), 0.95, "flowers", anchor)
    for sign in (-1, 1):  # two leaves near the base
        means = anchor + sign * w * 0.045
        means[:, 2] = 0.3 * h
        R = frame_from_normal(np.column_stack([sign * w[:, :2] * 0.4, np.ones(m)]), az)
        B.add(means, np.tile([0.04, 0.014, 0.003], (m, 1)), quat_from_matrix(R), B.jitter(stem_c * 0.85),
              0.95, "flowers", anchor)
    head = anchor + ld * (lean * h)[:, None]
    head[:, 2] = h
    nrm = np.array([0.0, 0, 1]) + 0.9 * ld + rng.normal(0, 0.15, (m, 3))
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    F = frame_from_normal(nrm, rng.uniform(0, 2 * math.pi, m))
    petal = FLOWER_COLORS[rng.integers(len(FLOWER_COLORS), size=m)] * rng.uniform(0.85, 1.05, (m, 1))
    B.add(head + 0.004 * nrm, np.tile([0.014, 0.014, 0.006], (m, 1)), quat_from_matrix(F),
          B.jitter(np.tile([0.75, 0.55, 0.1], (m, 1))), 0.98, "flowers", anchor)
    for k in range(5):
        a = 2 * math.pi * k / 5
        radial = math.cos(a) * F[:, :, 0] + math.sin(a) * F[:, :, 1]
        R = np.stack([radial, np.cross(nrm, radial), nrm], 2)
        B.add(head + 0.028 * radial, np.tile([0.026, 0.016, 0.003], (m, 1)), quat_from_matrix(R),
              B.jitter(petal, 0.04), 0.97, "flowers", anchor)


def _assemble(parts: list[_Part]) -> Gaussians:
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


def build_scene(cfg: SceneConfig | Any | None = None, seed: int = 0) -> Gaussians:
    """Build the garden as Gaussians (SH degree 0), deterministic for ``seed``.

    ``cfg``: a :class:`SceneConfig` (or a ``SynthConfig``: its ``scene`` and ``seed`` are used).
    Returns Gaussians with ``extras["label"]`` [N] int64 (see ``LABELS``) and
    ``extras["anchor"]`` [N,3] float32.
    """
    if cfg is not None and hasattr(cfg, "scene") and hasattr(cfg, "seed"):
        cfg, seed = cfg.scene, cfg.seed
    cfg = cfg or SceneConfig()
    rng = np.random.default_rng(int(seed))
    B = _Builder(rng, cfg.texture)
    n = {k: int(round(v * cfg.num_gaussians)) for k, v in BUDGET.items()}
    keep_out: list = [(BENCH[0], BENCH[1] + dy, 0.55) for dy in (-0.7, 0.0, 0.7)] + [(PLANTER[0], PLANTER[1], 0.65)]
    crowns = _trees(B, n["trunk"], int(0.62 * n["foliage"]), cfg.num_trees, keep_out)
    _bushes(B, n["foliage"] - int(0.62 * n["foliage"]), keep_out)
    _ground(B, n["ground"], crowns)
    _building(B, n["building"])
    _clutter(B, n["clutter"], keep_out)
    _grass(B, n["grass"], keep_out)
    _flowers(B, n["flowers"])
    return _assemble(B.parts)
