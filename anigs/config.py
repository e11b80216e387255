"""Workflow configuration: scenes, variants and the effective section each stage receives.

Effective section = global section (config.yaml) <- the scene file's override <- the variant's
override (deep merge, later wins). Scene files live in ``config/scenes/{name}.yaml``.
"""
from __future__ import annotations

import copy
import os
import re
from pathlib import Path
from typing import Any

import yaml

from anigs.registry import sections as _stage_sections

STAGE_SECTIONS = _stage_sections()  # from the stage registry (anigs/registry.py)
SCENE_KEYS = {"name", "source", "synthetic", "photos", "images", "sparse", "splat", "effects", "prompt", "background",
              *STAGE_SECTIONS}
#: the settings read once and handed to every section (and nested section) whose config class lists them in
#: ``HANDED`` (the schema's ``x-handed``): the run's ``seed``, ``device`` and playback ``fps`` from the workflow
#: config's top level, the sky colour ``background`` from the scene file's (unset: each stage's own default: the
#: fit trains on random colours, the views show grey). A section in a config file, scene file or variant that
#: sets one fails naming where it is set now (the text here).
HANDED: dict[str, str] = {
    "seed": "seed, set once at the top level of the workflow config (config.yaml, or --config seed=N)",
    "device": "device, set once at the top level of the workflow config (config.yaml, or --config device=cuda)",
    "background": "background, set once at the top level of the scene file (the sky colour, [r, g, b] in [0, 1])",
    "fps": "fps, set once at the top level of the workflow config (the playback rate of the videos, the export and "
           "the viewer)",
}
SOURCES = ("synthetic", "photos", "colmap")
_ENV_REF = re.compile(r"\$\{([A-Za-z_][A-Za-z0-9_]*)\}")


def expand_env(value: str, where: str) -> str:
    """``value`` with each ``${NAME}`` replaced by the environment variable NAME (and a leading ``~``
    by the home folder): a scene file can name a folder given at run time
    (``photos: ${ANIGS_PHOTOS}``). An unset or empty variable is an error naming it and ``where``."""

    def sub(m: re.Match) -> str:
        name = m.group(1)
        got = os.environ.get(name)
        if not got:
            raise ValueError(f"{where}: {m.group(0)} names the environment variable {name}, which is "
                             f"{'empty' if got == '' else 'not set'}; set it to the folder, e.g. "
                             f"{name}=/path/to/photos snakemake ...")
        return got

    return os.path.expanduser(_ENV_REF.sub(sub, value))


def deep_merge(base: dict, override: dict | None) -> dict:
    """Recursive dict merge; ``override`` wins; inputs are not modified."""
    out = copy.deepcopy(base)
    for k, v in (override or {}).items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = deep_merge(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out


def check_sections(d: dict, schema: dict | None, where: str) -> None:
    """Validate the stage sections of ``d`` (a scene file or a variant's overrides) against the
    config schema's section schemas: a misspelt or mistyped key fails here, naming it and ``where``."""
    if not schema:
        return
    import jsonschema

    props = schema.get("properties", {})
    for name in STAGE_SECTIONS:
        if name not in d or name not in props:
            continue
        value = d[name]
        if value is None:
            continue
        moved = renamed_keys(value, props[name], name)
        if moved:  # keys a section renamed or moved out (the schema's x-renamed): name where each is set now
            raise ValueError(f"{where}: " + "; ".join(f"{k} is now {new}" for k, new in moved) + " (CHANGELOG.md)")
        for err in sorted(jsonschema.Draft202012Validator(props[name]).iter_errors(value), key=lambda e: list(e.path)):
            key = ".".join([name, *map(str, err.path)])
            raise ValueError(f"{where}: {key}: {err.message}")


def check_workflow_config(config: dict, schema_path: str | Path) -> None:
    """The workflow config's stage sections checked before the schema's own validation, so that a key moved or
    renamed since (``static.seed``: the top-level ``seed`` now) fails naming where it is set now."""
    schema = yaml.safe_load(Path(schema_path).read_text())
    check_sections(config, schema, "config")


def renamed_keys(value: Any, node: dict, path: str) -> list[tuple[str, str]]:
    """(old key's path, where it is set now) for every key of the mapping ``value`` (at config ``path``, schema
    ``node``) and of its nested sections that the schema marks ``x-renamed``."""
    if not isinstance(value, dict):
        return []
    renamed = node.get("x-renamed", {})
    out = [(f"{path}.{k}", renamed[k]) for k in value if k in renamed]
    for k, v in value.items():
        sub = node.get("properties", {}).get(k)
        if sub is not None and sub.get("type") == "object":
            out += renamed_keys(v, sub, f"{path}.{k}")
    return out


def handed(d: dict, node: dict, values: dict[str, Any]) -> dict:
    """The section ``d`` with the ``values`` (:data:`HANDED`: seed, device, the scene's background when it sets one)
    filled in wherever the schema ``node`` and its nested sections take them (``x-handed``)."""
    out = dict(d)
    out.update({k: copy.deepcopy(values[k]) for k in node.get("x-handed", ()) if k in values})
    for k, sub in node.get("properties", {}).items():
        if _takes_handed(sub):
            out[k] = handed(out.get(k) or {}, sub, values)
    return out


def _takes_handed(node: dict) -> bool:
    return bool(node.get("x-handed")) or any(_takes_handed(s) for s in node.get("properties", {}).values())


def _with_effects_section(scene: dict) -> dict:
    """The scene with its ``effects`` shorthand (a list, or ``auto``) as the section it stands for."""
    eff = scene.get("effects")
    if isinstance(eff, (list, str)):
        return {**scene, "effects": {"requested": eff}}
    return scene


def load_scene(scene_dir: str | Path, name: str, schema: dict | None = None) -> dict[str, Any]:
    """Read and check ``{scene_dir}/{name}.yaml``; with the config ``schema``, its stage sections are
    validated too (so a typo fails when the workflow is parsed, before any job)."""
    path = Path(scene_dir) / f"{name}.yaml"
    if not path.exists():
        raise FileNotFoundError(f"scene {name!r}: no scene file {path} (create it; see config/README.md)")
    scene = yaml.safe_load(path.read_text()) or {}
    if not isinstance(scene, dict):
        raise ValueError(f"scene file {path}: expected a mapping of keys, got {type(scene).__name__}")
    unknown = sorted(set(scene) - SCENE_KEYS)
    if unknown:
        raise ValueError(f"scene file {path}: unknown key(s) {unknown}; allowed: {sorted(SCENE_KEYS)}")
    check_sections(_with_effects_section(scene), schema, f"scene file {path}")
    scene.setdefault("name", name)
    src = scene.get("source")
    if src not in SOURCES:
        raise ValueError(f"scene file {path}: 'source' must be one of {SOURCES}, got {src!r}")
    if src == "photos":
        p, given = _scene_path(scene, "photos", path, "source 'photos' needs 'photos: /path/to/your/photos'")
        if not p.is_dir():
            raise FileNotFoundError(f"scene {name!r}: photo folder {p} does not exist ({given})")
        if not any(f.suffix.lower() in (".jpg", ".jpeg", ".png") for f in p.iterdir()):
            raise ValueError(f"scene {name!r}: photo folder {p} holds no .jpg/.jpeg/.png files")
    elif src == "colmap":
        _check_colmap(scene, path)
    if src != "colmap" and ("images" in scene or "sparse" in scene):
        raise ValueError(f"scene file {path}: 'images' and 'sparse' belong to source 'colmap' (a COLMAP project), "
                         f"not {src!r}")
    if "splat" in scene:
        if src == "synthetic":
            raise ValueError(f"scene file {path}: 'splat' needs the photos it was trained on: source 'colmap' "
                             "(their COLMAP project) or 'photos'")
        p, given = _scene_path(scene, "splat", path, "'splat' names a splat file (PLY, compressed PLY, SPZ, glb, .splat)")
        if not p.is_file():
            raise FileNotFoundError(f"scene {name!r}: splat file {p} does not exist ({given})")
    bg = scene.get("background")
    if bg is not None:
        if not (isinstance(bg, list) and len(bg) == 3 and all(isinstance(x, (int, float)) and 0 <= x <= 1 for x in bg)):
            raise ValueError(f"scene file {path}: background must be [r, g, b] in [0, 1], got {bg!r}")
        if src == "synthetic":  # the synthetic capture is rendered onto it too
            syn = scene.get("synthetic") or {}
            syn.setdefault("capture", {}).setdefault("background", list(bg))
            scene["synthetic"] = syn
    # `effects: [..]` / `effects: auto` picks what may move: shorthand of the effects section's `requested`
    eff = scene.get("effects")
    if eff is None or isinstance(eff, (list, str)):
        scene["effects"] = {"requested": "auto" if eff in (None, [], "auto") else eff}
    return scene


def _scene_path(scene: dict, key: str, path: Path, missing: str) -> tuple[Path, str]:
    """The scene's path ``key`` with ``${NAME}`` and ``~`` expanded (written back into ``scene``) and the
    text the file gave, for errors; a missing key is an error with ``missing``."""
    value = scene.get(key)
    if not value:
        raise ValueError(f"scene file {path}: {missing}")
    given = str(value)
    scene[key] = expand_env(given, f"scene file {path}: {key}")
    return Path(scene[key]), f"{key}: {given} in {path}"


def _check_colmap(scene: dict, path: Path) -> None:
    """A COLMAP project scene: ``images`` (the photos the model names) and ``sparse`` (a model folder:
    ``sparse/0``, or ``sparse`` holding ``0/``; binary or text)."""
    name = scene["name"]
    need = "source 'colmap' needs 'images: PROJECT/images' and 'sparse: PROJECT/sparse/0'"
    images, given = _scene_path(scene, "images", path, need)
    sparse, given_sparse = _scene_path(scene, "sparse", path, need)
    if not images.is_dir():
        raise FileNotFoundError(f"scene {name!r}: image folder {images} does not exist ({given})")
    model = sparse / "0" if (sparse / "0").is_dir() and not any(sparse.glob("cameras.*")) else sparse
    found = {f.stem for f in model.glob("*.bin")} | {f.stem for f in model.glob("*.txt")} if model.is_dir() else set()
    if not {"cameras", "images", "points3D"} <= found:
        raise FileNotFoundError(f"scene {name!r}: {model} holds no COLMAP model (cameras, images, points3D as .bin or "
                                f".txt; {given_sparse})")
    scene["sparse"] = str(model)


def section(config: dict, scene: dict, variant: str, name: str, schema: dict) -> dict[str, Any]:
    """Effective config section ``name`` for (scene, variant), with the settings read once (:data:`HANDED`)
    handed in where the ``schema`` says the section takes them."""
    if name not in STAGE_SECTIONS:
        raise KeyError(f"unknown config section {name!r}")
    variants = config.get("variant_overrides", {})
    if variant not in variants:
        raise KeyError(f"variant {variant!r} is not defined under variant_overrides (have {sorted(variants)})")
    merged = deep_merge(deep_merge(config.get(name, {}), scene.get(name)), variants[variant].get(name))
    values = {"seed": config.get("seed", 0), "device": config.get("device", "auto"), "fps": config.get("fps", 12)}
    if "background" in scene:
        values["background"] = scene["background"]
    return handed(merged, schema["properties"][name], values)


def workflow_scenes(config: dict, schema: dict, basedir: str | Path, reserved: str) -> dict[str, dict]:
    """The scenes the workflow ``config`` names, each read and checked (:func:`load_scene`); the
    variant overrides checked against the ``schema``'s sections, and every variant the config runs
    defined. ``scene_dir`` is relative to the working directory, else to ``basedir`` (the workflow's
    folder); a scene name may not hold ``reserved`` (the sweep's derived-scene marker)."""
    scene_dir = Path(config["scene_dir"])
    if not scene_dir.is_absolute() and not scene_dir.is_dir():
        scene_dir = Path(basedir) / scene_dir
    scenes = {name: load_scene(scene_dir, name, schema) for name in config["scenes"]}
    for v, o in config["variant_overrides"].items():
        check_sections(o, schema, f"config: variant_overrides.{v}")
    for s in scenes:
        if reserved in s:
            raise ValueError(f"config: scene name {s!r} may not contain {reserved!r} (it marks the sweep's derived scenes)")
    for v in list(config["variants"]) + list(config["table_variants"]):
        if v not in config["variant_overrides"]:
            raise ValueError(f"config: variant {v!r} is not defined under variant_overrides "
                             f"(defined: {sorted(config['variant_overrides'])})")
    return scenes


def scene_pattern(scenes: dict[str, dict], source: str) -> str:
    """A regular expression matching exactly the names of the ``scenes`` of ``source`` (synthetic |
    photos): a rule's ``scene`` wildcard constraint; one that never matches when there is none."""
    names = [re.escape(n) for n, s in scenes.items() if s["source"] == source]
    return "|".join(names) if names else "(?!x)x"
