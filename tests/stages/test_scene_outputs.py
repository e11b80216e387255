"""The scene stages' Outputs: their checked loaders, as other stages, metrics and benchmarks read them."""
from __future__ import annotations

import json

import numpy as np
import pytest

from anigs.images import write_mask_png
from anigs.stages import capture, effects, masks, views


def test_effects_loaders_check_size_and_dtype(tmp_path):
    out = effects.Outputs(tmp_path)
    with pytest.raises(FileNotFoundError, match="run the effects stage"):
        out.chosen()
    out.path("effects").write_text(json.dumps({"chosen": ["grass_wave"]}))
    np.save(out.path("regions"), np.array([-1, 1, 1], np.int8))
    np.save(out.path("dynamic"), np.array([0, 1, 1], np.float32))
    assert out.chosen() == ["grass_wave"] and out.regions(3).tolist() == [-1, 1, 1]
    with pytest.raises(ValueError, match=r"regions.npy: shape \[3\] where \[4\]"):
        out.regions(4)
    with pytest.raises(ValueError, match="dynamic.npy: dtype float32"):
        out.dynamic(3)  # a float ROI is not the stage's bool set


def test_masks_view_and_effect_masks(tmp_path):
    out = masks.Outputs(tmp_path)
    m = np.zeros((4, 5), bool)
    m[1:3, 2:4] = True
    write_mask_png(out.path("mask", view="v00"), m)
    write_mask_png(out.path("effect_mask", view="v00", effect="grass_wave"), m)
    write_mask_png(out.path("effect_mask", view="v00", effect="flower_bob"), np.zeros_like(m))
    write_mask_png(out.path("overlay", view="v00"), m)  # not an effect
    write_mask_png(out.path("mask", view="v01"), m)
    assert out.has_view_mask("v00") and not out.has_view_mask("v02")
    np.testing.assert_array_equal(out.view_mask("v00"), m.astype(np.float32))
    assert sorted(out.effect_masks("v00")) == ["flower_bob", "grass_wave"] and out.effect_masks("v01") == {}
    with pytest.raises(FileNotFoundError, match="v02.png: missing"):
        out.view_mask("v02")
    np.save(out.path("effect_labels"), np.array([0, 1, 3], np.int8))
    assert out.effect_labels(3).dtype == np.int8


def test_views_queue_and_capture_ground_truth(tmp_path):
    v = views.Outputs(tmp_path / "views")
    v.root.mkdir()
    cam = {"K": [[50, 0, 32], [0, 50, 24], [0, 0, 1]], "viewmat": np.eye(4).tolist(), "width": 64, "height": 48}
    v.path("views").write_text(json.dumps({"views": [{"id": "v00", "camera": cam}, {"id": "v01", "camera": cam}]}))
    assert v.count() == 2 and v.view_ids() == ["v00", "v01"] and [c.name for c in v.views()] == ["v00", "v01"]
    cap = capture.Outputs(tmp_path / "capture")
    assert not cap.is_synthetic() and cap.original_photos() is None
    with pytest.raises(ValueError, match="not the capture stage's ground-truth folder"):
        capture.Outputs.from_gt(tmp_path / "elsewhere")
    assert capture.Outputs.from_gt(cap.path("gt")) == cap
    cap.path("gt").mkdir(parents=True)
    np.save(cap.path("gt_anchors"), np.zeros((3, 2), np.float32))
    with pytest.raises(ValueError, match=r"anchors.npy: shape \[3, 2\] where \[\*, 3\]"):
        cap.gt_anchors()
