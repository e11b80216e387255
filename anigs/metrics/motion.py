"""Weight-free motion metrics (always computed; no network weights).

Image space, per camera-fixed clip [T,H,W,3] in [0,1] and its dynamic mask [H,W] (True =
region meant to move):

- ``static_abs_diff``: mean |I_{t+1} - I_t| over the static region (dynamic mask dilated by
  ``margin`` px, then complemented, so moving content that crosses the mask border is not
  counted), channels and t. Lower is better: this is the ComposedV2V claim (static stays still).
- ``static_drift``: mean |I_t - I_0| over the static region (slow drift that the frame-to-frame
  change misses).
- ``static_flow``: mean optical-flow magnitude (px/frame, OpenCV DIS on grey frames,
  consecutive pairs) over the static region.
- ``dynamic_abs_diff`` / ``dynamic_flow``: the same inside the dynamic mask (motion energy:
  higher = more motion; 0 = frozen).
- ``dominant_freq``: peak of the mean power spectrum (Hann window, per-pixel mean removed,
  DC excluded) of the grey-level time series of dynamic pixels, in cycles per frame (x fps =
  Hz). ``spectral_centroid`` is its power-weighted mean frequency.

Ground-truth comparison (synthetic scene), per-Gaussian trajectories [N,T,3] of the moving
Gaussians, learned vs ground truth. There is no one-to-one correspondence (the learned
Gaussians come from an SfM-initialised fit), so distributions are compared:

- amplitude of a Gaussian = RMS distance of its positions from their temporal mean, divided
  by the scene extent given with each set (scale-free: SfM coordinates differ from the
  ground truth's by a similarity);
- frequency of a Gaussian = dominant frequency (cycles per frame) of its displacement;
- reported: ``rms_amplitude_ratio`` (learned RMS amplitude over all Gaussians / GT; 1 is
  ideal), ``amplitude_w1`` (1-Wasserstein distance between the amplitude distributions, in
  units of scene extent), ``frequency_w1`` (same for the frequency distributions, cycles per
  frame), ``dominant_freq_learned`` / ``dominant_freq_gt`` (median per-Gaussian frequency).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from anigs.pixels import dilate

FLOW_PRESETS = ("ultrafast", "fast", "medium")


def _grey_u8(clip: np.ndarray) -> np.ndarray:
    g = clip[..., 0] * 0.299 + clip[..., 1] * 0.587 + clip[..., 2] * 0.114
    return (np.clip(g, 0, 1) * 255 + 0.5).astype(np.uint8)


def _check(clip: np.ndarray, mask: np.ndarray | None) -> tuple[np.ndarray, np.ndarray | None]:
    clip = np.asarray(clip, dtype=np.float32)
    if clip.ndim != 4 or clip.shape[-1] != 3:
        raise ValueError(f"motion metrics: expected a clip [T,H,W,3], got {clip.shape}")
    if mask is not None:
        mask = np.asarray(mask).astype(bool)
        if mask.shape != clip.shape[1:3]:
            raise ValueError(f"motion metrics: mask {mask.shape} does not match clip frames {clip.shape[1:3]}")
    return clip, mask


def resize_mask(mask: np.ndarray, height: int, width: int, threshold: float = 0.5) -> np.ndarray:
    """Boolean mask at [height,width] (nearest for booleans; area + threshold for soft masks)."""
    import cv2

    m = np.asarray(mask, dtype=np.float32)
    if m.ndim == 3:
        m = m[..., 0]
    if m.max() > 1.0:
        m = m / 255.0
    if m.shape != (height, width):
        m = cv2.resize(m, (width, height), interpolation=cv2.INTER_AREA)
    return m >= threshold


def optical_flow_magnitudes(clip: np.ndarray, preset: str = "medium") -> np.ndarray:
    """Per-pixel flow magnitude [T-1,H,W] (px/frame) between consecutive frames (OpenCV DIS)."""
    import cv2

    if preset not in FLOW_PRESETS:
        raise ValueError(f"flow preset {preset!r} unknown; choose one of {FLOW_PRESETS}")
    clip, _ = _check(clip, None)
    grey = _grey_u8(clip)
    code = {"ultrafast": cv2.DISOpticalFlow_PRESET_ULTRAFAST, "fast": cv2.DISOpticalFlow_PRESET_FAST,
            "medium": cv2.DISOpticalFlow_PRESET_MEDIUM}[preset]
    dis = cv2.DISOpticalFlow_create(code)
    out = np.zeros((max(0, len(grey) - 1),) + grey.shape[1:], np.float32)
    for t in range(len(grey) - 1):
        flow = dis.calc(grey[t], grey[t + 1], None)
        out[t] = np.sqrt((flow**2).sum(-1))
    return out


def temporal_spectrum(clip: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(freqs [F] in cycles/frame, mean power [F]) of grey time series of the masked pixels."""
    clip, mask = _check(clip, mask)
    T = clip.shape[0]
    grey = (clip * np.array([0.299, 0.587, 0.114], np.float32)).sum(-1)  # [T,H,W]
    series = grey[:, mask].astype(np.float64)  # [T,P]
    freqs = np.fft.rfftfreq(T)
    if series.shape[1] == 0 or T < 3:
        return freqs, np.zeros_like(freqs)
    series = series - series.mean(axis=0, keepdims=True)
    spec = np.abs(np.fft.rfft(series * np.hanning(T)[:, None], axis=0)) ** 2
    return freqs, spec.mean(axis=1)


def dominant_frequency(freqs: np.ndarray, power: np.ndarray) -> tuple[float, float]:
    """(peak frequency, power-weighted centroid) excluding DC; (nan, nan) without signal."""
    if len(freqs) < 2 or not np.any(power[1:] > 0):
        return float("nan"), float("nan")
    p = power[1:]
    f = freqs[1:]
    return float(f[int(np.argmax(p))]), float((f * p).sum() / p.sum())


@dataclass
class ClipMotion:
    """Weight-free motion metrics of one clip; NaN where a region is empty."""

    static_abs_diff: float
    static_drift: float
    static_flow: float
    dynamic_abs_diff: float
    dynamic_flow: float
    dominant_freq: float
    spectral_centroid: float
    static_pixels: int
    dynamic_pixels: int
    frames: int

    def to_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)


def _masked_mean(values: np.ndarray, mask: np.ndarray) -> float:
    """Mean of values [K,H,W] or [K,H,W,C] over mask [H,W]; NaN when mask or K empty."""
    if values.shape[0] == 0 or not mask.any():
        return float("nan")
    return float(values[:, mask].mean())


def clip_motion_metrics(clip: np.ndarray, dynamic_mask: np.ndarray, margin: int = 2,
                        flow_preset: str = "medium", with_flow: bool = True) -> ClipMotion:
    """Weight-free metrics of a clip [T,H,W,3] given its dynamic mask [H,W] (see module doc)."""
    clip, dyn = _check(clip, dynamic_mask)
    static = ~dilate(dyn, margin)
    diff = np.abs(np.diff(clip, axis=0))  # [T-1,H,W,3]
    drift = np.abs(clip - clip[:1])
    if with_flow and clip.shape[0] > 1:
        mag = optical_flow_magnitudes(clip, flow_preset)
        s_flow, d_flow = _masked_mean(mag, static), _masked_mean(mag, dyn)
    else:
        s_flow = d_flow = float("nan")
    freqs, power = temporal_spectrum(clip, dyn)
    peak, centroid = dominant_frequency(freqs, power)
    return ClipMotion(static_abs_diff=_masked_mean(diff, static), static_drift=_masked_mean(drift, static),
                      static_flow=s_flow, dynamic_abs_diff=_masked_mean(diff, dyn), dynamic_flow=d_flow,
                      dominant_freq=peak, spectral_centroid=centroid, static_pixels=int(static.sum()),
                      dynamic_pixels=int(dyn.sum()), frames=int(clip.shape[0]))


def outside_mask_still(clip: np.ndarray, dynamic_mask: np.ndarray, margin: int = 5, tolerance: float = 1 / 255) -> float:
    """Fraction of the pixels outside the dynamic mask (dilated by ``margin`` px) whose value never
    changes from frame 0 by more than ``tolerance`` (any channel, any frame) over the clip
    [T,H,W,3] in [0,1]: 1.0 when everything that should stand still does; NaN without such pixels."""
    clip, dyn = _check(clip, dynamic_mask)
    outside = ~dilate(dyn, margin)
    if not outside.any():
        return float("nan")
    change = np.abs(clip - clip[:1]).max(axis=(0, 3))  # [H,W]
    return float((change[outside] <= tolerance + 1e-6).mean())


# ----------------------------------------------------------------- ground-truth motion statistics

def trajectory_stats(positions: np.ndarray, extent: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Per-Gaussian (RMS amplitude / extent [N], dominant frequency in cycles/frame [N]) of positions [N,T,3]."""
    x = np.asarray(positions, dtype=np.float64)
    if x.ndim != 3 or x.shape[-1] != 3:
        raise ValueError(f"trajectory_stats: expected positions [N,T,3], got {x.shape}")
    if not np.isfinite(x).all():
        raise ValueError("trajectory_stats: positions contain NaN or Inf")
    if not extent > 0:
        raise ValueError(f"trajectory_stats: scene extent must be > 0, got {extent}")
    T = x.shape[1]
    d = x - x.mean(axis=1, keepdims=True)
    amp = np.sqrt((d**2).sum(-1).mean(axis=1)) / extent
    if T < 3:
        return amp, np.full(len(x), np.nan)
    spec = (np.abs(np.fft.rfft(d * np.hanning(T)[None, :, None], axis=1)) ** 2).sum(-1)  # [N,F]
    freqs = np.fft.rfftfreq(T)
    peak = freqs[1:][np.argmax(spec[:, 1:], axis=1)]
    peak = np.where(spec[:, 1:].max(axis=1) > 0, peak, np.nan)
    return amp, peak


def gt_motion_distances(learned: np.ndarray, gt: np.ndarray, learned_extent: float = 1.0,
                        gt_extent: float = 1.0) -> dict[str, float]:
    """Distances between learned [N,T,3] and ground-truth [M,T',3] motion statistics (see module doc)."""
    from scipy.stats import wasserstein_distance

    a_l, f_l = trajectory_stats(learned, learned_extent)
    a_g, f_g = trajectory_stats(gt, gt_extent)
    if len(a_l) == 0 or len(a_g) == 0:
        raise ValueError(f"gt_motion_distances: empty trajectory set (learned {len(a_l)}, gt {len(a_g)})")
    rms_l = float(np.sqrt(np.mean(a_l**2)))
    rms_g = float(np.sqrt(np.mean(a_g**2)))
    fl, fg = f_l[np.isfinite(f_l)], f_g[np.isfinite(f_g)]
    return {
        "rms_amplitude_ratio": rms_l / rms_g if rms_g > 0 else float("nan"),
        "amplitude_w1": float(wasserstein_distance(a_l, a_g)),
        "frequency_w1": float(wasserstein_distance(fl, fg)) if len(fl) and len(fg) else float("nan"),
        "dominant_freq_learned": float(np.median(fl)) if len(fl) else float("nan"),
        "dominant_freq_gt": float(np.median(fg)) if len(fg) else float("nan"),
        "n_learned": int(len(a_l)),
        "n_gt": int(len(a_g)),
    }
