"""What moves that must stay still (synthetic scenes): ``gt/moving_labelled_still``.

The share of the animated model's moving Gaussians whose ground-truth label says they must stay
still (ground, building, clutter, trunk: every label without an effect). Each fitted Gaussian
takes the label of the nearest ground-truth Gaussian (centres, after the similarity that aligns
the SfM cameras to the ground-truth cameras; farther than ``max_dist`` x the scene extent: no
label, left out). A Gaussian moves when its largest displacement over the loop exceeds
``min_motion`` x the scene extent. Lower is better; 0 = nothing labelled still moves.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from anigs.animate.deform import load_model
from anigs.cameras import load_cameras
from anigs.contract import CaptureFiles
from anigs.geometry.extent import scene_extent
from anigs.metrics import metric_record, not_available
from anigs.sfm.align import align_cameras
from anigs.synth.motion import LABEL_EFFECTS, WATER_LABEL_EFFECTS

KEY = "gt/moving_labelled_still"
PROTOCOL = {"moving": "largest displacement over the loop > 1e-4 x scene extent",
            "label": "nearest ground-truth Gaussian (aligned cameras) within 0.05 x scene extent",
            "still": "labels without an effect (ground, building, clutter, trunk)"}


def moving_labelled_still(model: Path | None, canonical: Path | None, truth: CaptureFiles | None,
                          cameras: Path | None, min_motion: float = 1e-4, max_dist: float = 0.05) -> dict[str, Any]:
    """``{KEY: record}`` on a synthetic scene (``truth``: the capture stage's folder with its ground
    truth), ``{}`` otherwise."""
    if truth is None:
        return {}
    if model is None or canonical is None or cameras is None:
        return {KEY: not_available("needs --model, --canonical and --cameras", False, "fraction", PROTOCOL)}
    import torch
    from scipy.spatial import cKDTree

    canon, deformation, _ = load_model(model, canonical)
    cams = load_cameras(cameras)
    extent = scene_extent(cams)
    moving = np.zeros(canon.num, bool)
    if deformation.num_dynamic > 0:
        T = deformation.num_frames
        with torch.no_grad():
            traj = deformation.trajectories(canon.means, torch.arange(T)).double().numpy()  # [T,D,3]
        moving = np.zeros(canon.num, bool)
        moving[deformation.dynamic_index.numpy()] = np.abs(traj - traj[:1]).max(axis=(0, 2)) > min_motion * extent
    names = {int(k): v for k, v in truth.gt_motion()["labels"].items()}
    still_ids = [k for k, v in names.items() if not {**LABEL_EFFECTS, **WATER_LABEL_EFFECTS}.get(v, ())]
    gt = truth.gt_gaussians()
    labels = truth.gt_labels(gt.num)
    gt_cams = truth.gt_cameras()
    sim, _ = align_cameras(cams, gt_cams)
    pts = sim.apply(canon.means.detach().double().numpy())
    gt_extent = scene_extent(gt_cams)
    dist, idx = cKDTree(gt.means.detach().double().numpy()).query(pts, k=1)
    known = dist <= max_dist * gt_extent
    still = known & np.isin(labels[idx], still_ids)
    n_moving = int((moving & known).sum())
    value = (still & moving).sum() / n_moving if n_moving else 0.0
    samples = {"moving_gaussians": n_moving, "moving_labelled_still": int((still & moving).sum()),
               "moving_unlabelled": int((moving & ~known).sum()), "gaussians": int(canon.num)}
    return {KEY: metric_record(value, False, "fraction", PROTOCOL, samples)}
