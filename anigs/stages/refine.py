"""Stage ``refine``: ComposedV2V refinement of one rendered camera-fixed clip.

    anigs refine --clip results/demo/round1/render/v003.npz --mask results/demo/masks/v003.png \\
                 --out results/demo/round1/target/v003.npz --params '{"prior": "procedural", "strength": 0.5}'

``--mask`` takes one mask (all configured effects inside it) or repeated ``EFFECT=PATH``
for per-effect masks. The noise seed combines the config's global ``seed``, the round and
the view id (parsed from ``.../round{R}/render/{view}.npz`` unless ``--round``/``--view``
are given), so every view and round draws independent noise.
"""
from __future__ import annotations

import argparse
import logging
import re
import time
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from anigs.typed_config import from_dict

log = logging.getLogger("anigs.refine")


@dataclass
class RefineConfig:
    """The ``refine`` stage's config section."""

    prior: str = "procedural"        # procedural | ltx
    strength: float = 0.5            # 0 = keep the clip's motion, 1 = new motion (LTX: starting sigma)
    steps: int = 8                   # LTX Euler steps (procedural: unused)
    compose: bool = True             # False = "w/o ComposedV2V" ablation
    feather_px: float = 0.0          # inward mask feathering for the composition, pixels
    dilate_px: int = 0               # grow the masks by this many pixels (room for silhouettes to move)
    repaste_static: bool = True      # static pixels of frame 0 pasted back after refinement
    prompt: str = ""                 # text prompt (LTX; procedural: keywords pick effects / intensity)
    effects: list[str] = field(default_factory=lambda: ["foliage_sway", "leaf_flutter"])
    seed: int = 0                    # global seed (combined with round and view)
    procedural: dict[str, Any] = field(default_factory=dict)  # ProceduralConfig keys (not effects)
    ltx: dict[str, Any] = field(default_factory=dict)         # LTXConfig keys (not steps)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any] | None) -> "RefineConfig":
        cfg = from_dict(cls, d, "refine params", ValueError)
        if "effects" in cfg.procedural:
            raise ValueError("set `effects` at the top level of the refine params, not in `procedural`")
        if "steps" in cfg.ltx:
            raise ValueError("set `steps` at the top level of the refine params, not in `ltx`")
        return cfg

    def with_effects_json(self, path: str | Path | None) -> "RefineConfig":
        """With the effects stage's chosen effects (its ``effects.json``) instead of the listed ones."""
        if path:
            from anigs.io import read_json

            self.effects = list(read_json(path)["chosen"])
        return self

    def prior_config(self) -> dict[str, Any]:
        if self.prior == "procedural":
            return {**self.procedural, "effects": list(self.effects)}
        if self.prior == "ltx":
            return {**self.ltx, "steps": self.steps}
        raise ValueError(f"unknown video prior {self.prior!r}; available: ['procedural', 'ltx']")


Config = RefineConfig  # the `refine` config section


def view_seed(seed: int, round_: int, view: str) -> int:
    """Independent 31-bit seed per (global seed, round, view)."""
    ss = np.random.SeedSequence([int(seed) & 0xFFFFFFFF, int(round_), zlib.crc32(str(view).encode())])
    return int(ss.generate_state(1)[0] & 0x7FFFFFFF)


def load_mask(path: str | Path) -> np.ndarray:
    """Mask from PNG (0/255 or 0/1) or .npy -> float32 [H,W] in [0,1] (:func:`anigs.masks.read_mask`)."""
    from anigs.images import read_mask

    return read_mask(path)


def parse_masks(values: list[str]) -> np.ndarray | dict[str, np.ndarray]:
    """``--mask PATH`` (one) or ``--mask EFFECT=PATH`` (several) -> mask or {effect: mask}."""
    if not values:
        raise ValueError("at least one --mask is required")
    named = [v for v in values if "=" in v and not Path(v).exists()]
    if not named:
        if len(values) > 1:
            raise ValueError(f"several masks need EFFECT=PATH form, got {values}")
        return load_mask(values[0])
    if len(named) != len(values):
        raise ValueError(f"mix of plain and EFFECT=PATH masks: {values}")
    out = {}
    for v in values:
        name, path = v.split("=", 1)
        if name in out:
            raise ValueError(f"effect {name!r} given twice in --mask")
        out[name] = load_mask(path)
    return out


def run(clip_path: str | Path, masks: np.ndarray | dict[str, np.ndarray], out: str | Path, cfg: RefineConfig,
        round_: int | None = None, view: str | None = None, priors: dict | None = None) -> dict:
    """ComposedV2V refinement of the clip at ``clip_path`` (``masks``: one [H,W] mask or one per
    effect) into ``out``; returns what was done (seed, sigmas, seconds). ``priors``: a dict kept
    across calls, so that a process refining several clips builds (loads) each prior once."""
    import json

    from anigs.refine.prior import get_prior
    from anigs.refine.compose import ComposeConfig, composed_v2v
    from anigs.video import load_clip, save_clip

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


# ---- command line: anigs refine ----

def add_arguments(p: argparse.ArgumentParser) -> None:
    from anigs.cli import add_params, add_out

    p.add_argument("--clip", required=True, help="rendered clip (.npz), e.g. round1/render/v003.npz")
    p.add_argument("--mask", action="append", default=[], metavar="[EFFECT=]PATH",
                   help="dynamic mask PNG/.npy; repeat as EFFECT=PATH for per-effect masks")
    add_out(p, "refined target clip (.npz)")
    add_params(p, "refine")
    p.add_argument("--round", type=int, default=None, help="round number (default: from the clip path roundR/)")
    p.add_argument("--view", default=None, help="view id (default: the clip file's stem)")
    p.add_argument("--info", default=None, help="optional JSON file with what was done (sigmas, seed, timing)")
    p.add_argument("--effects-json", default=None,
                   help="effects.json of the effects stage: synthesise its chosen effects (replaces params effects)")


def main(args: argparse.Namespace) -> int:
    from anigs.cli import parse_params
    from anigs.io import write_json

    cfg = RefineConfig.from_dict(parse_params(args.params)).with_effects_json(args.effects_json)
    info = run(args.clip, parse_masks(args.mask), args.out, cfg, round_=args.round, view=args.view)
    if args.info:
        write_json(args.info, info)
    return 0
