"""``anigs tradeoff``: accuracy-versus-time report of one scene's sweep.

Reads the sweep points (``--points``: JSON list of {variant, knob, value, scene_tag}), each point's
``metrics.json`` and the benchmark TSVs under ``--results``, and writes ``--out-csv``
(scene, knob, value, variant, seconds, variant_seconds, jobs, every metric) plus one PNG per
knob next to it (``{scene}_{knob}.png``: the ``--plot-metrics`` against seconds).
"""
from __future__ import annotations

import argparse
import logging
from pathlib import Path

log = logging.getLogger("anigs.tradeoff")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scene", required=True)
    p.add_argument("--results", required=True, help="results folder (holds {scene}/{variant}/...)")
    p.add_argument("--points", required=True, help="sweep points as JSON or @file: [{variant, knob, value, scene_tag}]")
    p.add_argument("--out-csv", required=True, help="results/tradeoff/{scene}.csv")
    p.add_argument("--plot-metrics", nargs="*", default=[], help="metrics plotted against seconds")


def run(args: argparse.Namespace) -> int:
    from anigs.cli import parse_params
    from anigs.io import read_json
    from anigs.tradeoff import SweepPoint, knob_filename, plot_knob, report_rows, write_csv

    raw = parse_params(args.points)
    pts = raw.get("points") if isinstance(raw, dict) else raw
    if not pts:
        raise ValueError("--points lists no sweep points")
    points = [SweepPoint(p["variant"], p["knob"], p["value"], {}, scene_tag=p.get("scene_tag", "")) for p in pts]
    metrics = {}
    for p in points:
        run = f"{p.scene(args.scene)}/{p.variant}"
        path = Path(args.results) / run / "eval" / "metrics.json"
        if not path.exists():
            raise FileNotFoundError(f"{path}: metrics of sweep point {p.knob}={p.value} missing (run the eval rule)")
        metrics[run] = read_json(path)
    rows = report_rows(points, args.results, args.scene, metrics)
    out = write_csv(rows, args.out_csv)
    log.info("tradeoff: wrote %s (%d points)", out, len(rows))
    for knob in dict.fromkeys(p.knob for p in points):
        png = out.parent / f"{args.scene}_{knob_filename(knob)}.png"
        plot_knob(rows, knob, args.plot_metrics, png)
        log.info("tradeoff: wrote %s", png)
    for r in rows:
        shown = ", ".join(f"{m} {r[m]:.4g}" for m in args.plot_metrics if isinstance(r.get(m), float))
        log.info("tradeoff: %s=%s (%s)  %.0f s  %s", r["knob"], r["value"], r["run"], r["seconds"], shown)
    return 0
