"""The synthetic scene as Gaussians: the garden (with an optional pond) or the bare courtyard."""
from __future__ import annotations

from typing import Any

import numpy as np

from anigs.gaussians import Gaussians
from anigs.synth.courtyard import build_courtyard
from anigs.synth.garden import _building, _bushes, _clutter, _flowers, _grass, _ground, _trees
from anigs.synth.pond import POND_KEEP_OUT, add_pond
from anigs.synth.scene import BENCH, BUDGET, PLANTER, POND_BUDGET, SceneConfig, _assemble, _Builder


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
    B = _Builder(rng, cfg.texture)
    if cfg.layout == "courtyard":
        build_courtyard(B, cfg.num_gaussians)
        return _assemble(B.parts)
    n = {k: int(round(v * cfg.num_gaussians)) for k, v in BUDGET.items()}
    keep_out: list = [(BENCH[0], BENCH[1] + dy, 0.55) for dy in (-0.7, 0.0, 0.7)] + [(PLANTER[0], PLANTER[1], 0.65)]
    if cfg.pond:
        keep_out.append(POND_KEEP_OUT)
    crowns = _trees(B, n["trunk"], int(0.62 * n["foliage"]), cfg.num_trees, keep_out)
    _bushes(B, n["foliage"] - int(0.62 * n["foliage"]), keep_out)
    _ground(B, n["ground"], crowns)
    _building(B, n["building"])
    _clutter(B, n["clutter"], keep_out)
    _grass(B, n["grass"], keep_out)
    _flowers(B, n["flowers"])
    if cfg.pond:
        add_pond(B, int(round(POND_BUDGET * cfg.num_gaussians)))
    return _assemble(B.parts)
