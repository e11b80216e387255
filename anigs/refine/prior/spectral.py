"""Stochastic motion textures: per-effect displacement fields from filtered noise.

Built on the idea of Chuang et al. 2005 ("Animating Pictures with Stochastic Motion
Textures"), Stam 1997 (wind spectra) and the per-pixel motion spectra of Generative Image
Dynamics (Li et al. 2024): every effect type is a sum of ``n_modes`` temporal oscillators
whose frequencies lie in the effect's band, with spatial coefficient fields that are
filtered noise of the effect's correlation length, times an amplitude profile.

Every effect reduces to the same representation, a :class:`MotionField`:
``d(p, t) = sum_k A_k(p) cos(w_k t) + B_k(p) sin(w_k t) - d(p, 0)`` with coefficient fields
A_k, B_k [H,W,2] (pixels, backward-warp convention of :mod:`anigs.flow`). Subtracting
``d(p, 0)`` makes frame 0 the undisplaced canonical frame (the model's t = 0), so a
synthesised clip always starts at the static reference image.

Amplitudes and lengths are fractions of the image's shorter side (resolution independent),
frequencies are in Hz at ``fps`` frames per second. The field is exactly 0 outside the
effect's mask and tapers smoothly to 0 at the mask boundary (``edge`` in px, at least
``edge_amp_ratio`` x the amplitude) so the warp never folds or tears.
"""
from __future__ import annotations

import zlib
from dataclasses import dataclass, field, replace
from typing import Any, Mapping

import cv2
import numpy as np

from anigs.typed_config import reject_unknown_keys

KINDS = ("oscillate", "travel", "ripple")


@dataclass(frozen=True)
class EffectSpec:
    """Parameters of one effect type (lengths/amplitudes as fractions of the shorter image side)."""

    band_hz: tuple[float, float]     # temporal band [lo, hi] of the oscillators, Hz
    amplitude: float                 # RMS displacement where the profile is 1
    corr_len: float                  # spatial correlation length (Gaussian filter sigma)
    kind: str = "oscillate"          # oscillate | travel (waves along wind_dir) | ripple (water)
    axis_weights: tuple[float, float] = (1.0, 1.0)  # x, y weight (oscillate) / along, across (travel)
    profile: str = "uniform"         # uniform | anchor (grows away from the region's bottom)
    anchor_floor: float = 0.15       # profile value at the anchor (bottom) for profile=anchor
    n_modes: int = 4                 # oscillators per component
    wind_dir_deg: float = 0.0        # travel: wind direction in the image, 0 = +x, 90 = +y (down)
    wave_speed: float = 0.3          # travel: phase speed, shorter sides per second
    wavelength: float = 0.06         # ripple: wavelength

    def __post_init__(self) -> None:
        lo, hi = self.band_hz
        if not (0 < lo <= hi):
            raise ValueError(f"band_hz must satisfy 0 < lo <= hi, got {self.band_hz}")
        if self.kind not in KINDS:
            raise ValueError(f"effect kind {self.kind!r} is not one of {KINDS}")
        if self.profile not in ("uniform", "anchor"):
            raise ValueError(f"profile {self.profile!r} is not 'uniform' or 'anchor'")
        if self.amplitude < 0 or self.corr_len <= 0 or self.n_modes < 1:
            raise ValueError(f"invalid effect spec (amplitude >= 0, corr_len > 0, n_modes >= 1): {self}")


EFFECTS: dict[str, EffectSpec] = {
    # large coherent crowns, slow, amplitude grows with height above the anchor, mostly horizontal
    "foliage_sway": EffectSpec(band_hz=(0.3, 0.9), amplitude=0.008, corr_len=0.25, profile="anchor",
                               axis_weights=(1.0, 0.35), n_modes=3),
    # small-scale fast jitter of leaves
    "leaf_flutter": EffectSpec(band_hz=(2.0, 5.0), amplitude=0.002, corr_len=0.02, n_modes=4),
    # waves travelling across the grass along the wind direction
    "grass_wave": EffectSpec(band_hz=(0.5, 1.5), amplitude=0.005, corr_len=0.08, kind="travel",
                             axis_weights=(1.0, 0.2), n_modes=3),
    # flowers bobbing mostly vertically, neighbours out of phase
    "flower_bob": EffectSpec(band_hz=(0.8, 2.0), amplitude=0.003, corr_len=0.04,
                             axis_weights=(0.4, 1.0), n_modes=3),
    # refraction-like shimmer of a rippling water surface
    "water_ripple": EffectSpec(band_hz=(0.8, 2.5), amplitude=0.0015, corr_len=0.1, kind="ripple",
                               n_modes=8, wavelength=0.06),
}


def effect_spec(name: str, overrides: Mapping[str, Any] | None = None) -> EffectSpec:
    """The spec of effect ``name`` with config ``overrides`` applied (unknown keys rejected)."""
    if name not in EFFECTS:
        raise ValueError(f"unknown effect type {name!r}; known: {sorted(EFFECTS)}")
    spec = EFFECTS[name]
    if not overrides:
        return spec
    reject_unknown_keys(EffectSpec, overrides, f"effect {name!r}", ValueError)
    vals = {k: (tuple(v) if isinstance(v, list) else v) for k, v in overrides.items()}
    return replace(spec, **vals)


@dataclass
class MotionField:
    """Sum of temporal oscillators with spatial coefficient fields (see module docstring).

    freqs [K] Hz; coef_a, coef_b [K,H,W,2] px; ``at(t)`` -> [H,W,2] with ``at(0) == 0``.
    """

    height: int
    width: int
    fps: float
    freqs: np.ndarray = field(default_factory=lambda: np.zeros(0, np.float32))
    coef_a: np.ndarray | None = None
    coef_b: np.ndarray | None = None

    def add(self, freqs: np.ndarray, a: np.ndarray, b: np.ndarray) -> None:
        self.freqs = np.concatenate([self.freqs, np.asarray(freqs, np.float32)])
        self.coef_a = a if self.coef_a is None else np.concatenate([self.coef_a, a])
        self.coef_b = b if self.coef_b is None else np.concatenate([self.coef_b, b])

    @property
    def empty(self) -> bool:
        return self.coef_a is None or len(self.freqs) == 0

    def at(self, t: float) -> np.ndarray:
        """Displacement [H,W,2] at frame ``t`` (may be fractional)."""
        if self.empty:
            return np.zeros((self.height, self.width, 2), np.float32)
        w = 2.0 * np.pi * self.freqs * (float(t) / self.fps)
        c = (np.cos(w) - 1.0).astype(np.float32)  # minus d(0) = sum_k A_k
        s = np.sin(w).astype(np.float32)
        return (np.tensordot(c, self.coef_a, axes=1) + np.tensordot(s, self.coef_b, axes=1)).astype(np.float32)

    def sequence(self, num_frames: int) -> np.ndarray:
        """All frames [T,H,W,2]."""
        return np.stack([self.at(t) for t in range(num_frames)]) if num_frames else \
            np.zeros((0, self.height, self.width, 2), np.float32)


def smooth_noise(rng: np.random.Generator, height: int, width: int, sigma_px: float, count: int) -> np.ndarray:
    """``count`` unit-variance Gaussian random fields [count,H,W] with correlation length ``sigma_px``.

    Filtered at a coarse resolution (keeping >= 3 px per sigma) and resized bicubically.
    """
    step = max(1, int(sigma_px // 3))
    hc, wc = max(1, -(-height // step)), max(1, -(-width // step))
    sig = max(sigma_px / step, 0.5)
    pad = int(3 * sig) + 1
    out = np.empty((count, height, width), np.float32)
    for i in range(count):
        n = rng.standard_normal((hc + 2 * pad, wc + 2 * pad)).astype(np.float32)
        f = cv2.GaussianBlur(n, (0, 0), sig)[pad:pad + hc, pad:pad + wc]
        if step > 1:
            f = cv2.resize(f, (width, height), interpolation=cv2.INTER_CUBIC)
        f = f[:height, :width]
        sd = float(f.std())
        out[i] = (f - f.mean()) / sd if sd > 1e-8 else 0.0
    return out


def anchor_profile(region: np.ndarray, floor: float) -> np.ndarray:
    """[H,W] in [floor,1] inside ``region`` (bool [H,W]), growing linearly from each connected
    component's bottom row (its anchor) to its top row; 0 outside."""
    out = np.zeros(region.shape, np.float32)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(region.astype(np.uint8), connectivity=8)
    ys = np.arange(region.shape[0], dtype=np.float32)[:, None]
    for i in range(1, n):
        top, h = stats[i, cv2.CC_STAT_TOP], stats[i, cv2.CC_STAT_HEIGHT]
        bottom = top + h - 1
        rel = np.clip((bottom - ys) / max(h - 1, 1), 0.0, 1.0)
        prof = floor + (1.0 - floor) * rel
        sel = labels == i
        out[sel] = np.broadcast_to(prof, region.shape)[sel]
    return out


def edge_taper(region: np.ndarray, edge_px: float) -> np.ndarray:
    """Smoothstep of the distance to the region's boundary over ``edge_px``: 0 outside, 1 deep inside."""
    if not region.any():
        return np.zeros(region.shape, np.float32)
    padded = np.pad(region.astype(np.uint8), 1)  # the image border is not a boundary of the region
    padded[0, :], padded[-1, :], padded[:, 0], padded[:, -1] = padded[1, :], padded[-2, :], padded[:, 1], padded[:, -2]
    dist = cv2.distanceTransform(padded, cv2.DIST_L2, 5)[1:-1, 1:-1]
    x = np.clip(dist / max(edge_px, 1e-6), 0.0, 1.0)
    return (x * x * (3.0 - 2.0 * x)).astype(np.float32)


def synthesize_effect(motion: MotionField, name: str, spec: EffectSpec, mask: np.ndarray, seed: int,
                      edge: float = 0.03, edge_amp_ratio: float = 6.0, gain: float = 1.0) -> None:
    """Add effect ``name`` inside ``mask`` [H,W] (>0.5 = region) to ``motion``.

    Deterministic for (seed, effect name). ``edge``: taper width as a fraction of the shorter side.
    """
    H, W = motion.height, motion.width
    region = np.asarray(mask) > 0.5
    if not region.any() or spec.amplitude <= 0 or gain <= 0:
        return
    short = float(min(H, W))
    amp_px = spec.amplitude * short * gain
    rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, zlib.crc32(name.encode())])
    K = spec.n_modes
    lo, hi = spec.band_hz
    freqs = lo + (np.arange(K) + rng.uniform(0.1, 0.9, K)) / K * (hi - lo)  # stratified over the band
    taper = edge_taper(region, max(edge * short, edge_amp_ratio * amp_px * max(spec.axis_weights)))
    prof = anchor_profile(region, spec.anchor_floor) if spec.profile == "anchor" else region.astype(np.float32)
    weight = (amp_px * taper * prof)[None]  # [1,H,W]
    sigma = spec.corr_len * short
    a = np.zeros((K, H, W, 2), np.float32)
    b = np.zeros((K, H, W, 2), np.float32)
    if spec.kind == "oscillate":
        # per mode and component: cos/sin coefficient fields of unit variance -> RMS = amplitude
        nz = smooth_noise(rng, H, W, sigma, 4 * K).reshape(K, 4, H, W)
        scale = weight / np.sqrt(K) * np.sqrt(0.5)
        for c in range(2):
            a[..., c] = scale * spec.axis_weights[c] * nz[:, 2 * c]
            b[..., c] = scale * spec.axis_weights[c] * nz[:, 2 * c + 1]
    elif spec.kind == "travel":
        th = np.deg2rad(spec.wind_dir_deg)
        u = np.array([np.cos(th), np.sin(th)], np.float32)      # along the wind
        v = np.array([-np.sin(th), np.cos(th)], np.float32)     # across
        gx, gy = np.meshgrid(np.arange(W, dtype=np.float32), np.arange(H, dtype=np.float32))
        along = gx * u[0] + gy * u[1]
        jitter = smooth_noise(rng, H, W, sigma, 3 * K).reshape(K, 3, H, W)
        speed_px = spec.wave_speed * short
        for k in range(K):
            lam = speed_px / freqs[k]                           # wavelength so that phase speed = wave_speed
            phase = -2 * np.pi * along / lam + 0.6 * jitter[k, 0] + rng.uniform(0, 2 * np.pi)
            mag = weight[0] / np.sqrt(K) * np.clip(1.0 + 0.3 * jitter[k, 1], 0.2, None)
            # cos(wt + phase) = cos(phase) cos(wt) - sin(phase) sin(wt)
            for c in range(2):
                dirc = spec.axis_weights[0] * u[c] + spec.axis_weights[1] * v[c] * jitter[k, 2]
                a[k, ..., c] = mag * dirc * np.cos(phase)
                b[k, ..., c] = -mag * dirc * np.sin(phase)
    else:  # ripple: displacement along random wave vectors, sin(k.p - wt + phi)
        gx, gy = np.meshgrid(np.arange(W, dtype=np.float32), np.arange(H, dtype=np.float32))
        lam = spec.wavelength * short
        for k in range(K):
            ang = rng.uniform(0, 2 * np.pi)
            kl = 2 * np.pi / (lam * rng.uniform(0.7, 1.4))
            kv = np.array([np.cos(ang), np.sin(ang)], np.float32)
            theta = kl * (gx * kv[0] + gy * kv[1]) + rng.uniform(0, 2 * np.pi)
            mag = weight[0] / np.sqrt(K) * np.sqrt(2.0)
            # sin(theta - wt) = sin(theta) cos(wt) - cos(theta) sin(wt)
            for c in range(2):
                a[k, ..., c] = mag * kv[c] * np.sin(theta)
                b[k, ..., c] = -mag * kv[c] * np.cos(theta)
    motion.add(freqs.astype(np.float32), a, b)


PROMPT_EFFECTS = {
    "foliage_sway": ("tree", "trees", "foliage", "branch", "crown", "bush", "canopy"),
    "leaf_flutter": ("leaf", "leaves", "flutter", "rustl"),
    "grass_wave": ("grass", "meadow", "field", "lawn"),
    "flower_bob": ("flower", "blossom", "bloom"),
    "water_ripple": ("water", "pond", "lake", "river", "ripple", "stream"),
}
PROMPT_GAIN = {"gentle": 0.6, "light": 0.7, "calm": 0.5, "subtle": 0.6, "strong": 1.5, "gust": 1.6, "windy": 1.3}


def effects_from_prompt(prompt: str) -> list[str]:
    """Effect types named by keywords in a prompt (used when a config lists no effects)."""
    p = (prompt or "").lower()
    return [name for name, words in PROMPT_EFFECTS.items() if any(w in p for w in words)]


def prompt_gain(prompt: str) -> float:
    """Amplitude multiplier from intensity words in the prompt (1.0 if none)."""
    p = (prompt or "").lower()
    g = [v for w, v in PROMPT_GAIN.items() if w in p]
    return float(np.prod(g)) if g else 1.0
