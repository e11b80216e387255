"""The user corrects what moves: drop / force a numbered candidate of overview.png, a 3D box, a
SuperSplat selection export matched by position; and the per-frame PLYs load in SuperSplat as one
timeline (its rule: one shared prefix and a trailing frame number, `(.*?)(\\d+)\\.ply`)."""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
import torch

from anigs.cli import main
from anigs.effects.config import REGIONS
from anigs.stages.effects import Outputs as EffectsOutputs

SUPERSPLAT_SEQUENCE = re.compile(r"(.*?)(\d+)(?:\.compressed)?\.ply$")  # SuperSplat's isPlySequence (src/file-handler.ts)


@pytest.fixture(scope="module")
def room(tmp_path_factory):
    from anigs.cameras import save_cameras
    from anigs.images import write_rgb_png
    from anigs.synth import render_image
    from anigs.synth.decoys import build_decoy

    tmp = tmp_path_factory.mktemp("room")
    d = build_decoy("room")
    d.gaussians.save_ply(tmp / "canonical.ply")
    save_cameras(tmp / "cameras.json", d.cameras)
    for cam in d.cameras:
        write_rgb_png(tmp / "images" / cam.name, render_image(d.gaussians, cam))
    auto = _run(tmp, "auto", {})
    return tmp, d, auto


def _run(tmp: Path, out: str, params: dict) -> dict:
    args = ["effects", "--canonical", str(tmp / "canonical.ply"), "--cameras", str(tmp / "cameras.json"),
            "--images", str(tmp / "images"), "--out", str(tmp / out), "--params", json.dumps(params)]
    assert main(args) == 0
    return EffectsOutputs(tmp / out).report()


def _fails(tmp: Path, params: dict, caplog, pattern: str) -> None:
    args = ["effects", "--canonical", str(tmp / "canonical.ply"), "--cameras", str(tmp / "cameras.json"),
            "--images", str(tmp / "images"), "--out", str(tmp / "failed"), "--params", json.dumps(params)]
    assert main(args) != 0
    assert re.search(pattern, caplog.text), caplog.text[-2000:]


def test_drop_and_force_by_number(room, caplog):
    tmp, d, auto = room
    assert auto["chosen"] == ["foliage_sway", "leaf_flutter"]
    plant = max((c for c in auto["candidates"] if c["region"] == "foliage" and c["kept"]), key=lambda c: c["num_gaussians"])
    rejected = auto["rejected"][0]
    doc = _run(tmp, "drop", {"drop": [plant["number"]], "force": [rejected["number"]]})
    regions = np.load(tmp / "drop" / "regions.npy")
    part = d.gaussians.extras["decoy"].numpy()
    label = d.gaussians.extras["label"].numpy()
    assert (regions[label == 4] == REGIONS.index("foliage")).mean() < 0.1  # the plant was dropped
    from anigs.synth.decoys import DECOY_IDS

    forced = regions == REGIONS.index(rejected["region"])
    # forced back (the candidate also holds the wall Gaussians around the picture's rim)
    assert (forced & (part == DECOY_IDS["picture"])).sum() >= 0.75 * rejected["num_gaussians"]
    assert len(doc["corrections"]) == 2 and "dropped" in doc["corrections"][1]
    _fails(tmp, {"drop": [999]}, caplog, "no candidate 999")


def test_box_and_supersplat_selection(room, caplog):
    tmp, d, auto = room
    from anigs.gaussians import load_ply
    from anigs.synth.decoys import DECOY_IDS

    g = load_ply(tmp / "canonical.ply")
    part = d.gaussians.extras["decoy"].numpy()
    rug = part == DECOY_IDS["rug"]
    m = g.means.numpy()[rug]
    box = {"min": (m.min(0) - 0.01).tolist(), "max": (m.max(0) + 0.01).tolist(), "effect": "flower_bob"}
    # a SuperSplat export of the selected plant: the selected Gaussians, positions unchanged
    label = d.gaussians.extras["label"].numpy()
    g.subset(torch.from_numpy(np.flatnonzero(label == 4))).save_ply(tmp / "plant_selection.ply")
    doc = _run(tmp, "sel", {"boxes": [box], "selections": [{"ply": str(tmp / "plant_selection.ply"), "effect": "still"}]})
    dyn = EffectsOutputs(tmp / "sel").dynamic()
    assert doc["chosen"] == ["flower_bob"]  # the rug bobs because the box says so; the plant stays still
    assert dyn[rug].mean() > 0.99 and not dyn[label == 4].any()
    # a selection exported after moving the model in SuperSplat does not match: a clear error
    moved = g.subset(torch.from_numpy(np.flatnonzero(label == 4)))
    moved.means[:, 2] += 0.5
    moved.save_ply(tmp / "moved.ply")
    _fails(tmp, {"selections": [{"ply": str(tmp / "moved.ply")}]}, caplog, "Reset its transform")


def test_frame_plys_load_as_one_supersplat_timeline(tmp_path):
    from anigs.animate import deform
    from anigs.gaussians import Gaussians
    from anigs.viewer.compact import write_frame_plys

    g = Gaussians.from_points(torch.rand(50, 3), torch.full((50, 3), 0.5))
    d = deform.DCTDeformation(torch.arange(10), 9, 4, rotation=False, num_gaussians=g.num)
    names = write_frame_plys(tmp_path, g, d, 2)
    folder = {Path(n).parent for n in names}
    assert len(folder) == 1 and sorted(p.name for p in (tmp_path / folder.pop()).iterdir()) == sorted(
        Path(n).name for n in names)  # the folder holds the sequence only (SuperSplat takes a dropped folder)
    matches = [SUPERSPLAT_SEQUENCE.match(Path(n).name.lower()) for n in names]
    assert all(matches) and len({mt.group(1) for mt in matches}) == 1
    assert [int(mt.group(2)) for mt in matches] == sorted(int(mt.group(2)) for mt in matches)
