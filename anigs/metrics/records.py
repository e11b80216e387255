"""Evaluation records (``metrics.json``, :mod:`anigs.reports.tables`' schema): joining the halves of one
evaluation into the record a single run writes."""
from __future__ import annotations

from pathlib import Path

from anigs.io import read_json, write_json


def merge_records(clips_record: str | Path, model_record: str | Path, out: str | Path,
                  extra: list[str | Path] | None = None) -> dict:
    """``metrics.json`` from the two halves of an evaluation: a ``--part clips`` record (the final
    clips' metrics) and a ``--part model`` record (the model's), checked to be of the same scene,
    variant and method; the metrics in the order of one ``--part all`` run. ``extra``: further
    records of the same evaluation to join (``anigs fvd_gt``'s, ``part: fvd_gt``). No torch: the
    workflow runs it inside Snakemake (the eval stage's merge of the parts)."""
    clips, model = read_json(clips_record), read_json(model_record)
    more = [(p, read_json(p)) for p in (extra or [])]
    for path, rec, part in ((clips_record, clips, "clips"), (model_record, model, "model")):
        if not isinstance(rec, dict) or rec.get("part") != part or not isinstance(rec.get("metrics"), dict):
            raise ValueError(f"eval merge: {path} is not the record of an `anigs eval --part {part}` run")
    key = ("scene", "variant", "method", "dataset")
    if tuple(clips.get(k) for k in key) != tuple(model.get(k) for k in key):
        raise ValueError(f"eval merge: {clips_record} and {model_record} are of different evaluations "
                         f"({[clips.get(k) for k in key]} against {[model.get(k) for k in key]})")
    inputs = {k: v if v not in (None, [], {}) else model.get("inputs", {}).get(k)
              for k, v in clips.get("inputs", {}).items()}
    for path, rec in more:
        if not isinstance(rec, dict) or rec.get("part") != "fvd_gt" or not isinstance(rec.get("metrics"), dict):
            raise ValueError(f"eval merge: {path} is not the record of an `anigs fvd_gt` run")
        if tuple(rec.get(k) for k in key) != tuple(clips.get(k) for k in key):
            raise ValueError(f"eval merge: {path} is of another evaluation ({[rec.get(k) for k in key]})")
    metrics = {**clips["metrics"], **model["metrics"]}
    for _, rec in more:
        metrics.update(rec["metrics"])
    record = dict(clips, part="all", inputs=inputs, seconds=round(clips.get("seconds", 0) + model.get("seconds", 0)
                                                                  + sum(r.get("seconds", 0) for _, r in more), 2),
                  metrics=metrics)
    write_json(out, record)
    return record
