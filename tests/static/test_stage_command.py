"""``anigs static`` prints its summary line for every valid config, also ``holdout_every: 0`` (no held-out
photos: the fit writes null held-out figures, which the line must not try to format as numbers)."""
from __future__ import annotations

import argparse
import json

import pytest

from anigs.stages import static as stage


@pytest.mark.parametrize("held", [None, 23.456])
def test_summary_line_with_and_without_held_out_photos(tmp_path, monkeypatch, capsys, held):
    out = stage.Outputs(tmp_path / "static")
    out.root.mkdir(parents=True)
    metrics = {"num_gaussians": 1234, "test_psnr": held, "test_ssim": None if held is None else 0.8123,
               "train_psnr": 27.5, "seconds": 12.0}
    out.path("metrics").write_text(json.dumps(metrics))
    seen = {}

    def fake_run(inputs, cfg):
        seen["holdout_every"] = cfg.holdout_every
        return out

    monkeypatch.setattr(stage, "run", fake_run)
    args = argparse.Namespace(params=json.dumps({"holdout_every": 0 if held is None else 8}), out=str(out.root),
                              images=str(tmp_path / "images"), cameras=str(tmp_path / "cameras.json"),
                              points=str(tmp_path / "points.npz"))
    assert stage.main(args) == 0
    line = capsys.readouterr().out
    assert seen["holdout_every"] == (0 if held is None else 8)
    assert "1234 Gaussians" in line and "train PSNR 27.50 dB" in line
    if held is None:
        assert "no held-out photos (static.holdout_every: 0)" in line and "nan" not in line
    else:
        assert "held-out PSNR 23.46 dB, SSIM 0.812" in line


def test_fit_picture_without_held_out_photos_draws_the_growth_and_says_why(tmp_path):
    """fit.png of a fit with no held-out photos: the Gaussians against the steps, not an empty frame."""
    import cv2
    import numpy as np

    from anigs.static.report import draw_fit

    nan = float("nan")
    curve = [{"iteration": i, "test_psnr": nan, "test_ssim": nan, "num_gaussians": 1000 + 40 * i} for i in (0, 250, 500)]
    base = {"plan": {"level": "auto", "iterations": 500, "max_gaussians": 30000},
            "accuracy": {"now": {"test_psnr": None, "test_ssim": None, "train_psnr": 25.0, "steps": 500,
                                 "gaussians": 21000}}}
    pics = {}
    for name, rows in (("none", curve), ("held", [dict(r, test_psnr=20.0 + r["iteration"] / 100) for r in curve])):
        draw_fit({**base, "curve": rows}, tmp_path / f"{name}.png")
        pics[name] = cv2.imread(str(tmp_path / f"{name}.png"))
    plot = pics["none"][40:250, 70:620]  # inside the plot's frame
    assert (plot < 128).any(axis=-1).sum() > 200  # a drawn curve, not a blank frame
    assert not np.array_equal(pics["none"], pics["held"])
