"""A Gaussian joins a region only where its footprint agrees (``effects.lift.footprint_share``), and vegetation
colour needs a chroma above noise (``effects.regions.green_min_chroma``).

On the street walk (a 15 dB fit) blurred splats centred on a bush reached over a green gate and the
facades: their centres voted foliage, so 18% of the gate moved; the flower capture's dark mossy stones
had a green cast of a few levels, so their splats moved too. The garden here gets one such smear: a
wide splat centred on a bush, over what the photos show around it.
"""
from __future__ import annotations

import numpy as np
import pytest
import torch

from anigs.effects import REGIONS, EffectsConfig, detect_effects
from anigs.effects import cues
from anigs.gaussians import Gaussians
from anigs.synth import SceneConfig

from test_effects import _capture

FOLIAGE = REGIONS.index("foliage")


@pytest.fixture(scope="module")
def smeared():
    """The garden's photos, and its model with a wide, half-transparent splat (the last one) centred on
    the foliage Gaussian farthest out from the foliage's middle, 40 x its size: what a blurry fit puts
    over a bush's edge and the wall or the lawn beside it."""
    g, cams, imgs = _capture(SceneConfig(), images=8, width=128)
    res = detect_effects(imgs, cams, g, EffectsConfig.from_dict({"photos": {"max_photos": 8}}))
    fol = np.flatnonzero(res.region_of == FOLIAGE)
    centre = g.means[fol].median(0).values
    near = fol[int(torch.linalg.norm(g.means[fol] - centre, dim=1).argmax())]
    smear = g.subset(torch.tensor([near]))
    smear = Gaussians(smear.means, smear.quats, smear.log_scales + np.log(40.0), torch.full_like(smear.opacity_logits, 0.0),
                      smear.sh, {k: v for k, v in smear.extras.items()})
    return Gaussians.concat([g, smear]), cams, imgs, res


def test_a_smear_centred_on_a_bush_stays_still_while_the_bush_sways(smeared):
    g, cams, imgs, before = smeared
    off = detect_effects(imgs, cams, g, EffectsConfig.from_dict({"photos": {"max_photos": 8}, "lift": {"footprint_share": 0.0}}))
    assert off.region_of[-1] == FOLIAGE  # its centre votes foliage: without the footprint it would move
    on = detect_effects(imgs, cams, g, EffectsConfig.from_dict({"photos": {"max_photos": 8}}))
    assert on.region_of[-1] == -1
    kept = (on.region_of[:-1] == FOLIAGE) & (before.region_of == FOLIAGE)
    assert kept.sum() >= 0.9 * (before.region_of == FOLIAGE).sum()  # the bush's own Gaussians still sway
    assert on.effects["foliage_sway"].detected


def test_dark_pixels_with_a_faint_green_cast_are_no_vegetation():
    stone = [0.10, 0.12, 0.09]  # chroma 0.03: a mossy stone in shadow (hue green, saturation 0.25)
    leaf = [0.05, 0.15, 0.04]   # chroma 0.11: a shaded leaf
    img = np.array([[stone, leaf]], np.float32)
    cfg = EffectsConfig()
    args = (img, cfg.regions.green_hue, cfg.regions.green_min_saturation, cfg.regions.min_value)
    assert cues.green(*args, 0.0).tolist() == [[True, True]]
    assert cues.green(*args, cfg.regions.green_min_chroma).tolist() == [[False, True]]


def test_footprint_and_chroma_settings_are_checked():
    with pytest.raises(ValueError, match="footprint_share"):
        EffectsConfig.from_dict({"lift": {"footprint_share": 1.5}})
    with pytest.raises(ValueError, match="footprint_reach_px"):
        EffectsConfig.from_dict({"lift": {"footprint_reach_px": -1}})
