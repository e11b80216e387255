"""The still model: what the workflow writes instead of any round when nothing should move."""
from __future__ import annotations

import argparse

import pytest
import torch

from anigs.animate.deform import load_model
from anigs.animate.frames import render_clip
from anigs.animate.still import write_still_model
from tests._scenes import ring_cameras, sway_scene


def test_still_model_renders_the_canonical_scene_on_every_frame(tmp_path):
    g, _ = sway_scene()
    ply = tmp_path / "canonical.ply"
    g.save_ply(ply)
    info = write_still_model(ply, tmp_path / "model.pt", num_frames=9, num_bases=4, reason="nothing found")
    assert info["still"] and info["reason"] == "nothing found"
    canonical, deformation, payload = load_model(tmp_path / "model.pt", ply)
    assert deformation.num_dynamic == 0 and deformation.num_frames == 9
    assert payload["extra"]["reason"] == "nothing found"
    clip = render_clip(canonical, deformation, ring_cameras(1)[0], 9, torch.zeros(3), "cpu")
    assert clip.abs().sum() > 0  # the scene is in view
    assert torch.equal(clip, clip[:1].expand_as(clip))  # bit for bit the same on every frame


def test_still_model_needs_a_reason(tmp_path):
    g, _ = sway_scene()
    g.save_ply(tmp_path / "c.ply")
    with pytest.raises(ValueError, match="why nothing moves"):
        write_still_model(tmp_path / "c.ply", tmp_path / "m.pt", 9, 4, "")
    assert not (tmp_path / "m.pt").exists()


def test_update_command_still_needs_no_targets_and_clamps_k(tmp_path):
    from anigs.stages import update
    from anigs.stages.command import stage_arguments

    g, _ = sway_scene()
    (tmp_path / "static").mkdir()
    g.save_ply(tmp_path / "static" / "canonical.ply")
    p = argparse.ArgumentParser()
    stage_arguments(update, "update", p)
    args = p.parse_args(["--static", str(tmp_path / "static"), "--still", "no effect", "--frames", "5",
                         "--out", str(tmp_path / "still"), "--params", '{"num_bases": 16}'])
    assert update.main(args) == 0
    _, deformation, _ = load_model(tmp_path / "still" / "model.pt")
    assert deformation.num_bases == 4 and deformation.num_dynamic == 0  # K <= T-1
    bad = p.parse_args(["--static", str(tmp_path / "static"), "--out", str(tmp_path / "x")])
    with pytest.raises(ValueError, match="--targets and --masks are required"):
        update.main(bad)
