"""Every rule named after a stage writes only files its stage's ``Outputs`` names, in its folder.

The workflow is loaded through the Snakemake API (the demo config; no job runs). For each stage
of :data:`anigs.stages.STAGES` whose module has an ``Outputs`` type, its rules (the rule of the
stage's name and those named ``<stage>_...``) must declare outputs that are either the stage's
folder itself (a ``directory()`` of the whole folder) or ``<folder>/<LAYOUT name>`` for an entry of
its ``LAYOUT``, all in one folder (for a per-scene stage: ``results/{scene}/<stage>``); and every
entry not marked ``optional`` is declared by one of the rules (unless a rule declares the whole
folder).
"""
from __future__ import annotations

import re
from pathlib import Path

import pytest

from anigs.stages import STAGES

ROOT = Path(__file__).resolve().parents[2]
WILDCARD = re.compile(r"\{(\w+),[^{}]*(?:\{[^{}]*\}[^{}]*)*\}")  # {name,constraint} -> {name}


def _plain(path: str) -> str:
    return WILDCARD.sub(r"{\1}", str(path))


@pytest.fixture(scope="module")
def workflow_rules():
    """rule name -> (output paths with wildcard constraints stripped, results root)."""
    snakemake_api = pytest.importorskip("snakemake.api")
    from snakemake.settings.types import ConfigSettings, OutputSettings, ResourceSettings, StorageSettings

    with snakemake_api.SnakemakeApi(OutputSettings()) as api:
        wf = api.workflow(resource_settings=ResourceSettings(), config_settings=ConfigSettings(),
                          storage_settings=StorageSettings(), workdir=ROOT, snakefile=ROOT / "Snakefile")
        w = wf._workflow
        rules = {r.name: [_plain(o) for o in r.output] for r in w.rules}
        return rules, w.config["results"]


def stage_rule_problems(stage, outputs_type, rules: dict[str, list[str]], results: str) -> list[str]:
    """What is wrong with the outputs the rules of ``stage`` declare (empty: nothing)."""
    names = {k: f.name.rstrip("/") for k, f in outputs_type.LAYOUT.items()}
    mine = {r: outs for r, outs in rules.items() if r == stage.name or r.startswith(stage.name + "_")}
    problems, declared, whole = [], set(), False
    for rule, outs in mine.items():
        roots = set()
        for o in outs:
            hits = [(o[: -len(n) - 1], k) for k, n in names.items() if o.endswith("/" + n)]
            if hits:
                roots.add(hits[0][0])
                declared.update(k for _, k in hits)
            elif o.rsplit("/", 1)[-1] == stage.name:
                roots.add(o)
                whole = True
            else:
                problems.append(f"rule {rule}: output {o} is not a file of {outputs_type.__name__}.LAYOUT "
                                f"({sorted(names.values())}) nor the {stage.name} folder")
        if len(roots) > 1:
            problems.append(f"rule {rule}: outputs in several folders {sorted(roots)}")
        want = f"{results}/{{scene}}/{stage.name}"
        if stage.scope == "scene" and roots and roots != {want}:
            problems.append(f"rule {rule}: outputs in {sorted(roots)}, not the stage's folder {want}")
    missing = [k for k, f in outputs_type.LAYOUT.items() if not f.optional and k not in declared]
    if mine and not whole and missing:
        problems.append(f"{stage.name}: LAYOUT files {missing} are not optional but no rule declares them")
    return problems


STAGES_WITH_OUTPUTS = [s for s in STAGES if hasattr(s.load(), "Outputs")]


@pytest.mark.parametrize("stage", STAGES_WITH_OUTPUTS, ids=lambda s: s.name)
def test_rule_outputs_are_files_of_the_stage_outputs(stage, workflow_rules):
    rules, results = workflow_rules
    if not any(r == stage.name or r.startswith(stage.name + "_") for r in rules):
        pytest.skip(f"no rule runs the {stage.name} stage")  # e.g. a command-only stage
    assert stage_rule_problems(stage, stage.load().Outputs, rules, results) == []


def test_the_check_finds_a_file_the_layout_does_not_name(workflow_rules):
    """The check is not vacuous: a rule output missing from the LAYOUT, or a LAYOUT file that no rule
    declares, is reported."""
    from anigs.stages import BY_NAME
    from anigs.stages.contract import File
    from anigs.stages.views import Outputs

    rules, results = workflow_rules
    stage = BY_NAME["views"]
    fewer = type("Fewer", (Outputs,), {"LAYOUT": {k: f for k, f in Outputs.LAYOUT.items() if k != "topdown"}})
    assert any("topdown.png is not a file" in p for p in stage_rule_problems(stage, fewer, rules, results))
    more = type("More", (Outputs,), {"LAYOUT": {**Outputs.LAYOUT, "extra": File("extra.json", "nobody writes it")}})
    assert any("['extra']" in p for p in stage_rule_problems(stage, more, rules, results))
    assert STAGES_WITH_OUTPUTS and {"capture", "sfm", "static", "effects", "views", "masks"} <= {
        s.name for s in STAGES_WITH_OUTPUTS}
