"""Workflow configuration: scenes, variants and the effective section each stage receives.

Effective section = global section (config.yaml) <- the scene file's override <- the variant's
override (deep merge, later wins). Scene files live in ``config/scenes/{name}.yaml``.
"""
from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import yaml

STAGE_SECTIONS = ("capture", "sfm", "static", "views", "masks", "animate", "render_clip", "refine", "update",
                  "final", "export", "eval")
SCENE_KEYS = {"name", "source", "synthetic", "photos", "colmap", "ply", "effects", "prompt", *STAGE_SECTIONS}
SOURCES = ("synthetic", "photos")


def deep_merge(base: dict, override: dict | None) -> dict:
    """Recursive dict merge; ``override`` wins; inputs are not modified."""
    out = copy.deepcopy(base)
    for k, v in (override or {}).items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = deep_merge(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out


def load_scene(scene_dir: str | Path, name: str) -> dict[str, Any]:
    """Read and check ``{scene_dir}/{name}.yaml``."""
    path = Path(scene_dir) / f"{name}.yaml"
    if not path.exists():
        raise FileNotFoundError(f"scene {name!r}: no scene file {path} (create it; see config/README.md)")
    scene = yaml.safe_load(path.read_text()) or {}
    unknown = sorted(set(scene) - SCENE_KEYS)
    if unknown:
        raise ValueError(f"scene file {path}: unknown key(s) {unknown}; allowed: {sorted(SCENE_KEYS)}")
    scene.setdefault("name", name)
    src = scene.get("source")
    if src not in SOURCES:
        raise ValueError(f"scene file {path}: 'source' must be one of {SOURCES}, got {src!r}")
    if src == "photos":
        photos = scene.get("photos")
        if not photos:
            raise ValueError(f"scene file {path}: source 'photos' needs 'photos: /path/to/your/photos'")
        p = Path(photos)
        if not p.is_dir():
            raise FileNotFoundError(f"scene {name!r}: photo folder {p} does not exist")
        if not any(f.suffix.lower() in (".jpg", ".jpeg", ".png") for f in p.iterdir()):
            raise ValueError(f"scene {name!r}: photo folder {p} holds no .jpg/.jpeg/.png files")
    if not scene.get("effects"):
        scene["effects"] = []
    return scene


def section(config: dict, scene: dict, variant: str, name: str) -> dict[str, Any]:
    """Effective config section ``name`` for (scene, variant)."""
    if name not in STAGE_SECTIONS:
        raise KeyError(f"unknown config section {name!r}")
    variants = config.get("variant_overrides", {})
    if variant not in variants:
        raise KeyError(f"variant {variant!r} is not defined under variant_overrides (have {sorted(variants)})")
    merged = deep_merge(config.get(name, {}), scene.get(name))
    return deep_merge(merged, variants[variant].get(name))
