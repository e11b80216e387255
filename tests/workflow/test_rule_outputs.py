"""Every rule that runs a stage writes only files its stages' ``Outputs`` name, where they say.

The workflow is loaded through the Snakemake API (the demo config; no job runs). A stage's
``Outputs`` types (:func:`anigs.contract.outputs_of`: several when it writes into several
folders) each say their folder under the results root (``FOLDER``) and its files (``LAYOUT``).
The rules of a stage (the rule of its name and those named ``<stage>_...``) run it, and a rule whose
command chains another stage (``anigs ... --then STAGE``, :data:`THEN`) runs that one too. Each
output a rule declares is the folder of one of those ``Outputs`` (a ``directory()``) or
``<FOLDER>/<LAYOUT name>`` of one of them; every ``LAYOUT`` entry that is not ``optional`` and has
no format field is declared by a rule that runs its stage (a folder entry by a file in it, a file
by its folder). An entry with a format field (``{view}.mp4``: one file per view, while the rule's
wildcard is the scene) cannot be a rule output, so it need not be declared.
"""
from __future__ import annotations

import re
import string
from pathlib import Path

import pytest

from anigs.stages import BY_NAME, STAGES
from anigs.contract import Outputs, outputs_of

ROOT = Path(__file__).resolve().parents[2]
WILDCARD = re.compile(r"\{(\w+),[^{}]*(?:\{[^{}]*\}[^{}]*)*\}")  # {name,constraint} -> {name}
THEN = {"round": ("update",), "final": ("eval",)}  # rule -> the stages its command chains with --then


def _plain(path: str) -> str:
    return WILDCARD.sub(r"{\1}", str(path))


def _chains(rule) -> bool:
    """Whether the rule's command has ``--then`` (in its shell line or in a params function's text)."""
    texts = [rule.shellcmd or ""]
    for p in rule.params:
        code = getattr(p, "__code__", None)
        if code is not None:
            texts += [c for c in code.co_consts if isinstance(c, str)]
    return any("--then" in t for t in texts)


@pytest.fixture(scope="module")
def workflow_rules():
    """(rule name -> output paths with wildcard constraints stripped, results root, rules that chain)."""
    snakemake_api = pytest.importorskip("snakemake.api")
    from snakemake.settings.types import ConfigSettings, OutputSettings, ResourceSettings, StorageSettings

    with snakemake_api.SnakemakeApi(OutputSettings()) as api:
        wf = api.workflow(resource_settings=ResourceSettings(), config_settings=ConfigSettings(),
                          storage_settings=StorageSettings(), workdir=ROOT, snakefile=ROOT / "Snakefile")
        w = wf._workflow
        rules = {r.name: [_plain(o) for o in r.output] for r in w.rules}
        chaining = {r.name for r in w.rules if _chains(r)}
        shells = {r.name: r.shellcmd for r in w.rules}
        return rules, w.config["results"], chaining, shells


def _regex(pattern: str) -> re.Pattern:
    """``pattern`` with each format field matching one path component (a wildcard or a value)."""
    out = ""
    for literal, fld, _, _ in string.Formatter().parse(pattern):
        out += re.escape(literal) + ("[^/]+" if fld is not None else "")
    return re.compile(out)


def rules_of(stage: str, rules) -> list[str]:
    """The rules that run ``stage``: its own (``stage``, ``stage_...``) and those that chain it."""
    return [r for r in rules if r == stage or r.startswith(stage + "_") or stage in THEN.get(r, ())]


def _match(o: str, types: list[type[Outputs]], results: str) -> tuple[type[Outputs], str | None] | None:
    """(the Outputs type, the LAYOUT key or None for its whole folder) that output path ``o`` is."""
    hits = []
    for t in types:
        folder = f"{results}/{t.FOLDER}"
        if _regex(folder).fullmatch(o):
            hits.append((0, t, None))
        for k, f in t.LAYOUT.items():
            if _regex(f"{folder}/{f.name.rstrip('/')}").fullmatch(o):
                hits.append((len(f.fields), t, k))
    hits.sort(key=lambda h: h[0])  # a literal name before a pattern that also matches it
    return (hits[0][1], hits[0][2]) if hits else None


def _own_stage(rule: str) -> str | None:
    """The stage a rule is named after (``eval_model`` -> ``eval``), None for a target rule."""
    names = [s.name for s in STAGES if rule == s.name or rule.startswith(s.name + "_")]
    return max(names, key=len) if names else None


def stage_rule_problems(stage, types: tuple[type[Outputs], ...], rules: dict[str, list[str]],
                        results: str, others: dict[str, tuple[type[Outputs], ...]] | None = None) -> list[str]:
    """What is wrong with the outputs the rules running ``stage`` declare (empty: nothing).
    ``types``: the stage's Outputs types; ``others``: those of other stages in place of theirs."""
    def types_of(name: str) -> list[type[Outputs]]:
        if name == stage.name:
            return list(types)
        return list((others or {}).get(name) or outputs_of(BY_NAME[name].load()))

    problems, declared = [], set()
    for rule in rules_of(stage.name, rules):
        cands = [t for s in (_own_stage(rule), *THEN.get(rule, ())) if s for t in types_of(s)]
        for o in rules[rule]:
            hit = _match(o, cands, results)
            if hit is None:
                names = sorted(f"{results}/{t.FOLDER}/{f.name}" for t in cands for f in t.LAYOUT.values())
                problems.append(f"rule {rule}: output {o} is no folder or file of "
                                f"{[f'{t.STAGE}.{t.__name__}' for t in cands]} ({names})")
                continue
            t, key = hit
            keys = list(t.LAYOUT) if key is None else [key]
            declared.update((t, k) for k in keys)
    if not rules_of(stage.name, rules):
        return problems
    for t in types:
        names = {k: f.name for k, f in t.LAYOUT.items()}
        for k, f in t.LAYOUT.items():
            if f.optional or f.fields or (t, k) in declared:
                continue
            inside = [j for j, n in names.items() if j != k and n.startswith(f.name) and f.name.endswith("/")]
            above = [j for j, n in names.items() if n.endswith("/") and f.name.startswith(n) and j != k]
            if any((t, j) in declared for j in inside + above):
                continue  # a folder entry declared through a file in it, or a file through its folder
            if inside and all(t.LAYOUT[j].fields for j in inside):
                continue  # a folder of per-view (...) files: no rule can declare them
            problems.append(f"{stage.name}: {t.STAGE}.{t.__name__}.LAYOUT file {k!r} ({t.FOLDER}/{f.name}) is not optional "
                            f"but no rule declares it")
    return problems


STAGES_WITH_OUTPUTS = [s for s in STAGES if outputs_of(s.load())]


def test_every_stage_that_writes_has_outputs_with_a_folder(workflow_rules):
    rules, _, _, _ = workflow_rules
    writes = [s for s in STAGES if s.command or any(rules[r] for r in rules_of(s.name, rules))]
    assert [s.name for s in writes if not outputs_of(s.load())] == []
    assert [t.__name__ for s in STAGES_WITH_OUTPUTS for t in outputs_of(s.load())
            if not t.FOLDER or t.STAGE not in BY_NAME] == []


def test_a_file_belongs_to_one_outputs():
    owner: dict[str, str] = {}
    clash = []
    for s in STAGES_WITH_OUTPUTS:
        for t in outputs_of(s.load()):
            for k, f in t.LAYOUT.items():
                where = f"{t.FOLDER}/{f.name}"
                name = f"{t.__module__}.{t.__name__}[{k!r}]"
                if owner.setdefault(where, name) != name:
                    clash.append((where, owner[where], name))
    assert clash == []


def test_rules_that_chain_stages_are_known(workflow_rules):
    """:data:`THEN` lists exactly the rules whose command chains a stage with ``--then``."""
    rules, _, chaining, _ = workflow_rules
    assert chaining == set(THEN)


@pytest.mark.parametrize("stage", STAGES_WITH_OUTPUTS, ids=lambda s: s.name)
def test_rule_outputs_are_files_of_the_stage_outputs(stage, workflow_rules):
    rules, results, _, _ = workflow_rules
    if not rules_of(stage.name, rules):
        pytest.skip(f"no rule runs the {stage.name} stage")  # e.g. a command-only stage
    assert stage_rule_problems(stage, outputs_of(stage.load()), rules, results) == []


def test_the_check_finds_a_file_the_layout_does_not_name(workflow_rules):
    """The check is not vacuous: a rule output missing from the LAYOUT, one in another folder, or a
    LAYOUT file that no rule declares, is reported."""
    from anigs.contract import File
    from anigs.stages.eval import Outputs as EvalOutputs
    from anigs.stages.views import Outputs

    rules, results, _, _ = workflow_rules
    stage = BY_NAME["views"]
    fewer = type("Fewer", (Outputs,), {"LAYOUT": {k: f for k, f in Outputs.LAYOUT.items() if k != "topdown"}})
    assert any("topdown.png is no folder or file" in p for p in stage_rule_problems(stage, (fewer,), rules, results))
    more = type("More", (Outputs,), {"LAYOUT": {**Outputs.LAYOUT, "extra": File("extra.json", "nobody writes it")}})
    assert any("'extra'" in p for p in stage_rule_problems(stage, (more,), rules, results))
    moved = type("Moved", (Outputs,), {"FOLDER": "{scene}/elsewhere"})
    assert len(stage_rule_problems(stage, (moved,), rules, results)) == 4  # 2 outputs elsewhere, 2 undeclared
    # the final rule's eval/clip_metrics.json is the chained eval stage's: without it, it is unnamed
    no_clip = type("NoClip", (EvalOutputs,), {"LAYOUT": {k: f for k, f in EvalOutputs.LAYOUT.items()
                                                         if k != "clip_metrics"}})
    problems = stage_rule_problems(BY_NAME["final"], outputs_of(BY_NAME["final"].load()), rules, results,
                                   others={"eval": (no_clip,)})
    assert any("clip_metrics.json is no folder or file" in p for p in problems)
    assert {"capture", "sfm", "static", "effects", "views", "masks", "round", "final", "fvd_gt", "tables"} <= {
        s.name for s in STAGES_WITH_OUTPUTS}


def test_a_rule_writing_another_stage_s_file_is_reported(workflow_rules):
    """Rules are generated from the Outputs (common.smk: stage_out), so the check compares them with
    what a rule declares: a rule of the views stage that also wrote the masks stage's dynamic set
    (built from the masks Outputs, as a rule would) is reported."""
    from anigs.stages.masks import Outputs as MasksOutputs

    rules, results, _, _ = workflow_rules
    stray = f"{results}/{MasksOutputs.FOLDER}/{MasksOutputs.LAYOUT['dynamic'].name}"
    views = BY_NAME["views"]
    assert stage_rule_problems(views, outputs_of(views.load()), rules, results) == []
    problems = stage_rule_problems(views, outputs_of(views.load()), {**rules, "views": [*rules["views"], stray]},
                                   results)
    assert len(problems) == 1 and "masks" in problems[0] and "is no folder or file" in problems[0]


def _layout_names():
    import importlib
    import sys

    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        return importlib.import_module("layout_names")
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))


def test_rules_spell_no_layout_file_name():
    """Rules name their files through their stages' Outputs (stage_out, stage_file, layout_name in
    common.smk); no string in a rule file or the Snakefile spells a layout file name
    (benchmarks/layout_names.py, the issue's grep)."""
    _, code, _ = _layout_names().hits(ROOT, ("workflow/rules", "Snakefile"))
    assert code == []


def test_the_layout_name_grep_finds_a_spelled_name(tmp_path):
    """The grep above is not vacuous: a rule output spelled as a string is found, a comment is not."""
    from anigs.stages.static import Outputs as StaticOutputs

    name = StaticOutputs.LAYOUT["canonical"].name
    (tmp_path / "x.smk").write_text(f'# {name} in a comment\nrule x:\n    output:\n        f"{{R}}/s/static/{name}",\n')
    _, code, docs = _layout_names().hits(tmp_path, ("x.smk",))
    assert [c.split(":")[:2] for c in code] == [["x.smk", "4"]] and len(docs) == 1


COMMAND = "anigs --threads {threads} {params.cmd} > {log} 2>&1"


def test_every_stage_rule_runs_the_command_its_inputs_build(workflow_rules):
    """No stage rule spells its own flags: each runs ``params.cmd``, built from the stage's ``Inputs``
    (``stage_command`` in workflow/rules/common.smk)."""
    rules, _, _, shells = workflow_rules
    stage_rules = [r for r in rules if _own_stage(r) and shells[r] is not None]
    assert {_own_stage(r) for r in stage_rules} >= {"capture", "sfm", "static", "effects", "views", "masks"}
    assert {r: shells[r].strip() for r in stage_rules if shells[r].strip() != COMMAND} == {}
