"""The workflow tests' divergence report (tests/workflow/_diverge.py): the first differing stage in
pipeline order, the JSON files that differ beyond paths and timings, the trees kept."""
from __future__ import annotations

import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from _diverge import by_stage, first_stage, json_differences, keep_trees, report, stage_of  # noqa: E402


def test_first_stage_follows_the_pipeline_not_the_alphabet():
    keys = ["tiny/static/canonical.ply", "tiny/full/round2/model.pt", "tiny/effects/dynamic.npy",
            "tiny/sfm/points.npz", "tiny/full/round1/target/v00.npz", "tiny/masks/dynamic.npy"]
    assert first_stage(keys) == "sfm"  # sorted by name, effects/ would come first
    assert first_stage(keys[1:2] + keys[4:5]) == "round1"
    assert first_stage(["tiny/full/final/clips/v00.npz", "tiny/full/eval/metrics.json"]) == "final"
    assert first_stage([]) is None
    assert list(by_stage(keys)) == ["sfm", "static", "effects", "masks", "round1", "round2"]
    assert stage_of("tiny/full/viewer/index.html")[2] == "view"
    assert stage_of("tiny/elsewhere/x.npy")[0] > stage_of("tiny/full/eval/m.json")[0]  # unknown folders last


def _tree(root: Path, cams: list, seconds: float) -> Path:
    (root / "tiny" / "sfm").mkdir(parents=True)
    (root / "tiny" / "sfm" / "cameras.json").write_text(json.dumps({"cameras": cams}))
    (root / "tiny" / "sfm" / "report.json").write_text(json.dumps({"out": str(root / "tiny"), "timings_s": seconds}))
    return root


def test_json_differences_ignore_roots_and_timings_only(tmp_path):
    a = _tree(tmp_path / "a", [1.0, 2.0], 3.0)
    b = _tree(tmp_path / "b", [1.0, 2.0], 9.0)
    assert json_differences(a, b) == []
    (b / "tiny" / "sfm" / "cameras.json").write_text(json.dumps({"cameras": [1.0, 2.5]}))
    assert json_differences(a, b) == ["tiny/sfm/cameras.json"]


def test_failed_comparison_keeps_both_trees(tmp_path, monkeypatch):
    a = _tree(tmp_path / "a", [1.0], 1.0)
    b = _tree(tmp_path / "b", [2.0], 1.0)
    monkeypatch.setenv("ANIGS_KEEP_FAILED", str(tmp_path / "kept"))
    kept = keep_trees({"uninterrupted": a, "resumed": b}, tmp_path / "unused")
    assert kept == tmp_path / "kept" and not (tmp_path / "unused").exists()
    assert (kept / "resumed" / "tiny" / "sfm" / "cameras.json").read_text() == '{"cameras": [2.0]}'
    msg = report(["tiny/static/canonical.ply", "tiny/sfm/points.npz"], a, b, kept)
    assert msg.splitlines()[0] == "first differing stage: sfm"
    assert "tiny/sfm/cameras.json" in msg and str(kept) in msg
    monkeypatch.delenv("ANIGS_KEEP_FAILED")
    assert keep_trees({"x": a}, tmp_path / "fallback") == tmp_path / "fallback"
