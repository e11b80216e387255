"""Snakemake benchmark TSVs: read them, sum their seconds, and break a run down per rule.

Every heavy rule of the workflow has a ``benchmark:`` file (columns ``s`` wall seconds,
``cpu_time``, ``max_rss`` MB, ...; one row per ``--benchmark-repeats``). The accuracy-versus-time
report (:mod:`anigs.reports.tradeoff`) sums them per sweep point; ``benchmarks/rules.py`` prints the
per-rule breakdown of a run.
"""
from __future__ import annotations

import csv
import re
from pathlib import Path
from typing import Any, Iterable, Sequence

import numpy as np


def read_benchmark(path: str | Path) -> list[dict[str, float | None]]:
    """The rows of a Snakemake benchmark TSV (one per --benchmark-repeats), every column as a float
    (None where Snakemake wrote ``NA`` or ``-``). A file without an ``s`` column is an error."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f, delimiter="\t"))
    if not rows or "s" not in rows[0]:
        raise ValueError(f"{path}: not a Snakemake benchmark TSV (no 's' column)")

    def num(v: str | None) -> float | None:
        try:
            x = float(v)  # type: ignore[arg-type]
        except (TypeError, ValueError):
            return None
        return None if np.isnan(x) else x

    return [{k: num(v) for k, v in r.items() if k != "h:m:s"} for r in rows]


def _column_mean(rows: Sequence[dict[str, float | None]], column: str) -> float | None:
    vals = [r.get(column) for r in rows]
    if any(v is None for v in vals):
        return None
    return sum(vals) / len(vals)  # type: ignore[arg-type]


def benchmark_seconds(paths: Iterable[str | Path], column: str = "s") -> float | None:
    """Sum over Snakemake benchmark TSVs of ``column`` (mean over --benchmark-repeats): ``s`` wall
    seconds, ``cpu_time`` CPU seconds of the job's process tree. None when a TSV lacks ``column``
    (older Snakemake versions write no cpu_time); a TSV without ``s`` is an error."""
    total = 0.0
    for p in paths:
        v = _column_mean(read_benchmark(p), column)
        if v is None:
            if column == "s":
                raise ValueError(f"{p}: no wall seconds in column 's'")
            return None
        total += v
    return total


# ---- where the time goes: Snakemake's benchmark TSVs per rule (benchmarks/rules.py) ----

_VIEW_SUFFIX = re.compile(r"_v\d+$")


def rule_name(path: str | Path) -> str:
    """The rule a benchmark TSV belongs to: its file name without ``.tsv`` and without a view suffix
    (``round2/render_clip_v03.tsv`` -> ``render_clip``, ``round1/update.tsv`` -> ``update``)."""
    return _VIEW_SUFFIX.sub("", Path(path).name.removesuffix(".tsv"))


def benchmark_files(root: str | Path) -> list[Path]:
    """Every ``*.tsv`` under ``root`` inside a ``benchmarks`` folder (where the workflow's
    ``benchmark:`` directives write), sorted."""
    root = Path(root)
    return sorted(p for p in root.rglob("*.tsv")
                  if "benchmarks" in root.parts or "benchmarks" in p.relative_to(root).parts[:-1])


def rule_breakdown(paths: Iterable[str | Path]) -> list[dict[str, Any]]:
    """One row per rule over benchmark TSVs (:func:`rule_name` of each file), the most wall time
    first: rule, jobs (files), seconds (wall, sum of each job's mean over repeats), cpu_seconds (the
    same for ``cpu_time``; None when a file lacks it), max_rss_mb (the largest ``max_rss`` of any
    job and repeat; None when none has one)."""
    by_rule: dict[str, dict[str, Any]] = {}
    for p in paths:
        rows = read_benchmark(p)
        r = by_rule.setdefault(rule_name(p), {"rule": rule_name(p), "jobs": 0, "seconds": 0.0,
                                              "cpu_seconds": 0.0, "max_rss_mb": None})
        r["jobs"] += 1
        r["seconds"] += _column_mean(rows, "s") or 0.0
        cpu = _column_mean(rows, "cpu_time")
        r["cpu_seconds"] = None if cpu is None or r["cpu_seconds"] is None else r["cpu_seconds"] + cpu
        rss = [x["max_rss"] for x in rows if x.get("max_rss") is not None]
        if rss:
            r["max_rss_mb"] = max(rss + ([r["max_rss_mb"]] if r["max_rss_mb"] is not None else []))
    for r in by_rule.values():
        r["seconds"] = round(r["seconds"], 3)
        r["cpu_seconds"] = None if r["cpu_seconds"] is None else round(r["cpu_seconds"], 3)
    return sorted(by_rule.values(), key=lambda r: (-r["seconds"], r["rule"]))


def breakdown_total(rows: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """The ``total`` row of :func:`rule_breakdown` rows (peak memory: the largest)."""
    cpu = [r["cpu_seconds"] for r in rows]
    rss = [r["max_rss_mb"] for r in rows if r["max_rss_mb"] is not None]
    return {"rule": "total", "jobs": sum(r["jobs"] for r in rows), "seconds": round(sum(r["seconds"] for r in rows), 3),
            "cpu_seconds": None if any(c is None for c in cpu) else round(sum(cpu), 3),
            "max_rss_mb": max(rss) if rss else None}


def compare_breakdowns(before: Sequence[dict[str, Any]], after: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per rule (those of either run; the most wall time after first, then rules only before):
    jobs, seconds and cpu_seconds before and after, and their ratios after / before (None where
    either side lacks the rule or a value, or before is 0)."""
    b, a = {r["rule"]: r for r in before}, {r["rule"]: r for r in after}
    order = [r["rule"] for r in after] + [r["rule"] for r in before if r["rule"] not in a]

    def ratio(x, y):
        return None if x is None or y is None or x == 0 else round(y / x, 4)

    out = []
    for name in order:
        rb, ra = b.get(name, {}), a.get(name, {})
        row: dict[str, Any] = {"rule": name, "jobs_before": rb.get("jobs"), "jobs_after": ra.get("jobs")}
        for k in ("seconds", "cpu_seconds"):
            row[f"{k}_before"], row[f"{k}_after"] = rb.get(k), ra.get(k)
            row[f"{k}_ratio"] = ratio(rb.get(k), ra.get(k))
        out.append(row)
    return out
