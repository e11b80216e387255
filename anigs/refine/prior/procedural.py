"""Procedural spectral motion prior (default backend: offline, CPU, no weights).

``refine`` estimates the motion already present in the clip (DIS optical flow, backward
convention of :mod:`anigs.flow`: ``clip[t](p) ≈ clip[0](p + d_t(p))``) inside the dynamic
region, blends it with a freshly sampled stochastic motion texture (:mod:`anigs.refine.prior.spectral`)
by ``strength`` s (0 = keep the clip's motion, 1 = new motion) and re-synthesises every frame
by warping frame 0 with the blended field ``(1 - s) d_clip + sqrt(s (2 - s)) d_new``: the
weights' squares sum to 1, so blending two independent fields of equal energy keeps the
motion's energy (a linear blend would shrink it by up to 1/sqrt(2) at s = 0.5). Pixels outside the mask are copied from the input
unchanged. Frame 0 is the canonical frame: its displacement is 0, so ``out[0] == clip[0]``.

Different seeds give different motion phases, like a diffusion model run independently per
view: the multi-view inconsistency that the dataset-model loop has to resolve.

Diffusion-prior flaws (all off by default: the clean offline prior, byte-identical outputs).
A video diffusion model refining a clip independently per view keeps the clip's coarse motion
only approximately and re-synthesises every pixel. :class:`ProceduralConfig` can emulate that,
deterministically per seed (so per view and round):

- ``view_phase_frames``: the motion kept from the clip is shifted in time by a per-view
  ``N(0, view_phase_frames^2)`` frames (``d'(t) = d(t + δ) - d(δ)``, frame 0 stays canonical);
- ``view_amplitude_log``: the refined field is scaled by ``exp(N(0, view_amplitude_log^2))``;
- ``view_direction_deg``: the refined field is rotated in the image by ``N(0, view_direction_deg^2)`` degrees;
- ``static_drift_px``: static pixels (outside the dynamic region) drift: they are warped by a
  smooth field (correlation length a quarter of the shorter side) whose RMS grows linearly from
  0 at frame 0 to ``static_drift_px`` pixels at the last frame;
- ``static_shimmer``: static pixels get per-frame, spatially correlated (``shimmer_corr_px``)
  intensity noise of standard deviation ``static_shimmer`` (frames 1..T-1).

Magnitudes. Shimmer: VBench (Huang et al., CVPR 2024) scores "temporal flickering" of static
scenes as ``(255 - mean |I_t+1 - I_t|) / 255``; current open text/image-to-video models score
about 0.97-0.99 there (reported values quoted from memory: check against the VBench
leaderboard), i.e. a mean frame-to-frame change of about 2.5-7.5 grey levels of 255. For
per-frame independent noise of std σ the mean absolute frame difference is 2σ/sqrt(π) ≈ 1.13σ,
so ``static_shimmer = 0.0125`` gives 0.014 (≈ 3.6/255, VBench ≈ 0.986). The other four are
assumptions, not measurements: nothing offline measures them. Suggested table settings:
``view_phase_frames = 2`` (a quarter period of a 0.5-Hz sway at 24 fps is 12 frames; 2 frames is a
mild 60° at 2 Hz), ``view_amplitude_log = 0.25`` (±28% per view), ``view_direction_deg = 15``,
``static_drift_px = 0.5`` (sub-pixel, the order of the static flow the metrics already resolve).
To measure them with LTX-Video on a GPU: refine one rendered clip with several seeds and compare
the flows (:mod:`anigs.flow`) of the results in the dynamic and static regions.
"""
from __future__ import annotations

import logging
import zlib
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from anigs.typed_config import Section
from anigs.flow import clip_backward_flow, identity_grid, warp
from anigs.refine.prior.base import MaskLike, VideoPrior, check_prior_mask, check_strength
from anigs.refine.prior.spectral import (EFFECTS, MotionField, effect_spec, effects_from_prompt, prompt_gain, smooth_noise,
                                  synthesize_effect)
from anigs.video import check_clip

log = logging.getLogger(__name__)


@dataclass
class ProceduralConfig(Section):
    """Config of the procedural prior (section ``procedural`` of the refine stage)."""

    WHERE = "procedural prior config"

    effects: list[str] = field(default_factory=lambda: ["foliage_sway", "leaf_flutter"])  # effect types to synthesise
    fps: float = 24.0                 # frames per second of the clips (frequencies are in Hz)
    effect_params: dict[str, dict[str, Any]] = field(default_factory=dict)  # per-effect EffectSpec overrides
    amplitude_scale: float = 1.0      # global amplitude multiplier
    edge: float = 0.03                # mask-edge taper width, fraction of the shorter side
    flow_preset: str = "medium"       # DIS preset for the motion estimate: ultrafast | fast | medium
    #: effects from prompt keywords when `effects` is empty; intensity words scale amplitude
    use_prompt: bool = True
    # diffusion-prior flaws (module docstring); 0 = off, the clean prior
    view_phase_frames: float = 0.0    # std of a per-view time shift of the motion kept from the clip (frames)
    view_amplitude_log: float = 0.0   # std of the per-view log-gain of the refined motion
    view_direction_deg: float = 0.0   # std of a per-view image-plane rotation of the refined motion (degrees)
    static_drift_px: float = 0.0      # RMS drift of static pixels at the last frame (px), linear from frame 0
    static_shimmer: float = 0.0       # std of per-frame intensity noise in static pixels ([0,1] units)
    shimmer_corr_px: float = 1.5      # spatial correlation length of the shimmer (px)

    def validate(self) -> None:
        cfg = self
        cfg.effects = list(cfg.effects)
        for name in cfg.effects:
            effect_spec(name, cfg.effect_params.get(name))  # validates names and overrides
        for name in cfg.effect_params:
            if name not in EFFECTS:
                raise ValueError(f"effect_params names unknown effect {name!r}; known: {sorted(EFFECTS)}")
        if cfg.fps <= 0:
            raise ValueError(f"fps must be > 0, got {cfg.fps}")
        for k in FLAW_KEYS + ("shimmer_corr_px",):
            v = float(getattr(cfg, k))
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f"{k} must be a finite number >= 0, got {getattr(cfg, k)!r}")
        if cfg.shimmer_corr_px <= 0:
            raise ValueError(f"shimmer_corr_px must be > 0, got {cfg.shimmer_corr_px}")

    @property
    def flaws_on(self) -> bool:
        """Whether any diffusion-prior flaw is enabled."""
        return any(float(getattr(self, k)) > 0 for k in FLAW_KEYS)


FLAW_KEYS = ("view_phase_frames", "view_amplitude_log", "view_direction_deg", "static_drift_px", "static_shimmer")


@dataclass
class ViewFlaws:
    """One view's draw of the flaws: time shift (frames), gain, rotation (rad)."""

    phase: float = 0.0
    gain: float = 1.0
    angle: float = 0.0

    @staticmethod
    def draw(cfg: "ProceduralConfig", seed: int) -> "ViewFlaws":
        """Deterministic for the seed; independent of the motion texture's random stream."""
        rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, zlib.crc32(b"diffusion-flaws")])
        z = rng.standard_normal(3)
        return ViewFlaws(float(z[0] * cfg.view_phase_frames), float(np.exp(z[1] * cfg.view_amplitude_log)),
                         float(np.deg2rad(z[2] * cfg.view_direction_deg)))

    def transform(self, d: np.ndarray) -> np.ndarray:
        """Gain and rotation of a displacement field [...,2]."""
        if self.gain == 1.0 and self.angle == 0.0:
            return d
        c, s = np.cos(self.angle), np.sin(self.angle)
        x, y = d[..., 0], d[..., 1]
        return (self.gain * np.stack([c * x - s * y, s * x + c * y], -1)).astype(np.float32)


def time_shifted(est: np.ndarray, shift: float) -> np.ndarray:
    """``d'(t) = d(t + shift) - d(shift)`` for a displacement sequence est [T,H,W,2] (linear
    interpolation in t, clamped to [0, T-1]); ``d'(0) = 0``."""
    if shift == 0.0:
        return est
    T = est.shape[0]

    def at(t: float) -> np.ndarray:
        t = min(max(t, 0.0), T - 1.0)
        i = min(int(np.floor(t)), T - 2) if T > 1 else 0
        w = t - i
        return est[i] if T == 1 else (1 - w) * est[i] + w * est[i + 1]

    base = at(shift)
    return np.stack([at(t + shift) - base for t in range(T)]).astype(np.float32)


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
                    out[name] = check_prior_mask(mask[name], height, width, f"mask[{name!r}]")
                else:
                    log.info("effect %s is configured but has no mask: not synthesised", name)
            ignored = sorted(set(mask) - set(effects))
            if ignored:
                log.info("masks for effects %s are not in the configured effects %s: ignored", ignored, effects)
            return out
        m = check_prior_mask(mask, height, width)
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
        flaws = ViewFlaws.draw(self.cfg, seed) if self.cfg.flaws_on else None
        if flaws is not None and est is not None:
            est = time_shifted(est, flaws.phase)
        for t in range(1, T):
            d = w_new * motion.at(t)
            if est is not None:
                d += w_keep * est[t] * region[..., None]
            if flaws is not None:
                d = flaws.transform(d)
            max_disp = max(max_disp, float(np.abs(d).max()))
            out[t] = np.where(sel, warp(clip[0], d, grid), clip[t])
        self.last_info["max_displacement_px"] = max_disp
        if flaws is not None:
            self._static_flaws(out, clip, region, seed)
            self.last_info["flaws"] = {"phase_frames": flaws.phase, "gain": flaws.gain,
                                       "angle_deg": float(np.rad2deg(flaws.angle)),
                                       "static_drift_px": self.cfg.static_drift_px,
                                       "static_shimmer": self.cfg.static_shimmer}
        log.info("procedural refine: T=%d %dx%d effects=%s strength=%.2f seed=%d region=%.1f%% max|d|=%.2fpx",
                 T, W, H, sorted(masks), s, seed, 100 * region.mean(), max_disp)
        return np.clip(out, 0.0, 1.0)

    def _static_flaws(self, out: np.ndarray, clip: np.ndarray, region: np.ndarray, seed: int) -> None:
        """Drift and shimmer of the static pixels (outside ``region`` [H,W]) of ``out`` [T,H,W,3], in place."""
        cfg = self.cfg
        T, H, W, _ = out.shape
        if (cfg.static_drift_px <= 0 and cfg.static_shimmer <= 0) or T < 2 or region.all():
            return
        rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, zlib.crc32(b"static-flaws")])
        still = ~region[..., None]
        grid = identity_grid(H, W)
        drift = None
        if cfg.static_drift_px > 0:
            field = np.stack(list(smooth_noise(rng, H, W, 0.25 * min(H, W), 2)), -1)  # unit variance per component
            field *= cfg.static_drift_px / max(float(np.sqrt((field ** 2).sum(-1).mean())), 1e-12)
            drift = field.astype(np.float32)
        for t in range(1, T):
            frame = clip[t]
            if drift is not None:
                frame = warp(frame, drift * (t / (T - 1)), grid)
            if cfg.static_shimmer > 0:
                noise = smooth_noise(rng, H, W, cfg.shimmer_corr_px, 3).transpose(1, 2, 0)
                frame = frame + cfg.static_shimmer * noise
            out[t] = np.where(still, np.clip(frame, 0.0, 1.0), out[t])

    def generate(self, first_frame: np.ndarray, mask: MaskLike, prompt: str = "", seed: int = 0,
                 num_frames: int = 49, fps: float | None = None) -> np.ndarray:
        """Animate one frame [H,W,3] into a clip [num_frames,H,W,3] (frame 0 = input)."""
        if num_frames < 1:
            raise ValueError(f"num_frames must be >= 1, got {num_frames}")
        frame = np.asarray(first_frame, np.float32)
        clip = np.repeat(frame[None], num_frames, axis=0)
        return self.refine(clip, mask, prompt, seed, strength=1.0, fps=fps)
