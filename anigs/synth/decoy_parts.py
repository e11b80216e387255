"""The decoy scenes' parts and the builder that tags them, shared by :mod:`anigs.synth.decoys` and
:mod:`anigs.synth.made_decoys` (here so that neither imports the other back): ``DECOY_PARTS`` (the
``extras["decoy"]`` ids, 0 = none), :class:`Tagged`, :func:`noise_colour` and :func:`arc_cameras`."""
from __future__ import annotations

import math

import numpy as np
import torch

from anigs.cameras import Camera, intrinsics_from_fov, look_at
from anigs.gaussians import Gaussians
from anigs.synth.scene import Builder, assemble

DECOY_PARTS: dict[int, str] = {1: "ornaments", 2: "window_surrounds", 3: "picture", 4: "rug", 5: "lamps",
                               6: "mown_lawn", 7: "sunlit_leaves",
                               # the made decoys' parts (anigs.synth.made_decoys)
                               8: "machine", 9: "bins", 10: "bare_tree", 11: "paving", 12: "pillars",
                               13: "leaf_carton", 14: "table", 15: "hall_floor", 16: "pot"}
DECOY_IDS = {v: k for k, v in DECOY_PARTS.items()}


class Tagged:
    """A :class:`anigs.synth.scene.Builder` that remembers the decoy part of every part it adds."""

    def __init__(self, seed: int):
        self.B = Builder(np.random.default_rng(seed), 1.0)
        self.tags: list[int] = []

    def tag(self, part: str | None, fn, *args, **kw) -> None:
        n0 = len(self.B.parts)
        fn(*args, **kw)
        self.tags += [DECOY_IDS[part] if part else 0] * (len(self.B.parts) - n0)

    def build(self) -> Gaussians:
        g = assemble(self.B.parts)
        g.extras["decoy"] = torch.from_numpy(np.concatenate(
            [np.full(len(p.means), t, np.int64) for p, t in zip(self.B.parts, self.tags)]))
        return g


def noise_colour(rng, base, amount: float):
    base = np.asarray(base, float)
    return lambda ab: base * (1 + amount * np.sin(ab[:, :1] * 9.1 + 2 * np.cos(ab[:, 1:2] * 7.3))
                              + rng.normal(0, 0.5 * amount, (len(ab), 1)))


def arc_cameras(target, radius: float, height: float, count: int, centre_deg: float, arc_deg: float,
                 size=(160, 120), fov: float = 60.0) -> list[Camera]:
    K = intrinsics_from_fov(fov, *size)
    cams = []
    for i in range(count):
        a = math.radians(centre_deg - arc_deg / 2 + arc_deg * i / max(count - 1, 1))
        eye = np.array([target[0] + radius * math.cos(a), target[1] + radius * math.sin(a), height])
        cams.append(Camera(K, look_at(eye, target), size[0], size[1], f"d{i:02d}.png"))
    return cams
