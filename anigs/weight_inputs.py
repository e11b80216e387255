"""The local model weights a workflow job reads, as files Snakemake can watch.

A stage that loads weights from a configured path (the effects stage's segmenter, the masks stage's
SAM2 checkpoint, the refine stage's LTX-Video folder, FVD's I3D) must re-run when those weights
change. The path's value is in the job's params, so pointing it elsewhere re-runs the job; these
functions give the files themselves as rule inputs, so that a replaced or updated file at the same
path re-runs it too (Snakemake's ``mtime`` trigger). A path that is empty, names a package's own
weights (``auto``) or does not exist gives no input: the stage itself then says what is missing,
where, and how to get it (Snakemake would only say "missing input").
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Mapping


def weight_files(*paths: str | os.PathLike | None) -> list[str]:
    """The files of ``paths``: a file itself, every file under a folder (hidden ones left out: a hub
    cache's lock files), sorted; nothing for an empty, ``auto`` or missing path."""
    out: list[str] = []
    for p in paths:
        if not p or str(p) == "auto":
            continue
        path = Path(os.path.expandvars(str(p))).expanduser()
        if path.is_file():
            out.append(str(path))
        elif path.is_dir():
            out += sorted(str(f) for f in path.rglob("*")
                          if f.is_file() and not any(part.startswith(".") for part in f.relative_to(path).parts))
    return out


def effects_weights(section: Mapping[str, Any]) -> list[str]:
    """The effects section's segmenter weights (``effects.segmenter``, when its backend is not ``none``)."""
    seg = section.get("segmenter") or {}
    return weight_files(seg.get("weights")) if seg.get("backend", "none") != "none" else []


def masks_weights(section: Mapping[str, Any]) -> list[str]:
    """The masks section's SAM2 checkpoint (``masks.sam2.checkpoint``, with ``masks.backend: sam2``)."""
    return weight_files((section.get("sam2") or {}).get("checkpoint")) if section.get("backend") == "sam2" else []


def refine_weights(section: Mapping[str, Any]) -> list[str]:
    """The refine section's LTX-Video folder and prompt embeddings (``refine.ltx``, with ``prior: ltx``)."""
    ltx = section.get("ltx") or {}
    return weight_files(ltx.get("model_path"), ltx.get("prompt_embeds")) if section.get("prior") == "ltx" else []


def eval_weights(section: Mapping[str, Any]) -> list[str]:
    """The eval section's I3D file (``eval.i3d_path``; ``auto``, the installed package's, is not watched)."""
    return weight_files(section.get("i3d_path"))
