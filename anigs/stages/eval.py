"""Stage ``eval``: every metric of one (scene, method, variant) into ``metrics.json``.

The metrics and their inputs are described in :mod:`anigs.metrics.suite`; the schema of the
output in :mod:`anigs.reports.tables`.

    anigs eval --final final/ --masks masks/ --model round4/ --static static/ --sfm sfm/ \\
        [--capture capture/] --scene demo --variant full --out eval/ --params '{...eval section...}'

The workflow runs it in two halves: ``--part model`` (the ground-truth motion and the multiview
protocol, which need the model but not the final clips) in a job beside the final renders, and
``--part clips`` in the final job after the videos; ``anigs eval --merge --out eval/`` (or
:func:`merge_parts` inside Snakemake) joins the two records into the one a ``--part all`` run writes.
"""
from __future__ import annotations

import argparse
import dataclasses
import logging
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from anigs.stages.record import metrics_record, prior_pairs, table_row  # noqa: F401 (table_row: the rules')
from anigs.io import write_json
from anigs.metrics.config import EvalConfig
from anigs.metrics.suite import ClipInputs, ModelInputs, evaluate_variant
from anigs import contract
from anigs.stages.command import parse_params
from anigs.stages.capture import Outputs as CaptureOutputs
from anigs.stages.masks import Outputs as MasksOutputs
from anigs.stages.sfm import Outputs as SfmOutputs
from anigs.stages.static import Outputs as StaticOutputs
from anigs.contract import File
from anigs.stages.shared_inputs import TableRowInputs
from anigs.stages.final import Outputs as FinalOutputs
from anigs.stages.update import Outputs as UpdateOutputs
from anigs.metrics.records import merge_records
from anigs.reports.tables import SCHEMA

Config = EvalConfig  # the `eval` config section

log = logging.getLogger("anigs.eval")

PART_FILE = {"all": "metrics", "clips": "clip_metrics", "model": "model_metrics"}  # --part -> its record


class Outputs(contract.Outputs):
    """The evaluation folder of a variant (``eval/``; ``fvd_gt``'s record lies beside, its own Outputs)."""

    LAYOUT = {"metrics": File("metrics.json", "the record of every metric: schema, scene, dataset, method, variant, "
                                              "config, inputs, metrics {name: {value, available, reason, ...}}"),
              "clip_metrics": File("clip_metrics.json", "the record of the final clips' metrics (--part clips)"),
              "model_metrics": File("model_metrics.json", "the record of the model's metrics (--part model)")}

    def record(self, key: str = "metrics") -> dict[str, Any]:
        """A metrics record, checked to have the ``metrics.json`` schema."""

        rec = self.json(key)
        if not isinstance(rec, dict) or rec.get("schema") != SCHEMA or not isinstance(rec.get("metrics"), dict):
            raise ValueError(f"{self.path(key)}: not a metrics record of schema {SCHEMA} (re-run the eval stage)")
        return rec


@dataclass
class Inputs(TableRowInputs):
    out: Path = contract.output_folder(Outputs, "the evaluation folder (the --part's record)")
    final: FinalOutputs | None = field(default=None, metadata={"help": "the final stage's folder (its clips)"})
    clips: list[str] | None = field(default=None, metadata={"help": "more clip files or folders (.npz/.mp4)"})
    masks: MasksOutputs | None = None
    reference: list[str] | None = field(default=None, metadata={"help": "PRIOR=PATH: reference clips of a prior's "
                                                                        "generate (FVD-/FID-PRIOR; repeated priors pool)"})
    fid_reference: list[str] | None = field(default=None, metadata={"help": "PRIOR=PATH: FID reference clips instead "
                                                                            "of --reference for that prior"})
    model: UpdateOutputs | None = field(default=None, metadata={"help": "the model's folder (multiview protocol, "
                                                                        "GT motion comparison)"})
    static: StaticOutputs | None = None
    sfm: SfmOutputs | None = field(default=None, metadata={"help": "the sfm stage's folder: training cameras, "
                                                                   "undistorted images, points (multiview protocol)"})
    capture: CaptureOutputs | None = field(default=None, metadata={"help": "the capture stage's folder: synthetic "
                                                                           "ground truth"})
    part: str = field(default="all", metadata={"help": "all | clips | model: all metrics, or a half's (two jobs)"})
    merge: bool = field(default=False, metadata={"help": "join the clips and model halves in --out into the --part all record"})


def _record_inputs(inputs: Inputs) -> dict[str, Any]:
    """The paths an evaluation reads, as ``metrics.json`` records them (the clips half reads no images or points)."""
    s = lambda o, key: str(o.path(key)) if o is not None else None  # noqa: E731
    whole = inputs.part != "clips"
    return {"clips": ([str(inputs.final.path("clips"))] if inputs.final else []) + list(inputs.clips or []),
            "masks": str(inputs.masks.root) if inputs.masks else None,
            "reference": prior_pairs(inputs.reference, "--reference"),
            "fid_reference": prior_pairs(inputs.fid_reference, "--fid-reference"),
            "model": s(inputs.model, "model"), "canonical": s(inputs.static, "canonical"),
            "cameras": s(inputs.sfm, "cameras"), "images": s(inputs.sfm, "images") if whole else None,
            "points": s(inputs.sfm, "points") if whole else None, "gt_dir": s(inputs.capture, "gt")}


def run(inputs: Inputs, cfg: EvalConfig) -> Outputs:
    """Evaluate and write the record of ``inputs.part`` into the evaluation folder."""
    if inputs.part not in PART_FILE:
        raise ValueError(f"eval: --part {inputs.part!r}; choose {sorted(PART_FILE)}")
    if not inputs.scene:
        raise ValueError("eval: --scene is required (the table column)")
    t0 = time.perf_counter()
    i = _record_inputs(inputs)
    P = (lambda p: None if p is None else Path(p))  # noqa: E731
    clips = ClipInputs(i["clips"], inputs.masks, i["reference"], i["fid_reference"])
    model = ModelInputs(P(i["model"]), P(i["canonical"]), P(i["cameras"]), P(i["images"]), P(i["points"]),
                        inputs.capture)
    metrics = evaluate_variant(cfg, clips, model, part=inputs.part)
    record = metrics_record(inputs, inputs.part, dataclasses.asdict(cfg), i, time.perf_counter() - t0, metrics)
    out = Outputs(inputs.out)
    write_json(out.path(PART_FILE[inputs.part]), record)
    n_ok = sum(1 for m in metrics.values() if m["available"])
    log.info("eval: %d/%d metrics available -> %s", n_ok, len(metrics), out.path(PART_FILE[inputs.part]))
    for name, m in metrics.items():
        log.info("  %-26s %s", name, f"{m['value']:.4g}" if m["available"] else f"n/a ({m['reason']})")
    return out


def merge_parts(out: Outputs, extra: list[str | Path] | None = None) -> dict:
    """``metrics.json`` of ``out`` from its clips and model halves (and ``extra`` records, e.g. FVD-GT's)."""

    return merge_records(out.path("clip_metrics"), out.path("model_metrics"), out.path("metrics"), extra)


def merge_halves(metrics: str, clips: str, model: str, fvd_gt: list[str], log: str) -> None:
    """The eval rule's job (in Snakemake: a JSON merge, no process start-up): ``metrics`` (the merged
    file) from the ``clips`` and ``model`` halves beside it and the FVD-GT records, noted in ``log``."""
    merge_parts(Outputs(os.path.dirname(metrics)), extra=list(fvd_gt))
    with open(log, "w") as f:
        f.write(f"merged {clips}, {model} and {len(fvd_gt)} FVD-GT record(s) into {metrics}\n")


# ---- command line: anigs eval ----

def main(args: argparse.Namespace) -> int:
    inputs = Inputs.from_args(args)
    if inputs.merge:
        merge_parts(Outputs(inputs.out))
        return 0
    run(inputs, EvalConfig.from_dict(parse_params(args.params)))
    return 0
