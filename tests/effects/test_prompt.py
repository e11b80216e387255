"""The prompt names the kinds that may move (anigs.effects.vocabulary), the effects stage follows it
with `effects: auto`, an explicit list overrides it, and a misspelt effect name in a scene file
fails when the workflow is parsed."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from anigs.effects.config import REGIONS
from anigs.effects.lexicon import GENERIC, PLANTS
from anigs.effects.vocabulary import prompt_kinds, vocabulary_markdown
from anigs.effects.choice import choose
from anigs.stages.effects import Outputs as EffectsOutputs

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("prompt, regions", [
    ("a garden with trees, bushes, grass and flowers swaying gently in the wind", ["foliage", "grass", "flowers"]),
    ("plants, leaves and flowers swaying gently in the wind", ["foliage", "flowers"]),
    ("a building with trees and lawns in the wind", ["foliage", "grass"]),
    ("a plant with fronds moving", ["foliage"]),
    ("an object in a room", []),
    ("a ROSE by the Fountain", ["foliage", "flowers", "water"]),  # a rose: its blossoms and its leaves
    ("a park", ["foliage", "grass", "flowers"]),
    ("a room without plants, lit by a lamp", []),
    ("no flowers, only trees in the wind", ["foliage"]),
    ("a meadow and a lake", ["grass", "water"]),
    ("", []),
])
def test_prompt_names_kinds(prompt, regions):
    assert prompt_kinds(prompt).regions == regions


def test_every_lexicon_word_names_its_kinds_and_the_table_lists_it():
    for w, regions in {**GENERIC, **PLANTS}.items():
        k = prompt_kinds(f"a {w} in the wind")
        assert k.regions == [r for r in REGIONS if r in regions], (w, k)
    table = vocabulary_markdown()
    assert all(w in table for w, regions in {**GENERIC, **PLANTS}.items() if regions)
    assert "garden" in (ROOT / "config" / "README.md").read_text()  # generated into the config docs


@pytest.mark.parametrize("prompt, words", [
    # inflections and plurals through the lemmatizer, not a list of word forms
    ("a flowering plant", {"flowering": ["flowers"], "plant": ["foliage"]}),
    ("blooming lilies", {"blooming": ["flowers"], "lilies": ["foliage", "flowers"]}),
    ("an overgrown wall", {"overgrown": ["foliage"]}),
    ("wolves and oxen under birches", {"birches": ["foliage"]}),
    # derived adjectives
    ("a leafy street and grassy hills", {"leafy": ["foliage"], "grassy": ["grass"]}),
    ("a flowery hillside", {"flowery": ["flowers"]}),
    # compounds by their parts
    ("wildflowers on a hillside", {"wildflowers": ["foliage", "flowers"]}),
    ("a rosebush", {"rosebush": ["foliage", "flowers"]}),
    ("a bamboo grove", {"bamboo": ["foliage"], "grove": ["foliage"]}),
    # plant names and crops map to their kinds; what the subject implies: a flowering shrub's blossoms
    ("an oak, a palm and ivy", {"oak": ["foliage"], "palm": ["foliage"], "ivy": ["foliage"]}),
    ("a rhododendron", {"rhododendron": ["foliage", "flowers"]}),
    ("a wheat field", {"wheat": ["grass"], "field": ["grass"]}),
    ("water lilies", {"water lilies": ["foliage", "flowers"]}),
    # what only looks like a kind names nothing
    ("a flowerpot and a treehouse", {}),
    ("a courtyard with parked cars", {}),
    ("a wood table", {}),
    ("trees waving", {"trees": ["foliage"]}),  # a verb form of "wave" is no water
])
def test_words_as_people_write_them(prompt, words):
    assert prompt_kinds(prompt).matches == words


@pytest.mark.parametrize("prompt, regions, negated, depicted", [
    # depictions and made things name nothing that moves (the words after "of", a word before the image)
    ("a painting of trees", [], [], ["trees"]),
    ("a fox on a wall covered in rose wallpaper, next to a painting of trees", [], [], ["rose", "trees"]),
    ("a room with flowers on the wall and a picture of trees", ["flowers"], [], ["trees"]),
    ("a still life of tulips", [], [], ["tulips"]),
    ("the reflection of trees in the lake", ["water"], [], ["trees"]),  # the lake itself is real
    ("plastic potted plants and fake flowers", [], [], ["plants", "flowers"]),
    ("a metal tree sculpture", [], [], ["tree"]),
    ("a stone wall with ivy", ["foliage"], [], []),  # "stone" is the wall's, not the ivy's
    ("a wooden planter with ferns", ["foliage"], [], []),
    # what the prompt says stays still: a negated motion verb or a stillness after a verb of staying
    ("the trees sway and the flowers stay still", ["foliage"], ["flowers"], []),
    ("the trees and the flowers must not move", [], ["trees", "flowers"], []),
    ("trees that don't move", [], ["trees"], []),
    ("the trees are still swaying", ["foliage"], [], []),  # "still" as "yet"
    ("the grass is motionless, but the trees sway", ["foliage"], ["grass"], []),
    ("not only the trees but also the flowers sway", ["foliage", "flowers"], [], []),
    ("a tree trunk, nothing moving", [], ["tree"], []),  # the whole scene
    ("trees and a lawn on a day with no wind", [], ["trees", "lawn"], []),
    ("trees bending in the wind, no flowers", ["foliage"], ["flowers"], []),
    # a scene word's kinds less those switched off; a plant named outright keeps its own
    ("a garden with no flowers", ["foliage", "grass"], ["flowers"], []),
    ("a rose garden without trees", ["foliage", "grass", "flowers"], ["trees"], []),
    ("a parkland without trees", ["grass", "flowers"], ["trees"], []),  # a scene word like "garden"
])
def test_what_is_depicted_or_said_to_stay_still_names_nothing(prompt, regions, negated, depicted):
    k = prompt_kinds(prompt)
    assert (k.regions, k.negated, k.depicted) == (regions, negated, depicted), k
    assert k.unknown == []


def test_words_not_understood_are_listed():
    k = prompt_kinds("a flwers garden with a zorbleflax, a chateau and a trunk")
    assert k.unknown == ["flwers", "zorbleflax"]  # typos and rare words; function words and still things are not listed
    assert k.regions == ["foliage", "grass", "flowers"]  # the garden
    assert prompt_kinds("a fox on a table in a living room").unknown == []
    assert prompt_kinds("Bäume and trees").unknown == ["bäume"]  # a word of another language, whole


def test_words_matched_are_recorded():
    k = prompt_kinds("Trees and a flower bed")
    assert k.matches == {"trees": ["foliage"], "flower bed": ["flowers"]}
    assert k.effects == ["foliage_sway", "leaf_flutter", "flower_bob"]


def test_choose_follows_the_prompt_unless_a_list_is_given():
    detected = ["foliage_sway", "leaf_flutter", "flower_bob"]
    assert choose(detected, "auto", ["foliage_sway", "leaf_flutter"]) == (["foliage_sway", "leaf_flutter"], [])
    assert choose(detected, "auto", []) == ([], [])
    assert choose(detected, "auto", ["water_ripple"]) == ([], ["water_ripple"])
    assert choose(detected, ["flower_bob"], ["foliage_sway"]) == (["flower_bob"], [])  # the list overrides


@pytest.fixture(scope="module")
def garden_stage(tmp_path_factory):
    """A small garden capture written as the effects stage's inputs."""
    from anigs.cameras import save_cameras
    from anigs.images import write_rgb_png
    from anigs.synth import CameraPathConfig, SceneConfig, build_scene, camera_path, render_image

    tmp = tmp_path_factory.mktemp("garden")
    g = build_scene(SceneConfig(num_gaussians=6000), 0)
    cams = camera_path(CameraPathConfig(num_images=8, width=128, height=96), 0)
    g.save_ply(tmp / "canonical.ply")
    save_cameras(tmp / "cameras.json", cams)
    for cam in cams:
        write_rgb_png(tmp / "images" / cam.name, render_image(g, cam))
    return tmp


def _run(tmp: Path, out: str, params: dict, prompt: str | None = None) -> dict:
    from anigs.cli import main

    args = ["effects", "--canonical", str(tmp / "canonical.ply"), "--cameras", str(tmp / "cameras.json"),
            "--images", str(tmp / "images"), "--out", str(tmp / out), "--params", json.dumps(params)]
    if prompt is not None:
        args += ["--prompt", prompt]
    assert main(args) == 0
    return EffectsOutputs(tmp / out).report()


def test_a_prompt_naming_nothing_that_moves_gives_a_still_scene(garden_stage):
    doc = _run(garden_stage, "still", {"prompt": "a wooden bench in a courtyard by a qwertzy"})
    assert doc["chosen"] == [] and doc["detected"] == [] and doc["requested_not_found"] == []
    assert doc["prompt"]["unknown"] == ["qwertzy"] and "qwertzy" in doc["prompt"]["unknown_note"]
    assert "names nothing that moves" in doc["prompt"]["note"] and doc["prompt"]["used"]
    assert not EffectsOutputs(garden_stage / "still").dynamic().any()
    for e, r in doc["effects"].items():
        assert "the prompt does not name it" in r["reason"], (e, r["reason"])


def test_a_prompt_naming_only_painted_or_still_plants_gives_a_still_scene_and_says_why(garden_stage):
    doc = _run(garden_stage, "painted", {"prompt": "a painting of trees; the grass stays still"})
    assert doc["chosen"] == [] and not EffectsOutputs(garden_stage / "painted").dynamic().any()
    assert doc["prompt"]["depicted"] == ["trees"] and doc["prompt"]["negated"] == ["grass"]
    note = doc["prompt"]["switched_off_note"]
    assert "depicted or made, not alive: trees" in note and "said to stay still: grass" in note
    assert "names nothing that moves (its words of the vocabulary are negated" in doc["prompt"]["note"]


def test_a_prompt_naming_only_trees_never_chooses_flowers(garden_stage):
    doc = _run(garden_stage, "trees", {}, prompt="tall trees by a pond in the wind")
    assert doc["chosen"] == ["foliage_sway", "leaf_flutter"]
    assert doc["prompt"]["words"] == {"trees": ["foliage"], "pond": ["water"]}
    assert doc["requested_not_found"] == ["water_ripple"]  # named, not in the garden
    regions = np.load(garden_stage / "trees" / "regions.npy")
    assert not (regions == REGIONS.index("flowers")).any() and not (regions == REGIONS.index("grass")).any()
    listed = _run(garden_stage, "listed", {"requested": ["flower_bob"]}, prompt="tall trees in the wind")
    assert listed["chosen"] == ["flower_bob"] and listed["prompt"]["used"] is False  # the list overrides


def test_a_misspelt_effect_in_a_scene_file_fails_at_parse_time(tmp_path):
    from anigs.config import load_scene

    schema = yaml.safe_load((ROOT / "workflow" / "schemas" / "config.schema.yaml").read_text())
    (tmp_path / "bad.yaml").write_text("source: synthetic\neffects: [foliage_swayy]\n")
    with pytest.raises(ValueError, match=r"foliage_swayy.*foliage_sway.*leaf_flutter.*water_ripple"):
        load_scene(tmp_path, "bad", schema)
    (tmp_path / "auto.yaml").write_text("source: synthetic\neffects: autoo\n")
    with pytest.raises(ValueError, match="autoo"):
        load_scene(tmp_path, "auto", schema)
    (tmp_path / "good.yaml").write_text("source: synthetic\neffects: [foliage_sway, flower_bob]\n")
    assert load_scene(tmp_path, "good", schema)["effects"]["requested"] == ["foliage_sway", "flower_bob"]


def test_shipped_scene_prompts_name_their_effects():
    """Each shipped scene file's prompt names the kinds of the effects it lists (the demo's prompt,
    "a garden with trees, bushes, grass and flowers ...", names foliage, grass and flowers)."""
    from anigs.effects.config import EFFECT_REGION

    checked = 0
    for path in sorted((ROOT / "config" / "scenes").glob("*.yaml")):
        scene = yaml.safe_load(path.read_text()) or {}
        listed, prompt = scene.get("effects"), scene.get("prompt")
        if isinstance(listed, list) and prompt:
            assert {EFFECT_REGION[e] for e in listed} <= set(prompt_kinds(prompt).regions), path.name
            checked += 1
    assert checked >= 1
