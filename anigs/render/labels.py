"""Rendered labels: what labelled Gaussians show per pixel, and labels carried between Gaussian sets.

Each effect gets an indicator feature per Gaussian (1 if its label belongs to the effect, else
0); the rasterizer composites the indicators like colours, so a pixel's value is the blending
weight of that effect's Gaussians (:func:`render_effect_weights`). From those: the dominant
label per pixel (:func:`render_label_map`), the masks of the pixels an effect dominates
(:func:`label_masks`, :func:`dynamic_masks`). Two label transfers between Gaussian sets:
nearest neighbour (:func:`transfer_labels`, :func:`labels_for`) and by appearance
(:func:`appearance_labels`: each fitted Gaussian takes the label of what it depicts in the
training views, which a fitted model's floaters and thick ground layer need).
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Sequence

import numpy as np
import torch
from scipy.spatial import cKDTree

from anigs.cameras import Camera
from anigs.gaussians import Gaussians
from anigs.render.rasterize import rasterize
from anigs.render.visibility import frustum_subset, render_inputs

if TYPE_CHECKING:
    from anigs.geometry.similarity import Similarity


def effect_indicators(labels: np.ndarray, effects: dict[str, Sequence[int]]) -> np.ndarray:
    """Indicator features [N,E] (float32) of ``labels`` [N] for each effect's label ids."""
    labels = np.asarray(labels)
    if labels.ndim != 1:
        raise ValueError(f"labels must be 1D [N], got shape {labels.shape}")
    if not effects:
        raise ValueError("labels backend: no effect lists the labels that move (effects is empty)")
    return np.stack([np.isin(labels, list(ids)) for ids in effects.values()], 1).astype(np.float32)


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


def label_masks(g: Gaussians, labels: np.ndarray, effects: dict[str, Sequence[int]], cam: Camera,
                threshold: float = 0.5, min_alpha: float = 0.3) -> dict[str, np.ndarray]:
    """Masks bool [H,W] per effect of the pixels its labels dominate (effect weight >= ``threshold``
    of the pixel's alpha, alpha >= ``min_alpha``), and ``dynamic``, their union by the same rule."""
    weights, alpha = render_effect_weights(g, labels, effects, cam)
    ok = alpha >= min_alpha
    denom = np.maximum(alpha, 1e-6)
    masks = {k: ok & (w / denom >= threshold) for k, w in weights.items()}
    total = sum(weights.values())
    masks["dynamic"] = ok & (total / denom >= threshold)
    return masks


def dynamic_masks(g: Gaussians, dynamic: np.ndarray, cameras: Sequence[Camera], threshold: float = 0.5,
                  min_alpha: float = 0.3) -> list[np.ndarray]:
    """Masks bool [H,W] per camera of the pixels that the Gaussians flagged in ``dynamic`` [N] dominate.

    The render of a 3D dynamic set: a pixel is in the mask when the flagged Gaussians carry
    >= ``threshold`` of its alpha and the alpha is >= ``min_alpha`` (:func:`label_masks`).
    """
    dynamic = np.asarray(dynamic, bool)
    if dynamic.shape != (g.num,):
        raise ValueError(f"dynamic_masks: flags have shape {dynamic.shape}, the Gaussians number {g.num}")
    if not 0 < threshold <= 1:
        raise ValueError(f"dynamic_masks: threshold must be in (0, 1], got {threshold}")
    g, labels = g.detach(), dynamic.astype(np.int64)
    out = []
    for cam in cameras:
        if not dynamic.any():
            out.append(np.zeros((cam.height, cam.width), bool))
            continue
        out.append(label_masks(g, labels, {"dynamic": [1]}, cam, threshold, min_alpha)["dynamic"])
    return out


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


def transfer_labels(src_means: np.ndarray, src_labels: np.ndarray, dst_means: np.ndarray) -> np.ndarray:
    """Label of the nearest source Gaussian for each destination Gaussian [N_dst]."""
    _, idx = cKDTree(np.asarray(src_means)).query(np.asarray(dst_means), k=1)
    return np.asarray(src_labels)[idx]


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
                             "belong to (e.g. --gt-gaussians: the capture's ground-truth Gaussians) to transfer them")
        return labels
    if len(label_means) != len(labels):
        raise ValueError(f"{len(labels)} labels for {len(label_means)} labelled Gaussians")
    src = to_means_frame.apply(label_means) if to_means_frame is not None else np.asarray(label_means)
    return transfer_labels(src, labels, means)
