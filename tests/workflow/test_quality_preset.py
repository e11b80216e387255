"""config/quality.yaml (`--configfile config/quality.yaml`) validates against the workflow's schema on
top of the defaults, and raises what it says it raises."""
from __future__ import annotations

import copy
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]


def _load(name: str) -> dict:
    return yaml.safe_load((ROOT / "config" / name).read_text())


def test_quality_preset_validates_on_top_of_the_defaults():
    from snakemake.utils import validate

    from anigs.config import deep_merge

    base, preset = _load("config.yaml"), _load("quality.yaml")
    merged = deep_merge(copy.deepcopy(base), preset)
    validate(merged, str(ROOT / "workflow" / "schemas" / "config.schema.yaml"))  # raises on a bad key
    schema = yaml.safe_load((ROOT / "workflow" / "schemas" / "config.schema.yaml").read_text())["properties"]
    default = lambda sec, key: schema[sec]["properties"][key]["default"]  # noqa: E731
    assert default("static", "budget") == "auto" and merged["static"]["budget"] == "quality"
    assert merged["views"]["width"] > base["views"]["width"] and merged["animate"]["frames"] > base["animate"]["frames"]
    assert merged["update"]["steps"] > base["update"]["steps"]


def test_a_typo_in_a_preset_fails_validation():
    from snakemake.utils import validate
    from snakemake.exceptions import WorkflowError

    from anigs.config import deep_merge

    bad = deep_merge(_load("config.yaml"), {"static": {"iteratons": 7000}})
    with pytest.raises(WorkflowError):
        validate(bad, str(ROOT / "workflow" / "schemas" / "config.schema.yaml"))
