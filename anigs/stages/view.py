"""Stage ``view``: the interactive WebGL2 viewer of the animated scene (:mod:`anigs.viewer`).

Writes a self-contained folder (``index.html``, its JavaScript, the compact scene) that plays
the animation in any browser, offline, from the file system or served on 127.0.0.1.

    anigs view --model results/demo/full/round4 --static results/demo/static \\
               --views results/demo/views --out results/demo/full/viewer [--serve]
"""
from __future__ import annotations

import argparse
import json
import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from anigs.viewer.config import ViewConfig
from anigs import contract
from anigs.stages.command import parse_params
from anigs.stages.static import Outputs as StaticOutputs
from anigs.stages.views import Outputs as ViewsOutputs
from anigs.contract import File
from anigs.stages.update import Outputs as UpdateOutputs
from anigs.viewer.build import build_viewer
from anigs.viewer.serve import serve_folder

log = logging.getLogger("anigs.view")


Config = ViewConfig  # the `view` config section


class Outputs(contract.Outputs):
    """The viewer folder of a variant (``viewer/``; the names are :mod:`anigs.viewer.build`'s)."""

    FOLDER = "{scene}/{variant}/viewer"
    LAYOUT = {"index": File("index.html", "the viewer page (with its .js and .css beside it)"),
              "scene": File("scene.anigs", "the compact animated scene the page loads"),
              "embed": File("scene.js", "the scene as base64, for file:// (view.embed)", optional=True),
              "config": File("config.js", "start camera, view list, background, fps, title")}


@dataclass
class Inputs(contract.Inputs):
    out: Path = field(metadata={"help": "viewer folder to write"})
    model: UpdateOutputs | None = None
    compact: Path | None = field(default=None, metadata={"help": "a compact .anigs file instead of --model"})
    static: StaticOutputs | None = field(default=None, metadata={"help": "the static stage's folder (the canonical "
                                                                         "scene the model was trained on)"})
    views: ViewsOutputs | None = field(default=None, metadata={"help": "the views stage's folder (start camera, "
                                                                       "view list)"})
    serve: bool = field(default=False, metadata={"help": "then serve the folder on 127.0.0.1 until Ctrl-C"})
    port: int = field(default=8000, metadata={"help": "port for --serve (0: any free port)"})
    serve_seconds: float | None = field(default=None, metadata={"help": "stop serving after this many seconds"})


def build(inputs: Inputs, cfg: ViewConfig) -> dict[str, Any]:
    """Write the viewer folder of the model (or compact file); returns its summary (sizes, counts)."""

    if (inputs.model is None) == (inputs.compact is None):
        raise ValueError("view: give --model DIR (a model's folder) or --compact FILE (.anigs)")
    model = inputs.model.path("model") if inputs.model is not None else inputs.compact
    summary = build_viewer(model, Outputs(inputs.out), views_json=inputs.views.path("views") if inputs.views else None,
                           canonical=inputs.static.path("canonical") if inputs.static else None,
                           background=cfg.background, fps=cfg.fps, embed=cfg.embed, title=cfg.title)
    summary = {k: v for k, v in summary.items() if k != "files"}
    log.info("view: %s", summary)
    return summary


def run(inputs: Inputs, cfg: ViewConfig) -> Outputs:
    """Write the viewer folder of the model (or compact file)."""
    build(inputs, cfg)
    return Outputs(inputs.out)


# ---- command line: anigs view ----

def main(args: argparse.Namespace) -> int:
    inputs = Inputs.from_args(args)
    print(json.dumps(build(inputs, ViewConfig.from_dict(parse_params(args.params)))))
    if inputs.serve:
        serve_folder(Outputs(inputs.out), port=inputs.port, duration=inputs.serve_seconds)
    return 0
