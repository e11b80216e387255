"""The plain-Python helpers the Snakefile's rules call: global settings, scene wildcards, the
accuracy-versus-time sweep's registration, and the ground-truth inputs."""
from __future__ import annotations

import json
import re

from anigs.config import scene_pattern
from anigs.stages.targets import FINAL_FILES, final_targets, stage_outputs
from anigs.reports.tradeoff import points_json, workflow_sweep
from anigs.stages.eval import Outputs as EvalOutputs, merge_halves
from anigs.stages.shared_inputs import GroundTruthInputs, ground_truth


def test_scene_pattern_matches_exactly_the_scenes_of_one_source():
    scenes = {"demo.v2": {"source": "synthetic"}, "yard": {"source": "photos"}}
    pat = scene_pattern(scenes, "synthetic")
    assert re.fullmatch(pat, "demo.v2") and not re.fullmatch(pat, "demoxv2") and not re.fullmatch(pat, "yard")
    assert not re.fullmatch(scene_pattern({"yard": {"source": "photos"}}, "synthetic"), "")


def test_workflow_sweep_registers_its_variants_and_derived_scenes():
    config = {"tradeoff": {"base": "full", "knobs": {"update.steps": [40, 120], "static.iterations": [500]}},
              "variant_overrides": {"full": {}}}
    scenes = {"demo": {"source": "synthetic"}}
    all_scenes = dict(scenes)
    base = {"update": {"steps": 120}, "static": {"iterations": 1000}}
    sweep = workflow_sweep(config, scenes, all_scenes, lambda s, name, v: base[name])
    variants = [p.variant for p in sweep["demo"]]
    assert variants[1] == "full"  # steps 120 is the base setting: the base point itself
    assert config["variant_overrides"][variants[0]] == {"update": {"steps": 40}}
    derived = [p.scene("demo") for p in sweep["demo"] if p.scene_tag]
    assert len(derived) == 1 and all_scenes[derived[0]]["static"] == {"iterations": 500}
    points = json.loads(points_json(sweep))["demo"]
    assert [p["variant"] for p in points] == variants and points[0] == {
        "variant": variants[0], "knob": "update.steps", "value": 40, "scene_tag": ""}


def test_ground_truth_fills_the_ground_truth_inputs_from_the_capture_folder():
    gt = ground_truth("res", "demo")
    names = {f for f in GroundTruthInputs.__dataclass_fields__} - {"canonical"}
    assert set(gt) == names
    assert gt["labels"] == "res/demo/capture/gt/labels.npy" and gt["gt_cameras"] == "res/demo/capture/gt/cameras.json"


def test_the_eval_rules_merge_joins_the_halves_and_notes_it(tmp_path):
    out = EvalOutputs(tmp_path / "eval")
    out.root.mkdir()
    rec = {"scene": "demo", "variant": "full", "method": "anigs", "dataset": "synthetic", "inputs": {}}
    out.path("clip_metrics").write_text(json.dumps({**rec, "part": "clips", "metrics": {"fvd": 1.0}}))
    out.path("model_metrics").write_text(json.dumps({**rec, "part": "model", "metrics": {"psnr": 30.0}}))
    log = tmp_path / "eval.log"
    merge_halves(str(out.path("metrics")), "c.json", "m.json", [], str(log))
    assert json.loads(out.path("metrics").read_text())["metrics"] == {"fvd": 1.0, "psnr": 30.0}
    assert log.read_text() == f"merged c.json, m.json and 0 FVD-GT record(s) into {out.path('metrics')}\n"


def test_the_default_target_asks_for_each_variants_final_files_then_the_effects_report():
    files = final_targets("res", ["a", "b"], ["full", "x"])
    assert len(files) == 2 * (2 * len(FINAL_FILES) + 1)
    assert files[:len(FINAL_FILES)] == [stage_outputs(st).under("res", k, scene="a", variant="full") for st, k in FINAL_FILES]
    assert files[2 * len(FINAL_FILES)] == "res/a/effects/effects.json" and files[-1] == "res/b/effects/effects.json"
