"""The sfm escalation (anigs.sfm.escalate) on a real capture whose sequential pairs leave it in groups.

The capture (tests/sfm/_captures.py): 20 photos of one orbit, named so that sequential matching
with ``sequential_overlap: 1`` joins only runs of ring neighbours (groups of 10, 6 and 4 photos);
matching more pairs joins them. Real COLMAP throughout, 320x240 renders.
"""
from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np
import pytest

pycolmap = pytest.importorskip("pycolmap")

from _captures import SPLIT_GROUPS, split_ring_capture  # noqa: E402
from anigs.sfm import rematch  # noqa: E402
from anigs.sfm.colmap import SfmConfig, SfmError, run_sfm  # noqa: E402
from anigs.stages.sfm import Outputs as SfmOutputs  # noqa: E402
from anigs.sfm.diagnose import groups, likely_causes  # noqa: E402

# sequential pairs (i, i+1) only, no look-alike pairs: what leaves the split capture in groups
SEQUENTIAL = {"camera_model": "SIMPLE_PINHOLE", "matcher": "sequential", "sequential_overlap": 1,
              "sequential_similar": 0, "refine": False}


@pytest.fixture(scope="module")
def split(tmp_path_factory):
    root = tmp_path_factory.mktemp("split")
    images, gt = split_ring_capture(root)
    return {"root": root, "images": images, "gt": gt}


def _cfg(**kw) -> SfmConfig:
    return SfmConfig.from_dict({**SEQUENTIAL, **kw})


def test_sequential_groups_escalate_until_every_photo_registers(split, tmp_path, caplog):
    """Sequential matching registers one group; the escalation adds pairs and registers all 20.
    (Before the escalation this capture stopped with SfmError after the 4-degree retry.)"""
    with caplog.at_level(logging.INFO, logger="anigs.sfm"):
        res = run_sfm(split["images"], SfmOutputs(tmp_path / "sfm"), _cfg(), gt_cameras=split["gt"])
    attempts = res.report["mapping"]["attempts"]
    assert attempts[0]["step"] == "first" and attempts[0]["matcher"] == "sequential"
    assert attempts[0]["registered"] <= 12, attempts[0]  # one group (10) at most, plus a stray pair
    assert res.report["registered"] == 20 and res.report["status"] == "complete" and not res.report["partial"]
    assert attempts[-1]["registered"] == 20 and attempts[-1]["verified_pairs"] > attempts[0]["verified_pairs"]
    assert [a["step"] for a in attempts][:2] == ["first", "loops"]
    for a in attempts:  # each attempt logged with its result and time
        assert {"registered", "total", "models", "seconds", "keypoints_per_image", "verified_pairs"} <= set(a)
        assert a["total"] == 20 and a["seconds"] > 0
    assert "sfm attempt 1 (first" in caplog.text and "adding loop and look-alike pairs" in caplog.text
    on_disk = json.loads((tmp_path / "sfm" / "report.json").read_text())
    assert on_disk["mapping"]["attempts"] == attempts
    assert res.report["gt_errors"]["rotation_error_deg"]["max"] < 1.0, res.report["gt_errors"]


def test_exhaustive_step_joins_what_the_loop_step_leaves(split, tmp_path, monkeypatch):
    """With the loop step adding nothing, matching every pair is the step that joins the groups."""
    monkeypatch.setattr(rematch, "match_loops", lambda *a, **k: {"match_s": 0.0})
    res = run_sfm(split["images"], SfmOutputs(tmp_path / "sfm"), _cfg())
    steps = [(a["step"], a["registered"]) for a in res.report["mapping"]["attempts"]]
    assert [s for s, _ in steps] == ["first", "loops", "exhaustive"], steps
    assert steps[1][1] == steps[0][1] and steps[2][1] == 20
    assert res.report["mapping"]["attempts"][2]["verified_pairs"] > 100  # 190 pairs matched, most verify


def test_partial_run_continues_with_the_largest_model(split, tmp_path, caplog):
    """No escalation: the best model holds half the photos (>= partial_min_fraction): the run goes on
    with it, says partial, and lists the photos left out; the outputs hold the registered ones only."""
    with caplog.at_level(logging.WARNING, logger="anigs.sfm"):
        res = run_sfm(split["images"], SfmOutputs(tmp_path / "sfm"), _cfg(escalate=False, partial_min_fraction=0.45))
    r = res.report
    assert r["status"] == "partial" and r["partial"] is True
    assert [a["step"] for a in r["mapping"]["attempts"]] == ["first", "lower_angle"]
    reg = r["registered"]
    assert 9 <= reg < 16
    left_out = r["unregistered_images"]
    assert len(left_out) == 20 - reg
    cams = json.loads((tmp_path / "sfm" / "cameras.json").read_text())["cameras"]
    names = {c["name"] for c in cams}
    assert len(names) == reg and not names & set(left_out)
    assert {p.name for p in (tmp_path / "sfm" / "images").iterdir()} == names
    # the kept model is one group of the split: the first (10 photos)
    assert names == {f"photo_{k:02d}.png" for k in SPLIT_GROUPS[0]}
    assert "PARTIAL reconstruction" in caplog.text and left_out[0] in caplog.text


def test_below_half_is_an_error_naming_cause_and_settings(split, tmp_path):
    with pytest.raises(SfmError) as err:
        run_sfm(split["images"], SfmOutputs(tmp_path / "sfm"), _cfg(escalate=False, partial_min_fraction=0.6))
    msg = str(err.value)
    assert "registered 10/20" in msg and "partial_min_fraction=0.6" in msg
    assert "too little overlap" in msg and "groups of [10, 6, 4]" in msg
    assert "sfm.matcher: exhaustive" in msg and "Settings to try" in msg
    assert not (tmp_path / "sfm" / "cameras.json").exists()


# ---- the diagnosis on its own -------------------------------------------------------------

def test_groups_of_a_match_graph():
    adj = np.zeros((6, 6), bool)
    for i, j in [(0, 1), (1, 2), (3, 4)]:
        adj[i, j] = adj[j, i] = True
    assert groups(adj) == [[0, 1, 2], [3, 4], [5]]


def test_few_features_named_first():
    causes, settings, facts = likely_causes(None, [{"registered": 2, "keypoints_per_image": 120.0,
                                                    "verified_pairs": 3, "models": [2]}], [], True)
    assert causes[0].startswith("too few features (120")
    assert any("sift_peak_threshold" in s for s in settings) and facts["keypoints_per_image"] == 120.0


def test_config_checks_the_new_keys():
    with pytest.raises(ValueError, match="partial_min_fraction"):
        SfmConfig.from_dict({"partial_min_fraction": 0.0})
    assert SfmConfig().escalate is True and SfmConfig().partial_min_fraction == 0.5


def test_original_resolution_step_uses_the_full_size_photos(split, tmp_path, monkeypatch):
    """A capture downscaled to 160x120 from the 320x240 photos: with the pair steps adding nothing,
    the original photos register every view, and the model is scaled back to the capture's size."""
    from PIL import Image

    small = tmp_path / "capture" / "images"
    small.mkdir(parents=True)
    for p in sorted(split["images"].iterdir()):
        Image.open(p).resize((160, 120), Image.Resampling.LANCZOS).save(small / p.name)
    monkeypatch.setattr(rematch, "match_loops", lambda *a, **k: {"match_s": 0.0})
    monkeypatch.setattr(rematch, "match_every_pair", lambda *a, **k: {"match_s": 0.0})
    res = run_sfm(small, SfmOutputs(tmp_path / "sfm"), _cfg(), originals=split["images"])
    attempts = res.report["mapping"]["attempts"]
    assert [a["step"] for a in attempts][-1] == "original_resolution", attempts
    assert attempts[-1]["resolution"] == "original" and attempts[-1]["registered"] == 20
    assert res.report["registered"] == 20 and res.report["status"] == "complete"
    assert {(c.width, c.height) for c in res.cameras} == {(160, 120)}
    gt_fx = 160 / 2 / np.tan(np.radians(30))
    assert abs(res.cameras[0].K[0, 0] / gt_fx - 1) < 0.03
    assert res.report["mean_reprojection_error_px"] < 1.0  # 2D points scaled with the cameras


def test_originals_must_be_larger_for_every_photo(split, tmp_path):
    from anigs.photos import image_headers, list_images
    from anigs.sfm.colmap import larger_originals

    headers = image_headers(list_images(split["images"]))
    assert larger_originals(split["images"], headers) is None  # same size: nothing to gain
    small = {n: (w // 2, h // 2, o) for n, (w, h, o) in headers.items()}
    assert larger_originals(split["images"], small) == split["images"]
    assert larger_originals(tmp_path / "missing", small) is None


def test_a_stalled_mapping_restarts_with_the_next_seeds(split, tmp_path, monkeypatch, caplog):
    """The run's seed stalls the mapper (here: it maps 12 of the 20 photos on every rung, as seed 1 of the
    street capture stopped at 21 of 29 on every rung while seeds 0 and 2 reached 27): rung ``restart`` maps
    the same matches with seed + 1, + 2, ... and keeps the first that registers enough; without restarts the
    run is partial."""
    from anigs.sfm import steps

    real = steps.run_mapper
    seen = []

    def stall(database, image_dir, out_dir, cfg, names, mapper, angle):
        seen.append(cfg.seed)
        keep = names[:12] if cfg.seed in (7, 8) else names  # the run's seed and the first restart stall
        return real(database, image_dir, out_dir, cfg, keep, mapper, angle)

    monkeypatch.setattr(steps, "run_mapper", stall)
    cfg = _cfg(matcher="exhaustive", seed=7, partial_min_fraction=0.5)
    with caplog.at_level(logging.WARNING, logger="anigs.sfm"):
        res = run_sfm(split["images"], SfmOutputs(tmp_path / "sfm"), cfg)
    attempts = res.report["mapping"]["attempts"]
    restarts = [a for a in attempts if a["step"] == "restart"]
    assert [a["seed"] for a in restarts] == [8, 9], attempts  # stops at the first seed that registers enough
    assert restarts[0]["registered"] <= 12 and restarts[1]["registered"] == 20
    assert [a["seed"] for a in attempts if a["step"] == "reverify"] == [8]  # the first seed's pairs verified again
    assert all(a["seed"] == 7 for a in attempts if a["step"] not in ("restart", "reverify"))
    assert res.report["registered"] == 20 and res.report["status"] == "complete"
    assert "other mapper seeds (sfm.mapper_restarts)" in caplog.text
    seen.clear()
    off = run_sfm(split["images"], SfmOutputs(tmp_path / "off"), _cfg(matcher="exhaustive", seed=7, mapper_restarts=0,
                                                                       partial_min_fraction=0.5))
    assert off.report["status"] == "partial" and off.report["registered"] <= 12 and set(seen) == {7}


def test_a_restart_verifies_every_pair_again_with_its_seed(split, tmp_path, monkeypatch):
    """The verified pairs can be what stalls a mapping (the street capture's seed 1 on this machine: every mapper
    seed on its matches registered 21 or fewer of 29, the pairs verified with seeds 2-4 gave 27 with any mapper
    seed). Here the mapper stalls on the run's database whatever its seed: the restart maps the run's matches with
    seed 8 (stalled), then verifies every pair again with seed 8 in a copy of the database and maps that (all 20);
    the run's database keeps its matches."""
    from anigs.sfm import steps

    real = steps.run_mapper
    databases = []

    def stall(database, image_dir, out_dir, cfg, names, mapper, angle):
        databases.append(Path(database))
        keep = names if "reverify" in str(database) else names[:12]
        return real(database, image_dir, out_dir, cfg, keep, mapper, angle)

    real_match = rematch.match_every_pair
    before = []  # (database, verified pairs it holds when every pair is matched, the seed)

    def spy(database, cfg, device):
        before.append((Path(database), rematch.database_stats(database)["verified_pairs"], cfg.seed))
        return real_match(database, cfg, device)

    monkeypatch.setattr(steps, "run_mapper", stall)
    monkeypatch.setattr(rematch, "match_every_pair", spy)
    res = run_sfm(split["images"], SfmOutputs(tmp_path / "sfm"), _cfg(matcher="exhaustive", seed=7,
                                                                      partial_min_fraction=0.5))
    attempts = res.report["mapping"]["attempts"]
    assert [(a["step"], a["seed"]) for a in attempts][-2:] == [("restart", 8), ("reverify", 8)], attempts
    assert before[-1][0].parent.name == "reverify1" and before[-1][1:] == (0, 8)  # the copy's pairs cleared, seed 8
    first, again = attempts[-2], attempts[-1]
    assert first["registered"] <= 12 and again["registered"] == 20
    assert again["verified_pairs"] > 0 and again["match_seconds"] > 0
    assert databases[-1] != databases[-2] and databases[-1].parent.name == "reverify1"
    assert res.report["registered"] == 20 and res.report["status"] == "complete"


def test_mapper_restarts_is_checked():
    for bad in (-1, 65, 1.5, True):
        with pytest.raises(ValueError, match="mapper_restarts"):
            _cfg(mapper_restarts=bad)
