"""The synthetic scene as Gaussians: the garden (with an optional pond) or the bare courtyard."""
from __future__ import annotations

from typing import Any

import numpy as np

from anigs.gaussians import Gaussians
from anigs.synth.courtyard import build_courtyard
from anigs.synth.garden import add_building, add_bushes, add_clutter, add_flowers, add_grass, add_ground, add_trees
from anigs.synth.pond import POND_KEEP_OUT, add_pond
from anigs.synth.scene import BENCH, BUDGET, PLANTER, POND_BUDGET, SceneConfig, assemble, Builder


def build_scene(cfg: SceneConfig | Any | None = None, seed: int = 0) -> Gaussians:
    """Build the garden (or, with ``layout: courtyard``, the bare courtyard) as Gaussians (SH degree 0),
    deterministic for ``seed``. ``pond`` adds a pond to the garden (labels ``ALL_LABELS``).

    ``cfg``: a :class:`SceneConfig` (or a ``SynthConfig``: its ``scene`` and ``seed`` are used).
    Returns Gaussians with ``extras["label"]`` [N] int64 (see ``LABELS``) and
    ``extras["anchor"]`` [N,3] float32.
    """
    if cfg is not None and hasattr(cfg, "scene") and hasattr(cfg, "seed"):
        cfg, seed = cfg.scene, cfg.seed
    cfg = cfg or SceneConfig()
    rng = np.random.default_rng(int(seed))
    B = Builder(rng, cfg.texture)
    if cfg.layout == "courtyard":
        build_courtyard(B, cfg.num_gaussians)
        return assemble(B.parts)
    n = {k: int(round(v * cfg.num_gaussians)) for k, v in BUDGET.items()}
    keep_out: list = [(BENCH[0], BENCH[1] + dy, 0.55) for dy in (-0.7, 0.0, 0.7)] + [(PLANTER[0], PLANTER[1], 0.65)]
    if cfg.pond:
        keep_out.append(POND_KEEP_OUT)
    crowns = add_trees(B, n["trunk"], int(0.62 * n["foliage"]), cfg.num_trees, keep_out)
    add_bushes(B, n["foliage"] - int(0.62 * n["foliage"]), keep_out)
    add_ground(B, n["ground"], crowns)
    add_building(B, n["building"])
    add_clutter(B, n["clutter"], keep_out)
    add_grass(B, n["grass"], keep_out)
    add_flowers(B, n["flowers"])
    if cfg.pond:
        add_pond(B, int(round(POND_BUDGET * cfg.num_gaussians)))
    return assemble(B.parts)
