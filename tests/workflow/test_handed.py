"""Settings read once (anigs.config.HANDED): the run's seed, device and playback fps and the scene's background are
set in one place each, handed to every section that takes them, and refused where a stage section sets them."""
from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from anigs.config import HANDED, check_sections, load_scene, section

ROOT = Path(__file__).resolve().parents[2]
SCHEMA = yaml.safe_load((ROOT / "workflow/schemas/config.schema.yaml").read_text())
CONFIG = {"seed": 7, "device": "cpu", "fps": 24, "variant_overrides": {"full": {}}}
SKY = [0.1, 0.2, 0.3]


def _leaves(node: dict, path: str = "") -> list[str]:
    props = node.get("properties")
    if not props:
        return [path]
    return [leaf for k, v in props.items() for leaf in _leaves(v, f"{path}.{k}" if path else k)]


def _handed_paths(node: dict, path: str) -> list[str]:
    out = [f"{path}.{k}" for k in node.get("x-handed", ())]
    for k, sub in node.get("properties", {}).items():
        out += _handed_paths(sub, f"{path}.{k}")
    return out


#: where each setting is a key: seed, device and the playback fps at the workflow's top level, background in the
#: scene file (not the workflow config); the rates at which the video prior and the physics baseline generate
#: their motion (frequencies in Hz) are the prior's, not the playback's
WHERE = {"seed": ["seed"], "device": ["device"], "background": [],
         "fps": ["fps", "animate.physics.fps", "refine.procedural.fps"]}


@pytest.mark.parametrize("key", sorted(HANDED))
def test_the_schema_has_one_key_for_each_setting(key):
    assert [leaf for leaf in _leaves(SCHEMA) if leaf.rsplit(".", 1)[-1] == key] == WHERE[key]


def test_every_section_that_takes_a_setting_gets_the_one_value():
    scene = {"name": "s", "source": "photos", "background": SKY}
    paths = [p for name in SCHEMA["properties"] if name in {"sfm", "static", "views", "masks", "effects", "animate",
                                                               "render_clip", "refine", "update", "final", "view",
                                                               "eval", "fvd_gt"}
             for p in _handed_paths(SCHEMA["properties"][name], name)]
    assert len(paths) >= 25  # seed, device and background of 16 classes and their nested sections
    want = {"seed": 7, "device": "cpu", "background": SKY, "fps": 24}
    for path in paths:
        name, *rest = path.split(".")
        node = section(CONFIG, scene, "full", name, SCHEMA)
        for part in rest:
            node = node[part]
        assert node == want[rest[-1]], path


def test_without_a_scene_background_each_stage_keeps_its_own():
    static = section(CONFIG, {"name": "s", "source": "photos"}, "full", "static", SCHEMA)
    assert "background" not in static and static["seed"] == 7 and static["device"] == "cpu"


@pytest.mark.parametrize("override,old", [({"static": {"seed": 3}}, "static.seed"),
                                          ({"sfm": {"device": "cpu"}}, "sfm.device"),
                                          ({"final": {"background": SKY}}, "final.background"),
                                          ({"eval": {"multiview_fit": {"seed": 1}}}, "eval.multiview_fit.seed"),
                                          ({"masks": {"sam2": {"device": "cuda"}}}, "masks.sam2.device"),
                                          ({"export": {"fps": 24}}, "export.fps")])
def test_a_section_that_sets_one_fails_naming_where_it_is_set_now(override, old):
    key = old.rsplit(".", 1)[-1]
    with pytest.raises(ValueError, match=rf"{old} is now {key}, set once at the top level of the "
                                         rf"{'scene file' if key == 'background' else 'workflow config'}"):
        check_sections(override, SCHEMA, "config: variant_overrides.x")


def test_a_scene_file_that_sets_one_in_a_section_fails(tmp_path):
    (tmp_path / "old.yaml").write_text("source: synthetic\nstatic: {background: [0, 0, 0]}\n")
    with pytest.raises(ValueError, match=r"old\.yaml: static\.background is now background"):
        load_scene(tmp_path, "old", SCHEMA)


SCENE_FILES = sorted((ROOT / "config/scenes").glob("*.yaml")) + sorted((ROOT / "benchmarks/real/scenes").glob("*.yaml"))


@pytest.mark.parametrize("path", SCENE_FILES, ids=[f"{p.parent.parent.name}/{p.name}" for p in SCENE_FILES])
def test_every_scene_file_in_the_repository_parses(path):
    """The stage sections of the scene files the repository ships (config/scenes, the labelled benchmark's)
    pass the schema: none sets a setting that is read once now."""
    scene = yaml.safe_load(path.read_text())
    if isinstance(scene.get("effects"), (list, str)):
        scene["effects"] = {"requested": scene["effects"]}
    check_sections(scene, SCHEMA, str(path))
    assert not [k for k in HANDED if k != "background" and k in scene]


def test_the_workflow_configs_in_the_repository_parse():
    for path in sorted((ROOT / "config").glob("*.yaml")):
        check_sections(yaml.safe_load(path.read_text()) or {}, SCHEMA, str(path))
