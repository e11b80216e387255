"""Nested config sections are typed dataclasses; the schema and config/README.md are walked from the types."""
from __future__ import annotations

import dataclasses
import importlib.util
import inspect
import sys
import typing
from pathlib import Path
from types import SimpleNamespace

import pytest
import yaml

from anigs.stages import STAGES, BY_NAME

ROOT = Path(__file__).resolve().parents[2]

# (section, nested key) -> the dataclass it parses into
NESTED = {("masks", "vegetation"): "VegetationConfig", ("masks", "labels"): "LabelsConfig",
          ("masks", "sam2"): "Sam2Config", ("masks", "lift"): "LiftConfig",
          ("animate", "lifting"): "LiftingConfig", ("animate", "physics"): "PhysicsConfig",
          ("refine", "procedural"): "ProceduralConfig", ("refine", "ltx"): "LTXConfig",
          ("eval", "multiview_fit"): "MultiviewFitConfig",
          ("effects", "photos"): "PhotosConfig", ("effects", "cues"): "CuesConfig",
          ("effects", "regions"): "RegionsConfig", ("effects", "lift"): "LiftConfig",
          ("effects", "rules"): "RulesConfig", ("effects", "decide"): "DecideConfig"}


def _script(name: str):
    spec = importlib.util.spec_from_file_location(name, ROOT / "workflow" / "scripts" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _schema() -> dict:
    return yaml.safe_load((ROOT / "workflow/schemas/config.schema.yaml").read_text())


def _config_classes() -> list[type]:
    """Every config dataclass the stage sections reach (their bases and nested sections)."""
    out: list[type] = []

    def walk(cls):
        for b in cls.__mro__:
            if dataclasses.is_dataclass(b) and b not in out:
                out.append(b)
        hints = typing.get_type_hints(cls)
        for f in dataclasses.fields(cls):
            if dataclasses.is_dataclass(hints[f.name]):
                walk(hints[f.name])

    for s in STAGES:
        if s.section:
            walk(s.config_class())
    return out


@pytest.mark.parametrize("section,key", sorted(NESTED))
def test_a_nested_section_parses_into_its_dataclass_and_names_an_unknown_key(section, key):
    cls = BY_NAME[section].config_class()
    cfg = cls.from_dict({key: {}})
    sub = getattr(cfg, key)
    assert dataclasses.is_dataclass(sub) and type(sub).__name__ == NESTED[(section, key)]
    assert sub == getattr(cls(), key)  # an empty mapping is the defaults
    with pytest.raises((ValueError, KeyError), match=rf"{key}.*no_such_key"):
        cls.from_dict({key: {"no_such_key": 1}})
    with pytest.raises((ValueError, KeyError), match=key):
        cls.from_dict({key: [1, 2]})


def test_nested_values_are_checked_by_their_own_class():
    from anigs.animate.config import AnimateConfig
    from anigs.stages.masks import MasksConfig

    assert MasksConfig.from_dict({"lift": {"min_views": 3}}).lift.min_views == 3
    with pytest.raises(ValueError, match="min_views"):
        MasksConfig.from_dict({"lift": {"min_views": 0}})
    with pytest.raises(ValueError, match="integrator"):
        AnimateConfig.from_dict({"physics": {"integrator": "rk4"}})


def test_the_refine_stage_sets_the_priors_derived_keys():
    from anigs.stages.refine import RefineConfig

    with pytest.raises(ValueError, match="effects.*top level"):
        RefineConfig.from_dict({"procedural": {"effects": ["grass_wave"]}})
    with pytest.raises(ValueError, match="steps.*top level"):
        RefineConfig.from_dict({"ltx": {"steps": 3}})
    cfg = RefineConfig.from_dict({"effects": ["grass_wave"], "steps": 5, "procedural": {"fps": 10}})
    assert cfg.prior_config()["effects"] == ["grass_wave"] and cfg.prior_config()["fps"] == 10
    assert RefineConfig.from_dict({"prior": "ltx", "steps": 5}).prior_config()["steps"] == 5
    props = _schema()["properties"]["refine"]["properties"]
    assert "effects" not in props["procedural"]["properties"] and "steps" not in props["ltx"]["properties"]


def test_typed_defaults_are_those_the_code_used_before():
    """The labels backend's keywords and the protocol's fit keep their defaults."""
    from anigs.masks.labels_backend import LabelsBackend, LabelsConfig
    from anigs.metrics.multiview import MultiviewFitConfig
    from anigs.static.fit import StaticConfig

    sig = inspect.signature(LabelsBackend)
    assert dataclasses.asdict(LabelsConfig()) == {k: sig.parameters[k].default for k in ("threshold", "min_alpha")}
    # the protocol used to fill these into StaticConfig's keys (device: the eval section's when unset)
    # (and, since the static budget, the 0.7 static defaults the protocol was measured with: 1500 steps and
    # 30,000 Gaussians, a black background, threshold growth, no far points)
    before = StaticConfig.from_dict({"holdout_every": 0, "eval_every": 0, "checkpoint_every": 0,
                                  "regularize": {"enabled": False}, "budget": "fast", "background": [0.0, 0.0, 0.0],
                                  "far_share": 0.0, "densify": {"growth": "threshold"}})
    now = MultiviewFitConfig.from_dict({})
    assert now.device is None
    assert {**dataclasses.asdict(now), "device": before.device} == dataclasses.asdict(before)


def _keys(node: dict) -> dict:
    return {k: _keys(v) for k, v in node.get("properties", {}).items()}


def test_the_schema_is_the_types():
    """Every section's key tree (nested sections included) is its dataclass's field tree, with the
    fields' defaults, less the fields the workflow hands in (``HANDED``: seed, device, background, fps);
    a nested section is a closed object."""
    schema = _schema()["properties"]

    def tree(cls, skip=()):
        hints, derived = typing.get_type_hints(cls), getattr(cls, "DERIVED", {})
        skip = (*skip, *getattr(cls, "HANDED", ()))
        return {f.name: tree(hints[f.name], derived.get(f.name, ())) if dataclasses.is_dataclass(hints[f.name]) else {}
                for f in dataclasses.fields(cls) if f.name not in skip}

    def defaults(obj, node, path):
        """The schema's defaults are those of the section's default instance, nested ones included
        (a nested section's default in its parent may differ from its class's own defaults)."""
        for f in dataclasses.fields(obj):
            p = node["properties"].get(f.name)
            if p is None:
                continue
            value = getattr(obj, f.name)
            if dataclasses.is_dataclass(value):
                assert p["type"] == "object" and p["additionalProperties"] is False, f"{path}.{f.name}"
                defaults(value, p, f"{path}.{f.name}")
            else:
                assert p["default"] == (list(value) if isinstance(value, tuple) else value), f"{path}.{f.name}"

    for s in STAGES:
        if s.section:
            assert _keys(schema[s.name]) == tree(s.config_class()), s.name
            defaults(s.config_class()(), schema[s.name], s.name)
    assert schema["eval"]["properties"]["multiview_fit"]["properties"]["regularize"]["properties"]["enabled"][
        "default"] is False  # the protocol's fit: no regulariser unless asked
    for section, key in NESTED:
        assert schema[section]["properties"][key]["properties"], (section, key)


def test_every_config_field_has_a_doc():
    docs = _script("make_schema").field_docs
    missing = [f"{c.__module__}.{c.__name__}.{f.name}" for c in _config_classes()
               for f in dataclasses.fields(c) if not docs(c).get(f.name)]
    assert not missing, f"fields without a doc (a trailing comment or #: lines above): {missing}"


def test_field_docs_reads_trailing_comments_continuations_and_hash_colon_blocks(tmp_path):
    ms = _script("make_schema")
    src = tmp_path / "_doc_fixture.py"
    src.write_text('from dataclasses import dataclass, field\n\n\n@dataclass\nclass Fixture:\n'
                   '    a: int = 1  # one line\n'
                   '    b: int = 2  # first part\n'
                   '                # second part\n'
                   '    #: above, line one\n'
                   '    #: line two\n'
                   '    c: list = field(default_factory=list)\n'
                   '    # a plain comment above documents nothing\n'
                   '    d: int = 4\n')
    try:
        spec = importlib.util.spec_from_file_location("_doc_fixture", src)
        mod = importlib.util.module_from_spec(spec)
        sys.modules["_doc_fixture"] = mod
        spec.loader.exec_module(mod)
        docs = ms.field_docs(mod.Fixture)
        ms.MISSING.clear()
        ms.dataclass_schema(mod.Fixture, ("fixture",))
    finally:
        sys.modules.pop("_doc_fixture", None)
    assert docs == {"a": "one line", "b": "first part second part", "c": "above, line one line two"}
    assert ms.MISSING == ["fixture.d (_doc_fixture.Fixture.d)"]  # the generator refuses an undocumented field


def test_config_yaml_lines_are_short():
    long = [n for n, line in enumerate((ROOT / "config/config.yaml").read_text().splitlines(), 1) if len(line) > 120]
    assert not long, f"config/config.yaml lines over 120 characters: {long}"


def test_the_results_layout_lists_each_outputs_file_under_its_stage_folder():
    from anigs.contract import File, Outputs

    class MasksOut(Outputs):
        FOLDER = "{scene}/masks"
        LAYOUT = {"mask": File("{view}.png", "uint8 [H, W]: the mask"),
                  "labels": File("effect_labels.npy", "int8 [N]: a|b", optional=True)}

    class RoundOut(MasksOut):
        FOLDER = "{scene}/{variant}/round{round}"

    docs = _script("make_config_docs")
    stage = SimpleNamespace(name="masks", scope="scene", load=lambda: SimpleNamespace(Outputs=MasksOut))
    update = SimpleNamespace(name="update", scope="variant", load=lambda: SimpleNamespace(Outputs=RoundOut))
    bare = SimpleNamespace(name="tables", scope="global", load=lambda: SimpleNamespace())
    text = docs.results_layout([stage, update, bare])
    assert "### `results/{scene}/masks/` (masks)" in text
    assert "### `results/{scene}/{variant}/round{round}/` (update)" in text
    assert "| `{view}.png` | uint8 [H, W]: the mask |" in text
    assert "| `effect_labels.npy` (optional) | int8 [N]: a\\|b |" in text
    assert "no files of their own: tables." in text


def test_every_stage_with_a_command_is_in_the_results_layout():
    """Every stage's folders appear (from its Outputs' FOLDER; tests/workflow/test_rule_outputs.py checks
    the FOLDERs against the rules' outputs)."""
    from anigs.contract import outputs_of

    docs = _script("make_config_docs")
    text = docs.results_layout()
    for s in STAGES:
        if s.command:
            types_ = outputs_of(s.load())
            assert types_, s.name
            for o in types_:
                assert f"### `{docs.stage_folder(o)}`" in text, (s.name, o.FOLDER)


def test_workflow_comments_do_not_list_the_stages():
    """The stage list is STAGES (anigs/registry.py): the comments of the Snakefile and the
    profiles refer to it instead of copying it (the copies went stale)."""
    import re

    names = {s.name for s in STAGES}
    for path in [ROOT / "Snakefile", *sorted((ROOT / "workflow/profiles").rglob("*.yaml"))]:
        blocks, block = [], []
        for line in path.read_text().splitlines() + [""]:
            if line.lstrip().startswith("#"):
                block.append(line)
            elif block:
                blocks.append(" ".join(block))
                block = []
        for text in blocks:
            found = names & set(re.findall(r"[a-z_]+", text))
            assert len(found) < 6, f"{path.name}: a comment lists the stages {sorted(found)}; refer to STAGES"
