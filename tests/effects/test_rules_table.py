"""The effects section nested by step and rule, and the table of rules (anigs.effects.rules).

A key of the old flat section (anigs 0.13 and earlier) fails when the config is read, naming its new
key; every rule is a unit whose knobs are its own section; each region's candidates go through its row
of the table in order, and the first rule that gives a verdict decides.
"""
from __future__ import annotations

import dataclasses
import inspect
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import yaml

from anigs.config import check_sections, load_scene
from anigs.effects import rules as table
from anigs.effects.config import RENAMED, EffectsConfig
from anigs.effects.rules import BEFORE, TABLE, AFTER, Candidate, Verdict, rule_classes

ROOT = Path(__file__).resolve().parents[2]


def _schema() -> dict:
    return yaml.safe_load((ROOT / "workflow/schemas/config.schema.yaml").read_text())


@pytest.mark.parametrize("old", sorted(RENAMED))
def test_an_old_flat_key_fails_naming_its_new_key(old):
    new = re.escape(RENAMED[old].split(" and ")[0])
    with pytest.raises(ValueError, match=rf"effects config: {old} is now {new}"):
        EffectsConfig.from_dict({old: 1})


def test_every_new_key_exists():
    cfg = EffectsConfig()
    for old, new in RENAMED.items():
        if new.startswith("the constant "):  # a knob that moved no figure: a constant now (FIXED)
            continue
        for path in new.replace("effects.", "").split(" and "):
            node = cfg
            for part in path.split("."):
                assert hasattr(node, part), (old, new)
                node = getattr(node, part)


def test_an_old_key_in_a_scene_file_or_a_variant_names_its_new_key(tmp_path):
    (tmp_path / "old.yaml").write_text("source: synthetic\neffects: {plane_max_share: 0.5}\n")
    with pytest.raises(ValueError, match=r"old\.yaml.*effects\.plane_max_share is now effects\.rules\.plane\.max_share"):
        load_scene(tmp_path, "old", _schema())
    with pytest.raises(ValueError, match=r"variant_overrides\.x.*effects\.max_photos is now effects\.photos\.max_photos"):
        check_sections({"effects": {"max_photos": 4}}, _schema(), "config: variant_overrides.x")
    (tmp_path / "new.yaml").write_text("source: synthetic\neffects: {rules: {plane: {max_share: 0.5}}}\n")
    assert load_scene(tmp_path, "new", _schema())["effects"]["rules"]["plane"]["max_share"] == 0.5


def test_a_rules_knobs_are_its_own_section():
    cfg = EffectsConfig.from_dict({"rules": {"plane": {"max_share": 0.5}, "own_colour": {"min_share": 0.2}}})
    assert cfg.rules.plane.max_share == 0.5 and cfg.rules.own_colour.min_share == 0.2
    with pytest.raises(ValueError, match=r"effects\.rules.*plane.*maxshare"):
        EffectsConfig.from_dict({"rules": {"plane": {"maxshare": 0.5}}})
    assert cfg.to_dict()["rules"]["plane"]["max_share"] == 0.5


KNOBS_FIXED = [("plane", "sample", "SAMPLE"), ("held", "min_share", "MIN_ATTACHED"),
               ("blossoms", "min_share", "MIN_ATTACHED"), ("own_colour", "min_white_share", "MIN_WHITE_SHARE"),
               ("own_colour", "white_max_saturation", "WHITE_MAX_SATURATION"),
               ("own_colour", "white_min_value", "WHITE_MIN_VALUE"), ("own_colour", "light_min_above", "LIGHT_MIN_ABOVE"),
               ("sunlit_leaves", "min_in_crown", "MIN_IN_CROWN"), ("made_surface", "min_turning", "MIN_TURNING")]


@pytest.mark.parametrize("rule,key,const", KNOBS_FIXED, ids=[f"{r}.{k}" for r, k, _ in KNOBS_FIXED])
def test_a_knob_that_moved_no_figure_is_a_constant_and_its_key_says_so(rule, key, const, tmp_path):
    """Issue 49, item 4: the knobs that moved no figure of the labelled benchmark or the decoys at half and 1.5
    times their value (benchmarks/knob_sensitivity.py) are constants of their rule's module; the old key fails
    naming the constant, in code and in a scene file."""
    with pytest.raises(ValueError, match=rf"{key} is now the constant {const} = "):
        EffectsConfig.from_dict({"rules": {rule: {key: 1}}})
    (tmp_path / "old.yaml").write_text(f"source: synthetic\neffects: {{rules: {{{rule}: {{{key}: 1}}}}}}\n")
    with pytest.raises(ValueError, match=rf"effects\.rules\.{rule}\.{key} is now the constant {const}"):
        load_scene(tmp_path, "old", _schema())


def test_every_rule_is_a_unit_with_its_purpose_motivation_and_test():
    names = [r.NAME for r in rule_classes()]
    assert len(names) == len(set(names))
    assert names == [f.name for f in dataclasses.fields(EffectsConfig().rules)][2:]  # the config follows the table
    for cls in rule_classes():
        assert dataclasses.is_dataclass(cls) and cls.__dataclass_params__.frozen, cls
        doc = inspect.getmodule(cls).__doc__
        assert "Motivation:" in doc and "Test:" in doc, cls
        for test in doc.split("Test:")[1].split("``")[1::2]:
            if test.startswith("tests/"):
                assert (ROOT / test).exists(), (cls, test)
    for row in TABLE.values():
        assert all(callable(getattr(r, "check", None)) for r in row)
    assert all(hasattr(r, "apply") for r in BEFORE) and all(hasattr(r, "review") for r in AFTER)


def test_a_row_runs_in_order_until_a_rule_decides(monkeypatch):
    calls = []

    @dataclass(frozen=True)
    class Probe:
        NAME: str
        verdict: Verdict | None = None

        def check(self, cand: Candidate, ctx) -> Verdict | None:
            calls.append(self.NAME)
            return self.verdict

    @dataclass
    class Rules:
        link_frac: float = 1.0
        min_candidate: int = 1
        first: Probe = Probe("first")
        second: Probe = Probe("second", Verdict("second", "still"))
        third: Probe = Probe("third", Verdict("third", "moved", moved_to="foliage"))

    monkeypatch.setitem(TABLE, "grass", (Probe("first"), Probe("second"), Probe("third")))
    means = np.array([[0.0, 0, 0], [0.05, 0, 0], [0.1, 0, 0]])
    ctx = table.Context(means, np.full((3, 3), 0.5), np.array([1, 1, 1]), None, 1.0, 1.0, 0.2,
                        EffectsConfig().regions.bands())
    out = table.run_table(ctx, Rules())
    assert calls == ["first", "second"]  # the third is never asked
    assert out.region_of.tolist() == [-1, -1, -1]
    (cand,) = out.candidates
    assert (cand.kept, cand.rule, cand.reason, cand.number) == (False, "second", "still", 1)
