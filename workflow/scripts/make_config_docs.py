"""Write config/README.md from the code: every config key (type, default, description) from the
schema, and the results layout from the stages' ``Outputs`` types (``anigs.stages``).

    python workflow/scripts/make_config_docs.py          # rewrite
    python workflow/scripts/make_config_docs.py --check  # exit 1 if stale
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
SCHEMA = ROOT / "workflow" / "schemas" / "config.schema.yaml"
OUT = ROOT / "config" / "README.md"

INTRO = """# Configuration

`config/config.yaml` holds the workflow configuration; it is validated against
`workflow/schemas/config.schema.yaml` before any job starts (a misspelled key is an error
that names the key). Keys you leave out take the defaults below. This page is generated from
the schema (`python workflow/scripts/make_config_docs.py`), which is itself generated from
the stages' config dataclasses, so it always matches the code.

## Scenes

Each scene is a file `config/scenes/NAME.yaml` listed under `scenes:`. Keys:

| key | meaning |
|---|---|
| `name` | scene name (defaults to the file name) |
| `source` | `synthetic` (the embedded demo generator) or `photos` (a folder of your photos) |
| `synthetic` | parameters of the synthetic generator (see `config/scenes/demo.yaml`) |
| `photos` | folder of JPEG/PNG photos (for `source: photos`); `${NAME}` is replaced by the environment variable NAME when the scene is loaded (unset: an error naming it), so `config/scenes/photos.yaml` (`photos: ${ANIGS_PHOTOS}`) takes the folder at run time |
| `effects` | `auto` (the default: the effects the `effects` stage finds among the kinds the `prompt` names, see the vocabulary below; every effect it finds when the scene has no prompt) or a list of `foliage_sway`, `leaf_flutter`, `grass_wave`, `flower_bob`, `water_ripple` (only those, where found, whatever the prompt says; a listed effect the scene lacks is reported and skipped); a misspelt name fails when the workflow is parsed; nothing else moves. Shorthand of `effects: {requested: ...}` |
| `background` | `[r, g, b]` in [0, 1]: a synthetic scene's sky colour, which its capture is rendered onto and every rendering stage composites onto (static, masks, render_clip, update, final, view, views (its edge figure), eval's multiview fits, the baselines' visibility renders, an imported splat's check); the one background key: a stage section that sets its own fails naming this one. Leave it out for photos: the static fit then trains on random backgrounds (what no photo covered stays transparent) and the final videos and the viewer show a neutral grey there |
| `prompt` | text prompt for the video prior; with `effects: auto` it also names the kinds that may move (a prompt that names none gives a still scene) |
| any stage section | overrides of that section for this scene (e.g. `static: {iterations: 7000}`) |

The effective section a stage receives is: `config.yaml` section <- scene override <- variant
override (`variant_overrides`), merged key by key, with four settings handed in that are set once for the
whole run: `seed`, `device` and `fps` (the workflow config's top level) and the scene's `background`. A stage
section that sets one of them (`static: {seed: 3}`, `final: {background: ...}`) fails when the workflow is
parsed, naming where it is set now. `config/scenes/custom_example.yaml` shows a
user's photo folder with LTX-Video weights on a GPU.
"""


def _fmt(v) -> str:
    return "`" + json.dumps(v) + "`"


def _cell(text: str) -> str:
    """A Markdown table cell: a ``|`` in the text is escaped, so it does not split the row."""
    return text.replace("|", "\\|")


def _rows(node: dict, prefix: str, out: list[str]) -> None:
    for key, p in node.get("properties", {}).items():
        name = prefix + key
        if p.get("type") == "object" and "properties" in p:
            out.append(f"| `{name}` | object | | {_cell(p.get('description', ''))} (keys below) |")
            _rows(p, name + ".", out)
        else:
            t = p.get("type", "")
            t = " or ".join(t) if isinstance(t, list) else t
            out.append(f"| `{name}` | {t} | {_cell(_fmt(p.get('default')))} | {_cell(p.get('description', ''))} |")


VOCABULARY = """## What the prompt names

With `effects: auto` the `effects` stage localises only the kinds of motion the scene's `prompt`
names, by these words (whole words, any case; a word after "no", "not" or "without" names
nothing). The effects stage's record keeps which words matched which kinds under `prompt`. The table is
generated from `anigs/effects/vocabulary.py`.

"""


RULES = """## What moves: the effects stage's rules

The `effects` stage proposes regions from the photos and lifts them onto the Gaussians; then each
region's 3D candidates go through its row of rules in this order until one decides (still, or moved to
another region). Each rule's knobs are its own section `effects.rules.<rule>`; its module in
`anigs/effects/rules/` (the smeared sheet: `anigs/effects/outline.py`) says what it is for. The table is
generated from `anigs/effects/rules/__init__.py` (`TABLE`, `BEFORE`, `AFTER`).

"""


def stage_folder(outputs) -> str:
    """The folder an ``Outputs`` type names, e.g. ``results/{scene}/masks/`` (its ``FOLDER``)."""
    return f"results/{outputs.FOLDER}/"


def results_layout(stages=None) -> str:
    """The "Results layout" section: per stage with an ``Outputs`` contract, its folder and every
    file of its ``LAYOUT`` (name, optional, what it holds)."""
    from anigs.stages import STAGES

    lines = ["", "## Results layout", "",
             "Every stage writes one folder; the files below are its `Outputs` contract "
             "(`anigs/stages/<stage>.py`), the only place that names them. `{round}` is the round, `{view}` a "
             "queued view (`v00`, ...). Generated from the stages' `Outputs` types.", ""]
    from anigs.contract import outputs_of

    missing, seen = [], set()
    for stage in stages if stages is not None else STAGES:
        types_ = [o for o in outputs_of(stage.load()) if o.LAYOUT and o not in seen]
        seen.update(types_)
        if not outputs_of(stage.load()):
            missing.append(stage.name)
            continue
        for outputs in types_:
            lines += [f"### `{stage_folder(outputs)}` ({stage.name})", "", "| file | holds |", "|---|---|"]
            for f in outputs.LAYOUT.values():
                doc = f.doc.replace("|", "\\|")
                lines.append(f"| `{f.name}`{' (optional)' if f.optional else ''} | {doc} |")
            lines.append("")
    if missing:
        lines += [f"Stages that write no files of their own: {', '.join(missing)}.", ""]
    lines += ["Logs and Snakemake benchmark TSVs (time and memory per job) sit beside the stage folders in "
              "`logs/` and `benchmarks/` folders; `snakemake study` writes the 2AFC study page to `results/study/`.",
              ""]
    return "\n".join(lines)


def section_home(key: str) -> str:
    """Where the section's class lives (a stage's ``Config``), for a reader who wants the code."""
    from anigs.registry import BY_NAME

    stage = BY_NAME.get(key)
    if stage is None or not stage.section:
        return ""
    cls = stage.config_class()
    return f"Class `{cls.__name__}` in `{cls.__module__.replace('.', '/')}.py`; the stage: `anigs/stages/{key}.py`."


def build() -> str:
    from anigs.effects.rules import rules_markdown
    from anigs.effects.vocabulary import vocabulary_markdown

    schema = yaml.safe_load(SCHEMA.read_text())
    lines = [INTRO, results_layout(), VOCABULARY + vocabulary_markdown() + "\n",
             RULES + rules_markdown() + "\n", "## Keys", ""]
    top, sections = [], []
    for key, p in schema["properties"].items():
        (sections if p.get("type") == "object" and "properties" in p else top).append((key, p))
    lines += ["### Global", "", "| key | type | default | description |", "|---|---|---|---|"]
    _rows({"properties": dict(top)}, "", lines)
    for key, p in sections:
        home = section_home(key)
        lines += ["", f"### `{key}`: {p.get('description', '')}", ""] + ([home, ""] if home else []) + [
            "| key | type | default | description |", "|---|---|---|---|"]
        _rows(p, key + ".", lines)
    return "\n".join(lines) + "\n"


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--check", action="store_true")
    args = ap.parse_args()
    text = build()
    if args.check:
        ok = OUT.exists() and OUT.read_text() == text
        if not ok:
            print(f"{OUT} is stale: run python workflow/scripts/make_config_docs.py", file=sys.stderr)
        return 0 if ok else 1
    OUT.write_text(text)
    print(f"wrote {OUT}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
