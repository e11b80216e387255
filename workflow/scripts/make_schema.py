"""Generate workflow/schemas/config.schema.yaml from the stages' config dataclasses.

Each stage section's keys, defaults and descriptions (the field's trailing comment) come from
the code, so the schema cannot drift: tests/test_config_schema.py regenerates and compares.

    python workflow/scripts/make_schema.py          # rewrite the schema
    python workflow/scripts/make_schema.py --check  # exit 1 if the committed schema is stale
"""
from __future__ import annotations

import argparse
import dataclasses
import inspect
import re
import sys
import typing
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[2]
SCHEMA = ROOT / "workflow" / "schemas" / "config.schema.yaml"
sys.path.insert(0, str(ROOT))

from anigs.stages import sections_of  # noqa: E402
from anigs.tradeoff import SCENE_STAGES, VARIANT_SECTIONS  # noqa: E402


def sections():
    """Config section -> (dataclass, description), from the stage registry."""
    from anigs.stages import STAGES

    return {s.name: (s.config_class(), s.help) for s in STAGES if s.section}


def nested():
    from anigs.baselines.lifting import LiftingConfig
    from anigs.baselines.physics import PhysicsConfig
    from anigs.masks.lift import LiftConfig
    from anigs.masks.sam2 import Sam2Config
    from anigs.masks.vegetation import VegetationConfig
    from anigs.refine.prior.ltx import LTXConfig
    from anigs.refine.prior.procedural import ProceduralConfig

    return {("animate", "lifting"): LiftingConfig, ("animate", "physics"): PhysicsConfig,
            ("masks", "vegetation"): VegetationConfig, ("masks", "lift"): LiftConfig, ("masks", "sam2"): Sam2Config,
            ("refine", "procedural"): ProceduralConfig, ("refine", "ltx"): LTXConfig}


# Descriptions for fields that carry no trailing comment in the code.
EXTRA = {
    "lr_sh_dc": "learning rate of the DC SH coefficients",
    "lr_sh_rest": "learning rate of the higher-order SH coefficients",
    "lr_opacity": "learning rate of the opacity logits",
    "lr_scales": "learning rate of the log-scales",
    "lr_quats": "learning rate of the rotations",
    "init_opacity": "opacity of the initial Gaussians",
    "device": "torch device: auto picks CUDA when present (the workflow passes the global device)",
    "seed": "random seed (the workflow passes the global seed)",
    "background": "background colour (RGB in [0,1])",
    "densify": "densification strategy (clone, split, prune, opacity reset)",
    "backend": "rasterizer backend: auto | cpu | torch | gsplat",
    "fps": "frames per second of the written videos / sidecar",
    "masks.vegetation.flower_saturation": "minimum HSV saturation for a colourful (flower) pixel to count as vegetation",
    "render_clip.num_frames": "frames per clip (the workflow passes animate.frames)",
    "refine.effects": "effect types to synthesise (the workflow passes the scene's effects)",
    "refine.procedural.effects": "effect types (set by the refine section's effects)",
    "refine.ltx.negative_prompt": "negative text prompt (with guidance_scale > 1)",
    "refine.ltx.decode_noise_scale": "noise scale added before VAE decoding (null = model default)",
    "refine.ltx.sds_tau_max": "largest diffusion time sampled by the SDS loss",
    "update.steps": "optimisation steps per round",
    "update.views_per_step": "(view, t) samples per step for the animation loss",
    "update.cano_views_per_step": "views per step for the canonical loss (frame 0 vs the static render)",
    "update.num_bases": "K: DCT bases per motion channel (clamped to T-1)",
    "update.rotation": "learn per-Gaussian rotation offsets as well as position offsets",
    "update.param_groups": "trainable parameters: deformation+positions (paper) | deformation | all",
    "update.lr_position_coeffs": "learning rate of the position DCT coefficients (times spatial_lr_scale)",
    "update.lr_rotation_coeffs": "learning rate of the rotation DCT coefficients",
    "update.lr_means": "learning rate of the canonical positions (times spatial_lr_scale)",
    "update.lr_sh": "learning rate of the SH coefficients (param_groups all)",
    "update.lr_final_factor": "learning rates decay exponentially to this fraction at the last step",
    "update.spatial_lr_scale": "length scale of position learning rates (null = 1-99 percentile scene extent)",
    "update.lambda_cano": "weight of the canonical loss",
    "update.lambda_sds": "weight of the SDS loss (needs a prior with a score: ltx)",
    "update.sds_frames": "frames of the SDS sub-clip (4m+1)",
    "update.max_offset_frac": "smooth limit on offsets as a fraction of the height above the ground (null = none)",
    "update.max_offset_abs": "smooth absolute limit on offsets in world units (null = none)",
    "update.max_angle_deg": "smooth limit on rotation offsets in degrees (null = none)",
    "update.effect_limits": "per-effect-label overrides of the three limits",
    "update.log_every": "log the loss every this many steps",
    "update.nan_guard": "stop on NaN loss or gradients, saving the last good state",
}


def _comments(cls) -> dict[str, str]:
    """Field -> its trailing (or preceding) comment, from the class's source and its dataclass bases'."""
    out: dict[str, str] = {}
    for base in reversed([c for c in cls.__mro__[1:] if dataclasses.is_dataclass(c)]):
        out.update(_own_comments(base))
    out.update(_own_comments(cls))
    return out


def _own_comments(cls) -> dict[str, str]:
    out = {}
    try:
        src = inspect.getsource(cls)
    except (OSError, TypeError):
        return out
    lines = src.splitlines()
    for i, line in enumerate(lines):
        m = re.match(r"\s+(\w+)\s*:\s*[^=]+?(?:=.*?)?\s*#\s*(.+)$", line)
        if m:
            out[m.group(1)] = m.group(2).strip()
        else:
            m2 = re.match(r"\s+(\w+)\s*:", line)
            if m2 and i > 0 and lines[i - 1].strip().startswith("#"):
                out.setdefault(m2.group(1), lines[i - 1].strip().lstrip("#").strip())
    return out


def _default(f: dataclasses.Field):
    if f.default is not dataclasses.MISSING:
        v = f.default
    elif f.default_factory is not dataclasses.MISSING:  # type: ignore[misc]
        v = f.default_factory()  # type: ignore[misc]
    else:
        return None
    if dataclasses.is_dataclass(v):
        v = dataclasses.asdict(v)
    if isinstance(v, tuple):
        v = list(v)
    return v


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


# Fields a stage sets itself from its section's top level (not user keys of the nested dict).
EXCLUDE = {("refine", "procedural", "effects"), ("refine", "ltx", "steps")}


def dataclass_schema(cls, path: tuple[str, ...], nest) -> dict:
    com = _comments(cls)
    hints = typing.get_type_hints(cls) if True else {}
    props = {}
    for f in dataclasses.fields(cls):
        if path + (f.name,) in EXCLUDE:
            continue
        value = _default(f)
        sub = nest.get(path + (f.name,))
        desc = com.get(f.name) or EXTRA.get(".".join(path + (f.name,))) or EXTRA.get(f.name)
        if desc is None:
            MISSING.append(f"{'.'.join(path + (f.name,))} ({cls.__module__}.{cls.__name__})")
            desc = ""
        if dataclasses.is_dataclass(hints.get(f.name)):
            sub = hints[f.name]
        if sub is not None:
            p = dataclass_schema(sub, path + (f.name,), nest)
            p["description"] = desc
            p["default"] = {}
        else:
            p = {"type": _type(value, hints.get(f.name, "")), "description": desc, "default": value,
                 **_special().get(".".join(path + (f.name,)), {})}
        props[f.name] = p
    return {"type": "object", "additionalProperties": False, "properties": props}


MISSING: list[str] = []

TOP = {
    "results": {"type": "string", "default": "results", "description": "folder where every artifact is written"},
    "seed": {"type": "integer", "default": 0,
             "description": "global random seed: the same config and seed give the same artifacts on CPU"},
    "device": {"type": "string", "default": "auto", "pattern": "^(auto|cpu|cuda(:[0-9]+)?)$",
               "description": "torch device of every stage: auto picks CUDA when present; cuda on a machine "
                              "without a GPU is an error before any job starts"},
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
                             "description": "metrics of metrics.json plotted against seconds, one PNG per knob"},
        }},
}


def build() -> dict:
    schema = {"$schema": "https://json-schema.org/draft/2020-12/schema",
              "description": "anigs workflow configuration (generated by workflow/scripts/make_schema.py from the "
                             "stages' config dataclasses: do not edit by hand)",
              "type": "object", "additionalProperties": False, "properties": dict(TOP)}
    nest = nested()
    for name, (cls, desc) in sections().items():
        s = dataclass_schema(cls, (name,), nest)
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
        print("fields without a description (add a trailing comment):\n  " + "\n  ".join(MISSING), file=sys.stderr)
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
