"""Ground truth for the masks stage (synthetic scenes): the labelled Gaussians that move, their
label masks per view, and the yardsticks the masks and the lifted set are measured against."""
from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from anigs.cameras import Camera, load_cameras
from anigs.gaussians import Gaussians, load_ply
from anigs.io import read_json
from anigs.masks import Frame, compute_masks, mask_iou
from anigs.masks.labels_backend import LabelsBackend, roi_from_labels
from anigs.sfm.align import align_cameras
from anigs.render.labels import appearance_labels
from anigs.synth.truth import dynamic_label_ids, effects_from_motion
from anigs.masks.lift import precision_recall

log = logging.getLogger("anigs.masks")


@dataclass
class GroundTruth:
    """``labels``: int [M] label per labelled Gaussian (.npy); ``motion``: motion.json (which labels
    move, per effect); ``gaussians``: the PLY the labels belong to (None: the canonical set);
    ``cameras``: cameras in that PLY's frame, matched by name to the reconstruction's."""

    labels: Path
    motion: Path | None = None
    gaussians: Path | None = None
    cameras: Path | None = None

    def effects(self) -> dict[str, list[int]]:
        """Effect -> the label ids it moves."""
        if self.motion is None:
            raise ValueError("--labels needs --motion (the ground-truth motion tables) to know which labels move")
        return effects_from_motion(read_json(self.motion))

    def backend(self, g: Gaussians, recon_cameras: Sequence[Camera] | None, opts: dict) -> LabelsBackend:
        """The labels backend: the ground-truth Gaussians in their own frame (aligned by the cameras),
        or the canonical set ``g`` when the labels are its own."""
        labels, effects = np.load(self.labels), self.effects()
        if not self.gaussians:
            return LabelsBackend(g, labels, effects, **opts)
        sim = None
        if self.cameras:
            if not recon_cameras:
                raise ValueError("--gt-cameras needs --cameras (the reconstruction's cameras) to align the frames")
            sim, rms = align_cameras(recon_cameras, load_cameras(self.cameras))
            log.info("masks: camera frame -> ground-truth frame: scale %.4g, centre RMS %.3g", sim.scale, rms)
        return LabelsBackend(load_ply(self.gaussians), labels, effects, to_gaussians_frame=sim, **opts)

    def appearance(self, g: Gaussians, capture_cams: Sequence[Camera], frames: Sequence[Frame],
                   opts: dict) -> tuple[np.ndarray, list[np.ndarray]]:
        """(dynamic flag [N] of the appearance labels, their label masks [H,W] per frame)."""
        effects = self.effects()
        sim, _ = align_cameras(capture_cams, load_cameras(self.cameras))
        app, _, _ = appearance_labels(g, load_ply(self.gaussians), np.load(self.labels), capture_cams,
                                      to_labels_frame=sim)
        masks = [r["dynamic"] for r in compute_masks(LabelsBackend(g, app, effects, **opts), frames)]
        return np.isin(app, dynamic_label_ids(effects)), masks

    def roi(self, g: Gaussians, cameras: Sequence[Camera]) -> np.ndarray:
        """bool [N]: the canonical Gaussians the labels say move."""
        return roi_from_labels(g, self.labels, self.motion, None, self.gaussians, self.cameras, list(cameras))


def compare(info: dict, g: Gaussians, frames: Sequence[Frame], results: Sequence[dict], dyn: np.ndarray,
            truth: GroundTruth, label_masks: Sequence[dict], appearance: tuple | None,
            cameras: Sequence[Camera]) -> None:
    """Add to ``info`` (``masks.json``) each view's IoU against the label masks (and the appearance
    labels' masks), their mean and min, and the lifted set's precision/recall against the labels."""
    for k, (entry, res) in enumerate(zip(info["views"], results)):
        m = res["dynamic"]
        entry["iou_vs_labels"] = mask_iou(m, label_masks[k]["dynamic"])
        entry["labels_fraction"] = float(label_masks[k]["dynamic"].mean())
        if appearance is not None:
            entry["iou_appearance"] = mask_iou(m, appearance[1][k])
        log.info("masks: %s IoU vs labels %.3f%s", frames[k].name, entry["iou_vs_labels"],
                 f" vs appearance {entry['iou_appearance']:.3f}" if appearance is not None else "")
    for key, on in (("iou_vs_labels", True), ("iou_appearance", appearance is not None)):
        if on:
            vals = [v[key] for v in info["views"]]
            info[key] = {"mean": float(np.mean(vals)), "min": float(np.min(vals))}
    gt = truth.roi(g, cameras)
    info["lift_vs_labels"] = {**precision_recall(dyn, gt), "num_gt_dynamic": int(gt.sum()), "num_lifted": int(dyn.sum())}
    log.info("masks: lifted Gaussians vs labels: precision %.3f recall %.3f",
             info["lift_vs_labels"]["precision"], info["lift_vs_labels"]["recall"])
    if appearance is not None:
        info["lift_appearance"] = {**precision_recall(dyn, appearance[0]),
                                   "num_appearance_dynamic": int(appearance[0].sum()), "num_lifted": int(dyn.sum())}
        log.info("masks: lifted Gaussians vs appearance labels: precision %.3f recall %.3f",
                 info["lift_appearance"]["precision"], info["lift_appearance"]["recall"])
