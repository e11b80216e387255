"""Stage ``tables``: the paper's tables (CSV, Markdown, LaTeX) from metrics.json files."""
from __future__ import annotations

import argparse
import logging
from pathlib import Path

log = logging.getLogger("anigs.tables")


def run(metrics: list[str | Path], out: str | Path) -> list[Path]:
    """Write the tables of the ``metrics`` files into ``out`` (and ``tables.json``); returns the files."""
    from anigs.io import write_json
    from anigs.tables import load_metrics, write_tables

    records = load_metrics(metrics)
    paths = write_tables(records, out)
    write_json(Path(out) / "tables.json", {"records": len(records), "metrics": list(map(str, metrics)),
                                           "files": sorted(str(p) for p in paths)})
    log.info("tables: %d records -> %d files in %s", len(records), len(paths), out)
    return paths


# ---- command line: anigs tables ----

def add_arguments(parser: argparse.ArgumentParser) -> None:
    from anigs.cli import add_out

    parser.add_argument("--metrics", nargs="+", required=True, help="metrics.json files (one per scene/method/variant)")
    add_out(parser, "output folder (e.g. results/tables)")


def main(args: argparse.Namespace) -> int:
    run(args.metrics, args.out)
    return 0
