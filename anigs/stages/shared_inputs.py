"""``Inputs`` fields that several stages read, declared once: the canonical model (:class:`CanonicalInputs`:
effects, views, masks) and a synthetic scene's ground truth (:class:`GroundTruthInputs`: views, masks)."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from anigs import contract
from anigs.stages.capture import Outputs as CaptureOutputs
from anigs.stages.static import Outputs as StaticOutputs


@dataclass
class CanonicalInputs(contract.Inputs):
    """``--canonical``: the static stage's canonical 3DGS (the first field of the stage's inputs)."""

    canonical: Path = contract.upstream(StaticOutputs, "canonical", "canonical 3DGS PLY")


def _gt(key: str, what: str):
    return contract.upstream(CaptureOutputs, key, what, default=None, kw_only=True)


@dataclass
class GroundTruthInputs(CanonicalInputs):
    """Per-Gaussian labels (``--labels``, with ``--motion`` naming the moving ones), and the Gaussians and
    cameras they belong to when that is not the canonical set (:class:`anigs.masks.truth.GroundTruth`)."""

    labels: Path | None = _gt("gt_labels", "per-Gaussian labels .npy of a synthetic scene, with --motion")
    motion: Path | None = _gt("gt_motion", "which labels move, per effect type (with --labels)")
    gt_gaussians: Path | None = _gt("gt_gaussians", "PLY the --labels belong to when it is not the canonical set")
    gt_cameras: Path | None = _gt("gt_cameras", "cameras in the frame of --gt-gaussians, matched by name to "
                                                "--cameras to align the frames (default: same frame)")


# the GroundTruthInputs fields and the capture stage's files that fill them
GT_FILES = {"labels": "gt_labels", "motion": "gt_motion", "gt_gaussians": "gt_gaussians", "gt_cameras": "gt_cameras"}


def ground_truth(results: str, scene: str) -> dict[str, str]:
    """Synthetic ``scene``'s capture files under the results root as :class:`GroundTruthInputs` fields
    (``--labels --motion --gt-gaussians --gt-cameras``: what the views and masks stages compare with)."""
    return {f: CaptureOutputs.under(results, key, scene=scene) for f, key in GT_FILES.items()}


def _row(default: str | None, what: str):
    return field(default=default, kw_only=True, metadata={"help": what})


@dataclass
class TableRowInputs(contract.Inputs):
    """The table row a metrics record belongs to (eval, fvd_gt; :func:`anigs.stages.record.metrics_record`)."""

    scene: str | None = _row(None, "scene name (table column; required to write a record)")
    method: str = _row("Ours", "method name (table row)")
    variant: str = _row("full", "ablation variant id (Table 5)")
    dataset: str = _row("anigs", "scene group (one FVD table per dataset)")
