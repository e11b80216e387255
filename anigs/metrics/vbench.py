"""Two of VBench's motion dimensions without network weights: temporal flickering and a
dynamic-degree proxy (Huang et al., VBench, CVPR 2024; definitions checked against
``vbench/temporal_flickering.py`` and ``vbench/dynamic_degree.py`` of Vchitect/VBench).

Temporal flickering (VBench's own formula, no network)
    Frames as uint8 (VBench reads decoded videos; here ``round(255 x)`` of the float clip),
    per clip the mean over consecutive pairs of the mean absolute difference over all pixels
    and channels, ``score = (255 - mean_abs_diff) / 255``; the dimension is the mean over clips.
    VBench applies it to static-camera videos only: every clip here is camera-fixed. A still
    clip scores 1.0; higher is better.

Dynamic degree, proxy (VBench's rule with OpenCV DIS flow instead of RAFT)
    Frames sampled every ``max(1, round(fps / 8))`` frames; for each consecutive pair of sampled
    frames the flow magnitude's top 5% (``int(0.05 H W)`` largest) are averaged; a clip is
    dynamic when at least ``round(4 n / 16)`` pairs (``n`` sampled frames) exceed
    ``max(1, 8 / fps) * 6 * min(H, W) / 256`` pixels. The dimension is the share of dynamic clips.
    RAFT is replaced by OpenCV DIS (``preset``): a proxy, labelled as such wherever it is written.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from anigs.flow import backward_flow
from anigs.metrics import metric_record, not_available

TOP_FRACTION = 0.05  # VBench: mean of the largest 5% flow magnitudes
BASE_THRESHOLD_PX = 6.0  # VBench: at 256 px short side and 8 fps
SAMPLE_FPS = 8.0  # VBench samples frames at about 8 fps


def check_finite_clip(clip: np.ndarray, name: str) -> np.ndarray:
    """The clip [T,H,W,3] as float32; NaN or Inf frames are an error naming the clip and the frames."""
    c = np.asarray(clip, dtype=np.float32)
    if c.ndim != 4 or c.shape[-1] != 3:
        raise ValueError(f"clip {name!r}: expected [T,H,W,3], got {c.shape}")
    bad = np.flatnonzero(~np.isfinite(c).reshape(c.shape[0], -1).all(axis=1))
    if bad.size:
        raise ValueError(f"clip {name!r}: frames {bad[:10].tolist()} contain NaN or Inf "
                         f"({bad.size} of {c.shape[0]} frames)")
    return c


def _uint8(clip: np.ndarray) -> np.ndarray:
    return (np.clip(clip, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


def temporal_flickering(clip: np.ndarray, name: str = "clip") -> float:
    """VBench temporal-flickering score of one clip [T,H,W,3] in [0,1] (1.0 = no change at all)."""
    u = _uint8(check_finite_clip(clip, name)).astype(np.float32)
    if u.shape[0] < 2:
        raise ValueError(f"clip {name!r}: temporal flickering needs at least 2 frames, got {u.shape[0]}")
    mae = np.abs(u[1:] - u[:-1]).reshape(u.shape[0] - 1, -1).mean(axis=1)  # [T-1] per pair
    return float((255.0 - mae.mean()) / 255.0)


@dataclass
class DynamicDegree:
    """One clip's dynamic-degree decision and the figures behind it."""

    dynamic: bool
    pair_scores: list[float]  # top-5% mean flow magnitude (px) per sampled pair
    threshold_px: float
    count_needed: int
    interval: int

    def to_dict(self) -> dict[str, Any]:
        return {"dynamic": self.dynamic, "pair_scores": [round(s, 4) for s in self.pair_scores],
                "threshold_px": self.threshold_px, "count_needed": self.count_needed, "interval": self.interval,
                "pairs_over": int(sum(s > self.threshold_px for s in self.pair_scores))}


def top_flow_magnitude(flow: np.ndarray) -> float:
    """Mean of the largest ``TOP_FRACTION`` of the flow magnitudes [H,W,2] (VBench's per-pair score)."""
    rad = np.sqrt((flow.astype(np.float64) ** 2).sum(-1)).ravel()
    k = int(rad.size * TOP_FRACTION)
    if k < 1:
        raise ValueError(f"top_flow_magnitude: {rad.size} pixels are too few for the top {TOP_FRACTION:.0%}")
    return float(np.partition(rad, rad.size - k)[rad.size - k:].mean())


def dynamic_degree_proxy(clip: np.ndarray, fps: float, preset: str = "medium", name: str = "clip") -> DynamicDegree:
    """VBench's dynamic-degree rule on one camera-fixed clip [T,H,W,3], OpenCV DIS flow in place of RAFT."""
    c = check_finite_clip(clip, name)
    if fps <= 0:
        raise ValueError(f"clip {name!r}: fps must be > 0, got {fps}")
    interval = max(1, round(fps / SAMPLE_FPS))
    frames = c[::interval]
    if frames.shape[0] < 2:
        raise ValueError(f"clip {name!r}: {c.shape[0]} frames at interval {interval} leave fewer than 2 to compare")
    thres = max(1.0, SAMPLE_FPS / fps) * BASE_THRESHOLD_PX * min(c.shape[1], c.shape[2]) / 256.0
    need = round(4 * frames.shape[0] / 16.0)
    # flow from each sampled frame to the next (magnitudes: direction does not matter)
    scores = [top_flow_magnitude(backward_flow(frames[i], frames[i + 1], preset)) for i in range(frames.shape[0] - 1)]
    over = sum(s > thres for s in scores)
    return DynamicDegree(bool(over >= need), scores, float(thres), int(need), int(interval))


def vbench_metrics(clips: Mapping[str, np.ndarray], fps: Mapping[str, float], preset: str = "medium") -> dict[str, Any]:
    """``vbench/temporal_flickering``, ``vbench/dynamic_degree_proxy`` and its continuous score
    ``vbench/top5_flow_px`` over camera-fixed clips."""
    p_flick = {"definition": "VBench temporal flickering: per clip (255 - mean over consecutive frame pairs of the "
                             "mean |I_t+1 - I_t| over pixels and channels, uint8) / 255; mean over clips",
               "input": "camera-fixed clips (static camera, as VBench requires)"}
    p_dyn = {"definition": "PROXY of VBench dynamic degree: share of clips where at least round(4 n/16) of the pairs "
                           "of frames sampled every max(1, round(fps/8)) frames have a top-5% mean flow magnitude "
                           "above max(1, 8/fps) * 6 * min(H,W)/256 px",
             "flow": f"OpenCV DIS {preset} (VBench uses RAFT: this is a proxy, not VBench's score)"}
    p_top = dict(p_dyn, definition="the proxy's per-pair score (mean of the largest 5% flow magnitudes between frames "
                                   "sampled every max(1, round(fps/8)) frames), averaged over pairs and clips: the "
                                   "continuous quantity the dynamic-degree threshold cuts")
    if not clips:
        reason = "no rendered clips given (--final-dir / --clips)"
        return {"vbench/temporal_flickering": not_available(reason, True, "score", p_flick),
                "vbench/dynamic_degree_proxy": not_available(reason, True, "share of clips", p_dyn),
                "vbench/top5_flow_px": not_available(reason, True, "px per sampled pair", p_top)}
    flick = {v: temporal_flickering(c, v) for v, c in clips.items()}
    dyn = {v: dynamic_degree_proxy(c, fps[v], preset, v) for v, c in clips.items()}
    samples = {"clips": len(clips), "frames": int(sum(c.shape[0] for c in clips.values()))}
    return {
        "vbench/temporal_flickering": metric_record(float(np.mean(list(flick.values()))), True, "score", p_flick,
                                                    samples, per_view=flick),
        "vbench/dynamic_degree_proxy": metric_record(float(np.mean([d.dynamic for d in dyn.values()])), True,
                                                     "share of clips", p_dyn, samples,
                                                     per_view={v: d.to_dict() for v, d in dyn.items()}),
        "vbench/top5_flow_px": metric_record(float(np.mean([np.mean(d.pair_scores) for d in dyn.values()])), True,
                                             "px per sampled pair", p_top, samples,
                                             threshold_px={v: d.threshold_px for v, d in dyn.items()}),
    }
