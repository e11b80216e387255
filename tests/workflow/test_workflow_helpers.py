"""The plain-Python helpers the Snakefile's rules call: global settings, scene wildcards, the
accuracy-versus-time sweep's registration, and the ground-truth inputs."""
from __future__ import annotations

import json
import re

from anigs.config import scene_pattern, with_globals
from anigs.reports.tradeoff import points_json, workflow_sweep
from anigs.stages.shared_inputs import GroundTruthInputs, ground_truth


def test_a_sections_own_device_wins_over_the_global_one():
    assert with_globals({"device": "cpu", "a": 1}, {"device": "cuda", "seed": 3}) == {"device": "cpu", "a": 1, "seed": 3}
    assert with_globals({"device": "auto"}, {"device": "cuda"}) == {"device": "cuda"}
    assert with_globals({"a": 1}, {"seed": 3}) == {"a": 1, "seed": 3}


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
