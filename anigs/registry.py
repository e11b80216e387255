"""The pipeline's stages: one registry from which everything else derives.

A stage has one name, used for its config section, its Snakemake rule, its ``anigs`` command
and its module ``anigs/stages/<name>.py``. That module owns the stage's ``Config`` dataclass
(the config section's keys, defaults and descriptions), a ``run(...)`` that does the work
from explicit inputs and a config, and its command line (``add_arguments`` and ``main``).

Derived from :data:`STAGES`: the ``anigs`` command table (:mod:`anigs.cli`), the config
sections a scene or variant may override (:mod:`anigs.config`), the sweep's per-scene and
per-variant split (:mod:`anigs.reports.tradeoff`) and the generated config schema
(``workflow/scripts/make_schema.py``).

To add a stage: write ``anigs/stages/<name>.py`` (``Config``, ``Outputs``, ``Inputs``, ``run``),
add one :class:`Stage` line here in pipeline order, add its rule ``<name>`` in
``workflow/rules/``, and regenerate the schema.

The registry sits in the base layer (it imports no stage: :meth:`Stage.load` imports a stage's
module by name), so the config, the sweep and the schema generator read it without importing
the stages; ``anigs.stages`` re-exports it.
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass
from types import ModuleType
from typing import Literal

Scope = Literal["scene", "variant", "global"]


@dataclass(frozen=True)
class Stage:
    """One stage of the pipeline.

    ``scope``: ``scene`` stages run once per scene and every variant shares them; ``variant``
    stages run per (scene, variant); ``global`` stages combine scenes. ``section``: whether the
    stage has a config section (``config.yaml`` key of the same name). ``command``: whether
    ``anigs <name>`` runs it (``animate`` is the round plan: a section and a Snakemake target,
    but its jobs are the ``render_clip``, ``refine`` and ``update`` stages, or ``round`` in place of
    the first two).
    """

    name: str
    help: str
    scope: Scope
    section: bool = True
    command: bool = True

    @property
    def module(self) -> str:
        return f"anigs.stages.{self.name}"

    def load(self) -> ModuleType:
        """Import the stage's module (lazily: only the chosen stage's dependencies load)."""
        return importlib.import_module(self.module)

    def config_class(self) -> type:
        """The stage's config dataclass (its section's schema)."""
        return self.load().Config


STAGES: tuple[Stage, ...] = (
    Stage("capture", "render the synthetic demo capture or import user photos", "scene"),
    Stage("sfm", "COLMAP structure from motion (pycolmap)", "scene"),
    Stage("static", "fit the static canonical 3DGS", "scene"),
    Stage("effects", "which effects the scene contains and where: the region of interest", "scene"),
    Stage("views", "incremental viewpoint expansion: the view queue", "scene"),
    Stage("masks", "dynamic-region masks per view, lifted to the dynamic Gaussian set", "scene"),
    Stage("animate", "the dataset-model loop unrolled into rounds", "variant", command=False),
    Stage("render_clip", "render a camera-fixed clip of one view with a round's model", "variant"),
    Stage("refine", "ComposedV2V refinement of one rendered clip with the video prior", "variant"),
    Stage("round", "render and refine every view of a round in one process (round_jobs: round)", "variant",
          section=False),
    Stage("update", "model update: train the deformation field on a round's targets", "variant"),
    Stage("final", "final videos, moving-camera video and space-time slices", "variant"),
    Stage("export", "export the animated scene (compact .anigs file, DCT PLY + JSON, optional PLY frames)", "variant"),
    Stage("view", "interactive WebGL2 viewer folder of the animated scene (--serve: on 127.0.0.1)", "variant"),
    Stage("eval", "evaluation metrics of one variant", "variant"),
    Stage("fvd_gt", "FVD against the synthetic ground-truth motion on evaluation-only views (FVD-GT)", "variant"),
    Stage("tables", "the paper's tables from metric files", "global", section=False),
    Stage("tradeoff", "accuracy-versus-time report of a sweep (CSV + plots)", "global", section=False),
)

BY_NAME: dict[str, Stage] = {s.name: s for s in STAGES}

# Names a stage had before it got its one name: a config key, rule or command under the old
# name fails with a message naming the new one.
RENAMED: dict[str, str] = {
    "render": "final",          # old CLI name of the final stage (and its rule final_render)
    "render-clip": "render_clip",
    "final_render": "final",
    "static_fit": "static",
    "export_scene": "export",
    "eval_scene": "eval",
    "tables_build": "tables",
    "tradeoff_report": "tradeoff",
}


def sections() -> tuple[str, ...]:
    """Config sections of the stages, in pipeline order."""
    return tuple(s.name for s in STAGES if s.section)


def sections_of(scope: Scope) -> tuple[str, ...]:
    """Config sections of the stages of one scope, in pipeline order."""
    return tuple(s.name for s in STAGES if s.section and s.scope == scope)


def get(name: str) -> Stage:
    """The stage called ``name``; an old name raises naming the new one."""
    if name in BY_NAME:
        return BY_NAME[name]
    if name in RENAMED:
        raise KeyError(f"stage {name!r} is now called {RENAMED[name]!r}")
    raise KeyError(f"unknown stage {name!r}; stages: {[s.name for s in STAGES]}")
