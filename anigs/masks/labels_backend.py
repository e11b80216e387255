"""``labels`` mask backend: the label map rendered from labelled Gaussians (synthetic scenes).

A pixel is in an effect's mask when the blending weight of the Gaussians whose labels carry
the effect is >= ``threshold`` of the pixel's alpha and the alpha is >= ``min_alpha``
(:func:`anigs.render.labels.label_masks`). Labels of ground-truth Gaussians render from the
cameras of a reconstruction in another frame through a similarity between the two camera
sets (:func:`anigs.sfm.align.align_cameras`). :func:`roi_from_labels` turns ground-truth
labels into the dynamic flags of a reconstruction's Gaussians.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from anigs.cameras import Camera, load_cameras
from anigs.gaussians import Gaussians, load_ply
from anigs.io import read_json
from anigs.masks.frame import Frame
from anigs.render.labels import effect_indicators, label_masks, labels_for
from anigs.sfm.align import Similarity, align_cameras
from anigs.synth.truth import dynamic_label_ids, effects_from_motion
from anigs.typed_config import Section


@dataclass
class LabelsConfig(Section):
    """Parameters of the labels backend (config section ``masks.labels``): the keywords of
    :class:`LabelsBackend` after its first three arguments."""

    WHERE = "masks.labels config"

    threshold: float = 0.5  # an effect's pixel: its blending weight is at least this fraction of the pixel's alpha
    min_alpha: float = 0.3  # a pixel is in no mask below this rendered alpha (sky, empty)


class LabelsBackend:
    """Callable mask backend rendering labelled Gaussians (see module docstring).

    Args:
        gaussians: the labelled Gaussians (any frame; see ``to_gaussians_frame``).
        labels: int [N] label per Gaussian.
        effects: effect name -> label ids that move with it (several effects give several masks).
        threshold: min effect weight as a fraction of the pixel's alpha.
        min_alpha: min pixel alpha to be in any mask.
        to_gaussians_frame: optional similarity mapping the cameras' frame to the Gaussians'
            frame (e.g. SfM -> ground truth); cameras are moved with it before rendering.
    """

    def __init__(self, gaussians: Gaussians, labels: np.ndarray, effects: dict[str, Sequence[int]],
                 threshold: float = 0.5, min_alpha: float = 0.3, to_gaussians_frame: Similarity | None = None):
        labels = np.asarray(labels)
        if labels.shape != (gaussians.num,):
            raise ValueError(f"labels backend: labels have shape {labels.shape}, Gaussians number {gaussians.num}")
        if not 0 < threshold <= 1:
            raise ValueError(f"labels backend: threshold must be in (0, 1], got {threshold}")
        effect_indicators(labels, effects)
        self.g, self.labels, self.effects = gaussians.detach(), labels, {k: list(v) for k, v in effects.items()}
        self.threshold, self.min_alpha, self.sim = threshold, min_alpha, to_gaussians_frame

    def __call__(self, frame: Frame) -> dict[str, np.ndarray]:
        if frame.camera is None:
            raise ValueError(f"labels backend needs the camera of frame {frame.name!r}")
        cam = frame.camera if self.sim is None else self.sim.apply_camera(frame.camera)
        return label_masks(self.g, self.labels, self.effects, cam, self.threshold, self.min_alpha)


def build(gaussians: Gaussians, labels: np.ndarray, effects: dict[str, Sequence[int]] | None = None,
          dynamic_labels: Sequence[int] | None = None, threshold: float = 0.5, min_alpha: float = 0.3,
          to_gaussians_frame: Similarity | None = None) -> LabelsBackend:
    """Registry entry: ``effects`` or (one effect ``dynamic`` of) ``dynamic_labels``."""
    if effects is None:
        if dynamic_labels is None:
            raise ValueError("labels backend: give effects {name: [label ids]} or dynamic_labels [ids]")
        effects = {"dynamic": list(dynamic_labels)}
    return LabelsBackend(gaussians, labels, effects, threshold, min_alpha, to_gaussians_frame)


def roi_from_labels(g: Gaussians, labels_path: str, motion_path: str | None, dynamic_labels, gt_gaussians: str | None,
                    gt_cameras: str | None, cameras: list[Camera]) -> np.ndarray:
    """Dynamic flag [N] of the canonical Gaussians from ground-truth labels."""
    labels = np.load(labels_path)
    if motion_path:
        ids = dynamic_label_ids(effects_from_motion(read_json(motion_path)))
    elif dynamic_labels:
        ids = [int(i) for i in dynamic_labels]
    else:
        raise ValueError("--labels needs --motion (the ground-truth motion tables) or params dynamic_labels [ids] to know what moves")
    label_means, sim = None, None
    if gt_gaussians:
        label_means = load_ply(gt_gaussians).means.detach().double().numpy()
        if gt_cameras:
            sim, rms = align_cameras(load_cameras(gt_cameras), cameras)
            logging.getLogger("anigs.views").info("views: ground-truth frame -> camera frame: scale %.4g, camera centre RMS %.3g", sim.scale, rms)
    lab = labels_for(g.means.detach().double().numpy(), labels, label_means, sim)
    return np.isin(lab, ids)
