"""Stage ``view``: the interactive WebGL2 viewer of the animated scene (:mod:`anigs.viewer`).

Writes a self-contained folder (``index.html``, its JavaScript, the compact scene) that plays
the animation in any browser, offline, from the file system or served on 127.0.0.1.

    anigs view --model results/demo/full/round4/model.pt --canonical results/demo/static/canonical.ply \\
               --views results/demo/views/views.json --out results/demo/full/viewer [--serve]
"""
from __future__ import annotations

import argparse
import json
import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from anigs.typed_config import from_dict

log = logging.getLogger("anigs.view")


@dataclass
class ViewConfig:
    """The ``view`` config section."""

    background: list = field(default_factory=lambda: [0.62, 0.76, 0.92])  # RGB behind the splats
    fps: float = 12.0  # frames per second of the animation at speed 1x
    embed: bool = True  # also write scene.js, so index.html opens straight from the file system
    title: str = "anigs"  # page title

    @staticmethod
    def from_dict(d: dict[str, Any] | None) -> "ViewConfig":
        return from_dict(ViewConfig, d, "view", KeyError)


Config = ViewConfig  # the `view` config section


def run(model: str | Path, out: str | Path, cfg: ViewConfig, canonical: str | Path | None = None,
        views: str | Path | None = None) -> dict:
    """Write the viewer folder of ``model`` (a model.pt, or a compact .anigs file); returns its summary."""
    from anigs.viewer.build import build_viewer

    summary = build_viewer(model, out, views_json=views, canonical=canonical, background=cfg.background,
                           fps=cfg.fps, embed=cfg.embed, title=cfg.title)
    log.info("view: %s", {k: v for k, v in summary.items() if k != "files"})
    return summary


# ---- command line: anigs view ----

def add_arguments(p: argparse.ArgumentParser) -> None:
    from anigs.cli import add_params, add_canonical, add_out

    p.add_argument("--model", required=True, help="trained model.pt, or a compact .anigs file")
    add_canonical(p, required=False, help="canonical 3DGS PLY the model was trained on")
    p.add_argument("--views", default=None, help="views.json of the views stage (start camera, view list)")
    add_out(p, "viewer folder to write")
    add_params(p, "view")
    p.add_argument("--serve", action="store_true", help="then serve the folder on 127.0.0.1 until Ctrl-C")
    p.add_argument("--port", type=int, default=8000, help="port for --serve (0: any free port)")
    p.add_argument("--serve-seconds", type=float, default=None, help="stop serving after this many seconds")


def main(args: argparse.Namespace) -> int:
    from anigs.cli import parse_params

    summary = run(args.model, args.out, ViewConfig.from_dict(parse_params(args.params)), args.canonical, args.views)
    print(json.dumps({k: v for k, v in summary.items() if k != "files"}))
    if args.serve:
        from anigs.viewer.serve import serve_folder

        serve_folder(args.out, port=args.port, duration=args.serve_seconds)
    return 0
