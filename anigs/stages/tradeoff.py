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

import argparse
import logging
from pathlib import Path

log = logging.getLogger("anigs.tradeoff")


def run(scene: str, points: list, results: str | Path, out_csv: str | Path, plot_metrics: list[str]) -> Path:
    """Write the report of one scene's sweep ``points`` (:class:`anigs.tradeoff.SweepPoint`); returns the CSV."""
    from anigs.io import atomic_path, read_json
    from anigs.tradeoff import (front_section, knob_filename, mark_fronts, markdown_report, metric_directions,
                                plot_knob, report_fronts, report_rows, write_csv)

    if not points:
        raise ValueError(f"tradeoff: scene {scene!r} has no sweep points")
    metrics = {}
    for p in points:
        run_dir = f"{p.scene(scene)}/{p.variant}"
        path = Path(results) / run_dir / "eval" / "metrics.json"
        if not path.exists():
            raise FileNotFoundError(f"{path}: metrics of sweep point {p.knob}={p.value} missing (run the eval rule)")
        metrics[run_dir] = read_json(path)
    rows = report_rows(points, results, scene, metrics)
    directions = metric_directions(metrics)
    fronts = report_fronts(rows, plot_metrics, directions)
    mark_fronts(rows, fronts)
    out = write_csv(rows, out_csv)
    log.info("tradeoff: wrote %s (%d points)", out, len(rows))
    md = out.with_suffix(".md")
    with atomic_path(md) as tmp:
        Path(tmp).write_text(markdown_report(rows, plot_metrics, fronts, directions,
                                             title=f"Accuracy versus time: {scene}"), encoding="utf-8")
    log.info("tradeoff: wrote %s", md)
    for knob in dict.fromkeys(p.knob for p in points):
        png = out.parent / f"{scene}_{knob_filename(knob)}.png"
        plot_knob(rows, knob, plot_metrics, png, fronts=fronts)
        log.info("tradeoff: wrote %s", png)
    for r in rows:
        shown = ", ".join(f"{m} {r[m]:.4g}" for m in plot_metrics if isinstance(r.get(m), float))
        log.info("tradeoff: %s=%s (%s)  %.0f s  %s", r["knob"], r["value"], r["run"], r["seconds"], shown)
    for line in front_section(rows, fronts, directions, plot_metrics).splitlines():
        log.info("tradeoff: %s", line)
    return out


# ---- command line: anigs tradeoff ----

def add_arguments(p: argparse.ArgumentParser) -> None:
    from anigs.cli import add_out

    p.add_argument("--results", required=True, help="results folder (holds {scene}/{variant}/...)")
    p.add_argument("--points", required=True,
                   help="sweep points as JSON or @file: {scene: [{variant, knob, value, scene_tag}]}")
    add_out(p, "report folder (results/tradeoff): {scene}.csv and plots")
    p.add_argument("--plot-metrics", nargs="*", default=[], help="metrics plotted against seconds")


def main(args: argparse.Namespace) -> int:
    from anigs.cli import parse_params
    from anigs.tradeoff import SweepPoint

    raw = parse_params(args.points)
    if not isinstance(raw, dict) or not raw:
        raise ValueError("--points must map each scene to its sweep points: {scene: [{variant, knob, value}]}")
    for scene, pts in raw.items():
        points = [SweepPoint(p["variant"], p["knob"], p["value"], {}, scene_tag=p.get("scene_tag", "")) for p in pts]
        run(scene, points, args.results, Path(args.out) / f"{scene}.csv", args.plot_metrics)
    return 0
