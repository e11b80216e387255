"""The static fit's photos held as uint8 (a quarter of float32's memory): the same pixels, the same fit."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from anigs.cameras import save_cameras
from anigs.images import load_image, load_image_compact, load_inputs
from anigs.static.fit import StaticConfig, fit_static
from tests.static.test_fit import FAST, make_scene, sfm_points
from anigs.video import save_png

pytestmark = pytest.mark.usefixtures("one_thread")


def test_compact_image_is_load_image_exactly(tmp_path):
    rng = np.random.default_rng(0)
    img = rng.random((7, 9, 3)).astype(np.float32)
    save_png(tmp_path / "a.png", img)
    small = load_image_compact(tmp_path / "a.png")
    assert small.dtype == np.uint8 and small.shape == (7, 9, 3)
    np.testing.assert_array_equal(torch.from_numpy(small).float() / 255.0, load_image(tmp_path / "a.png"))


def test_compact_inputs_fit_the_same_model(tmp_path):
    gt, cams, imgs = make_scene(n_cams=10, width=48, height=36)
    for c, im in zip(cams, imgs):
        save_png(tmp_path / c.name, im.numpy())
    save_cameras(tmp_path / "cameras.json", cams)
    full, cams_f = load_inputs(tmp_path, tmp_path / "cameras.json")
    small, cams_c = load_inputs(tmp_path, tmp_path / "cameras.json", compact=True)
    assert all(s.dtype == torch.uint8 for s in small) and all(f.dtype == torch.float32 for f in full)
    assert sum(s.numel() * s.element_size() for s in small) * 4 == sum(f.numel() * f.element_size() for f in full)
    p, c = sfm_points(gt, every=6)
    cfg = {**FAST, "iterations": 20}
    g_full, m_full = fit_static(full, cams_f, p, c, StaticConfig.from_dict(cfg), progress=False)
    g_small, m_small = fit_static(small, cams_c, p, c, StaticConfig.from_dict(cfg), progress=False)
    assert torch.equal(g_full.means, g_small.means) and torch.equal(g_full.sh, g_small.sh)
    assert m_full["test_psnr"] == m_small["test_psnr"] and m_full["train_psnr"] == m_small["train_psnr"]
