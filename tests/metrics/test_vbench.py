"""VBench temporal flickering and the dynamic-degree proxy (anigs.metrics.vbench)."""
from __future__ import annotations

import numpy as np
import pytest

from anigs.metrics.vbench import check_finite_clip, dynamic_degree_proxy, temporal_flickering, top_flow_magnitude, \
    vbench_metrics


def _texture(h: int, w: int, seed: int = 0) -> np.ndarray:
    """A smooth random texture [h,w,3] in [0,1] (flow has something to track)."""
    import cv2

    rng = np.random.default_rng(seed)
    return np.clip(cv2.GaussianBlur(rng.random((h, w, 3)).astype(np.float32), (0, 0), 2.0) * 3 - 1, 0, 1)


def _moving(shift_px: float, T: int = 25, h: int = 96, w: int = 128) -> np.ndarray:
    """A texture translating by ``shift_px`` per frame (integer steps via np.roll)."""
    base = _texture(h, w + int(shift_px * T) + 8)
    return np.stack([base[:, int(round(t * shift_px)):int(round(t * shift_px)) + w] for t in range(T)])


def test_flicker_of_a_still_clip_is_one_and_of_noise_lower():
    still = np.repeat(_texture(48, 64)[None], 10, axis=0)
    assert temporal_flickering(still) == 1.0
    noise = np.random.default_rng(0).random((10, 48, 64, 3)).astype(np.float32)
    f = temporal_flickering(noise)
    # uniform noise: E|a-b| = 1/3 of the range, so the score is about 2/3
    assert 0.6 < f < 0.7


def test_flicker_follows_vbench_formula():
    clip = np.zeros((3, 4, 4, 3), np.float32)
    clip[1] = 10 / 255  # pair 1: |diff| 10, pair 2: 10 -> mean 10
    assert temporal_flickering(clip) == pytest.approx((255 - 10) / 255)


def test_nan_frames_are_an_error_naming_the_clip():
    clip = np.zeros((5, 8, 8, 3), np.float32)
    clip[3, 2, 2, 1] = np.nan
    with pytest.raises(ValueError, match=r"clip 'v07'.*frames \[3\]"):
        temporal_flickering(clip, "v07")
    clip[3] = 0
    clip[1, 0, 0, 0] = np.inf
    with pytest.raises(ValueError, match="v07"):
        dynamic_degree_proxy(clip, 12, name="v07")
    with pytest.raises(ValueError, match="v07"):
        check_finite_clip(clip, "v07")


def test_dynamic_degree_proxy_moving_and_still():
    # threshold at 96 px short side, 8 fps: 6 * 96/256 = 2.25 px per sampled pair
    fast = dynamic_degree_proxy(_moving(4.0), fps=8.0)
    assert fast.dynamic and fast.threshold_px == pytest.approx(2.25) and fast.interval == 1
    assert min(fast.pair_scores) > 3.0  # DIS recovers the 4 px shift
    still = dynamic_degree_proxy(np.repeat(_texture(96, 128)[None], 25, axis=0), fps=8.0)
    assert not still.dynamic and max(still.pair_scores) < 0.05
    slow = dynamic_degree_proxy(_moving(1.0), fps=8.0)  # 1 px per frame: moving, but below VBench's threshold
    assert not slow.dynamic and 0.5 < np.median(slow.pair_scores) < 2.25


def test_dynamic_degree_proxy_sampling_follows_vbench():
    clip = _moving(1.0, T=25, h=192, w=256)
    d = dynamic_degree_proxy(clip, fps=12.0)
    # fps 12: every round(12/8) = 2nd frame -> 13 frames, 12 pairs; need round(4*13/16) = 3; 6 * 192/256 = 4.5 px
    assert d.interval == 2 and len(d.pair_scores) == 12 and d.count_needed == 3 and d.threshold_px == pytest.approx(4.5)
    assert np.median(d.pair_scores) == pytest.approx(2.0, abs=0.5)  # two frames apart: 2 px
    d4 = dynamic_degree_proxy(clip, fps=4.0)  # slow video: threshold doubles (factor 8/fps)
    assert d4.threshold_px == pytest.approx(9.0)


def test_top_flow_magnitude_is_the_top_five_percent_mean():
    flow = np.zeros((10, 20, 2), np.float32)
    flow.reshape(-1, 2)[:10, 0] = 3.0  # exactly 5% of 200 pixels at 3 px
    assert top_flow_magnitude(flow) == pytest.approx(3.0)


def test_vbench_records():
    clips = {"v00": np.repeat(_texture(48, 64)[None], 6, axis=0), "v01": _moving(4.0, T=6, h=48, w=64)}
    rec = vbench_metrics(clips, {"v00": 8.0, "v01": 8.0})
    f, d = rec["vbench/temporal_flickering"], rec["vbench/dynamic_degree_proxy"]
    assert f["available"] and f["per_view"]["v00"] == 1.0 and f["value"] < 1.0
    assert d["value"] == 0.5 and d["per_view"]["v01"]["dynamic"] and "PROXY" in d["protocol"]["definition"]
    assert d["samples"] == {"clips": 2, "frames": 12}
    top = rec["vbench/top5_flow_px"]["value"]
    assert top == pytest.approx(np.mean([np.mean(d["per_view"][v]["pair_scores"]) for v in clips]), abs=1e-3)
    assert top > 1.5  # half the clips move 4 px per frame
    empty = vbench_metrics({}, {})
    assert not empty["vbench/temporal_flickering"]["available"] and not empty["vbench/top5_flow_px"]["available"]
