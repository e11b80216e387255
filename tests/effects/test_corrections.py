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
from anigs.effects.config import EFFECT_REGION, REGIONS
from anigs.stages.effects import Outputs as EffectsOutputs
from tests._node import needs_node, splat_transform

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
    # a selection of Gaussians this model does not have (another run's: other colours, elsewhere): a clear error
    other = g.subset(torch.from_numpy(np.flatnonzero(label == 4)))
    other.means[:, 2] += 0.5
    other.sh[:, 0] += 0.3
    other.save_ply(tmp / "other.ply")
    _fails(tmp, {"selections": [{"ply": str(tmp / "other.ply")}]}, caplog, "reset its transform.*select on static/canonical.ply")


# ---- the SuperSplat round trip without traps (issue 37) ----------------------------------------

def _rug_box(g, rug: np.ndarray) -> tuple[list, list]:
    m = g.means.numpy()[rug]
    return (m.min(0) - 0.01).tolist(), (m.max(0) + 0.01).tolist()


def test_box_corners_read_off_supersplat(room, caplog):
    """Trap 1: SuperSplat shows positions as (-x, -y, z); its corners with ``frame: supersplat`` select
    the rug, not its mirror image; without it the note says what the SuperSplat reading would hold."""
    from anigs.formats.orientation import SUPERSPLAT
    from anigs.gaussians import load_ply
    from anigs.synth.decoys import DECOY_IDS

    tmp, d, _ = room
    g = load_ply(tmp / "canonical.ply")
    rug = d.gaussians.extras["decoy"].numpy() == DECOY_IDS["rug"]
    lo, hi = _rug_box(g, rug)
    shown = np.array([lo, hi]) @ SUPERSPLAT  # the corners as SuperSplat displays them
    box = {"min": shown.min(0).tolist(), "max": shown.max(0).tolist(), "effect": "flower_bob"}
    flowers = lambda out: np.load(tmp / out / "regions.npy") == REGIONS.index(EFFECT_REGION["flower_bob"])
    before = flowers("auto")
    doc = _run(tmp, "ss_box", {"boxes": [{**box, "frame": "supersplat"}]})
    added = flowers("ss_box") & ~before
    assert "flower_bob" in doc["chosen"] and added[rug].mean() > 0.99
    m = g.means.numpy()
    in_box = np.all((m >= lo) & (m <= hi), axis=1)
    assert np.array_equal(added, in_box & ~before)  # exactly the box around the rug, not its mirror image
    # the same corners without the frame: the mirror image, and the note names the SuperSplat reading
    doc = _run(tmp, "ss_box_anigs", {"boxes": [box]})
    assert "frame: supersplat" in doc["corrections"][0], doc["corrections"]
    in_mirror = np.all((m >= shown.min(0)) & (m <= shown.max(0)), axis=1)
    assert np.array_equal(flowers("ss_box_anigs") & ~before, in_mirror & ~before) and in_mirror.sum() < in_box.sum()
    # a box far outside the scene is an error, not a silent no-op; an unknown key too
    _fails(tmp, {"boxes": [{"min": [50, 50, 50], "max": [51, 51, 51]}]}, caplog, "holds no Gaussian")
    _fails(tmp, {"boxes": [{**box, "frame": "threejs"}]}, caplog, "frame: one of")


def test_selection_made_on_animated_ply_or_a_frame(room, caplog):
    """Trap 2: the plant selected on export/animated.ply (canonical positions trained by the update) or
    on a frame PLY (moved by the animation) is matched, by colour, opacity and scale."""
    from anigs.animate.deform import DCTDeformation
    from anigs.animate.frames import deformed
    from anigs.export import save_animated_ply
    from anigs.gaussians import load_ply

    tmp, d, _ = room
    g = load_ply(tmp / "canonical.ply")
    plant = np.flatnonzero(d.gaussians.extras["label"].numpy() == 4)
    idx = torch.from_numpy(plant)
    deform = DCTDeformation(idx, 9, 3, rotation=True, num_gaussians=g.num)
    with torch.no_grad():
        deform.pos_coeffs.copy_(torch.randn(deform.pos_coeffs.shape, generator=torch.Generator().manual_seed(0)) * 0.05)
        deform.rot_coeffs.copy_(torch.randn(deform.rot_coeffs.shape, generator=torch.Generator().manual_seed(1)) * 0.1)
    trained = g.detach()
    trained.means[idx] += torch.randn(len(plant), 3, generator=torch.Generator().manual_seed(2)) * 0.01  # the update's
    save_animated_ply(tmp / "animated.ply", trained, deform)
    load_ply(tmp / "animated.ply").subset(idx).save_ply(tmp / "sel_animated.ply")
    frame = deformed(trained, deform, 4)
    moved = (frame.means[idx] - g.means[idx]).norm(dim=1)
    assert moved.median() > 0.02  # the frame's plant is far from canonical.ply's (beyond the position tolerance)
    frame.subset(idx).save_ply(tmp / "sel_frame.ply")
    for name in ("sel_animated", "sel_frame"):
        doc = _run(tmp, name, {"selections": [{"ply": str(tmp / f"{name}.ply"), "effect": "still"}]})
        dyn = EffectsOutputs(tmp / name).dynamic()
        # the synthetic plant has groups of identical Gaussians (48 share colour, opacity and scale with up to 24
        # others): such a splat takes the nearest of its look-alikes, so a few of the plant stay unmatched
        assert dyn[plant].mean() < 0.03, (name, dyn[plant].mean())
        assert "had moved" in doc["corrections"][0], doc["corrections"]


@needs_node("splat-transform")
def test_supersplat_compressed_ply_selection(room, caplog):
    """Trap 3: SuperSplat's "Compressed PLY" export (splat-transform's writer, which SuperSplat calls) is
    read, and matched with a tolerance that follows its quantisation: a large sparse selection whose
    rounding exceeds the float tolerance matches in full."""
    from anigs.formats.compressed_ply import read_compressed_ply
    from anigs.gaussians import load_ply

    tmp, d, _ = room
    g = load_ply(tmp / "canonical.ply")
    label = d.gaussians.extras["label"].numpy()
    plant = np.flatnonzero(label == 4)
    sparse = np.flatnonzero(label != 4)[::7]  # spread over the room: coarse chunks
    sel = np.concatenate([plant, sparse])
    g.subset(torch.from_numpy(sel)).save_ply(tmp / "sel.ply")
    splat_transform(tmp / "sel.ply", tmp / "sel.compressed.ply")
    back, step = read_compressed_ply(tmp / "sel.compressed.ply")
    diag = float(np.linalg.norm(g.means.numpy().max(0) - g.means.numpy().min(0)))
    err = np.linalg.norm(back.means.numpy()[:, None] - g.means.numpy()[sel][None], axis=-1).min(1)
    assert err.max() > 1e-4 * diag  # the rounding exceeds the float tolerance (selection_tol x diagonal) ...
    assert (err <= np.linalg.norm(step, axis=1) / 2 + 1e-5).all()  # ... and stays within half a step
    doc = _run(tmp, "sel_compressed", {"selections": [{"ply": str(tmp / "sel.compressed.ply"), "effect": "still"}]})
    dyn = EffectsOutputs(tmp / "sel_compressed").dynamic()
    assert not dyn[plant].any()
    assert f"{len(sel)} Gaussians never move" in doc["corrections"][0], doc["corrections"]


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
