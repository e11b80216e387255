"""The static fit's per-training-photo exposure (anigs.static.exposure)."""
from __future__ import annotations

import pytest
import torch

from anigs.static.exposure import Exposure
from anigs.static.fit import StaticConfig, fit_static, split_holdout

from test_fit import FAST, make_scene, sfm_points

pytestmark = pytest.mark.usefixtures("one_thread")


def test_identity_at_the_start_and_only_the_rendered_photo_moves():
    e = Exposure(3, lr=0.1)
    rgb = torch.rand(4, 5, 3)
    assert torch.equal(e.apply(rgb, 1), rgb)
    (e.apply(rgb, 1) - 0.5 * rgb).abs().mean().backward()
    e.step()
    assert not torch.equal(e.maps[1], Exposure(1, 0.1).maps[0])
    assert torch.equal(e.maps[0], Exposure(1, 0.1).maps[0]) and torch.equal(e.maps[2], e.maps[0])


def test_a_darker_photo_gets_a_lower_gain_than_the_others():
    gt, cams, imgs = make_scene()
    train_idx, _ = split_holdout(len(cams), 8)
    dark = train_idx[3]
    imgs = [im * 0.6 if i == dark else im for i, im in enumerate(imgs)]
    p, c = sfm_points(gt, every=4)
    cfg = {**FAST, "iterations": 120, "background": [0.0, 0.0, 0.0]}
    _, m0 = fit_static(imgs, cams, p, c, StaticConfig.from_dict(cfg), progress=False)
    _, m1 = fit_static(imgs, cams, p, c, StaticConfig.from_dict({**cfg, "exposure_lr": 0.02}), progress=False)
    assert "exposure" not in m0
    gains = m1["exposure"]["gains"]
    others = sorted(g for i, g in enumerate(gains) if i != 3)
    assert len(gains) == len(train_idx)
    assert gains[3] < 0.85 * others[len(others) // 2], gains  # the dark photo's, against the median
    with pytest.raises(ValueError, match="exposure_lr"):
        StaticConfig.from_dict({"exposure_lr": -0.1})
