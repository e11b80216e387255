"""Stage ``tradeoff``: accuracy-versus-time report of the sweep, for every scene.

Reads the sweep points (``--points``: JSON {scene: [{variant, knob, value, scene_tag}]}), each
point's ``metrics.json`` and the benchmark TSVs under ``--results``, and writes
``OUT/{scene}.csv`` (scene, knob, value, variant, seconds, variant_seconds, jobs, every metric)
plus one PNG per knob (``OUT/{scene}_{knob}.png``: the ``--plot-metrics`` against seconds).
"""
from __future__ import annotations

import argparse
import logging
from pathlib import Path

log = logging.getLogger("anigs.tradeoff")


def run(scene: str, points: list, results: str | Path, out_csv: str | Path, plot_metrics: list[str]) -> Path:
    """Write the report of one scene's sweep ``points`` (:class:`anigs.tradeoff.SweepPoint`); returns the CSV."""
    from anigs.io import read_json
    from anigs.tradeoff import knob_filename, plot_knob, report_rows, write_csv

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
    out = write_csv(rows, out_csv)
    log.info("tradeoff: wrote %s (%d points)", out, len(rows))
    for knob in dict.fromkeys(p.knob for p in points):
        png = out.parent / f"{scene}_{knob_filename(knob)}.png"
        plot_knob(rows, knob, plot_metrics, png)
        log.info("tradeoff: wrote %s", png)
    for r in rows:
        shown = ", ".join(f"{m} {r[m]:.4g}" for m in plot_metrics if isinstance(r.get(m), float))
        log.info("tradeoff: %s=%s (%s)  %.0f s  %s", r["knob"], r["value"], r["run"], r["seconds"], shown)
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
