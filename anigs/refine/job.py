"""One refinement job: a rendered clip file in, its ComposedV2V-refined target file out.

The noise seed of a job combines the global seed, the round and the view (:func:`view_seed`), so
every view and round draws independent noise; the refine and round stages call :func:`refine_clip`.
"""
from __future__ import annotations

import json
import logging
import re
import time
import zlib
from pathlib import Path

import numpy as np
from anigs.images import read_mask
from anigs.refine.compose import ComposeConfig, composed_v2v
from anigs.refine.prior import get_prior
from anigs.video import load_clip, save_clip

log = logging.getLogger("anigs.refine")


def view_seed(seed: int, round_: int, view: str) -> int:
    """Independent 31-bit seed per (global seed, round, view)."""
    ss = np.random.SeedSequence([int(seed) & 0xFFFFFFFF, int(round_), zlib.crc32(str(view).encode())])
    return int(ss.generate_state(1)[0] & 0x7FFFFFFF)


def parse_masks(values: list[str]) -> np.ndarray | dict[str, np.ndarray]:
    """``--mask PATH`` (one) or ``--mask EFFECT=PATH`` (several) -> mask or {effect: mask}."""

    if not values:
        raise ValueError("at least one --mask is required")
    named = [v for v in values if "=" in v and not Path(v).exists()]
    if not named:
        if len(values) > 1:
            raise ValueError(f"several masks need EFFECT=PATH form, got {values}")
        return read_mask(values[0])
    if len(named) != len(values):
        raise ValueError(f"mix of plain and EFFECT=PATH masks: {values}")
    out = {}
    for v in values:
        name, path = v.split("=", 1)
        if name in out:
            raise ValueError(f"effect {name!r} given twice in --mask")
        out[name] = read_mask(path)
    return out


def refine_clip(clip_path: str | Path, masks: np.ndarray | dict[str, np.ndarray], out: str | Path, cfg,
                round_: int | None = None, view: str | None = None, priors: dict | None = None) -> dict:
    """ComposedV2V refinement of the clip at ``clip_path`` (``masks``: one [H,W] mask or one per
    effect) into ``out`` with ``cfg`` (the refine stage's config); returns what was done (seed, sigmas, seconds). ``priors``: a dict kept
    across calls, so that a process refining several clips builds (loads) each prior once."""

    clip_path = Path(clip_path)
    view = view if view is not None else clip_path.stem
    if round_ is None:
        m = re.search(r"round(\d+)", str(clip_path.parent))
        round_ = int(m.group(1)) if m else 0
    seed = view_seed(cfg.seed, round_, view)
    clip, meta = load_clip(clip_path)
    prior_cfg = cfg.prior_config()
    if cfg.prior == "procedural" and "fps" in meta and "fps" not in prior_cfg:
        prior_cfg["fps"] = float(meta["fps"])
    key = json.dumps([cfg.prior, prior_cfg], sort_keys=True, default=str)
    prior = priors.get(key) if priors is not None else None
    if prior is None:
        prior = get_prior(cfg.prior, prior_cfg)
        if priors is not None:
            priors[key] = prior
    t0 = time.perf_counter()
    refined, info = composed_v2v(prior, clip, masks, cfg.prompt, seed, cfg.strength,
                                 ComposeConfig(compose=cfg.compose, feather_px=cfg.feather_px,
                                               dilate_px=cfg.dilate_px, repaste_static=cfg.repaste_static))
    info.update({"seconds": round(time.perf_counter() - t0, 3), "view": view, "round": round_,
                 "global_seed": cfg.seed, **{k: v for k, v in getattr(prior, "last_info", {}).items()
                                             if isinstance(v, (int, float, str, list))}})
    log.info("refined %s (round %d, view %s, seed %d) with %s in %.2fs -> %s", clip_path, round_, view, seed,
             cfg.prior, info["seconds"], out)
    # wall time goes to the log, not into the artifact: the same inputs give the same file
    stored = {k: v for k, v in info.items() if k != "seconds"}
    save_clip(out, refined, {**meta, "refine": stored})
    return info
