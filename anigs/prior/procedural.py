"""Procedural spectral motion prior (default backend: offline, CPU, no weights).

``refine`` estimates the motion already present in the clip (DIS optical flow, backward
convention of :mod:`anigs.flow`: ``clip[t](p) ≈ clip[0](p + d_t(p))``) inside the dynamic
region, blends it with a freshly sampled stochastic motion texture (:mod:`anigs.prior.spectral`)
by ``strength`` s (0 = keep the clip's motion, 1 = new motion) and re-synthesises every frame
by warping frame 0 with the blended field ``(1 - s) d_clip + sqrt(s (2 - s)) d_new``: the
weights' squares sum to 1, so blending two independent fields of equal energy keeps the
motion's energy (a linear blend would shrink it by up to 1/sqrt(2) at s = 0.5). Pixels outside the mask are copied from the input
unchanged. Frame 0 is the canonical frame: its displacement is 0, so ``out[0] == clip[0]``.

Different seeds give different motion phases, like a diffusion model run independently per
view: the multi-view inconsistency that the dataset-model loop has to resolve.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from anigs.configs import reject_unknown_keys
from anigs.flow import clip_backward_flow, identity_grid, warp
from anigs.prior.base import MaskLike, VideoPrior, check_mask, check_strength
from anigs.prior.spectral import EFFECTS, MotionField, effect_spec, effects_from_prompt, prompt_gain, synthesize_effect
from anigs.video import check_clip

log = logging.getLogger(__name__)


@dataclass
class ProceduralConfig:
    """Config of the procedural prior (section ``procedural`` of the refine stage)."""

    effects: list[str] = field(default_factory=lambda: ["foliage_sway", "leaf_flutter"])
    fps: float = 24.0                 # frames per second of the clips (frequencies are in Hz)
    effect_params: dict[str, dict[str, Any]] = field(default_factory=dict)  # per-effect EffectSpec overrides
    amplitude_scale: float = 1.0      # global amplitude multiplier
    edge: float = 0.03                # mask-edge taper width, fraction of the shorter side
    flow_preset: str = "medium"       # DIS preset for the motion estimate: ultrafast | fast | medium
    use_prompt: bool = True           # effects from prompt keywords when `effects` is empty; intensity words scale amplitude

    @classmethod
    def from_dict(cls, d: Mapping[str, Any] | None) -> "ProceduralConfig":
        d = dict(d or {})
        reject_unknown_keys(cls, d, "procedural prior config", ValueError)
        cfg = cls(**d)
        cfg.effects = list(cfg.effects)
        for name in cfg.effects:
            effect_spec(name, cfg.effect_params.get(name))  # validates names and overrides
        for name in cfg.effect_params:
            if name not in EFFECTS:
                raise ValueError(f"effect_params names unknown effect {name!r}; known: {sorted(EFFECTS)}")
        if cfg.fps <= 0:
            raise ValueError(f"fps must be > 0, got {cfg.fps}")
        return cfg


class ProceduralPrior(VideoPrior):
    """Stochastic-motion-texture prior; see the module docstring."""

    name = "procedural"
    has_score = False

    def __init__(self, cfg: ProceduralConfig | Mapping[str, Any] | None = None):
        self.cfg = cfg if isinstance(cfg, ProceduralConfig) else ProceduralConfig.from_dict(cfg)
        self.last_info: dict[str, Any] = {}

    # -- masks per effect -------------------------------------------------------------
    def effect_masks(self, mask: MaskLike, prompt: str, height: int, width: int) -> dict[str, np.ndarray]:
        """{effect: [H,W] mask} for the effects that will be synthesised.

        A single mask carries every configured effect (superposed); a dict maps effect names
        to their own masks (names must be known effects; configured effects without a mask are
        skipped, mask entries for effects the config does not list are ignored, both logged).
        """
        effects = list(self.cfg.effects)
        if not effects and self.cfg.use_prompt:
            effects = effects_from_prompt(prompt)
            log.info("effects from prompt %r: %s", prompt, effects)
        if isinstance(mask, Mapping):
            unknown = sorted(set(mask) - set(EFFECTS))
            if unknown:
                raise ValueError(f"mask dict has unknown effect name(s) {unknown}; known: {sorted(EFFECTS)}")
            out = {}
            for name in effects:
                if name in mask:
                    out[name] = check_mask(mask[name], height, width, f"mask[{name!r}]")
                else:
                    log.info("effect %s is configured but has no mask: not synthesised", name)
            ignored = sorted(set(mask) - set(effects))
            if ignored:
                log.info("masks for effects %s are not in the configured effects %s: ignored", ignored, effects)
            return out
        m = check_mask(mask, height, width)
        return {name: m for name in effects}

    def motion_field(self, masks: Mapping[str, np.ndarray], height: int, width: int, seed: int,
                     prompt: str = "", fps: float | None = None) -> MotionField:
        """Sample the displacement field of all effects (deterministic for ``seed``)."""
        motion = MotionField(height, width, float(fps or self.cfg.fps))
        gain = self.cfg.amplitude_scale * (prompt_gain(prompt) if self.cfg.use_prompt else 1.0)
        for name, m in masks.items():
            spec = effect_spec(name, self.cfg.effect_params.get(name))
            synthesize_effect(motion, name, spec, m, seed, edge=self.cfg.edge, gain=gain)
        return motion

    # -- interface ----------------------------------------------------------------------
    def refine(self, clip: np.ndarray, mask: MaskLike, prompt: str = "", seed: int = 0,
               strength: float = 0.5, fps: float | None = None) -> np.ndarray:
        """Refine a clip [T,H,W,3] (see module docstring); returns float32 [T,H,W,3]."""
        clip = check_clip(clip).astype(np.float32, copy=False)
        s = check_strength(strength)
        T, H, W, _ = clip.shape
        masks = self.effect_masks(mask, prompt, H, W)
        region = np.zeros((H, W), bool)
        for m in masks.values():
            region |= m > 0.5
        self.last_info = {"effects": sorted(masks), "region_fraction": float(region.mean()), "strength": s,
                          "frames": T}
        if not region.any() or T == 1:
            log.info("procedural refine: %s: clip passes through unchanged",
                     "empty dynamic mask" if not region.any() else "single-frame clip")
            return clip.copy()
        motion = self.motion_field(masks, H, W, seed, prompt, fps)
        est = clip_backward_flow(clip, self.cfg.flow_preset) if s < 1.0 else None
        grid = identity_grid(H, W)
        out = clip.copy()
        sel = region[..., None]
        max_disp = 0.0
        w_keep, w_new = 1.0 - s, float(np.sqrt(s * (2.0 - s)))  # w_keep^2 + w_new^2 = 1
        for t in range(1, T):
            d = w_new * motion.at(t)
            if est is not None:
                d += w_keep * est[t] * region[..., None]
            max_disp = max(max_disp, float(np.abs(d).max()))
            out[t] = np.where(sel, warp(clip[0], d, grid), clip[t])
        self.last_info["max_displacement_px"] = max_disp
        log.info("procedural refine: T=%d %dx%d effects=%s strength=%.2f seed=%d region=%.1f%% max|d|=%.2fpx",
                 T, W, H, sorted(masks), s, seed, 100 * region.mean(), max_disp)
        return np.clip(out, 0.0, 1.0)

    def generate(self, first_frame: np.ndarray, mask: MaskLike, prompt: str = "", seed: int = 0,
                 num_frames: int = 49, fps: float | None = None) -> np.ndarray:
        """Animate one frame [H,W,3] into a clip [num_frames,H,W,3] (frame 0 = input)."""
        if num_frames < 1:
            raise ValueError(f"num_frames must be >= 1, got {num_frames}")
        frame = np.asarray(first_frame, np.float32)
        clip = np.repeat(frame[None], num_frames, axis=0)
        return self.refine(clip, mask, prompt, seed, strength=1.0, fps=fps)
