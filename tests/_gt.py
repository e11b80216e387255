"""A capture's ground-truth folder written by hand, for tests of the GT metrics."""
from __future__ import annotations

from pathlib import Path

import numpy as np


def write_gt(root: Path, gaussians, labels: np.ndarray, motion: dict, cameras: list,
             anchors: np.ndarray | None = None) -> Path:
    """Write the capture stage's ``gt/`` under ``root`` (the Gaussians, int32 ``labels`` [N], float32
    ``anchors`` [N,3] when given, ``motion`` as motion.json, the ``cameras``) and the same cameras as
    ``root``/cameras.json (the reconstruction's, aligned to the truth by identity); returns ``gt/``."""
    from anigs.cameras import save_cameras
    from anigs.io import write_json
    from anigs.stages.capture import Outputs as CaptureOutputs

    cap = CaptureOutputs(root)
    cap.path("gt").mkdir()
    gaussians.save_ply(cap.path("gt_gaussians"))
    np.save(cap.path("gt_labels"), labels.astype(np.int32))
    if anchors is not None:
        np.save(cap.path("gt_anchors"), anchors.astype(np.float32))
    write_json(cap.path("gt_motion"), motion)
    save_cameras(cap.path("gt_cameras"), cameras)
    save_cameras(root / "cameras.json", cameras)
    return cap.path("gt")
