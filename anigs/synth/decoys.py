"""Decoy scenes: things that look like plants or blossoms by colour but must stay still, with labels.

``build_decoy(name, num_gaussians, seed) -> Decoy``: Gaussians (labels as in
:data:`anigs.synth.scene.LABEL_IDS` in ``extras["label"]``, plus ``extras["decoy"]`` [N] int64:
the decoy part of each Gaussian, 0 = none, see ``DECOY_PARTS``), the capture cameras, the scene's
prompt and the effects it really contains. ``ALLOWED`` says which effects may take each decoy
part: none for what must stay still.

Scenes (z up, metres, ground z = 0):

- ``facade``: a brick facade with saturated red brick window surrounds standing out of the wall and
  orange-red ornaments (rosettes) on it, behind a tree whose sunlit crown has yellow leaves, on a
  mown lawn that rises towards the facade (a bank). Real effect: the tree's foliage.
- ``room``: a room (floor, walls, ceiling) with a green landscape picture in a frame on the wall, a
  red rug on the floor, ceiling lamps and a potted plant. Real effect: the plant's foliage.
- ``lawn``: a mown lawn (flat, then a bank) beside a flower bed and a bush. Real effects: the bed's
  flowers and the bush's foliage.

``MADE_DECOYS`` (``yard``, ``hall``: green made things under prompts that name plants, issue 47) are
built by :mod:`anigs.synth.made_decoys`; their parts continue the numbering of ``DECOY_PARTS``. The parts
and the builder that tags them (``Tagged``), which both modules use, live in :mod:`anigs.synth.decoy_parts`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from anigs.cameras import Camera
from anigs.gaussians import Gaussians
from anigs.geometry.quaternion import quat_from_matrix
from anigs.synth.decoy_parts import DECOY_IDS, DECOY_PARTS, Tagged, arc_cameras, noise_colour
from anigs.synth.garden import FLOWER_COLORS
from anigs.synth.made_decoys import MADE_DECOYS, build_made
from anigs.synth.scene import LABEL_IDS, SUN, Part, frame_from_normal

# effects that may take each decoy part (nothing for what must stay still)
ALLOWED: dict[str, tuple[str, ...]] = {"ornaments": (), "window_surrounds": (), "picture": (), "rug": (), "lamps": (),
                                       "mown_lawn": ("grass_wave",), "sunlit_leaves": ("foliage_sway", "leaf_flutter"),
                                       **dict.fromkeys(("machine", "bins", "bare_tree", "paving", "pillars",
                                                        "leaf_carton", "table", "hall_floor", "pot"), ())}
DECOYS = ("facade", "room", "lawn")
PROMPTS = {"facade": "a building with trees and lawns in the wind",
           "room": "a potted plant in a room, its leaves moving",
           "lawn": "a garden with a lawn, a bush and a flower bed in the wind",
           "yard": "a castle courtyard with trees in the wind",
           "hall": "an office with potted plants"}
TRUE_EFFECTS = {"facade": ("foliage_sway", "leaf_flutter"), "room": ("foliage_sway", "leaf_flutter"),
                "lawn": ("foliage_sway", "leaf_flutter", "flower_bob"), "yard": (),
                "hall": ("foliage_sway", "leaf_flutter")}


@dataclass
class Decoy:
    """A decoy scene: its Gaussians (``extras``: label, decoy, anchor), cameras and prompt."""

    name: str
    gaussians: Gaussians
    cameras: list[Camera]
    prompt: str
    effects: tuple[str, ...]

    def still_mask(self) -> np.ndarray:
        """bool [N]: Gaussians that must not move at all: those whose label is not a moving one
        (outside the decoy parts some effect may take) and the decoy parts no effect may take."""
        labels = self.gaussians.extras["label"].numpy()
        decoy = self.gaussians.extras["decoy"].numpy()
        moving = np.isin(labels, [_label(x) for x in ("foliage", "grass", "flowers", "water")])
        may_move = np.array([bool(ALLOWED[DECOY_PARTS[k]]) for k in sorted(DECOY_PARTS)])
        part_may = np.where(decoy > 0, may_move[np.maximum(decoy, 1) - 1], False)
        return (~moving & ~part_may) | ((decoy > 0) & ~part_may)


def _label(name: str) -> int:
    return LABEL_IDS[name]


def _lawn_bank(T: Tagged, x: tuple, y: tuple, bank_from: float, slope_deg: float, step: float, part: str | None) -> None:
    """A mown lawn over x [x0,x1] x y [y0,y1]: flat up to ``bank_from``, then rising at ``slope_deg``."""
    rng = T.B.rng
    base = np.array([0.30, 0.46, 0.16])
    col = noise_colour(rng, base, 0.12)
    flat = (x[1] - x[0], bank_from - y[0])
    T.tag(part, T.B.surface, (x[0], y[0], 0.0), (1, 0, 0), (0, 1, 0), flat, (step, step), col, "ground")
    if y[1] > bank_from:
        a = math.radians(slope_deg)
        length = (y[1] - bank_from) / math.cos(a)
        T.tag(part, T.B.surface, (x[0], bank_from, 0.0), (1, 0, 0), (0, math.cos(a), math.sin(a)),
              (x[1] - x[0], length), (step, step), col, "ground")


def _tree(T: Tagged, at, height: float, crown: float, leaves: int, sunlit_share: float) -> None:
    """Trunk and crown; the crown's sun-facing leaves (``sunlit_share``) are yellow (decoy sunlit_leaves)."""
    B = T.B
    x, y = at
    bark = lambda tv: np.tile([0.32, 0.23, 0.16], (len(tv), 1)) * (1 + 0.2 * np.sin(tv[:, :1] * 20))
    T.tag(None, B.cylinder, (x, y, 0.0), (x, y, height + 0.4), 0.16, 0.1, 0.08, bark, "trunk")
    c = np.array([x, y, height + crown * 0.8])
    spheres = [(c, (crown, crown, 0.85 * crown))] + [
        (c + [0.5 * crown * math.cos(a), 0.5 * crown * math.sin(a), 0.1], (0.6 * crown,) * 3)
        for a in (0.3, 2.4, 4.4)]
    T.tag(None, B.blob, spheres, leaves, (0.22, 0.40, 0.13), "foliage", (x, y, 0.0), 0.7 * math.sqrt(4 * math.pi * crown ** 2 / leaves))
    # the blob adds the leaves, then its dark core: turn the sunlit side's leaves yellow
    leaves_part = B.parts[-2]
    d = leaves_part.means - c
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    lit = np.argsort(-(d @ SUN))[: int(sunlit_share * len(d))]
    sun = np.zeros(len(d), bool)
    sun[lit] = True
    yellow = np.array([0.88, 0.76, 0.22]) * B.rng.uniform(0.85, 1.1, (sun.sum(), 1))
    leaves_part.colors[sun] = np.clip(yellow, 0.02, 0.97)
    # split the leaves into two parts so the yellow ones carry their decoy tag
    keep = Part(leaves_part.means[~sun], leaves_part.scales[~sun], leaves_part.quats[~sun], leaves_part.colors[~sun],
                 leaves_part.opacity[~sun], leaves_part.label, leaves_part.anchors[~sun])
    lit_part = Part(leaves_part.means[sun], leaves_part.scales[sun], leaves_part.quats[sun], leaves_part.colors[sun],
                     leaves_part.opacity[sun], leaves_part.label, leaves_part.anchors[sun])
    B.parts[-2] = keep
    B.parts.append(lit_part)
    T.tags.append(DECOY_IDS["sunlit_leaves"])


def _facade(T: Tagged, n: int) -> None:
    rng, B = T.B.rng, T.B
    X, Y, H = 5.0, 4.0, 5.0
    step = math.sqrt(2 * X * H / (0.45 * n))
    brick = np.array([0.56, 0.36, 0.28])

    def wall(ab):
        row = np.floor(ab[:, 1] / 0.19).astype(int)
        col = np.floor(ab[:, 0] / 0.42 + 0.5 * (row % 2)).astype(int)
        c = brick * (0.85 + 0.25 * ((row * 7919 + col * 104729) % 13)[:, None] / 13)
        c[(ab[:, 1] % 0.19) < 0.03] = [0.7, 0.68, 0.64]
        return c
    T.tag(None, B.surface, (-X, Y, 0.0), (1, 0, 0), (0, 0, 1), (2 * X, H), (step, step), wall, "building")
    red = np.array([0.72, 0.16, 0.11])
    fine = 0.6 * step
    for xc in (-3.2, -1.1, 1.1, 3.2):
        for z0 in (0.9, 2.9):
            w, h = 1.0, 1.3
            glass = lambda ab: np.tile([0.18, 0.22, 0.3], (len(ab), 1)) * (1 + 0.3 * ab[:, 1:2] / h)
            T.tag(None, B.surface, (xc - w / 2, Y - 0.01, z0), (1, 0, 0), (0, 0, 1), (w, h), (fine, fine), glass, "building")
            # red brick surround standing 8 cm out of the wall: four boxes around the window
            col = lambda p: red * (1 + 0.12 * np.sin(p[:, :1] * 31 + p[:, 2:3] * 17))
            for center, size in (((xc, Y - 0.04, z0 - 0.12), (w + 0.48, 0.08, 0.24)),
                                 ((xc, Y - 0.04, z0 + h), (w + 0.48, 0.08, 0.24)),
                                 ((xc - w / 2 - 0.12, Y - 0.04, z0), (0.24, 0.08, h)),
                                 ((xc + w / 2 + 0.12, Y - 0.04, z0), (0.24, 0.08, h))):
                T.tag("window_surrounds", B.box, center, size, 0.0, fine, col, "building")
    # ornaments: orange-red rosettes (half spheres) in a band under the cornice and between the windows
    orn = np.array([0.82, 0.32, 0.12])
    for xc, zc in [(x, 4.6) for x in np.arange(-4.5, 4.6, 0.75)] + [(x, 2.55) for x in (-2.15, 0.0, 2.15)]:
        m = 60
        d = rng.normal(size=(3 * m, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        d = d[d[:, 1] < -0.05][:m]
        means = np.array([xc, Y, zc]) + d * 0.14
        T.tag("ornaments", B.add, means, np.tile([0.035, 0.035, 0.004], (len(d), 1)),
              quat_from_matrix(frame_from_normal(d)), orn * rng.uniform(0.85, 1.1, (len(d), 1)), 0.97, "building")
    _lawn_bank(T, (-X, X), (-5.0, Y), 1.0, 14.0, math.sqrt(10 * 9 / (0.25 * n)), "mown_lawn")
    _tree(T, (0.3, -0.2), 2.4, 1.2, int(0.22 * n), 0.3)


def _room(T: Tagged, n: int) -> None:
    rng, B = T.B.rng, T.B
    X, Y0, Y1, H = 3.0, -3.0, 3.0, 2.8
    step = math.sqrt((2 * X * (Y1 - Y0) * 2 + (2 * X + 2 * (Y1 - Y0)) * H) / (0.6 * n))
    wood = lambda ab: np.array([0.55, 0.4, 0.27]) * (1 + 0.15 * np.sin(np.floor(ab[:, :1] / 0.18) * 2.7))
    T.tag(None, B.surface, (-X, Y0, 0.0), (1, 0, 0), (0, 1, 0), (2 * X, Y1 - Y0), (step, step), wood, "ground")
    plaster = noise_colour(rng, (0.85, 0.83, 0.78), 0.03)
    T.tag(None, B.surface, (-X, Y1, 0.0), (1, 0, 0), (0, 0, 1), (2 * X, H), (step, step), plaster, "building")
    T.tag(None, B.surface, (-X, Y0, 0.0), (0, 1, 0), (0, 0, 1), (Y1 - Y0, H), (step, step), plaster, "building")
    T.tag(None, B.surface, (X, Y1, 0.0), (0, -1, 0), (0, 0, 1), (Y1 - Y0, H), (step, step), plaster, "building")
    T.tag(None, B.surface, (-X, Y0, H), (1, 0, 0), (0, 1, 0), (2 * X, Y1 - Y0), (step, step),
          noise_colour(rng, (0.9, 0.9, 0.88), 0.02), "building")
    # a green landscape picture (meadow, hills, a little sky) in a dark frame on the back wall
    w, h, cx, cz = 1.6, 1.0, -0.9, 1.55
    fine = 0.5 * step

    def landscape(ab):
        u, v = ab[:, 0] / w, ab[:, 1] / h
        hill = 0.65 + 0.12 * np.sin(u * 7.0)
        c = np.where((v > hill)[:, None], [[0.55, 0.72, 0.9]], [[0.26, 0.5, 0.16]])
        c = c * (1 + 0.2 * np.sin(u * 40) * np.cos(v * 33))[:, None]
        c[(v < 0.3)] *= [1.1, 1.15, 0.8]
        return c
    T.tag("picture", B.surface, (cx - w / 2, Y1 - 0.03, cz - h / 2), (1, 0, 0), (0, 0, 1), (w, h), (fine, fine),
          landscape, "clutter")
    frame = lambda p: np.tile([0.16, 0.12, 0.08], (len(p), 1))
    for center, size in (((cx, Y1 - 0.03, cz - h / 2 - 0.06), (w + 0.12, 0.06, 0.06)),
                         ((cx, Y1 - 0.03, cz + h / 2), (w + 0.12, 0.06, 0.06)),
                         ((cx - w / 2 - 0.03, Y1 - 0.03, cz - h / 2), (0.06, 0.06, h)),
                         ((cx + w / 2 + 0.03, Y1 - 0.03, cz - h / 2), (0.06, 0.06, h))):
        T.tag("picture", B.box, center, size, 0.0, 0.5 * fine, frame, "clutter")
    # a red rug with a pattern on the floor in front of the plant
    def rug(ab):
        c = np.tile([0.72, 0.12, 0.1], (len(ab), 1))
        border = (ab[:, 0] < 0.15) | (ab[:, 0] > 2.05) | (ab[:, 1] < 0.15) | (ab[:, 1] > 1.45)
        c[border] = [0.85, 0.6, 0.2]
        c[(np.sin(ab[:, 0] * 12) * np.sin(ab[:, 1] * 12) > 0.7) & ~border] = [0.25, 0.1, 0.35]
        return c
    T.tag("rug", B.surface, (-0.4, -0.4, 0.004), (1, 0, 0), (0, 1, 0), (2.2, 1.6), (fine, fine), rug, "clutter", thin=0.003)
    # ceiling lamps: bright warm-white half spheres under the ceiling
    for lx, ly in ((-1.5, 0.8), (1.5, 0.8), (0.0, 2.0), (0.0, -1.2)):
        m = 90
        d = rng.normal(size=(3 * m, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        d = d[d[:, 2] < 0.0][:m]
        T.tag("lamps", B.add, np.array([lx, ly, H - 0.05]) + d * [0.22, 0.22, 0.14], np.tile([0.045, 0.045, 0.004], (len(d), 1)),
              quat_from_matrix(frame_from_normal(d)), np.tile([0.97, 0.93, 0.8], (len(d), 1)), 0.98, "clutter")
    # a potted plant standing on the rug: a terracotta pot and a leafy crown
    pot = lambda p: np.tile([0.62, 0.36, 0.22], (len(p), 1))
    T.tag(None, B.box, (0.9, 0.6, 0.0), (0.4, 0.4, 0.4), 0.0, 0.6 * fine, pot, "clutter")
    crown = [((0.9, 0.6, 1.0), (0.45, 0.45, 0.5)), ((0.75, 0.5, 1.25), (0.3, 0.3, 0.3))]
    leaves = int(0.12 * n)
    T.tag(None, B.blob, crown, leaves, (0.2, 0.42, 0.12), "foliage", (0.9, 0.6, 0.4), 0.7 * math.sqrt(4 * math.pi * 0.2 / leaves))


def _lawn(T: Tagged, n: int) -> None:
    rng, B = T.B.rng, T.B
    X, Y0, Y1 = 5.0, -5.0, 5.0
    _lawn_bank(T, (-X, X), (Y0, Y1), 1.5, 12.0, math.sqrt(10 * 10 / (0.45 * n)), "mown_lawn")
    # a flower bed (soil) beside the lawn, with flowers of several colours on stems
    x0, x1, y0, y1 = -3.5, -0.8, -1.0, 1.0
    soil = noise_colour(rng, (0.33, 0.23, 0.15), 0.1)
    T.tag(None, B.surface, (x0, y0, 0.006), (1, 0, 0), (0, 1, 0), (x1 - x0, y1 - y0), (0.06, 0.06), soil, "ground")
    m = int(0.2 * n) // 8
    pts = np.column_stack([rng.uniform(x0 + 0.1, x1 - 0.1, m), rng.uniform(y0 + 0.1, y1 - 0.1, m)])
    h = rng.uniform(0.3, 0.5, m)
    anchor = np.column_stack([pts, np.zeros(m)])
    up = np.tile([0.0, 0, 1], (m, 1))
    for t in (0.25, 0.6):
        T.tag(None, B.add, anchor + up * (h * t)[:, None], np.column_stack([np.full(m, 0.008), 0.2 * h, np.full(m, 0.003)]),
              quat_from_matrix(frame_from_normal(np.tile([1.0, 0, 0], (m, 1)))), np.tile([0.22, 0.42, 0.14], (m, 1)),
              0.95, "flowers", anchor)
    head = anchor + up * h[:, None]
    petal = FLOWER_COLORS[rng.integers(len(FLOWER_COLORS), size=m)]
    for k in range(6):
        a = 2 * math.pi * k / 6
        off = np.column_stack([np.full(m, 0.035 * math.cos(a)), np.full(m, 0.035 * math.sin(a)), np.zeros(m)])
        T.tag(None, B.add, head + off, np.tile([0.03, 0.02, 0.004], (m, 1)), quat_from_matrix(frame_from_normal(up)),
              petal, 0.97, "flowers", anchor)
    # a bush
    crown = [((2.0, 0.2, 0.6), (0.75, 0.75, 0.6)), ((2.4, 0.5, 0.7), (0.5, 0.5, 0.45))]
    leaves = int(0.2 * n)
    T.tag(None, B.blob, crown, leaves, (0.2, 0.38, 0.13), "foliage", (2.0, 0.2, 0.0), 0.7 * math.sqrt(4 * math.pi * 0.6 / leaves))


def build_decoy(name: str, num_gaussians: int = 12000, seed: int = 0, images: int = 10, width: int = 160) -> Decoy:
    """The decoy scene ``name`` (one of ``DECOYS`` or ``MADE_DECOYS``) with ``images`` capture cameras ``width`` px
    wide."""
    if name not in DECOYS + MADE_DECOYS:
        raise ValueError(f"unknown decoy scene {name!r}; known: {list(DECOYS + MADE_DECOYS)}")
    T = Tagged(seed)
    size = (width, width * 3 // 4)
    if name in MADE_DECOYS:
        cams = build_made(name, T, num_gaussians, images, size)
    elif name == "facade":
        _facade(T, num_gaussians)
        cams = arc_cameras((0.0, 2.0, 1.8), 7.0, 1.6, images, -90.0, 60.0, size)
    elif name == "room":
        _room(T, num_gaussians)
        cams = arc_cameras((0.0, 1.5, 1.3), 3.6, 1.5, images, -90.0, 50.0, size, fov=70.0)
    else:
        _lawn(T, num_gaussians)
        cams = arc_cameras((-0.5, 1.0, 0.3), 5.5, 1.6, images, -90.0, 80.0, size)
    return Decoy(name, T.build(), cams, PROMPTS[name], TRUE_EFFECTS[name])
