"""The stages' folders by name, for the workflow and the stage helpers: :func:`stage_outputs` (a stage's
``Outputs`` type from its name, the stage module imported by name) and what the default target builds
(:data:`FINAL_FILES`, :func:`final_targets`) and how many views the views stage queued
(:func:`queued_view_count`, which sets the per-view targets). They live here, in the stage layer, so
that the base (:mod:`anigs.contract`) imports no stage; this module imports no torch."""
from __future__ import annotations

import importlib
import json
from pathlib import Path

from anigs.contract import Outputs


def stage_outputs(stage: str, kind: str = "Outputs") -> type[Outputs]:
    """The ``Outputs`` type ``kind`` of stage module ``anigs.stages.<stage>`` (a dotted name: that
    module's, e.g. ``anigs.study.layout``), imported by name."""
    return getattr(importlib.import_module(stage if "." in stage else f"anigs.stages.{stage}"), kind)


# the files `snakemake` (the default target) asks for of each variant, by stage and key (None: the folder)
FINAL_FILES = (("final", "summary"), ("export", "sidecar"), ("eval", "metrics"), ("view", None))


def final_targets(results: str, scenes: list[str], variants: list[str]) -> list[str]:
    """What the default target builds under ``results``: each scene's variants' :data:`FINAL_FILES`,
    then the scene's effects report (the effects stage's choice, which a still scene shows too)."""
    out = []
    for s in scenes:
        out += [stage_outputs(st).under(results, k, scene=s, variant=v) for v in variants for st, k in FINAL_FILES]
        out.append(stage_outputs("effects").under(results, "effects", scene=s))
    return out


def queued_view_count(views_json: str | Path) -> int:
    """Number of queued views in a ``views.json`` (the views stage's queue): its ``views`` list, ids
    v00..v{n-1}. json only, no torch: the workflow reads it when the views checkpoint has run.

    Views the stage dropped (``dynamic_fraction.dropped``) are not counted. Raises ValueError
    when the queue is empty or its ids are not consecutive from v00.
    """
    with open(views_json) as fh:
        views = json.load(fh)["views"]
    ids = [v["id"] for v in views]
    if not ids or ids != [f"v{i:02d}" for i in range(len(ids))]:
        raise ValueError(f"{views_json}: the queued view ids must be v00, v01, ... (at least one), got {ids}")
    return len(ids)
