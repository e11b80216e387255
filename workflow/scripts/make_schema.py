"""Generate workflow/schemas/config.schema.yaml from the stages' config dataclasses.

The generator walks the types: each stage's ``Config`` gives its section, a field typed with a
dataclass gives a nested section (``masks.vegetation``), and every field's description is its
doc in the code (:func:`field_docs`), so the schema cannot drift: tests/workflow/test_config_schema.py
regenerates and compares, and a field without a doc fails the generator.

    python workflow/scripts/make_schema.py          # rewrite the schema
    python workflow/scripts/make_schema.py --check  # exit 1 if the committed schema is stale
"""
from __future__ import annotations

import argparse
import ast
import dataclasses
import inspect
import io
import re
import sys
import textwrap
import tokenize
import typing
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[2]
SCHEMA = ROOT / "workflow" / "schemas" / "config.schema.yaml"
sys.path.insert(0, str(ROOT))

from anigs.config import HANDED  # noqa: E402
from anigs.stages import sections_of  # noqa: E402
from anigs.reports.tradeoff import SCENE_STAGES, VARIANT_SECTIONS  # noqa: E402


def sections():
    """Config section -> (dataclass, description), from the stage registry."""
    from anigs.stages import STAGES

    return {s.name: (s.config_class(), s.help) for s in STAGES if s.section}


def field_docs(cls) -> dict[str, str]:
    """Field -> its doc, for dataclass ``cls`` and its dataclass bases (a subclass's own doc wins).

    A field's doc is the block of ``#:`` comment lines right above it, else its trailing comment,
    continued by the comment-only lines below it that start in the same column, else its metadata's ``doc``."""
    out: dict[str, str] = {}
    for base in reversed([c for c in cls.__mro__ if dataclasses.is_dataclass(c)]):
        out.update(_own_docs(base))
    # a generated dataclass (no source: anigs.effects.rules.RulesConfig) carries its fields' docs as metadata
    out.update({f.name: f.metadata["doc"] for f in dataclasses.fields(cls) if f.name not in out and "doc" in f.metadata})
    return out


def _own_docs(cls) -> dict[str, str]:
    try:
        src = textwrap.dedent(inspect.getsource(cls))
    except (OSError, TypeError):
        return {}
    lines = src.splitlines()
    comments = {t.start[0]: (t.start[1], t.string.lstrip("#").strip())
                for t in tokenize.generate_tokens(io.StringIO(src).readline) if t.type == tokenize.COMMENT}
    own = {f.name for f in dataclasses.fields(cls)}
    out = {}
    for node in ast.parse(src).body[0].body:
        if not (isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name)) or node.target.id not in own:
            continue
        above, i = [], node.lineno - 1
        while i >= 1 and lines[i - 1].lstrip().startswith("#:"):
            above.insert(0, lines[i - 1].lstrip()[2:].strip())
            i -= 1
        if above:
            out[node.target.id] = " ".join(above)
            continue
        trailing = [n for n in range(node.lineno, node.end_lineno + 1) if n in comments]
        if not trailing:
            continue
        col, text = comments[trailing[0]]
        parts, n = [text], node.end_lineno + 1
        while n in comments and comments[n][0] == col and lines[n - 1].lstrip().startswith("#"):
            parts.append(comments[n][1])
            n += 1
        out[node.target.id] = " ".join(parts)
    return out


def _type(value, annotation) -> list[str] | str:
    ann = str(annotation)
    types = []
    for py, js in (("bool", "boolean"), ("int", "integer"), ("float", "number"), ("str", "string"),
                   ("list", "array"), ("tuple", "array"), ("dict", "object"), ("Mapping", "object"),
                   ("Sequence", "array")):
        if re.search(rf"\b{py}\b", ann):
            types.append(js)
    if isinstance(value, bool):
        types.append("boolean")
    elif isinstance(value, int):
        types.append("integer")
    elif isinstance(value, float):
        types += ["number"]
    elif isinstance(value, str):
        types.append("string")
    elif isinstance(value, list):
        types.append("array")
    elif isinstance(value, dict):
        types.append("object")
    if "integer" in types and "number" not in types and "float" in ann:
        types.append("number")
    if "number" in types and "integer" not in types:
        types.append("integer")  # YAML writes 1 for 1.0
    if value is None or "None" in ann or "Optional" in ann:
        types.append("null")
    types = sorted(set(types)) or ["string", "number", "integer", "boolean", "array", "object", "null"]
    return types[0] if len(types) == 1 else types


def _special() -> dict:
    """Extra schema keywords of single keys: effect names are an enum, so a misspelt one in a scene
    file's `effects:` list fails when the workflow is parsed, naming the valid effects."""
    from anigs.effects.config import EFFECTS

    return {"effects.requested": {"pattern": "^auto$", "items": {"type": "string", "enum": list(EFFECTS)}}}


def dataclass_schema(cls, path: tuple[str, ...], skip: tuple[str, ...] = (), defaults=None) -> dict:
    """The object schema of dataclass ``cls`` at config ``path``: one property per field (nested
    dataclasses recursively), minus ``skip`` (keys the parent section sets itself: its
    ``DERIVED`` class attribute, nested section -> keys). ``defaults``: the instance whose values
    are the defaults (a nested section's default in its parent may differ from its class's)."""
    defaults = cls() if defaults is None else defaults
    handed = tuple(getattr(cls, "HANDED", ()))
    skip = tuple(skip) + handed
    docs = field_docs(cls)
    hints = typing.get_type_hints(cls)
    derived = getattr(cls, "DERIVED", {})
    special = _special()
    props = {}
    for f in dataclasses.fields(cls):
        if f.name in skip:
            continue
        key = ".".join(path + (f.name,))
        desc = docs.get(f.name)
        if not desc:
            MISSING.append(f"{key} ({cls.__module__}.{cls.__name__}.{f.name})")
            desc = ""
        value = getattr(defaults, f.name)
        if dataclasses.is_dataclass(hints[f.name]):
            p = dataclass_schema(hints[f.name], path + (f.name,), tuple(derived.get(f.name, ())), value)
            p["description"] = desc
            p["default"] = {}
        else:
            value = list(value) if isinstance(value, tuple) else value
            p = {"type": _type(value, hints[f.name]), "description": desc, "default": value, **special.get(key, {})}
        props[f.name] = p
    out = {"type": "object", "additionalProperties": False, "properties": props}
    if handed:  # set once, at the workflow's or the scene's top level (anigs.config.HANDED), and handed in
        out["x-handed"] = list(handed)
        out["x-renamed"] = {k: HANDED[k] for k in handed}
    if getattr(cls, "RENAMED", None):  # old key -> new key: the config check names the new key
        out["x-renamed"] = {**out.get("x-renamed", {}), **cls.RENAMED}
    return out


MISSING: list[str] = []

TOP = {
    "results": {"type": "string", "default": "results", "description": "folder where every artifact is written"},
    "seed": {"type": "integer", "default": 0,
             "description": "global random seed: the same config and seed give the same artifacts on CPU"},
    "device": {"type": "string", "default": "auto", "pattern": "^(auto|cpu|cuda(:[0-9]+)?)$",
               "description": "torch device of every stage: auto picks CUDA when present; cuda on a machine "
                              "without a GPU is an error before any job starts"},
    "fps": {"type": "number", "exclusiveMinimum": 0, "default": 12,
            "description": "frames per second at which the animation plays: the final videos, the export's sidecar "
                           "and the viewer (the video prior generates its motion at its own rate: "
                           "refine.procedural.fps)"},
    "round_jobs": {"type": "string", "enum": ["auto", "round", "view"], "default": "auto",
                   "description": "how a round's work is split into jobs: round = one job per round (render, refine "
                                  "and update: one Python start-up, models loaded once), view = one render_clip and one "
                                  "refine job per view (a cluster's GPUs take the views in parallel), then an update "
                                  "job, auto = round for local runs and view under a cluster executor; the artifacts "
                                  "are byte-identical either way"},
    "scene_dir": {"type": "string", "default": "config/scenes", "description": "folder of the scene files ({name}.yaml)"},
    "scenes": {"type": "array", "items": {"type": "string", "pattern": "^[A-Za-z0-9_.-]+$"}, "minItems": 1,
               "default": ["demo"], "description": "scenes to process (names of files in scene_dir)"},
    "variants": {"type": "array", "items": {"type": "string"}, "minItems": 1, "default": ["full"],
                 "description": "method variants `snakemake` (rule all) builds; each lands in results/{scene}/{variant}"},
    "table_variants": {"type": "array", "items": {"type": "string"},
                       "default": ["full", "no_dataset_update", "no_view_expansion", "no_composed_v2v", "opt_all", "opt_deform_only"],
                       "description": "variants `snakemake tables` evaluates for the ablation table (paper Table 5)"},
    "variant_overrides": {
        "type": "object",
        "additionalProperties": {"type": "object", "additionalProperties": False,
                                 "properties": {k: {"type": "object"} for k in sections_of("variant")}},
        "default": {},
        "description": "per-variant overrides of the animate/refine/update/final/export/eval sections "
                       "(the paper's ablations are just config)"},
    "tradeoff": {
        "type": "object", "additionalProperties": False, "default": {},
        "description": "accuracy-versus-time sweep (`snakemake tradeoff`): one knob at a time around a base variant",
        "properties": {
            "base": {"type": "string", "default": "full", "description": "variant the sweep varies"},
            "knobs": {"type": "object", "default": {},
                      "propertyNames": {"pattern": rf"^(({'|'.join(VARIANT_SECTIONS + SCENE_STAGES)})"
                                                   r"(\.[A-Za-z0-9_.]+)?)$"},
                      "additionalProperties": {"type": ["array", "null"], "minItems": 1},
                      "description": "section.key -> values, or section -> mappings of its keys; a per-variant section's "
                                     "value becomes the variant tradeoff-SECTION-KEY-VALUE, a per-scene stage's (static, "
                                     "views, masks) the derived scene SCENE--tradeoff-SECTION-KEY-VALUE; null drops a knob"},
            "plot_metrics": {"type": "array", "items": {"type": "string"}, "default": [],
                             "description": "metrics of the evaluation (eval stage) plotted against seconds, one PNG per knob"},
        }},
}


def build() -> dict:
    schema = {"$schema": "https://json-schema.org/draft/2020-12/schema",
              "description": "anigs workflow configuration (generated by workflow/scripts/make_schema.py from the "
                             "stages' config dataclasses: do not edit by hand)",
              "type": "object", "additionalProperties": False, "properties": dict(TOP)}
    for name, (cls, desc) in sections().items():
        s = dataclass_schema(cls, (name,))
        s["description"] = desc
        s["default"] = {}
        schema["properties"][name] = s
    return schema


def dump(schema: dict) -> str:
    return yaml.safe_dump(schema, sort_keys=False, width=110, allow_unicode=True)


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--check", action="store_true")
    args = ap.parse_args()
    text = dump(build())
    if MISSING:
        print("fields without a doc (add a trailing comment, or #: lines above the field):\n  "
              + "\n  ".join(MISSING), file=sys.stderr)
        return 1
    if args.check:
        if not SCHEMA.exists() or SCHEMA.read_text() != text:
            print(f"{SCHEMA} is stale: run python workflow/scripts/make_schema.py", file=sys.stderr)
            return 1
        return 0
    SCHEMA.write_text(text)
    print(f"wrote {SCHEMA}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
