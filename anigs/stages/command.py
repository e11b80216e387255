"""A stage's command line (``anigs <stage>``; the command table and chaining: :mod:`anigs.cli`).

By default a stage's flags are its ``Inputs``' fields plus ``--params`` (its ``Config``) and the
command calls ``run(Inputs.from_args(args), Config.from_dict(params))``; a module that needs more
(a summary line, extra modes) defines ``add_arguments(parser)`` and ``main(args) -> int`` itself,
with :func:`add_params` and :func:`parse_params` from here."""
from __future__ import annotations

import argparse
import importlib
import json
import shlex
from pathlib import Path
from typing import Any


def add_params(p: argparse.ArgumentParser, section: str) -> None:
    """``--params``: the stage's config section as JSON, or ``@file.json`` / ``@file.yaml``."""
    p.add_argument("--params", default=None, help=f"the {section} config section as JSON, or @file.json / @file.yaml")


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


def stage_arguments(module, name: str, p: argparse.ArgumentParser) -> None:
    """The command's flags: the module's ``add_arguments``, else its ``Inputs``' flags (derived from the
    fields) and ``--params`` when it has a ``Config``."""
    if hasattr(module, "add_arguments"):
        module.add_arguments(p)
        return
    module.Inputs.add_arguments(p)
    if getattr(module, "Config", None) is not None:
        add_params(p, name)


def stage_main(module, args: argparse.Namespace) -> int:
    """Run the command: the module's ``main``, else ``run(Inputs.from_args(args), Config.from_dict(params))``."""
    if hasattr(module, "main"):
        return module.main(args)
    inputs = module.Inputs.from_args(args)
    if getattr(module, "Config", None) is None:
        module.run(inputs)
    else:
        module.run(inputs, module.Config.from_dict(parse_params(args.params)))
    return 0


def stage_command(stage: str, params: str | None = None, **inputs: Any) -> str:
    """``STAGE --flag value ...`` (shell-quoted) from ``anigs.stages.<stage>.Inputs(**inputs)``
    (:meth:`anigs.contract.Inputs.argv`), with ``--params`` (the stage's config section as JSON)
    when given: the one builder of every stage rule's command (``params.cmd``)."""
    argv = [stage, *importlib.import_module(f"anigs.stages.{stage}").Inputs(**inputs).argv()]
    if params is not None:
        argv += ["--params", params]
    return " ".join(shlex.quote(str(a)) for a in argv)
