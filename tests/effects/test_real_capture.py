"""What moves on a real capture, against what a person marked (benchmarks/real/labels/fern-llff.json).

The fern capture of ``../shared/captures/fern-llff`` (20 photos at 504x378; never in the project)
through the real SfM, a short static fit and the effects stage, three phrasings: the user's
prompt, one that names flowers the photos do not have (no blossoms: the trunk's bark and the
warm ceiling lamps must not bob) and one that names nothing that moves. The label figures are
those of benchmarks/real_captures.py: recall of the must-move marks (the fronds) >= 0.8, no
must-stay-still mark (trunk, planter, lamps, floor, shop fronts) more than 1% moving.

Skips, saying why, when the captures folder is missing (CI has ``../shared`` beside the clone;
``ANIGS_CAPTURES`` points elsewhere).
"""
from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))
CAPTURES = Path(os.environ.get("ANIGS_CAPTURES", ROOT.parent / "shared" / "captures"))
FERN = CAPTURES / "fern-llff"

pytestmark = pytest.mark.skipif(not FERN.is_dir(), reason=f"real capture folder {FERN} is missing (the shared "
                                "captures are not beside this clone; set ANIGS_CAPTURES to their folder)")

# a short fit: the default plan (static.budget auto) cut to 1000 steps, so that this test follows what a user's
# fit gives, at a fifth of its time (anigs 0.10: held-out 24.9 dB, 30,150 Gaussians, 69 CPU s on one thread;
# benchmarks/real_captures.py on that fit: recall 0.92 and no still mark moving for all six phrasings)
SHORT_FIT = {"iterations": 1000}

PROMPTS = {"user": "a fern with its fronds moving in the wind",
           "absent": "a potted plant with leaves and flowers in a breeze",
           "nothing": "an atrium with shops, a glass railing and ceiling lamps"}


@pytest.fixture(scope="module")
def fern(tmp_path_factory):
    """SfM and a short static fit of the fern capture (the workflow's stages, through the CLI)."""
    from anigs.cli import main

    tmp = tmp_path_factory.mktemp("fern")
    assert main(["--threads", "2", "sfm", "--images", str(FERN), "--out", str(tmp / "sfm"), "--params", "{}"]) == 0
    assert main(["--threads", "2", "static", "--images", str(tmp / "sfm" / "images"), "--cameras",
                 str(tmp / "sfm" / "cameras.json"), "--points", str(tmp / "sfm" / "points.npz"), "--out",
                 str(tmp / "static"), "--no-progress", "--params", json.dumps(SHORT_FIT)]) == 0
    return tmp


def _effects(fern: Path, key: str) -> tuple[dict, dict]:
    from anigs.cli import main
    from real.labels import load_labels, read_photo
    from real_captures import moving_maps, score

    out = fern / key / "effects"
    assert main(["--threads", "2", "effects", "--canonical", str(fern / "static" / "canonical.ply"), "--cameras",
                 str(fern / "sfm" / "cameras.json"), "--images", str(fern / "sfm" / "images"), "--out", str(out),
                 "--prompt", PROMPTS[key], "--params", "{}"]) == 0
    labels = load_labels("fern-llff")
    sizes = {p.name: read_photo(FERN / p.name).shape[1::-1] for p in labels.photos}
    moving = moving_maps(out, fern, [p.name for p in labels.photos])
    assert sorted(moving) == sorted(p.name for p in labels.photos)  # every labelled photo registered
    sc = score(labels, moving, sizes)
    rep = json.loads((out / "effects.json").read_text())
    print(f"{key}: chosen {rep['chosen']}, recall {sc['recall']:.3f}, still moving {sc['still']:.4f}, worst "
          f"{sc['worst_still']:.4f} ({sc['worst_what']})")
    return rep, sc


def test_the_fronds_move_and_nothing_marked_still_does(fern):
    rep, sc = _effects(fern, "user")
    assert rep["chosen"] == ["foliage_sway", "leaf_flutter"]
    assert sc["recall"] >= 0.8, sc
    assert sc["worst_still"] <= 0.01, sc


def test_flowers_the_photos_do_not_have_are_not_chosen(fern):
    rep, sc = _effects(fern, "absent")
    assert "flower_bob" not in rep["chosen"], rep["effects"]["flower_bob"]  # no bark or lamp bobs
    assert rep["requested_not_found"] == ["flower_bob"]
    assert sc["recall"] >= 0.8 and sc["worst_still"] <= 0.01, sc


def test_a_prompt_naming_nothing_that_moves_keeps_the_capture_still(fern):
    rep, sc = _effects(fern, "nothing")
    assert rep["chosen"] == [] and sc["recall"] == 0.0 and sc["still"] == 0.0


def test_the_views_show_the_fronds_as_sharply_as_the_photos_and_no_holes(fern):
    """The views stage on real photos (issue 36): each queued view's moving region is judged against
    the photos; a view under the bar is a photo pose the queue fell back to, with its advice."""
    from anigs.cli import main
    from anigs.views import ViewsConfig

    if not (fern / "user" / "effects" / "dynamic.npy").exists():
        _effects(fern, "user")
    out = fern / "user" / "views"
    assert main(["--threads", "2", "views", "--canonical", str(fern / "static" / "canonical.ply"), "--cameras",
                 str(fern / "sfm" / "cameras.json"), "--points", str(fern / "sfm" / "points.npz"), "--images",
                 str(fern / "sfm" / "images"), "--effects", str(fern / "user" / "effects"), "--out", str(out),
                 "--params", "{}"]) == 0
    data = json.loads((out / "views.json").read_text())
    cfg = ViewsConfig()
    views = data["views"]
    print("views:", [(v["id"], v.get("photo_pose"), round(v["motion_sharpness"] or 0, 2), round(v["unobserved"], 3))
                     for v in views])
    assert views and all(v["motion_sharpness"] is not None for v in views)
    for v in views:
        if v.get("photo_pose"):
            assert data["motion"]["advice"], v
        else:
            assert v["motion_sharpness"] >= cfg.min_motion_sharpness and v["unobserved"] <= cfg.max_unobserved, v
    # the fern's fronds fill the photos: most views are placed ones, not a fallback to the photos' poses
    assert sum(not v.get("photo_pose") for v in views) >= len(views) // 2
