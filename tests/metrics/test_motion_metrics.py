"""Weight-free motion metrics on clips with known motion, and GT motion statistic distances."""
from __future__ import annotations

import numpy as np
import pytest

from anigs.metrics.motion import (clip_motion_metrics, dominant_frequency, gt_motion_distances, optical_flow_magnitudes,
                                  resize_mask, temporal_spectrum, trajectory_stats)
from anigs.pixels import dilate

T, H, W = 32, 48, 64
FREQ = 0.125  # cycles per frame (4 periods in 32 frames: an exact FFT bin)
WAVELEN = 16.0  # px -> flow = WAVELEN * FREQ = 2 px/frame


def _texture(seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    import cv2

    tex = rng.uniform(0, 1, (H // 4, W // 4, 3)).astype(np.float32)
    return cv2.resize(tex, (W, H), interpolation=cv2.INTER_CUBIC).clip(0, 1)


def make_clip(static_noise: float = 0.0, static_shift: float = 0.0, seed: int = 0):
    """Static textured background; the right half is a travelling sine wave (known freq & speed)."""
    rng = np.random.default_rng(seed)
    bg = _texture(seed)
    mask = np.zeros((H, W), bool)
    mask[:, W // 2:] = True
    x = np.arange(W, dtype=np.float32)
    clip = np.empty((T, H, W, 3), np.float32)
    for t in range(T):
        frame = bg.copy()
        if static_shift:
            frame = np.roll(bg, int(round(static_shift * t)), axis=1)
        frame = frame + static_noise * rng.normal(size=frame.shape).astype(np.float32)
        wave = 0.5 + 0.35 * np.sin(2 * np.pi * (x / WAVELEN - FREQ * t))
        frame[:, W // 2:] = wave[None, W // 2:, None] * np.array([0.3, 1.0, 0.4], np.float32)
        clip[t] = frame.clip(0, 1)
    return clip, mask


def test_known_motion_is_measured():
    clip, mask = make_clip()
    m = clip_motion_metrics(clip, mask, margin=2)
    assert m.static_abs_diff == 0.0 and m.static_drift == 0.0
    assert m.static_flow < 0.05
    assert m.dominant_freq == pytest.approx(FREQ, abs=1.0 / T)
    assert m.dynamic_flow == pytest.approx(WAVELEN * FREQ, rel=0.25)
    assert m.dynamic_abs_diff > 0.05
    assert m.static_pixels + m.dynamic_pixels < H * W  # the margin band belongs to neither
    assert m.frames == T


def test_static_leakage_ranks_clips():
    still, mask = make_clip()
    noisy, _ = make_clip(static_noise=0.03)
    drifting, _ = make_clip(static_shift=0.5)
    a, b, c = (clip_motion_metrics(x, mask) for x in (still, noisy, drifting))
    assert a.static_abs_diff < b.static_abs_diff
    assert a.static_abs_diff < c.static_abs_diff and a.static_drift < c.static_drift
    assert c.static_flow > 0.2 > a.static_flow  # 0.5 px/frame drift is seen by the flow
    # the dynamic region is identical in all three
    assert b.dominant_freq == a.dominant_freq == c.dominant_freq


def test_frozen_clip_and_empty_regions():
    clip = np.repeat(_texture()[None], 8, axis=0)
    m = clip_motion_metrics(clip, np.zeros((H, W), bool))
    assert m.static_abs_diff == 0.0 and np.isnan(m.dynamic_abs_diff) and np.isnan(m.dominant_freq)
    m = clip_motion_metrics(clip[:1], np.ones((H, W), bool), with_flow=True)
    assert np.isnan(m.static_abs_diff) and np.isnan(m.dynamic_abs_diff)


def test_spectrum_helpers_and_errors():
    clip, mask = make_clip()
    f, p = temporal_spectrum(clip, mask)
    assert f[np.argmax(p[1:]) + 1] == pytest.approx(FREQ)
    assert np.isnan(dominant_frequency(f, np.zeros_like(p))[0])
    with pytest.raises(ValueError, match="does not match"):
        clip_motion_metrics(clip, mask[:10])
    with pytest.raises(ValueError, match="preset"):
        optical_flow_magnitudes(clip, preset="slowest")
    assert optical_flow_magnitudes(clip[:3]).shape == (2, H, W)


def test_mask_helpers():
    m = np.zeros((10, 10), bool)
    m[5, 5] = True
    assert dilate(m, 1).sum() == 9 and dilate(m, 0).sum() == 1
    soft = np.zeros((20, 20), np.uint8)
    soft[:, 10:] = 255
    r = resize_mask(soft, 10, 10)
    assert r.shape == (10, 10) and r[:, 5:].all() and not r[:, :5].any()


def _trajectories(n: int, amp: float, freq: float, T: int = 48, seed: int = 0, scale: float = 1.0):
    rng = np.random.default_rng(seed)
    anchors = rng.uniform(-1, 1, (n, 3))
    a = amp * rng.uniform(0.5, 1.5, n)
    phase = rng.uniform(0, 2 * np.pi, n)
    t = np.arange(T)
    disp = a[:, None] * np.sin(2 * np.pi * freq * t[None] + phase[:, None])
    pos = np.repeat(anchors[:, None], T, axis=1)
    pos[..., 0] += disp
    return pos * scale


def test_trajectory_stats_known_sines():
    T_, A = 48, 0.1
    t = np.arange(T_)
    phase = np.random.default_rng(3).uniform(0, 2 * np.pi, 20)
    pos = np.zeros((20, T_, 3))
    pos[..., 2] = A * np.sin(2 * np.pi * 0.125 * t[None] + phase[:, None])  # 6 whole periods
    amp, freq = trajectory_stats(pos + 5.0, extent=2.0)
    np.testing.assert_allclose(amp, A / np.sqrt(2) / 2.0, rtol=1e-9)  # RMS of a sine = A / sqrt(2)
    np.testing.assert_allclose(freq, 0.125)
    assert np.isnan(trajectory_stats(np.zeros((3, T_, 3)))[1]).all()  # no motion: no frequency
    with pytest.raises(ValueError, match="extent"):
        trajectory_stats(pos, extent=0)
    with pytest.raises(ValueError, match=r"\[N,T,3\]"):
        trajectory_stats(pos[..., :2])


def test_gt_distances_are_scale_free_and_discriminative():
    gt = _trajectories(300, 0.1, 0.125, seed=1)
    same_scaled = _trajectories(250, 0.1, 0.125, seed=2, scale=3.0)  # SfM frame: 3x larger units
    d = gt_motion_distances(same_scaled, gt, learned_extent=3.0, gt_extent=1.0)
    assert d["rms_amplitude_ratio"] == pytest.approx(1.0, abs=0.1)
    weak = gt_motion_distances(_trajectories(250, 0.05, 0.125, seed=2), gt)
    assert weak["rms_amplitude_ratio"] == pytest.approx(0.5, abs=0.07)
    assert weak["amplitude_w1"] > 3 * d["amplitude_w1"]
    fast = gt_motion_distances(_trajectories(250, 0.1, 0.25, seed=2), gt)
    assert fast["frequency_w1"] > 0.08 > d["frequency_w1"]
    assert fast["dominant_freq_learned"] == pytest.approx(0.25, abs=1 / 48)
    assert d["n_learned"] == 250 and d["n_gt"] == 300
    with pytest.raises(ValueError, match="empty"):
        gt_motion_distances(np.zeros((0, 48, 3)), gt)


def test_eval_gt_glue_with_synthetic_truth_and_dct_model(tmp_path):
    """gt_metrics: GT offsets of anigs.synth vs a DCT model fitted to them (ratio ~1) or halved (~0.5)."""
    torch = pytest.importorskip("torch")
    motion = pytest.importorskip("anigs.synth.motion", reason="anigs.synth (GT motion) not in this checkout")
    deform = pytest.importorskip("anigs.animate.deform", reason="anigs.animate.deform (DCT model) not in this checkout")
    from anigs.cameras import Camera, intrinsics_from_fov, look_at
    from anigs.metrics.suite import gt_metrics
    from anigs.stages.capture import Outputs as CaptureOutputs
    from anigs.gaussians import Gaussians
    from anigs.synth import LABEL_IDS
    from tests._gt import write_gt

    rng = np.random.default_rng(0)
    n_dyn, n_static = 120, 60
    anchors = np.concatenate([rng.uniform(-1, 1, (n_dyn, 3)) * [1, 1, 0], rng.uniform(-1, 1, (n_static, 3))])
    means = anchors + np.concatenate([rng.uniform(0.2, 1.0, (n_dyn, 3)) * [0.3, 0.3, 1.5], np.zeros((n_static, 3))])
    labels = np.array([LABEL_IDS["foliage"]] * n_dyn + [LABEL_IDS["ground"]] * n_static)
    gs = Gaussians.from_points(torch.tensor(means, dtype=torch.float32), torch.full((len(means), 3), 0.5))
    params = motion.MotionParams()
    cams = [Camera(intrinsics_from_fov(60, 32, 24), look_at((4 * np.cos(a), 4 * np.sin(a), 2), (0, 0, 0)), 32, 24, f"c{i}")
            for i, a in enumerate(np.linspace(0, 2 * np.pi, 6, endpoint=False))]
    gt = CaptureOutputs.from_gt(write_gt(tmp_path, gs, labels, {"params": params.to_dict()}, cams, anchors=anchors))

    T = params.frames
    off = motion.gt_clip_offsets(params, gs.means, torch.tensor(anchors, dtype=torch.float32),
                                 torch.tensor(labels).long())  # [T,N,3]
    dyn = torch.arange(n_dyn)
    K = T - 1
    B = deform.dct_basis(torch.arange(T, dtype=torch.float64), T, K).float()  # [T,K]
    coeffs = torch.linalg.lstsq(B, off[:, :n_dyn].reshape(T, -1)).solution  # [K, D*3]
    ply = tmp_path / "canonical.ply"
    gs.save_ply(ply)
    out = {}
    for tag, scale in (("fit", 1.0), ("half", 0.5)):
        d = deform.DCTDeformation(dyn, T, K, rotation=False, num_gaussians=gs.num)
        with torch.no_grad():
            d.pos_coeffs.copy_(scale * coeffs.T.reshape(n_dyn, 3, K))
        deform.save_model(tmp_path / f"{tag}.pt", d, gs)
        out[tag] = gt_metrics(tmp_path / f"{tag}.pt", ply, gt, tmp_path / "cameras.json")
    fit, half = out["fit"], out["half"]
    assert fit["gt/rms_amplitude_ratio"]["value"] == pytest.approx(1.0, abs=0.02)
    assert half["gt/rms_amplitude_ratio"]["value"] == pytest.approx(0.5, abs=0.02)
    assert fit["gt/amplitude_w1"]["value"] < 0.2 * half["gt/amplitude_w1"]["value"]
    assert fit["gt/frequency_w1"]["value"] < 1e-6
    assert fit["gt/rms_amplitude_ratio"]["samples"]["gt_gaussians"] == n_dyn
    # inputs missing -> not available, with the reason
    na = gt_metrics(None, None, gt, None)
    assert not na["gt/amplitude_w1"]["available"] and "--model" in na["gt/amplitude_w1"]["reason"]


def test_outside_mask_still_counts_pixels_that_never_change():
    """The issue's stillness measure: outside the dynamic mask dilated by 5 px, the share of pixels
    whose change from frame 0 stays within 1/255 over the whole clip."""
    from anigs.metrics.motion import outside_mask_still

    T, H, W = 6, 40, 50
    rng = np.random.default_rng(0)
    clip = np.repeat(rng.uniform(0.2, 0.8, (1, H, W, 3)).astype(np.float32), T, 0)
    mask = np.zeros((H, W), bool)
    mask[10:20, 10:20] = True
    clip[:, 10:20, 10:20] += np.linspace(0, 0.2, T)[:, None, None, None]  # the dynamic region moves
    clip[:, 12:18, 21:24] += np.linspace(0, 0.1, T)[:, None, None, None]  # a halo within the 5 px margin
    assert outside_mask_still(clip, mask) == 1.0
    outside = (~np.pad(np.ones((20, 20), bool), ((5, 15), (5, 25)))).sum()  # pixels beyond the dilated mask
    clip[3, 35, 40, 1] += 2 / 255  # one pixel flickers by 2 levels in one frame
    clip[:, 0, 0, :] += np.array([0, 1, 0, 1, 0, 1], np.float32)[:, None] / 255  # one by exactly 1 level: still
    assert outside_mask_still(clip, mask) == pytest.approx(1 - 1 / outside)
    assert outside_mask_still(clip, mask, tolerance=3 / 255) == 1.0
    assert np.isnan(outside_mask_still(clip, np.ones((H, W), bool)))
