"""Procedural spectral motion prior: spectra, masks, smoothness, strength, edge cases."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from anigs.flow import backward_flow, field_gradient_max, warp
from anigs.refine.prior import get_prior
from anigs.refine.prior.procedural import ProceduralConfig, ProceduralPrior
from anigs.refine.prior.spectral import EFFECTS, effect_spec

H, W = 64, 80


def textured_frame(h=H, w=W, seed=0):
    rng = np.random.default_rng(seed)
    img = rng.random((h, w, 3)).astype(np.float32)
    return cv2.GaussianBlur(img, (0, 0), 1.2)


def box_mask(h=H, w=W):
    m = np.zeros((h, w), np.float32)
    m[10:54, 15:65] = 1
    return m


@pytest.mark.parametrize("effect", sorted(EFFECTS))
def test_temporal_spectrum_peaks_in_band(effect):
    fps, T = 24.0, 240  # 10 s: 0.1 Hz frequency resolution
    prior = ProceduralPrior({"effects": [effect], "fps": fps})
    mask = box_mask()
    seq = prior.motion_field({effect: mask}, H, W, seed=3).sequence(T)  # [T,H,W,2]
    sig = seq[:, mask > 0.5].reshape(T, -1)
    sig = sig - sig.mean(0)
    spec = (np.abs(np.fft.rfft(sig * np.hanning(T)[:, None], axis=0)) ** 2).sum(1)
    freqs = np.fft.rfftfreq(T, 1 / fps)
    lo, hi = EFFECTS[effect].band_hz
    assert lo - 0.1 <= freqs[spec.argmax()] <= hi + 0.1   # peak inside the band (+- one frequency bin)
    inband = (freqs >= lo - 0.2) & (freqs <= hi + 0.2)
    assert spec[inband].sum() / spec.sum() > 0.9


@pytest.mark.parametrize("effect", sorted(EFFECTS))
def test_zero_outside_mask_and_no_tearing(effect):
    prior = ProceduralPrior({"effects": [effect]})
    mask = box_mask()
    for seed in (0, 1):
        seq = prior.motion_field({effect: mask}, H, W, seed=seed).sequence(49)
        assert np.all(seq[:, mask == 0] == 0)
        assert np.abs(seq).max() > 0.05                     # it does move
        assert np.all(seq[0] == 0)                          # frame 0 is the canonical frame
        assert field_gradient_max(seq) < 0.8                # no fold-over: warp stays one-to-one
        # temporally smooth too: frame-to-frame change well below a pixel
        assert np.abs(np.diff(seq, axis=0)).max() < 1.0


def test_refine_leaves_static_pixels_and_frame0():
    prior = ProceduralPrior({"effects": ["foliage_sway", "leaf_flutter"]})
    clip = np.repeat(textured_frame()[None], 25, 0)
    clip[:, :, :5] += 0.05 * np.random.default_rng(0).random((25, H, 5, 3)).astype(np.float32)  # static flicker
    clip = np.clip(clip, 0, 1)
    mask = box_mask()
    out = prior.refine(clip, mask, "trees in wind", seed=1, strength=1.0)
    assert out.shape == clip.shape and out.dtype == np.float32
    assert np.array_equal(out[:, mask == 0], clip[:, mask == 0])
    assert np.array_equal(out[0], clip[0])
    assert np.abs(out[:, mask > 0] - clip[:, mask > 0]).mean() > 1e-3


def test_anchor_profile_grows_upwards():
    prior = ProceduralPrior({"effects": ["foliage_sway"]})
    mask = box_mask()
    seq = prior.motion_field({"foliage_sway": mask}, H, W, seed=0).sequence(96)
    rms = np.sqrt((seq ** 2).mean(axis=(0, 3)))
    top, bottom = rms[20:25, 30:50].mean(), rms[46:50, 30:50].mean()
    assert top > 2.0 * bottom


@pytest.mark.parametrize("wind", [0.0, 180.0])
def test_grass_wave_travels_with_the_wind(wind):
    prior = ProceduralPrior({"effects": ["grass_wave"],
                             "effect_params": {"grass_wave": {"wind_dir_deg": wind, "axis_weights": [1.0, 0.0]}}})
    mask = np.ones((H, W), np.float32)
    seq = prior.motion_field({"grass_wave": mask}, H, W, seed=2).sequence(240)[..., 0]  # x component
    a, b = seq[:, 10:54, 20:50], seq[:, 10:54, 26:56]   # b is 6 px further along +x
    a = a - a.mean(0)
    b = b - b.mean(0)
    lags = np.arange(-10, 11)
    corr = [np.mean(a[max(0, -l):240 - max(0, l)] * b[max(0, l):240 - max(0, -l)]) for l in lags]
    best = lags[int(np.argmax(corr))]
    # b(t + lag) ~ a(t): downwind points repeat the motion later
    assert (best > 0) if wind == 0.0 else (best < 0)


def test_strength_zero_reproduces_input_motion():
    frame = textured_frame()
    mask = box_mask()
    src = ProceduralPrior({"effects": ["foliage_sway"], "amplitude_scale": 4.0}).generate(frame, mask, "", 5, 13)
    prior = ProceduralPrior({"effects": ["foliage_sway", "leaf_flutter"]})
    keep = prior.refine(src, mask, "", seed=9, strength=0.0)
    new = prior.refine(src, mask, "", seed=9, strength=1.0)
    inside = mask > 0.5
    err_keep = np.abs(keep[:, inside] - src[:, inside]).mean()
    err_new = np.abs(new[:, inside] - src[:, inside]).mean()
    assert err_keep < 0.01 and err_keep < 0.35 * err_new
    # the motion itself: flow of the result matches the flow of the input (px)
    f_src, f_keep = backward_flow(src[-1], src[0]), backward_flow(keep[-1], keep[0])
    core = cv2.erode(mask, np.ones((9, 9))) > 0.5
    assert np.abs(f_src[core] - f_keep[core]).mean() < 0.3 * max(np.abs(f_src[core]).mean(), 1e-3) + 0.05


def test_deterministic_and_seed_dependent():
    prior = ProceduralPrior()
    frame, mask = textured_frame(), box_mask()
    a = prior.generate(frame, mask, "", 7, 9)
    b = prior.generate(frame, mask, "", 7, 9)
    c = prior.generate(frame, mask, "", 8, 9)
    assert np.array_equal(a, b)
    assert np.abs(a - c).mean() > 1e-4
    # with a flow estimate in the loop (strength < 1) too
    assert np.array_equal(prior.refine(c, mask, "", 1, 0.5), prior.refine(c, mask, "", 1, 0.5))


def test_one_frame_and_empty_and_full_masks():
    prior = ProceduralPrior()
    frame = textured_frame()
    one = frame[None]
    assert np.array_equal(prior.refine(one, box_mask(), "", 0, 1.0), one)
    clip = np.repeat(frame[None], 9, 0)
    assert np.array_equal(prior.refine(clip, np.zeros((H, W)), "", 0, 1.0), clip)
    full = prior.refine(clip, np.ones((H, W)), "", 0, 1.0)
    assert np.isfinite(full).all() and np.array_equal(full[0], clip[0])
    assert np.abs(full[-1] - clip[-1]).mean() > 1e-3
    assert prior.generate(frame, box_mask(), "", 0, 1).shape == (1, H, W, 3)


def test_effect_masks_only_configured_effects_move():
    prior = ProceduralPrior({"effects": ["foliage_sway"]})
    m1 = np.zeros((H, W), np.float32)
    m1[5:30, 10:70] = 1
    m2 = np.zeros((H, W), np.float32)
    m2[40:60, 10:70] = 1
    clip = np.repeat(textured_frame()[None], 9, 0)
    out = prior.refine(clip, {"foliage_sway": m1, "grass_wave": m2}, "", 0, 1.0)
    assert np.array_equal(out[:, m2 > 0], clip[:, m2 > 0])
    assert np.abs(out[:, m1 > 0] - clip[:, m1 > 0]).mean() > 1e-3


def test_config_and_input_errors():
    with pytest.raises(ValueError, match="unknown key"):
        ProceduralConfig.from_dict({"amplitude": 2})
    with pytest.raises(ValueError, match="unknown effect"):
        ProceduralConfig.from_dict({"effects": ["tornado"]})
    with pytest.raises(ValueError, match="unknown key"):
        effect_spec("foliage_sway", {"speed": 1})
    prior = get_prior("procedural")
    clip = np.zeros((3, H, W, 3), np.float32)
    with pytest.raises(ValueError, match="does not match"):
        prior.refine(clip, np.ones((H + 1, W)), "", 0, 0.5)
    with pytest.raises(ValueError, match="strength"):
        prior.refine(clip, np.ones((H, W)), "", 0, 1.5)
    with pytest.raises(ValueError, match="NaN"):
        prior.refine(clip * np.nan, np.ones((H, W)), "", 0, 0.5)
    with pytest.raises(ValueError, match="unknown video prior"):
        get_prior("sora")


def test_warp_identity_is_exact():
    frame = textured_frame()
    assert np.array_equal(warp(frame, np.zeros((H, W, 2), np.float32)), frame)


# ---- diffusion-prior flaws (issue 18): off by default, each one does what it says -------------------
def grey_textured(h=H, w=W, seed=0):
    """Mid-grey texture (no clipping at 0/1 for intensity noise)."""
    return 0.3 + 0.4 * textured_frame(h, w, seed)


def test_flaws_are_off_by_default_and_validated():
    from anigs.refine.prior.procedural import FLAW_KEYS

    cfg = ProceduralConfig()
    assert not cfg.flaws_on and all(getattr(cfg, k) == 0 for k in FLAW_KEYS)
    prior = ProceduralPrior()
    clip = np.repeat(grey_textured()[None], 9, 0)
    prior.refine(clip, box_mask(), "", 3, 0.5)
    assert "flaws" not in prior.last_info
    for k in FLAW_KEYS:
        with pytest.raises(ValueError, match=k):
            ProceduralConfig.from_dict({k: -0.1})
    with pytest.raises(ValueError, match="shimmer_corr_px"):
        ProceduralConfig.from_dict({"shimmer_corr_px": 0})


def test_static_shimmer_magnitude_and_only_static_pixels():
    sigma, T = 0.0125, 9
    clip = np.repeat(grey_textured()[None], T, 0)
    mask = box_mask()
    clean = ProceduralPrior().refine(clip, mask, "", 4, 0.5)
    out = ProceduralPrior({"static_shimmer": sigma}).refine(clip, mask, "", 4, 0.5)
    static = mask == 0
    assert np.array_equal(out[0], clip[0])                      # frame 0 stays the canonical frame
    assert np.array_equal(out[:, ~static], clean[:, ~static])   # the dynamic region is untouched
    mad = np.abs(np.diff(out[:, static], axis=0)).mean()
    assert mad == pytest.approx(2 * sigma / np.sqrt(np.pi), rel=0.2)   # the stated VBench-style figure


def test_static_drift_grows_to_the_configured_rms():
    T, drift = 9, 1.0
    clip = np.repeat(grey_textured(96, 128, 1)[None], T, 0)
    mask = np.zeros((96, 128), np.float32)
    mask[30:60, 40:80] = 1
    out = ProceduralPrior({"static_drift_px": drift}).refine(clip, mask, "", 2, 0.5)
    core = cv2.erode((mask == 0).astype(np.uint8), np.ones((15, 15))) > 0
    core[:8], core[-8:], core[:, :8], core[:, -8:] = False, False, False, False
    rms = [float(np.sqrt((backward_flow(out[t], out[0])[core] ** 2).sum(-1).mean())) for t in (T // 2, T - 1)]
    assert rms[1] == pytest.approx(drift, rel=0.3)
    assert rms[0] == pytest.approx(drift * (T // 2) / (T - 1), rel=0.35)


def test_per_view_gain_and_direction_of_the_kept_motion():
    """strength 0 keeps the clip's motion; the flaws scale and rotate it by the view's draw."""
    frame, mask = grey_textured(), box_mask()
    src = ProceduralPrior({"effects": ["foliage_sway"], "amplitude_scale": 4.0}).generate(frame, mask, "", 5, 13)
    prior = ProceduralPrior({"view_amplitude_log": 0.3, "view_direction_deg": 40.0})
    draws = []
    for seed in (1, 2):
        out = prior.refine(src, mask, "", seed, 0.0)
        f = prior.last_info["flaws"]
        draws.append((f["gain"], f["angle_deg"]))
        core = cv2.erode(mask, np.ones((11, 11))) > 0
        d_src = backward_flow(src[-1], src[0])[core]
        d_out = backward_flow(out[-1], out[0])[core]
        a = np.deg2rad(f["angle_deg"])
        rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
        want = f["gain"] * d_src @ rot.T
        assert np.abs(d_out - want).mean() < 0.3 * np.abs(want).mean() + 0.05
    assert draws[0] != draws[1]                      # each view (seed) draws its own flaw
    again = prior.refine(src, mask, "", 1, 0.0)
    assert prior.last_info["flaws"]["gain"] == draws[0][0]  # deterministic per seed
    assert np.isfinite(again).all()


def test_time_shift_of_the_kept_motion():
    from anigs.refine.prior.procedural import time_shifted

    T = 7
    est = np.zeros((T, 2, 3, 2), np.float32)
    est[..., 0] = np.arange(T, dtype=np.float32)[:, None, None] ** 2      # d(t) = t^2 in x
    sh = time_shifted(est, 1.5)
    assert np.all(sh[0] == 0)
    t = 2
    assert sh[t, 0, 0, 0] == pytest.approx((t + 1.5) ** 2 - 1.5 ** 2, abs=0.3)  # linear interpolation of t^2
    assert np.array_equal(time_shifted(est, 0.0), est)
    assert np.all(np.isfinite(time_shifted(est, 100.0)))                         # clamped past the end
