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
from typing import ClassVar

from anigs.typed_config import Section
from anigs.metrics.fvd_gt import METRIC, i3d_detector  # noqa: F401  (i3d_detector: the network the stage uses)
from anigs.stages import contract
from anigs.stages.capture import Outputs as CaptureOutputs
from anigs.stages.sfm import Outputs as SfmOutputs
from anigs.stages.static import Outputs as StaticOutputs
from anigs.stages.contract import File
from anigs.stages.update import Outputs as UpdateOutputs

log = logging.getLogger("anigs.fvd_gt")

WHEN = ("tables", "always", "never")


@dataclass
class FvdGtConfig(Section):
    """``fvd_gt`` config section."""

    #: tables (only `snakemake tables` computes it), always (also the default target, into metrics.json) or never
    when: str = "tables"
    num_views: int = 64  # evaluation-only camera-fixed views (64 x 2 windows = 128 clips per method)
    windows: int = 2  # windows of `frames` frames per view, evenly spread over the clip
    frames: int = 16  # frames per clip (I3D's usual 16)
    width: int = 256  # image size of the evaluation views (the demo's view size)
    height: int = 192  # (I3D sees the short side resized to eval.fvd_crop_size)
    fov_deg: float = 70.0  # horizontal field of view of the evaluation views
    jitter_m: float = 0.35  # std of the eye's offset from a capture camera (m)
    min_distance: float = 1.0  # eye-to-target distance bounds (m, ground-truth frame)
    max_distance: float = 8.0  # (farther targets are rejected)
    clearance: float = 0.3  # no Gaussian centre closer to the eye (m)
    min_dynamic_fraction: float = 0.1  # share of a view's pixels whose dominant label moves
    max_tries_per_view: int = 40  # placement gives up (an error) after num_views x this many tries
    bootstrap: int = 200  # resamples of the views for the spread
    level: float = 0.9  # central interval of the bootstrap values
    still_control: bool = True  # also the FVD-GT of the static canonical scene (no motion)
    background: list = field(default_factory=lambda: [0.62, 0.76, 0.92])  # background colour (RGB in [0,1])
    seed: int = 0  # random seed (the workflow passes the global seed)

    WHERE: ClassVar[str] = "fvd_gt"

    def validate(self) -> None:
        if self.when not in WHEN:
            raise ValueError(f"fvd_gt.when must be one of {WHEN}, got {self.when!r}")
        for k in ("num_views", "windows", "frames", "width", "height", "max_tries_per_view"):
            if getattr(self, k) < 1:
                raise ValueError(f"fvd_gt.{k} must be >= 1, got {getattr(self, k)}")
        if self.num_views < 2 or self.bootstrap < 2:
            raise ValueError("fvd_gt.num_views and fvd_gt.bootstrap must be >= 2 (the spread resamples views)")
        if not 0 < self.level < 1:
            raise ValueError(f"fvd_gt.level must be in (0,1), got {self.level}")
        if not 0 < self.min_distance < self.max_distance:
            raise ValueError("fvd_gt: need 0 < min_distance < max_distance")

    def placement(self):
        from anigs.metrics.eval_views import Placement

        return Placement(self.num_views, self.width, self.height, self.fov_deg, self.seed, self.jitter_m,
                         self.min_distance, self.max_distance, self.clearance, self.min_dynamic_fraction,
                         self.max_tries_per_view)


Config = FvdGtConfig  # the `fvd_gt` config section


class ReferenceOutputs(contract.Outputs):
    """A synthetic scene's FVD-GT reference folder (``{scene}/fvd_gt/``), shared by its variants."""

    STAGE = "fvd_gt"
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

    STAGE = "fvd_gt"
    FOLDER = "{scene}/{variant}/eval"
    LAYOUT = {"record": File("fvd_gt.json", "metrics.json schema, part fvd_gt: the fvd/gt metric"),
              "features": File("fvd_gt_features.npz", "the method's I3D features float [n,D] (paired comparisons)",
                               optional=True),
              "sheet": File("fvd_gt.png", "contact sheet of the method's views", optional=True)}


OUTPUTS = (ReferenceOutputs, Outputs)  # the scene's reference folder and the variant's record in eval/


@dataclass
class Inputs(contract.Inputs):
    capture: CaptureOutputs
    sfm: SfmOutputs
    static: StaticOutputs
    out: Path = field(metadata={"help": "the reference folder (--reference) or the variant's eval folder"})
    reference: bool = field(default=False, metadata={"help": "make the scene's ground-truth reference"})
    reference_dir: ReferenceOutputs | None = field(default=None, metadata={"help": "the scene's reference folder"})
    model: UpdateOutputs | None = field(default=None, metadata={"help": "the method's model folder"})
    frames: int | None = field(default=None, metadata={"help": "frames per clip of the models (--reference)"})
    scene: str | None = field(default=None, metadata={"help": "scene name (table column)"})
    method: str = field(default="Ours", metadata={"help": "method name (table row)"})
    variant: str = field(default="full", metadata={"help": "ablation variant id"})
    dataset: str = field(default="anigs", metadata={"help": "scene group"})
    eval_params: str | None = field(default=None, metadata={"help": "the eval config section as JSON (I3D network)"})


def run(inputs: Inputs, cfg: FvdGtConfig) -> contract.Outputs:
    """``--reference``: the scene's reference folder; else the variant's ``fvd_gt.json`` record."""
    from anigs.cli import parse_params
    from anigs.metrics.suite import EvalConfig

    ecfg = EvalConfig.from_dict(parse_params(inputs.eval_params))
    cameras, canonical = inputs.sfm.path("cameras"), inputs.static.path("canonical")
    if inputs.reference:
        from anigs.metrics.fvd_gt import run_reference

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
    from anigs import __version__
    from anigs.io import write_json, write_npz
    from anigs.metrics.eval_views import contact_sheet
    from anigs.metrics.fvd_gt import run_method
    from anigs.tables import SCHEMA
    from anigs.video import save_png

    t0 = time.perf_counter()
    out = Outputs(inputs.out)
    model, canonical = inputs.model.path("model"), inputs.static.path("canonical")
    cameras, gt = inputs.sfm.path("cameras"), inputs.capture.path("gt")
    metrics, firsts = run_method(inputs.reference_dir, model, canonical, cameras, inputs.capture, cfg, ecfg)
    feats = metrics[METRIC].pop("_features", None)
    if feats is not None:  # the method's I3D features: paired comparisons between methods (benchmarks/fvd_gt.py)
        write_npz(out.path("features"), features=feats)
    record = {"schema": SCHEMA, "scene": inputs.scene, "dataset": inputs.dataset, "method": inputs.method,
              "variant": inputs.variant, "part": "fvd_gt", "anigs_version": __version__,
              "config": {"fvd_gt": dataclasses.asdict(cfg), "eval": dataclasses.asdict(ecfg)},
              "inputs": {"reference_dir": str(inputs.reference_dir.root), "model": str(model),
                         "canonical": str(canonical), "cameras": str(cameras), "gt_dir": str(gt)},
              "seconds": round(time.perf_counter() - t0, 2), "metrics": metrics}
    write_json(out.path("record"), record)
    if firsts:
        save_png(out.path("sheet"), contact_sheet([firsts[i:i + 8] for i in range(0, len(firsts), 8)]))
    m = metrics[METRIC]
    log.info("fvd_gt: %s %s: %s", inputs.method, inputs.variant,
             f"{m['value']:.2f} ± {m['bootstrap']['std']:.2f} ({m['samples']['test']} clips)" if m["available"]
             else f"n/a ({m['reason']})")
    return out
