"""Stage ``fvd_gt``: FVD against the synthetic scene's ground-truth motion (FVD-GT).

Two commands, both on evaluation-only camera-fixed views (:mod:`anigs.metrics.fvd_gt`):
``--reference`` (once per synthetic scene: the ground truth's features at the placed views, and
the no-motion control) and, per (scene, variant), the method's ``fvd/gt`` record::

    anigs fvd_gt --reference --capture capture/ --sfm sfm/ --static static/ --frames 25 --out fvd_gt/ \\
        --params '{...fvd_gt...}' --eval-params '{...eval...}'
    anigs fvd_gt --reference-dir fvd_gt/ --model round4/ --capture capture/ --sfm sfm/ --static static/ \\
        --scene demo --method Ours --variant full --out eval/ --params '{...}' --eval-params '{...}'

The record has the schema of ``metrics.json`` with ``part: fvd_gt``; ``anigs tables`` joins it to
the variant's ``metrics.json`` (and ``eval`` merges it there with ``fvd_gt.when: always``).
"""
from __future__ import annotations

import dataclasses
import logging
import time
from dataclasses import dataclass, field
from pathlib import Path

from anigs.stages.record import metrics_record
from anigs.metrics.config import FvdGtConfig
from anigs.metrics.fvd_gt import METRIC, i3d_detector  # noqa: F401  (i3d_detector: the network the stage uses)
from anigs import contract
from anigs.stages.command import parse_params
from anigs.stages.capture import Outputs as CaptureOutputs
from anigs.stages.sfm import Outputs as SfmOutputs
from anigs.stages.static import Outputs as StaticOutputs
from anigs.contract import File
from anigs.stages.shared_inputs import TableRowInputs
from anigs.stages.update import Outputs as UpdateOutputs
from anigs.io import write_json, write_npz
from anigs.metrics.eval_views import thumbnail_sheet
from anigs.metrics.fvd_gt import run_reference, run_method
from anigs.metrics.config import EvalConfig
from anigs.video import save_png

log = logging.getLogger("anigs.fvd_gt")

Config = FvdGtConfig  # the `fvd_gt` config section


class ReferenceOutputs(contract.Outputs):
    """A synthetic scene's FVD-GT reference folder (``{scene}/fvd_gt/``), shared by its variants."""

    FOLDER = "{scene}/fvd_gt"
    LAYOUT = {"reference": File("reference.json", "config, frames, window_starts, protocol, available, clips, "
                                                  "still_control record, gt_vbench"),
              "features": File("features.npz", "features float [n,D] of the ground truth's windows, views str [n] "
                                               "(when the I3D network is available)", optional=True),
              "still_features": File("still_features.npz", "the same of the static canonical scene", optional=True),
              "views": File("views.json", "the evaluation views (ground-truth frame)"),
              "sheet": File("views.png", "contact sheet of the views (ground truth, static rows; when the I3D "
                                         "network is available)", optional=True)}


class Outputs(contract.Outputs):
    """A variant's FVD-GT record, beside its ``metrics.json`` (``eval/``)."""

    FOLDER = "{scene}/{variant}/eval"
    LAYOUT = {"record": File("fvd_gt.json", "metrics.json schema, part fvd_gt: the fvd/gt metric"),
              "features": File("fvd_gt_features.npz", "the method's I3D features float [n,D] (paired comparisons)",
                               optional=True),
              "sheet": File("fvd_gt.png", "contact sheet of the method's views", optional=True)}


OUTPUTS = (ReferenceOutputs, Outputs)  # the scene's reference folder and the variant's record in eval/


@dataclass
class Inputs(TableRowInputs):
    capture: CaptureOutputs
    sfm: SfmOutputs
    static: StaticOutputs
    out: Path = field(metadata={"help": "the reference folder (--reference) or the variant's eval folder"})
    reference: bool = field(default=False, metadata={"help": "make the scene's ground-truth reference"})
    reference_dir: ReferenceOutputs | None = field(default=None, metadata={"help": "the scene's reference folder"})
    model: UpdateOutputs | None = field(default=None, metadata={"help": "the method's model folder"})
    frames: int | None = field(default=None, metadata={"help": "frames per clip of the models (--reference)"})
    eval_params: str | None = field(default=None, metadata={"help": "the eval config section as JSON (I3D network)"})


def run(inputs: Inputs, cfg: FvdGtConfig) -> contract.Outputs:
    """``--reference``: the scene's reference folder; else the variant's ``fvd_gt.json`` record."""

    ecfg = EvalConfig.from_dict(parse_params(inputs.eval_params))
    cameras, canonical = inputs.sfm.path("cameras"), inputs.static.path("canonical")
    if inputs.reference:
        if not inputs.frames:
            raise ValueError("fvd_gt --reference needs --frames (the models' T)")
        out = ReferenceOutputs(inputs.out)
        run_reference(inputs.capture, cameras, canonical, inputs.frames, out, cfg, ecfg)
        return out
    missing = [o for o, v in (("--reference-dir", inputs.reference_dir), ("--model", inputs.model),
                              ("--scene", inputs.scene)) if not v]
    if missing:
        raise ValueError(f"fvd_gt: the per-variant command needs {', '.join(missing)}")
    return write_record(inputs, cfg, ecfg)


def write_record(inputs: Inputs, cfg: FvdGtConfig, ecfg) -> Outputs:
    """The per-variant command: the method's ``fvd/gt`` against the reference, as a metrics record."""

    t0 = time.perf_counter()
    out = Outputs(inputs.out)
    model, canonical = inputs.model.path("model"), inputs.static.path("canonical")
    cameras, gt = inputs.sfm.path("cameras"), inputs.capture.path("gt")
    metrics, firsts = run_method(inputs.reference_dir, model, canonical, cameras, inputs.capture, cfg, ecfg)
    feats = metrics[METRIC].pop("_features", None)
    if feats is not None:  # the method's I3D features: paired comparisons between methods (benchmarks/fvd_gt.py)
        write_npz(out.path("features"), features=feats)
    config = {"fvd_gt": dataclasses.asdict(cfg), "eval": dataclasses.asdict(ecfg)}
    paths = {"reference_dir": str(inputs.reference_dir.root), "model": str(model), "canonical": str(canonical),
             "cameras": str(cameras), "gt_dir": str(gt)}
    record = metrics_record(inputs, "fvd_gt", config, paths, time.perf_counter() - t0, metrics)
    write_json(out.path("record"), record)
    if firsts:
        save_png(out.path("sheet"), thumbnail_sheet([firsts[i:i + 8] for i in range(0, len(firsts), 8)]))
    m = metrics[METRIC]
    log.info("fvd_gt: %s %s: %s", inputs.method, inputs.variant,
             f"{m['value']:.2f} ± {m['bootstrap']['std']:.2f} ({m['samples']['test']} clips)" if m["available"]
             else f"n/a ({m['reason']})")
    return out


def wanted(synthetic: bool, when: str, target: str) -> bool:
    """Whether FVD-GT runs for a variant when the workflow builds ``target`` (tables | eval): only on a
    synthetic scene (it needs the ground-truth motion), with ``fvd_gt.when`` always, or tables for the tables."""
    return synthetic and (when == "always" or (when == "tables" and target == "tables"))
