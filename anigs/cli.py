"""``anigs`` command line: one subcommand per workflow stage.

Each subcommand lives in ``anigs/commands/<name>.py`` and exposes
``add_arguments(parser)`` and ``run(args) -> int``. Stage parameters come as the config
section in JSON (``--params '{...}'`` or ``--params @file.json``) so Snakemake can pass
its ``params:`` verbatim; paths are explicit options.
"""
from __future__ import annotations

import argparse
import importlib
import json
import logging
import sys
from pathlib import Path
from typing import Any

# subcommand -> (module, one-line help)
COMMANDS: dict[str, tuple[str, str]] = {
    "build-kernel": ("anigs.commands.build_kernel", "compile the CPU rasterizer kernel ahead of time"),
    "capture": ("anigs.commands.capture", "render the synthetic demo capture or import user photos"),
    "sfm": ("anigs.commands.sfm", "COLMAP structure from motion (pycolmap)"),
    "static": ("anigs.commands.static", "fit the static canonical 3DGS"),
    "views": ("anigs.commands.views", "incremental viewpoint expansion: the view queue"),
    "masks": ("anigs.commands.masks", "dynamic-region masks per view"),
    "render-clip": ("anigs.commands.render_clip", "render a camera-fixed clip of one view with a round's model"),
    "refine": ("anigs.commands.refine", "ComposedV2V refinement of one rendered clip"),
    "update": ("anigs.commands.update", "model update: train the deformation field on a round's targets"),
    "render": ("anigs.commands.render", "final videos and space-time slices"),
    "export": ("anigs.commands.export", "export the animated scene (PLY sequence, DCT PLY + JSON)"),
    "eval": ("anigs.commands.eval", "evaluation metrics"),
    "tables": ("anigs.commands.tables", "paper tables from metric files"),
    "tradeoff": ("anigs.commands.tradeoff", "accuracy-versus-time report of a sweep (CSV + plots)"),
}


def parse_params(value: str | None) -> dict[str, Any]:
    """Parse ``--params``: inline JSON, or ``@path`` to a JSON/YAML file; empty -> {}."""
    if not value:
        return {}
    if value.startswith("@"):
        path = Path(value[1:])
        text = path.read_text()
        if path.suffix in (".yaml", ".yml"):
            import yaml

            return yaml.safe_load(text) or {}
        return json.loads(text)
    return json.loads(value)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="anigs", description=__doc__.splitlines()[0])
    parser.add_argument("-v", "--verbose", action="store_true", help="debug logging")
    parser.add_argument("--threads", type=int, default=None,
                        help="CPU threads for torch and the rasterizer (Snakemake passes {threads})")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    modules = {}
    argv = sys.argv[1:] if argv is None else argv
    wanted = next((a for a in argv if a in COMMANDS), None)
    for name, (mod, help_) in COMMANDS.items():
        p = sub.add_parser(name, help=help_)
        if name == wanted:  # import lazily: only the chosen stage's dependencies load
            try:
                modules[name] = importlib.import_module(mod)
            except ModuleNotFoundError as exc:
                if exc.name == mod:
                    parser.error(f"stage {name!r} is not implemented in this version of anigs")
                raise
            modules[name].add_arguments(p)
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.INFO,
                        format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    if args.command is None:
        parser.print_help()
        return 2
    if args.threads:
        import torch

        torch.set_num_threads(max(1, args.threads))
    try:
        return int(modules[args.command].run(args) or 0)
    except (ValueError, FileNotFoundError, RuntimeError, KeyError) as exc:
        logging.getLogger("anigs").error("%s: %s", type(exc).__name__, exc)
        if args.verbose:
            raise
        return 1


if __name__ == "__main__":
    sys.exit(main())
