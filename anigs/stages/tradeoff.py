"""Stage ``tradeoff``: accuracy-versus-time report of the sweep, for every scene.

Reads the sweep points (``--points``: JSON {scene: [{variant, knob, value, scene_tag}]}), each
point's ``metrics.json`` and the benchmark TSVs under ``--results``, and writes
``OUT/{scene}.csv`` (scene, knob, value, variant, seconds, variant_seconds, jobs, every metric,
front), one PNG per knob (``OUT/{scene}_{knob}.png``: the ``--plot-metrics`` against seconds) and
``OUT/{scene}.md`` (the table and "On the front").

The Pareto front of each plotted metric (in its direction, ``higher_is_better`` of its
metrics.json record) runs over every point of the scene, whatever its knob: the CSV's ``front``
names the metrics on whose front a point lies, the plots draw it, and "On the front" (in the
Markdown and the log) lists its settings fastest first.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path

from anigs import contract
from anigs.stages.command import parse_params
from anigs.contract import File
from anigs.stages.eval import Outputs as EvalOutputs
from anigs.io import atomic_path, read_json
from anigs.reports.tradeoff import (SweepPoint, front_section, knob_filename, mark_fronts, markdown_report, metric_directions,
                            plot_knob, report_fronts, report_rows, write_csv)

log = logging.getLogger("anigs.reports.tradeoff")


class Outputs(contract.Outputs):
    """The report folder of a sweep (``results/tradeoff``)."""

    LAYOUT = {"csv": File("{scene}.csv", "scene, knob, value, variant, seconds, variant_seconds, jobs, every metric, "
                                         "front"),
              "md": File("{scene}.md", "the table and the settings on the front"),
              "plot": File("{scene}_{knob}.png", "the plotted metrics against seconds, one knob")}


@dataclass
class Inputs(contract.Inputs):
    results: Path = field(metadata={"help": "results folder (holds {scene}/{variant}/...)"})
    points: str = field(metadata={"help": "sweep points as JSON or @file: {scene: [{variant, knob, value, scene_tag}]}"})
    out: Path = field(metadata={"help": "report folder (results/tradeoff)"})
    plot_metrics: list[str] | None = field(default=None, metadata={"help": "metrics plotted against seconds"})


def run(inputs: Inputs, cfg: None = None) -> Outputs:
    """The report of every scene of the sweep points (the stage has no config section)."""

    raw = parse_params(inputs.points)
    if not isinstance(raw, dict) or not raw:
        raise ValueError("--points must map each scene to its sweep points: {scene: [{variant, knob, value}]}")
    out = Outputs(inputs.out)
    for scene, pts in raw.items():
        points = [SweepPoint(p["variant"], p["knob"], p["value"], {}, scene_tag=p.get("scene_tag", "")) for p in pts]
        report(scene, points, inputs.results, out, list(inputs.plot_metrics or []))
    return out


def report(scene: str, points: list, results: str | Path, out: Outputs, plot_metrics: list[str]) -> Path:
    """Write the report of one scene's sweep ``points`` (:class:`anigs.reports.tradeoff.SweepPoint`) into ``out``;
    returns the CSV."""

    if not points:
        raise ValueError(f"tradeoff: scene {scene!r} has no sweep points")
    metrics = {}
    for p in points:
        run_dir = f"{p.scene(scene)}/{p.variant}"
        path = EvalOutputs(Path(results) / run_dir / "eval").path("metrics")
        if not path.exists():
            raise FileNotFoundError(f"{path}: metrics of sweep point {p.knob}={p.value} missing (run the eval rule)")
        metrics[run_dir] = read_json(path)
    rows = report_rows(points, results, scene, metrics)
    directions = metric_directions(metrics)
    fronts = report_fronts(rows, plot_metrics, directions)
    mark_fronts(rows, fronts)
    csv = write_csv(rows, out.path("csv", scene=scene))
    log.info("tradeoff: wrote %s (%d points)", csv, len(rows))
    md = out.path("md", scene=scene)
    with atomic_path(md) as tmp:
        Path(tmp).write_text(markdown_report(rows, plot_metrics, fronts, directions,
                                             title=f"Accuracy versus time: {scene}"), encoding="utf-8")
    log.info("tradeoff: wrote %s", md)
    for knob in dict.fromkeys(p.knob for p in points):
        png = out.path("plot", scene=scene, knob=knob_filename(knob))
        plot_knob(rows, knob, plot_metrics, png, fronts=fronts)
        log.info("tradeoff: wrote %s", png)
    for r in rows:
        shown = ", ".join(f"{m} {r[m]:.4g}" for m in plot_metrics if isinstance(r.get(m), float))
        log.info("tradeoff: %s=%s (%s)  %.0f s  %s", r["knob"], r["value"], r["run"], r["seconds"], shown)
    for line in front_section(rows, fronts, directions, plot_metrics).splitlines():
        log.info("tradeoff: %s", line)
    return csv


def swept_knobs(tradeoff: dict) -> list[str]:
    """The knobs the config's ``tradeoff`` section sweeps (a null or empty value list drops one)."""
    return [k for k, v in tradeoff.get("knobs", {}).items() if v]


def plot_files(results: str, scenes: list[str], knobs: list[str]) -> list[str]:
    """The report's plots under the results root: one per scene and swept knob, scene by scene."""
    return [Outputs.under(results, "plot", scene=s, knob=knob_filename(k)) for s in scenes for k in knobs]
