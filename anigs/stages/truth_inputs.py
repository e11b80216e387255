"""The ground truth of a synthetic scene as the views and masks stages read it (an ``Inputs`` mixin)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from anigs.stages import contract
from anigs.stages.capture import Outputs as CaptureOutputs


def _gt(key: str, what: str):
    return contract.upstream(CaptureOutputs, key, what, default=None, kw_only=True)


@dataclass
class GroundTruthInputs(contract.Inputs):
    """Per-Gaussian labels (``--labels``, with ``--motion`` naming the moving ones), and the Gaussians and
    cameras they belong to when that is not the canonical set (:class:`anigs.masks.truth.GroundTruth`)."""

    labels: Path | None = _gt("gt_labels", "per-Gaussian labels .npy of a synthetic scene, with --motion")
    motion: Path | None = _gt("gt_motion", "which labels move, per effect type (with --labels)")
    gt_gaussians: Path | None = _gt("gt_gaussians", "PLY the --labels belong to when it is not the canonical set")
    gt_cameras: Path | None = _gt("gt_cameras", "cameras in the frame of --gt-gaussians, matched by name to "
                                                "--cameras to align the frames (default: same frame)")
