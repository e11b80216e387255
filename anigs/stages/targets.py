"""The stages' folders by name, for the workflow and the stage helpers: :func:`stage_outputs` (a stage's
``Outputs`` type from its name, the stage module imported by name) and what the default target builds
(:data:`FINAL_FILES`, :func:`final_targets`). They live here, in the stage layer, so that the base
(:mod:`anigs.contract`) imports no stage."""
from __future__ import annotations

import importlib

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
