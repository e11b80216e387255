"""Stage ``eval``: every metric of one (scene, method, variant) into ``metrics.json``.

The metrics and their inputs are described in :mod:`anigs.metrics.suite`; the schema of the
output in :mod:`anigs.tables`.

    anigs eval --final-dir final/ --masks masks/ --model round4/model.pt --canonical static/canonical.ply \
        --cameras sfm/cameras.json --images sfm/images --points sfm/points.npz [--gt-dir capture/gt] \
        --scene demo --variant full --out eval/metrics.json --params '{...eval section...}'

The workflow runs it in two halves: ``--part model`` (the ground-truth motion and the multiview
protocol, which need the model but not the final clips) in a job beside the final renders, and
``--part clips`` in the final job after the videos; :func:`merge` (``anigs eval --merge CLIPS
MODEL --out metrics.json``) joins the two records into the one a ``--part all`` run writes.
"""
from __future__ import annotations

import argparse
import dataclasses
import logging
import time
from dataclasses import dataclass, field
from pathlib import Path

from anigs.metrics.suite import EvalConfig

Config = EvalConfig  # the `eval` config section

log = logging.getLogger("anigs.eval")


@dataclass
class EvalInputs:
    """What one evaluation reads (every input but the clips is optional; a metric whose inputs are
    missing is recorded as not available, with the reason)."""

    clips: list[str] = field(default_factory=list)  # final-dir and/or clip files
    masks: str | None = None
    reference: dict[str, list[str]] = field(default_factory=dict)  # prior -> its generated clips (FVD/FID)
    fid_reference: dict[str, list[str]] = field(default_factory=dict)
    model: str | None = None
    canonical: str | None = None
    cameras: str | None = None
    images: str | None = None
    points: str | None = None
    gt_dir: str | None = None
    part: str = "all"                   # all | clips | model (anigs.metrics.suite.evaluate)


def run(inputs: EvalInputs, cfg: EvalConfig, out: str | Path, scene: str, method: str = "Ours",
        variant: str = "full", dataset: str = "anigs") -> dict:
    """Evaluate and write the ``metrics.json`` record to ``out``; returns the record."""
    from anigs import __version__
    from anigs.io import write_json
    from anigs.metrics.suite import evaluate
    from anigs.tables import SCHEMA

    t0 = time.perf_counter()
    metrics = evaluate(cfg, inputs.clips, inputs.masks, inputs.reference, inputs.model, inputs.canonical,
                       inputs.cameras, inputs.images, inputs.points, inputs.gt_dir, inputs.fid_reference,
                       part=inputs.part)
    record = {"schema": SCHEMA, "scene": scene, "dataset": dataset, "method": method,
              "variant": variant, "part": inputs.part, "anigs_version": __version__,
              "config": dataclasses.asdict(cfg),
              "inputs": {"clips": inputs.clips, "masks": inputs.masks, "reference": inputs.reference,
                         "fid_reference": inputs.fid_reference, "model": inputs.model,
                         "canonical": inputs.canonical, "cameras": inputs.cameras, "images": inputs.images,
                         "points": inputs.points, "gt_dir": inputs.gt_dir},
              "seconds": round(time.perf_counter() - t0, 2), "metrics": metrics}
    write_json(out, record)
    n_ok = sum(1 for m in metrics.values() if m["available"])
    log.info("eval: %d/%d metrics available -> %s", n_ok, len(metrics), out)
    for name, m in metrics.items():
        log.info("  %-26s %s", name, f"{m['value']:.4g}" if m["available"] else f"n/a ({m['reason']})")
    return record


def merge(clips_record: str | Path, model_record: str | Path, out: str | Path,
          extra: list[str | Path] | None = None) -> dict:
    """``metrics.json`` from the two halves of an evaluation: a ``--part clips`` record (the final
    clips' metrics) and a ``--part model`` record (the model's), checked to be of the same scene,
    variant and method; the metrics in the order of one ``--part all`` run. ``extra``: further
    records of the same evaluation to join (``anigs fvd_gt``'s, ``part: fvd_gt``). No torch: the
    workflow runs it inside Snakemake."""
    from anigs.io import read_json, write_json

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


# ---- command line: anigs eval ----

def add_arguments(parser: argparse.ArgumentParser) -> None:
    from anigs.cli import add_params, add_canonical, add_out

    parser.add_argument("--final-dir", help="folder with the method's camera-fixed clips (.npz/.mp4, recursive)")
    parser.add_argument("--clips", nargs="*", default=[], help="more clip files or folders")
    parser.add_argument("--masks", help="folder of dynamic masks <view>.png")
    parser.add_argument("--reference", action="append", default=[], metavar="PRIOR=PATH",
                        help="reference clips of a prior's generate (repeatable; repeated priors pool): FVD-/FID-PRIOR")
    parser.add_argument("--fid-reference", action="append", default=[], metavar="PRIOR=PATH",
                        help="FID reference clips instead of --reference for that prior (e.g. pooled over scenes)")
    parser.add_argument("--model", help="animated model.pt (multiview protocol, GT motion comparison)")
    add_canonical(parser, required=False, help="canonical.ply the model animates")
    parser.add_argument("--cameras", help="training cameras.json (multiview protocol, learned scene extent)")
    parser.add_argument("--images", help="capture images named by camera (multiview reference row)")
    parser.add_argument("--points", help="SfM points.npz (xyz, rgb) initialising the multiview fits")
    parser.add_argument("--gt-dir", help="synthetic ground truth folder (capture/gt)")
    parser.add_argument("--scene", help="scene name (table column; required unless --merge)")
    parser.add_argument("--method", default="Ours", help="method name (table row)")
    parser.add_argument("--variant", default="full", help="ablation variant id (Table 5)")
    parser.add_argument("--dataset", default="anigs", help="scene group (one FVD table per dataset)")
    parser.add_argument("--part", default="all", choices=("all", "clips", "model"),
                        help="all metrics, or only those of the final clips or of the model (two jobs)")
    parser.add_argument("--merge", nargs=2, metavar=("CLIPS", "MODEL"),
                        help="join the records of a --part clips and a --part model run into --out (nothing computed)")
    add_out(parser, "metrics.json to write")
    add_params(parser, "eval")


def _pairs(items: list[str], opt: str) -> dict[str, list[str]]:
    """``PRIOR=PATH`` options -> {prior: [paths]}."""
    out: dict[str, list[str]] = {}
    for item in items:
        if "=" not in item or not item.split("=", 1)[0].strip():
            raise ValueError(f"{opt} expects PRIOR=PATH, got {item!r}")
        prior, path = item.split("=", 1)
        out.setdefault(prior.strip(), []).append(path)
    return out


def main(args: argparse.Namespace) -> int:
    from anigs.cli import parse_params

    if args.merge:
        merge(args.merge[0], args.merge[1], args.out)
        return 0
    if not args.scene:
        raise ValueError("eval: --scene is required (the table column)")
    inputs = EvalInputs(clips=([args.final_dir] if args.final_dir else []) + list(args.clips), masks=args.masks,
                        reference=_pairs(args.reference, "--reference"),
                        fid_reference=_pairs(args.fid_reference, "--fid-reference"), model=args.model,
                        canonical=args.canonical, cameras=args.cameras, images=args.images, points=args.points,
                        gt_dir=args.gt_dir, part=args.part)
    run(inputs, EvalConfig.from_dict(parse_params(args.params)), args.out, args.scene, args.method, args.variant,
        args.dataset)
    return 0
