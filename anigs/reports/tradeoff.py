"""Accuracy versus time: the sweep's variants, and its report (CSV + one plot per knob).

A sweep varies one knob at a time around a base variant. A knob is a dotted key of a config
section with a list of values, or a bare section name whose values are mappings (several keys
set together, e.g. ``views: [{width: 128, height: 96}]`` for the render resolution).

* Per-variant sections (``update.steps``, ``refine.strength``, ``animate.views_per_round``):
  each (knob, value) becomes a workflow variant ``tradeoff-<section>-<key>-<value>`` whose
  overrides are the base variant's plus that one key.
* Per-scene stages (``static.iterations``, ``views``, ``masks.*``), which every variant of a
  scene shares: each (knob, value) becomes a *derived scene* ``<scene>--tradeoff-...`` (the
  scene with that override) run with the base variant. It reuses the base scene's outputs of
  the stages upstream of the knob's section (:data:`SCENE_STAGE_ORDER`; the capture and SfM
  always), and recomputes the rest.

A value equal to the base setting maps to the base point itself (no extra jobs).

Seconds come from Snakemake's benchmark TSVs (column ``s``, and ``cpu_time`` for the CPU
seconds, which stay comparable when other work shared the machine): the per-scene stages the point
uses (static, views, masks, from the scene that computed them) plus every job of the variant up
to its final renders (evaluation and export excluded), so a row says what the result cost to
compute.
"""
from __future__ import annotations

import copy
import csv
import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from anigs.reports.benchmark_tsv import benchmark_seconds
from anigs.config import deep_merge
from anigs.io import atomic_path
from anigs.registry import sections_of
from anigs.knob_chart import plot_knob as plot_knob  # re-exported: the sweep report's plot

# config sections a variant may override (the others are shared by every variant of a scene)
VARIANT_SECTIONS = sections_of("variant")
# per-scene stages whose time every variant includes and that a knob may sweep (a derived scene
# reuses the capture and SfM of its base scene as they are)
SCENE_STAGES = tuple(s for s in sections_of("scene") if s not in ("capture", "sfm"))
# per-scene stages in pipeline order: a derived scene shares every stage before its knob's
SCENE_STAGE_ORDER = sections_of("scene")
EXCLUDED_BENCHMARKS = ("eval.tsv", "eval_model.tsv", "export.tsv", "view.tsv")
DERIVED_SEP = "--"


@dataclass(frozen=True)
class SweepPoint:
    """One point of the sweep: ``variant`` of scene ``<scene><scene_tag>`` with ``knob`` = ``value``.

    ``scene_tag`` is empty for per-variant knobs; for a per-scene knob it is the derived scene's
    suffix (``--tradeoff-static-iterations-500``) and ``scene_overrides`` its section override.
    """

    variant: str
    knob: str
    value: Any
    overrides: dict
    scene_tag: str = ""
    scene_overrides: dict | None = None

    def scene(self, base_scene: str) -> str:
        return base_scene + self.scene_tag


def _slug(value: Any) -> str:
    if isinstance(value, dict):
        return "-".join(f"{k}-{_slug(v)}" for k, v in sorted(value.items()))
    s = str(value).lower().replace(".", "p").replace("-", "m")
    return re.sub(r"[^a-z0-9_]", "_", s)


def variant_name(knob: str, value: Any) -> str:
    """Workflow name of a sweep point, e.g. ``tradeoff-update-steps-40``, ``tradeoff-views-height-96-width-128``."""
    section, _, key = knob.partition(".")
    head = f"tradeoff-{section}-{key.replace('.', '-')}" if key else f"tradeoff-{section}"
    return f"{head}-{_slug(value)}"


def derived_scene(scene: str) -> tuple[str, str]:
    """(base scene, knob section) of a derived scene name; (scene, "") for a plain scene."""
    base, sep, tag = scene.partition(DERIVED_SEP)
    if not sep:
        return scene, ""
    return base, tag.split("-")[1]


def stage_owner(scene: str, stage: str) -> str:
    """The scene whose outputs of per-scene ``stage`` ``scene`` uses (itself, or a derived
    scene's base for the stages upstream of its knob's section)."""
    base, section = derived_scene(scene)
    if not section or SCENE_STAGE_ORDER.index(stage) >= SCENE_STAGE_ORDER.index(section):
        return scene
    return base


def _knob_value(value: Any, key: str) -> dict:
    """The section override of one knob value: {key: value} (nested by dots), or the mapping itself."""
    if not key:
        return copy.deepcopy(value)
    out: dict = {}
    node = out
    parts = key.split(".")
    for p in parts[:-1]:
        node = node.setdefault(p, {})
    node[parts[-1]] = copy.deepcopy(value)
    return out


def get_dotted(d: dict, keys: Sequence[str]) -> Any:
    """``d[k0][k1]...``, or None where a key is missing."""
    for k in keys:
        if not isinstance(d, dict) or k not in d:
            return None
        d = d[k]
    return d


def _same_as_base(value: Any, section: str, key: str, base_value) -> bool:
    """Whether ``value`` equals the base's effective setting (every key of a mapping value)."""
    if base_value is None:
        return False
    if not key:
        return all(base_value(f"{section}.{k}") == v for k, v in value.items())
    current = base_value(f"{section}.{key}")
    return current is not None and value == current


def sweep_points(knobs: dict[str, list], base: str, variant_overrides: dict[str, dict],
                 base_value=None) -> list[SweepPoint]:
    """Sweep points of ``knobs`` {"section.key": [values] | "section": [mappings] | None} around ``base``.

    ``base_value(knob)`` (optional; knob = "section.key") gives the base's effective setting; a
    value equal to it maps to the base point. Raises ValueError naming a knob outside the
    per-variant sections and per-scene stages, an empty value list, a bare-section knob whose
    values are not mappings, or an unknown base.
    """
    if base not in variant_overrides:
        raise ValueError(f"tradeoff.base: variant {base!r} is not defined under variant_overrides "
                         f"(defined: {sorted(variant_overrides)})")
    points = []
    for knob, values in knobs.items():
        if values is None:  # null drops a knob set by an earlier config file
            continue
        section, _, key = knob.partition(".")
        if section not in VARIANT_SECTIONS + SCENE_STAGES:
            raise ValueError(f"tradeoff.knobs: {knob!r} is not <section>.<key> of a per-variant section "
                             f"{VARIANT_SECTIONS} or a per-scene stage {SCENE_STAGES}")
        if not isinstance(values, list) or not values:
            raise ValueError(f"tradeoff.knobs.{knob}: give a non-empty list of values, got {values!r}")
        if not key and not all(isinstance(v, dict) and v for v in values):
            raise ValueError(f"tradeoff.knobs.{knob}: a bare section knob takes mappings of its keys "
                             f"(e.g. {{width: 128, height: 96}}), got {values!r}")
        for v in values:
            base_ov = copy.deepcopy(variant_overrides[base])
            if _same_as_base(v, section, key, base_value):
                points.append(SweepPoint(base, knob, v, base_ov))
            elif section in VARIANT_SECTIONS:
                ov = deep_merge(base_ov, {section: _knob_value(v, key)})
                points.append(SweepPoint(variant_name(knob, v), knob, v, ov))
            else:
                points.append(SweepPoint(base, knob, v, base_ov, scene_tag=DERIVED_SEP + variant_name(knob, v),
                                         scene_overrides={section: _knob_value(v, key)}))
    return points


def workflow_sweep(config: dict, scenes: dict[str, dict], all_scenes: dict[str, dict],
                   section_of: Callable[[str, str, str], dict]) -> dict[str, list[SweepPoint]]:
    """Every scene's sweep points (scene -> points) of the workflow ``config``'s ``tradeoff`` section.

    Each point's variant is added to ``config["variant_overrides"]`` and each derived scene to
    ``all_scenes``, in place, so the workflow's jobs read them as any other; ``section_of(scene,
    name, variant)`` is the effective config section (it sees the points added so far).
    """
    to = config.get("tradeoff", {})
    out: dict[str, list[SweepPoint]] = {}
    for s in scenes:
        base = to.get("base", "full")
        out[s] = sweep_points(to.get("knobs", {}), base, config["variant_overrides"],
                              lambda knob, s=s: get_dotted(section_of(s, knob.split(".")[0], base), knob.split(".")[1:]))
        for p in out[s]:
            config["variant_overrides"].setdefault(p.variant, p.overrides)
            if p.scene_tag:
                all_scenes[p.scene(s)] = deep_merge(scenes[s], p.scene_overrides)
    return out


def points_json(sweep: dict[str, list[SweepPoint]]) -> str:
    """The sweep's points as JSON (scene -> [{variant, knob, value, scene_tag}]: the report's ``--points``)."""
    return json.dumps({s: [{"variant": p.variant, "knob": p.knob, "value": p.value, "scene_tag": p.scene_tag}
                           for p in pts] for s, pts in sweep.items()})


def point_benchmarks(results: str | Path, scene: str, variant: str) -> tuple[list[Path], list[Path]]:
    """(per-scene stage TSVs, the variant's own TSVs) that a point's seconds add up.

    ``scene`` may be a derived scene: each stage's TSV is read from the scene that ran it.
    """
    shared = [Path(results) / stage_owner(scene, s) / "benchmarks" / f"{s}.tsv" for s in SCENE_STAGES]
    shared = [p for p in shared if p.exists()]
    own = sorted(p for p in (Path(results) / scene / variant / "benchmarks").rglob("*.tsv")
                 if p.name not in EXCLUDED_BENCHMARKS)
    return shared, own


def report_rows(points: Sequence[SweepPoint], results: str | Path, scene: str,
                metrics: dict[str, dict]) -> list[dict[str, Any]]:
    """One row per point: knob, value, variant, run (its results folder), seconds and
    variant_seconds (wall), cpu_seconds and variant_cpu_seconds (CPU time: comparable when the
    machine was shared), jobs, then every metric value.

    ``metrics``: "{point scene}/{variant}" -> its metrics.json content.
    """
    rows = []
    for p in points:
        run = f"{p.scene(scene)}/{p.variant}"
        shared, own = point_benchmarks(results, p.scene(scene), p.variant)
        if not own:
            raise FileNotFoundError(f"no benchmark TSVs for {run} under {results}")
        own_s, own_cpu = benchmark_seconds(own), benchmark_seconds(own, "cpu_time")
        shared_cpu = benchmark_seconds(shared, "cpu_time")
        value = json.dumps(p.value, sort_keys=True) if isinstance(p.value, dict) else p.value
        row: dict[str, Any] = {"scene": scene, "knob": p.knob, "value": value, "variant": p.variant, "run": run,
                               "seconds": round(benchmark_seconds(shared) + own_s, 3),
                               "variant_seconds": round(own_s, 3),
                               "cpu_seconds": None if own_cpu is None or shared_cpu is None
                               else round(shared_cpu + own_cpu, 3),
                               "variant_cpu_seconds": None if own_cpu is None else round(own_cpu, 3),
                               "jobs": len(own)}
        for name, rec in sorted(metrics[run].get("metrics", {}).items()):
            row[name] = rec.get("value") if rec.get("available") else None
        rows.append(row)
    return rows


# ---- the Pareto front: the settings no other is both faster and better than ----

def pareto_front(times: Sequence[float | None], values: Sequence[float | None], lower_is_better: bool) -> list[int]:
    """Indices of the points on the time-versus-metric Pareto front, fastest first.

    A point is on the front when no other is at least as fast and at least as good, and strictly
    one of the two. Equal points (the same time and value) are all on it; of points with equal
    times only the best value is. Points whose time or value is None or NaN are left out.
    """
    def ok(x) -> bool:
        return x is not None and not np.isnan(float(x))

    idx = [i for i in range(len(times)) if ok(times[i]) and ok(values[i])]
    t = {i: float(times[i]) for i in idx}
    v = {i: float(values[i]) if lower_is_better else -float(values[i]) for i in idx}  # lower is better
    front = [i for i in idx if not any(t[j] <= t[i] and v[j] <= v[i] and (t[j] < t[i] or v[j] < v[i])
                                       for j in idx)]
    return sorted(front, key=lambda i: (t[i], v[i], i))


def metric_directions(metrics: dict[str, dict]) -> dict[str, bool | None]:
    """Metric name -> higher_is_better (True / False; None for a metric without a direction, such as
    a ratio to the ground truth) from metrics.json contents ({run: content}); the first run that
    states one wins."""
    out: dict[str, bool | None] = {}
    for content in metrics.values():
        for name, rec in content.get("metrics", {}).items():
            if out.get(name) is None:
                hib = rec.get("higher_is_better")
                out[name] = None if hib is None else bool(hib)
    return out


def report_fronts(rows: Sequence[dict[str, Any]], metric_names: Sequence[str], directions: dict[str, bool | None],
                  time_key: str = "seconds") -> dict[str, list[int]]:
    """Metric -> indices into ``rows`` of its Pareto front over every point (:func:`pareto_front`
    of ``time_key`` against the metric), for the metrics with a direction and at least one value."""
    fronts = {}
    for m in metric_names:
        if directions.get(m) is None or not any(r.get(m) is not None for r in rows):
            continue
        fronts[m] = pareto_front([r.get(time_key) for r in rows], [r.get(m) for r in rows], not directions[m])
    return fronts


def mark_fronts(rows: Sequence[dict[str, Any]], fronts: dict[str, list[int]]) -> None:
    """Set each row's ``front``: the metrics on whose front it lies, separated by "; " ("" for none)."""
    for i, r in enumerate(rows):
        r["front"] = "; ".join(m for m, idx in fronts.items() if i in idx)


def _fmt(x: Any, seconds: bool = False) -> str:
    if x is None:
        return "n/a"
    if isinstance(x, float):
        return f"{x:.0f}" if seconds and abs(x) >= 100 else f"{x:.4g}"
    return str(x)


def front_section(rows: Sequence[dict[str, Any]], fronts: dict[str, list[int]],
                  directions: dict[str, bool | None], metric_names: Sequence[str] = (),
                  time_key: str = "seconds") -> str:
    """Markdown "On the front": per metric, the settings on its front, fastest first (knob = value,
    run, seconds, the metric); a point that stands for several knob values (the base) names them
    all. Metrics of ``metric_names`` without a direction or a value are named as such."""
    lines = ["## On the front", "",
             f"Per metric, the settings that no other beats in both {time_key} and the metric, fastest "
             "first: under a time budget, run the last one that fits.", ""]
    for m, idx in fronts.items():
        lines += [f"### {m} ({'higher' if directions[m] else 'lower'} is better)", ""]
        runs: dict[str, list[int]] = {}
        for i in idx:
            runs.setdefault(rows[i]["run"], []).append(i)
        for run, ii in runs.items():
            r = rows[ii[0]]
            setting = ", ".join(f"{rows[i]['knob']} = {rows[i]['value']}" for i in ii)
            cpu = (f" (CPU {_fmt(r['cpu_seconds'], True)} s)" if time_key != "cpu_seconds"
                   and r.get("cpu_seconds") is not None else "")
            lines.append(f"- {setting} (`{run}`): {_fmt(r.get(time_key), True)} s{cpu}, {m} {_fmt(r.get(m))}")
        lines.append("")
    for m in metric_names:
        if m in fronts:
            continue
        why = ("it has no direction (closeness to a reference matters)" if directions.get(m) is None
               and any(r.get(m) is not None for r in rows) else "no point has a value")
        lines += [f"### {m}: no front, {why}", ""]
    return "\n".join(lines)


def markdown_report(rows: Sequence[dict[str, Any]], metric_names: Sequence[str], fronts: dict[str, list[int]],
                    directions: dict[str, bool | None], title: str = "Accuracy versus time") -> str:
    """Markdown of the report: one table row per point (knob, value, run, seconds, CPU seconds and
    the metrics, a ✓ after a value on its metric's front), then :func:`front_section`."""
    shown = [m for m in metric_names if any(r.get(m) is not None for r in rows)]
    head = ["knob", "value", "run", "seconds", "cpu_seconds", *shown]
    lines = [f"# {title}", "", "✓: on the metric's Pareto front (time against the metric, over every point).", "",
             "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for i, r in enumerate(rows):
        cells = [_fmt(r.get(k), k.endswith("seconds")) for k in head[:5]]
        cells += [_fmt(r.get(m)) + (" ✓" if i in fronts.get(m, ()) else "") for m in shown]
        lines.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
    return "\n".join(lines) + "\n\n" + front_section(rows, fronts, directions, metric_names) + "\n"


def write_csv(rows: Sequence[dict[str, Any]], path: str | Path) -> Path:
    cols: list[str] = []
    for r in rows:
        cols += [k for k in r if k not in cols]
    with atomic_path(path) as tmp:
        with open(tmp, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=cols, lineterminator="\n")
            w.writeheader()
            for r in rows:
                w.writerow({k: ("n/a" if r.get(k) is None else r.get(k)) for k in cols})
    return Path(path)


def knob_filename(knob: str) -> str:
    return knob.replace(".", "-")

