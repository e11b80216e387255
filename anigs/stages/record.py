"""The metrics record the eval and fvd_gt stages write (the schema of ``metrics.json``,
:data:`anigs.reports.tables.SCHEMA`) and what it is made of: the variant's table row (:func:`table_row`,
which the rules ask too) and the ``PRIOR=PATH`` reference options (:func:`prior_pairs`)."""
from __future__ import annotations

from typing import Any

from anigs import __version__
from anigs.reports.tables import SCHEMA
from anigs.animate.config import METHODS


def table_row(method: str, variant: str) -> tuple[str, str]:
    """(method, variant) of a variant's table row: ours under its variant (Table 5), a baseline under
    its method's name (Tables 1-3). ``method``: ``animate.method``."""

    return ("Ours", variant) if method == "anigs" else (METHODS[method], "full")


def prior_pairs(items: list[str] | None, opt: str) -> dict[str, list[str]]:
    """``PRIOR=PATH`` options -> {prior: [paths]}; ``opt``: the flag, for the error."""
    out: dict[str, list[str]] = {}
    for item in items or []:
        if "=" not in item or not item.split("=", 1)[0].strip():
            raise ValueError(f"{opt} expects PRIOR=PATH, got {item!r}")
        prior, path = item.split("=", 1)
        out.setdefault(prior.strip(), []).append(path)
    return out


def metrics_record(row: Any, part: str, config: dict, inputs: dict, seconds: float,
                   metrics: dict[str, Any]) -> dict[str, Any]:
    """The record of ``metrics`` (name -> {value, available, reason, ...}) of one table row: ``row`` has
    ``scene``, ``dataset``, ``method`` and ``variant`` (a stage's inputs); ``part``: all, clips, model or
    fvd_gt; ``seconds``: rounded to 0.01."""

    return {"schema": SCHEMA, "scene": row.scene, "dataset": row.dataset, "method": row.method,
            "variant": row.variant, "part": part, "anigs_version": __version__, "config": config,
            "inputs": inputs, "seconds": round(seconds, 2), "metrics": metrics}
