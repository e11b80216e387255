"""``labels`` mask backend: the label map rendered from labelled Gaussians (synthetic scenes).

Each effect type gets an indicator feature per Gaussian (1 if its label belongs to the
effect, else 0); the rasterizer composites the indicators like colours, so a pixel's value
is the blending weight of that effect's Gaussians. A pixel is in the effect's mask when that
weight is >= ``threshold`` of the pixel's alpha and the alpha is >= ``min_alpha``.

Also: a similarity alignment between two camera sets (Umeyama on camera centres, via
:mod:`anigs.sfm.align`) so labels
of ground-truth Gaussians can be rendered from cameras of a reconstruction in another frame,
and two label transfers between Gaussian sets: nearest neighbour (:func:`transfer_labels`)
and by appearance (:func:`appearance_labels`: each fitted Gaussian takes the label of what it
depicts in the training views, which a fitted model's floaters and thick ground layer need).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Sequence

import numpy as np
import torch

from anigs.sfm.align import Similarity, umeyama
from anigs.cameras import Camera, load_cameras
from anigs.gaussians import Gaussians, load_ply
from anigs.io import read_json
from anigs.masks import Frame
from anigs.masks.lift import render_inputs, frustum_subset
from anigs.render import rasterize


def effect_indicators(labels: np.ndarray, effects: dict[str, Sequence[int]]) -> np.ndarray:
    """Indicator features [N,E] (float32) of ``labels`` [N] for each effect's label ids."""
    labels = np.asarray(labels)
    if labels.ndim != 1:
        raise ValueError(f"labels must be 1D [N], got shape {labels.shape}")
    if not effects:
        raise ValueError("labels backend: no effect lists the labels that move (effects is empty)")
    return np.stack([np.isin(labels, list(ids)) for ids in effects.values()], 1).astype(np.float32)


def align_cameras(src: Sequence[Camera], dst: Sequence[Camera]) -> tuple[Similarity, float]:
    """Similarity src-frame -> dst-frame from cameras matched by name; also the RMS centre error (dst units)."""
    by_name = {c.name: c for c in dst}
    pairs = [(c, by_name[c.name]) for c in src if c.name in by_name]
    if len(pairs) < 3:
        raise ValueError(f"align_cameras: only {len(pairs)} camera names in common (need >= 3); "
                         f"e.g. {[c.name for c in src[:3]]} vs {[c.name for c in dst[:3]]}")
    a = np.stack([p[0].center for p in pairs])
    b = np.stack([p[1].center for p in pairs])
    sim = umeyama(a, b)
    rms = float(np.sqrt(((sim.apply(a) - b) ** 2).sum(1).mean()))
    return sim, rms


def transfer_labels(src_means: np.ndarray, src_labels: np.ndarray, dst_means: np.ndarray) -> np.ndarray:
    """Label of the nearest source Gaussian for each destination Gaussian [N_dst]."""
    from scipy.spatial import cKDTree

    _, idx = cKDTree(np.asarray(src_means)).query(np.asarray(dst_means), k=1)
    return np.asarray(src_labels)[idx]


def render_label_map(g: Gaussians, labels: np.ndarray, cam: Camera, min_alpha: float = 0.3) -> np.ndarray:
    """Dominant label [H,W] (int64) of labelled Gaussians seen from ``cam``; -1 where alpha < ``min_alpha``."""
    ids = sorted({int(i) for i in np.unique(labels)})
    weights, alpha = render_effect_weights(g, labels, {str(i): [i] for i in ids}, cam)
    stack = np.stack([weights[str(i)] for i in ids], 0)
    out = np.asarray(ids, np.int64)[np.argmax(stack, 0)]
    out[alpha < min_alpha] = -1
    return out


def appearance_labels(g: Gaussians, label_gaussians: Gaussians, labels: np.ndarray, cameras: Sequence[Camera],
                      to_labels_frame: Similarity | None = None, min_alpha: float = 0.3,
                      min_weight: float = 0.05) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """Label per Gaussian of ``g`` by what it depicts in ``cameras`` (e.g. the training views).

    Each camera (in the frame of ``g``; moved by ``to_labels_frame`` into the frame of
    ``label_gaussians``) renders the dominant label of ``label_gaussians`` per pixel
    (:func:`render_label_map`); one backward pass of the rasterizer per 3 classes gives each
    Gaussian of ``g`` its blending weight summed over the pixels of each class. A Gaussian
    takes the class with the most weight; class -1 is empty space (sky): the Gaussian
    depicts nothing labelled. Gaussians that the cameras (nearly) do not see (summed weight
    < ``min_weight`` pixels: hidden ones only blend into the pixels of what hides them) take
    the nearest labelled Gaussian's label (:func:`transfer_labels`).

    Unlike the nearest-neighbour transfer this follows what a fitted Gaussian looks like
    where it was fitted: a lawn splat floating among grass blades stays lawn.

    Returns (labels [N] int64, weights [N, C] float64, class ids [C] with -1 first).
    """
    labels = np.asarray(labels)
    if labels.shape != (label_gaussians.num,):
        raise ValueError(f"appearance_labels: {len(labels)} labels for {label_gaussians.num} labelled Gaussians")
    if not len(cameras):
        raise ValueError("appearance_labels: no cameras")
    classes = [-1] + sorted({int(i) for i in np.unique(labels)})
    acc = np.zeros((g.num, len(classes)))
    for cam in cameras:
        lab_cam = cam if to_labels_frame is None else to_labels_frame.apply_camera(cam)
        lmap = torch.from_numpy(render_label_map(label_gaussians, labels, lab_cam, min_alpha))
        idx = frustum_subset(g, cam)
        if len(idx) == 0:
            continue
        args = render_inputs(g, idx)
        for s in range(0, len(classes), 3):
            chunk = classes[s:s + 3]
            colors = torch.zeros(len(idx), 3, requires_grad=True)
            rgb, _, _ = rasterize(*args, colors, cam.torch_viewmat(), cam.torch_K(), cam.width, cam.height)
            gout = torch.zeros_like(rgb)
            for j, c in enumerate(chunk):
                gout[..., j] = (lmap == c).float()
            rgb.backward(gout)
            if colors.grad is not None:
                acc[idx.numpy(), s:s + len(chunk)] += colors.grad[:, :len(chunk)].double().numpy()
    out = np.asarray(classes, np.int64)[np.argmax(acc, 1)]
    unseen = acc.sum(1) < min_weight
    if unseen.any():
        src = label_gaussians.means.detach().double().numpy()
        if to_labels_frame is not None:  # back into the frame of g: x = R^T (y - t) / s
            src = (src - to_labels_frame.t) @ to_labels_frame.R / to_labels_frame.scale
        out[unseen] = transfer_labels(src, labels, g.means.detach().double().numpy()[unseen])
    return out, acc, classes


def render_effect_weights(g: Gaussians, labels: np.ndarray, effects: dict[str, Sequence[int]],
                          cam: Camera) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Per-effect blending weight [H,W] and alpha [H,W] of ``g`` seen from ``cam``."""
    if len(labels) != g.num:
        raise ValueError(f"labels backend: {len(labels)} labels for {g.num} Gaussians")
    ind = torch.from_numpy(effect_indicators(labels, effects))
    names = list(effects)
    out: dict[str, np.ndarray] = {}
    alpha = None
    idx = frustum_subset(g, cam)
    args = render_inputs(g, idx)
    ind = ind[idx]
    with torch.no_grad():
        for s in range(0, len(names), 3):
            cols = torch.zeros(len(idx), 3)
            chunk = ind[:, s:s + 3]
            cols[:, :chunk.shape[1]] = chunk
            rgb, a, _ = rasterize(*args, cols, cam.torch_viewmat(), cam.torch_K(), cam.width, cam.height)
            alpha = a.numpy()
            for j in range(chunk.shape[1]):
                out[names[s + j]] = rgb[..., j].numpy()
    return out, alpha


@dataclass
class LabelsConfig:
    """Parameters of the labels backend (config section ``masks.labels``): the keywords of
    :class:`LabelsBackend` after its first three arguments."""

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
        weights, alpha = render_effect_weights(self.g, self.labels, self.effects, cam)
        ok = alpha >= self.min_alpha
        denom = np.maximum(alpha, 1e-6)
        masks = {k: ok & (w / denom >= self.threshold) for k, w in weights.items()}
        total = sum(weights.values())
        masks["dynamic"] = ok & (total / denom >= self.threshold)
        return masks


def dynamic_masks(g: Gaussians, dynamic: np.ndarray, cameras: Sequence[Camera], threshold: float = 0.5,
                  min_alpha: float = 0.3) -> list[np.ndarray]:
    """Masks bool [H,W] per camera of the pixels that the Gaussians flagged in ``dynamic`` [N] dominate.

    The render of a 3D dynamic set: a pixel is in the mask when the flagged Gaussians carry
    >= ``threshold`` of its alpha and the alpha is >= ``min_alpha`` (as :class:`LabelsBackend`).
    """
    dynamic = np.asarray(dynamic, bool)
    if dynamic.shape != (g.num,):
        raise ValueError(f"dynamic_masks: flags have shape {dynamic.shape}, the Gaussians number {g.num}")
    backend = LabelsBackend(g, dynamic.astype(np.int64), {"dynamic": [1]}, threshold, min_alpha)
    out = []
    for cam in cameras:
        if not dynamic.any():
            out.append(np.zeros((cam.height, cam.width), bool))
            continue
        out.append(backend(Frame(np.zeros((cam.height, cam.width, 3), np.float32), cam, name=cam.name))["dynamic"])
    return out


def build(gaussians: Gaussians, labels: np.ndarray, effects: dict[str, Sequence[int]] | None = None,
          dynamic_labels: Sequence[int] | None = None, threshold: float = 0.5, min_alpha: float = 0.3,
          to_gaussians_frame: Similarity | None = None) -> LabelsBackend:
    """Registry entry: ``effects`` or (one effect ``dynamic`` of) ``dynamic_labels``."""
    if effects is None:
        if dynamic_labels is None:
            raise ValueError("labels backend: give effects {name: [label ids]} or dynamic_labels [ids]")
        effects = {"dynamic": list(dynamic_labels)}
    return LabelsBackend(gaussians, labels, effects, threshold, min_alpha, to_gaussians_frame)


def effects_from_motion(motion: dict) -> dict[str, list[int]]:
    """Effect type -> label ids carrying it, from a ground-truth ``motion.json``.

    Reads ``labels`` ({id: name}) and ``label_effects`` ({name: [effect, ...]}) as written by
    :mod:`anigs.synth`; falls back to ``movable_labels`` as a single effect ``dynamic``.
    """
    if "labels" in motion and "label_effects" in motion:
        out: dict[str, list[int]] = {}
        for lid, name in motion["labels"].items():
            for eff in motion["label_effects"].get(name, []):
                out.setdefault(eff, []).append(int(lid))
        if out:
            return {k: sorted(v) for k, v in out.items()}
    if motion.get("movable_labels"):
        return {"dynamic": [int(i) for i in motion["movable_labels"]]}
    raise KeyError("motion.json names no moving labels: expected 'labels' + 'label_effects' or 'movable_labels'")


def dynamic_label_ids(effects: dict[str, Sequence[int]]) -> list[int]:
    """All label ids that move under any effect."""
    return sorted({int(i) for ids in effects.values() for i in ids})


def labels_for(means: np.ndarray, labels: np.ndarray, label_means: np.ndarray | None = None,
               to_means_frame: Similarity | None = None) -> np.ndarray:
    """Labels [N] for Gaussians at ``means`` [N,3].

    When ``labels`` already has N entries and no ``label_means`` is given they are used as
    is; otherwise each Gaussian takes the label of the nearest of ``label_means`` [M,3]
    (moved into the ``means`` frame by ``to_means_frame`` when the frames differ).
    """
    labels = np.asarray(labels)
    if label_means is None:
        if len(labels) != len(means):
            raise ValueError(f"{len(labels)} labels for {len(means)} Gaussians: give the Gaussians the labels "
                             "belong to (e.g. --gt-gaussians gt/gaussians.ply) to transfer them")
        return labels
    if len(label_means) != len(labels):
        raise ValueError(f"{len(labels)} labels for {len(label_means)} labelled Gaussians")
    src = to_means_frame.apply(label_means) if to_means_frame is not None else np.asarray(label_means)
    return transfer_labels(src, labels, means)


def roi_from_labels(g: Gaussians, labels_path: str, motion_path: str | None, dynamic_labels, gt_gaussians: str | None,
                    gt_cameras: str | None, cameras: list[Camera]) -> np.ndarray:
    """Dynamic flag [N] of the canonical Gaussians from ground-truth labels."""
    labels = np.load(labels_path)
    if motion_path:
        ids = dynamic_label_ids(effects_from_motion(read_json(motion_path)))
    elif dynamic_labels:
        ids = [int(i) for i in dynamic_labels]
    else:
        raise ValueError("--labels needs --motion motion.json or params dynamic_labels [ids] to know what moves")
    label_means, sim = None, None
    if gt_gaussians:
        label_means = load_ply(gt_gaussians).means.detach().double().numpy()
        if gt_cameras:
            sim, rms = align_cameras(load_cameras(gt_cameras), cameras)
            logging.getLogger("anigs.views").info("views: ground-truth frame -> camera frame: scale %.4g, camera centre RMS %.3g", sim.scale, rms)
    lab = labels_for(g.means.detach().double().numpy(), labels, label_means, sim)
    return np.isin(lab, ids)
