"""Stage ``tables``: the paper's tables (CSV, Markdown, LaTeX) from metrics.json files.

    anigs tables --metrics results/demo/full/eval/metrics.json ... --out results/tables
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path

from anigs import contract
from anigs.contract import File
from anigs.io import write_json
from anigs.reports.tables import load_metrics, write_tables

log = logging.getLogger("anigs.reports.tables")


Config = None  # no config section: the tables follow from the metrics files


class Outputs(contract.Outputs):
    """The tables folder (``results/tables``)."""

    LAYOUT = {"index": File("tables.json", "records read, the metrics files, the files written"),
              "table": File("{name}.{ext}", "one table (anigs.reports.tables: main, fvd, ablation, weightfree, fvd_gt, ...) "
                                            "as csv, md or tex")}


@dataclass
class Inputs(contract.Inputs):
    metrics: list[str] = field(metadata={"help": "the eval stage's records (one per scene/method/variant)"})
    out: Path = field(metadata={"help": "output folder (e.g. results/tables)"})


def run(inputs: Inputs, cfg: None = None) -> Outputs:
    """Write the tables of the metrics files (and ``tables.json``)."""

    out = Outputs(inputs.out)
    records = load_metrics(inputs.metrics)
    paths = write_tables(records, out.root)
    write_json(out.path("index"), {"records": len(records), "metrics": list(map(str, inputs.metrics)),
                                   "files": sorted(str(p) for p in paths)})
    log.info("tables: %d records -> %d files in %s", len(records), len(paths), out.root)
    return out
