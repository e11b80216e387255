"""The masks stage's ground-truth comparison (synthetic scenes): the label masks, optionally the
appearance labels, and :func:`anigs.masks.truth.compare` into the stage's report."""
from __future__ import annotations

import dataclasses
from typing import Sequence

from anigs.cameras import Camera
from anigs.gaussians import Gaussians
from anigs.masks import Frame, compute_masks
from anigs.masks.config import MasksConfig
from anigs.masks.segment import MasksResult
from anigs.masks.truth import GroundTruth, compare


def compare_with_truth(info: dict, cfg: MasksConfig, g: Gaussians, frames: Sequence[Frame], res: MasksResult,
                       truth: GroundTruth, cams: Sequence[Camera], capture_cams: Sequence[Camera] | None) -> None:
    """Add the comparison of ``res`` (the masks of ``frames`` and the dynamic set of ``g``) with ``truth`` to
    ``info``. ``cams``: the cameras the labels are aligned by (the capture's, else the views'); the
    appearance labels (``cfg.appearance``) need the ground-truth Gaussians and cameras and ``capture_cams``."""
    labels = dataclasses.asdict(cfg.labels)
    label_masks = res.masks if cfg.backend == "labels" else compute_masks(truth.backend(g, capture_cams, labels), frames)
    appearance = None
    if cfg.appearance and truth.gaussians and truth.cameras and capture_cams is not None:
        appearance = truth.appearance(g, capture_cams, frames, labels)
    compare(info, g, frames, res.masks, res.dynamic, truth, label_masks, appearance, cams)
