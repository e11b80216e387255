"""The bare courtyard (``synthetic.scene.layout: courtyard``): walls, paving, benches, no plants.

Same footprint and capture path as the garden: the brick facade with its windows and door on
the north side, brick walls with a stone coping on the west, east and south sides, the whole
floor paved with stone slabs in a running bond, two benches and an empty stone planter. Labels
``ground`` (paving), ``building`` (facade, walls) and ``clutter`` (benches, planter); nothing
moves, so the effects stage must find nothing here.
"""
from __future__ import annotations

import math

import numpy as np

from anigs.synth.garden import add_bench, brick_color, facade_color, stone_color
from anigs.synth.scene import BENCH, FACADE_H, PLANTER, X0, X1, Y0, Y1, Noise, Builder

COURT_WALL_H = 2.4  # height of the west, east and south walls (m)
SHARES = {"ground": 0.45, "building": 0.42, "clutter": 0.13}
SLAB = (0.6, 0.4)  # paving slab size (m) along x, y
BENCH_2 = (3.6, -3.2)  # the second bench (faces +x, like the first)


def _paving(rng: np.random.Generator):
    """Running-bond stone slabs with dark joints: f(xy [M,2]) -> colours [M,3]."""
    tone = np.array([0.63, 0.6, 0.55]) * rng.uniform(0.78, 1.12, (991, 1)) + rng.normal(0, 0.02, (991, 3))
    grain = Noise(rng, 2, 1.0, 12.0)

    def f(xy: np.ndarray) -> np.ndarray:
        row = np.floor(xy[:, 1] / SLAB[1]).astype(np.int64)
        u = xy[:, 0] / SLAB[0] + 0.5 * (row % 2)
        col = np.floor(u).astype(np.int64)
        c = tone[(row * 7919 + col * 104729) % 991] * (1 + 0.06 * grain(xy))[:, None]
        joint = ((xy[:, 1] - row * SLAB[1]) < 0.02) | ((u - col) * SLAB[0] < 0.02)
        c[joint] = [0.3, 0.29, 0.27]
        return c
    return f


def build_courtyard(B: "Builder", num_gaussians: int) -> None:
    """Add the courtyard's parts to builder ``B`` (about ``num_gaussians`` Gaussians in all)."""
    rng = B.rng
    n = {k: int(round(v * num_gaussians)) for k, v in SHARES.items()}
    # paving over the whole floor
    s = math.sqrt((X1 - X0) * (Y1 - Y0) / n["ground"])
    pave = _paving(rng)
    B.surface((X0, Y0, 0.0), (1, 0, 0), (0, 1, 0), (X1 - X0, Y1 - Y0), (s, s),
              lambda ab: pave(ab + np.array([X0, Y0])), "ground", thin=0.003, scale_frac=0.8)
    # facade (north) and three brick walls with a coping
    area = (X1 - X0) * FACADE_H + (2 * (Y1 - Y0) + (X1 - X0)) * COURT_WALL_H
    s = math.sqrt(area / n["building"])
    B.surface((X0, Y1, 0), (1, 0, 0), (0, 0, 1), (X1 - X0, FACADE_H), (s, s), facade_color(rng), "building")
    brick = brick_color(rng, (0.56, 0.36, 0.27))
    wall = lambda ab: brick(ab[:, 0], ab[:, 1])
    B.surface((X0, Y0, 0), (0, 1, 0), (0, 0, 1), (Y1 - Y0, COURT_WALL_H), (s, s), wall, "building")
    B.surface((X1, Y1, 0), (0, -1, 0), (0, 0, 1), (Y1 - Y0, COURT_WALL_H), (s, s), wall, "building")
    B.surface((X1, Y0, 0), (-1, 0, 0), (0, 0, 1), (X1 - X0, COURT_WALL_H), (s, s), wall, "building")
    # benches and an empty planter
    step = math.sqrt(2.6 / (0.35 * n["clutter"]))
    add_bench(B, BENCH, step)
    add_bench(B, BENCH_2, step)
    B.box((PLANTER[0], PLANTER[1], 0.0), (0.8, 0.8, 0.55), 0.35, math.sqrt(2.4 / (0.3 * n["clutter"])),
          stone_color(rng, (PLANTER[0], PLANTER[1], 0.3), 0.7, cell=0.12), "clutter")
