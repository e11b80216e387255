"""Stage ``tables``: the paper's tables (CSV, Markdown, LaTeX) from metrics.json files."""
from __future__ import annotations

import argparse
import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from anigs.typed_config import from_dict

log = logging.getLogger("anigs.tables")


@dataclass
class TablesConfig:
    """The ``tables`` config section."""

    ablation_prior: str | None = None  # prior of Table 5's FVD (None = the first prior found, LTX first)

    @staticmethod
    def from_dict(d: dict[str, Any] | None) -> "TablesConfig":
        return from_dict(TablesConfig, d, "tables config", ValueError)


Config = TablesConfig  # the `tables` config section


def run(metrics: list[str | Path], out: str | Path, cfg: TablesConfig) -> list[Path]:
    """Write the tables of the ``metrics`` files into ``out`` (and ``tables.json``); returns the files."""
    from anigs.io import write_json
    from anigs.tables import load_metrics, write_tables

    records = load_metrics(metrics)
    paths = write_tables(records, out, cfg.ablation_prior)
    write_json(Path(out) / "tables.json", {"records": len(records), "metrics": list(map(str, metrics)),
                                           "files": sorted(str(p) for p in paths)})
    log.info("tables: %d records -> %d files in %s", len(records), len(paths), out)
    return paths


# ---- command line: anigs tables ----

def add_arguments(parser: argparse.ArgumentParser) -> None:
    from anigs.cli import add_params, add_out

    parser.add_argument("--metrics", nargs="+", required=True, help="metrics.json files (one per scene/method/variant)")
    add_out(parser, "output folder (e.g. results/tables)")
    add_params(parser, "tables")


def main(args: argparse.Namespace) -> int:
    from anigs.cli import parse_params

    run(args.metrics, args.out, TablesConfig.from_dict(parse_params(args.params)))
    return 0
