"""ComposedV2V: the paper's composition, static re-paste, empty masks, the ablation switch."""
from __future__ import annotations

import numpy as np
import pytest

from anigs.refine.compose import ComposeConfig, compose, composed_v2v, soft_mask
from anigs.refine.prior.base import VideoPrior
from anigs.refine.prior.procedural import ProceduralPrior

T, H, W = 7, 32, 40


class RecordingPrior(VideoPrior):
    """Adds seeded noise everywhere (like a diffusion model touching every pixel); records its input."""

    name = "recording"

    def __init__(self):
        self.inputs = []

    def refine(self, clip, mask, prompt, seed, strength):
        self.inputs.append(clip.copy())
        noise = np.random.default_rng(seed).normal(0, 0.05, clip.shape).astype(np.float32)
        return np.clip(clip + strength * noise, 0, 1)

    def generate(self, first_frame, mask, prompt, seed, num_frames):
        return np.repeat(first_frame[None], num_frames, 0)


def flickering_clip(seed=0):
    rng = np.random.default_rng(seed)
    return rng.random((T, H, W, 3)).astype(np.float32)  # every pixel changes every frame


def mask_box():
    m = np.zeros((H, W), np.float32)
    m[8:24, 10:30] = 1
    return m


def test_compose_is_the_paper_equation():
    clip, m = flickering_clip(), mask_box()
    out = compose(clip, m)
    for t in range(T):
        np.testing.assert_array_equal(out[t], (1 - m)[..., None] * clip[0] + m[..., None] * clip[t])
    assert np.array_equal(out[:, m == 0], np.broadcast_to(clip[0][m == 0], out[:, m == 0].shape))
    assert np.array_equal(out[:, m == 1], clip[:, m == 1])


@pytest.mark.parametrize("feather", [0.0, 4.0])
def test_static_pixels_bit_exact_after_refinement(feather):
    clip, m = flickering_clip(), mask_box()
    prior = RecordingPrior()
    out, info = composed_v2v(prior, clip, m, "trees", 3, 0.8, ComposeConfig(feather_px=feather))
    static = m == 0
    for t in range(T):
        assert np.array_equal(out[t][static], clip[0][static])
    assert info["static_max_change"] == 0.0 and info["skipped"] is None
    assert np.abs(out[:, m == 1] - clip[:, m == 1]).mean() > 0.01   # the dynamic region was refined
    # the prior saw the composed clip: static region frozen at frame 0
    seen = prior.inputs[0]
    assert np.array_equal(seen[:, static], np.broadcast_to(clip[0][static], seen[:, static].shape))


def test_without_repaste_static_pixels_change():
    clip, m = flickering_clip(), mask_box()
    out, _ = composed_v2v(RecordingPrior(), clip, m, "", 3, 0.8, ComposeConfig(repaste_static=False))
    assert np.abs(out[:, m == 0] - clip[0][m == 0]).max() > 0.01


def test_ablation_refines_the_raw_clip():
    clip, m = flickering_clip(), mask_box()
    prior = RecordingPrior()
    composed_v2v(prior, clip, m, "", 1, 0.5, ComposeConfig(compose=False))
    assert np.array_equal(prior.inputs[0], clip)


def test_empty_mask_passes_through(caplog):
    clip = flickering_clip()
    prior = RecordingPrior()
    with caplog.at_level("INFO"):
        out, info = composed_v2v(prior, clip, np.zeros((H, W)), "", 0, 1.0)
    assert np.array_equal(out, clip) and not prior.inputs
    assert info["skipped"] == "empty mask" and "skipped" in caplog.text


def test_soft_mask_feathers_inwards_only():
    m = mask_box()
    s = soft_mask(m, 4.0)
    assert np.all(s[m == 0] == 0) and s.max() == 1.0
    assert 0 < s[8, 20] < 1 and s[16, 20] == 1.0        # edge row soft, centre full
    assert np.array_equal(soft_mask(m, 0.0), m)
    assert np.all(soft_mask(np.ones((H, W)), 3.0) == 1.0)  # the image border is not an edge


def test_per_effect_masks_and_procedural_prior():
    clip = np.repeat(flickering_clip()[:1], T, 0)
    m1, m2 = np.zeros((H, W), np.float32), np.zeros((H, W), np.float32)
    m1[2:14, 5:35] = 1
    m2[18:30, 5:35] = 1
    prior = ProceduralPrior({"effects": ["foliage_sway", "grass_wave"]})
    out, info = composed_v2v(prior, clip, {"foliage_sway": m1, "grass_wave": m2}, "", 0, 1.0)
    assert np.isclose(info["mask_fraction"], (m1 + m2).mean())
    static = (m1 + m2) == 0
    assert np.array_equal(out[:, static], clip[:, static])
    assert np.array_equal(out[0], clip[0])


def test_errors():
    clip = flickering_clip()
    with pytest.raises(ValueError, match="does not match"):
        composed_v2v(RecordingPrior(), clip, np.ones((H, W + 2)), "", 0, 0.5)
    with pytest.raises(ValueError, match="unknown key"):
        ComposeConfig.from_dict({"feather": 2})
    with pytest.raises(ValueError, match="strength"):
        composed_v2v(RecordingPrior(), clip, mask_box(), "", 0, -0.1)


def test_dilation_grows_the_dynamic_region():
    clip, m = flickering_clip(), mask_box()
    prior = RecordingPrior()
    out, info = composed_v2v(prior, clip, m, "", 2, 0.8, ComposeConfig(dilate_px=2))
    assert info["mask_fraction"] > m.mean()
    assert np.abs(out[:, 6, 20] - clip[0, 6, 20]).max() > 0        # 2 px above the box: now dynamic
    assert np.array_equal(out[:, 5, 20], np.broadcast_to(clip[0, 5, 20], out[:, 5, 20].shape))  # 3 px: static
    with pytest.raises(ValueError, match="dilate_px"):
        ComposeConfig.from_dict({"dilate_px": -1})


def test_refine_command_end_to_end(tmp_path):
    from anigs.cli import main
    from anigs.refine.job import view_seed
    from anigs.video import load_clip, save_clip, save_png

    frame = np.random.default_rng(0).random((H, W, 3)).astype(np.float32)
    clip = np.repeat(frame[None], T, 0)
    src = tmp_path / "round2" / "render" / "v001.npz"
    save_clip(src, clip, {"fps": 24})
    save_png(tmp_path / "m.png", mask_box())
    empty = np.zeros((H, W), np.float32)
    save_png(tmp_path / "e.png", empty)
    out = tmp_path / "round2" / "target" / "v001.npz"
    params = '{"strength": 1.0, "effects": ["foliage_sway", "grass_wave"], "seed": 5}'
    rd = str(tmp_path / "round2")
    rc = main(["refine", "--render-clip", rd, "--view", "v001", "--mask", f"foliage_sway={tmp_path / 'm.png'}",
               f"grass_wave={tmp_path / 'e.png'}", "--out", rd, "--params", params, "--info", str(tmp_path / "info.json")])
    assert rc == 0
    target, meta = load_clip(out)
    assert target.shape == clip.shape and meta["refine"]["seed"] == view_seed(5, 2, "v001")
    assert meta["refine"]["round"] == 2 and meta["refine"]["view"] == "v001"
    assert np.abs(target[:, mask_box() == 1] - clip[:, mask_box() == 1]).max() > 0.01
    assert len({view_seed(5, 2, "v001"), view_seed(5, 2, "v002"), view_seed(5, 3, "v001"), view_seed(6, 2, "v001")}) == 4
    assert main(["refine", "--render-clip", rd, "--view", "v001", "--mask", str(tmp_path / "m.png"), "--out", rd,
                 "--params", '{"strenght": 1}']) == 1
