"""Evaluation-only camera-fixed views of a synthetic scene, and its ground-truth animated clips.

FVD needs many clips (the paper: 250 per method); the twelve queued views of the demo give too
few. These views exist only for evaluation: no method trains on them.

Placement (in the ground-truth frame, deterministic for a seed): each try picks a capture
camera, moves its centre by a hand-held-sized random offset, and looks at a random moving
Gaussian (a moving label drawn first, uniformly, so that grass and flowers are aimed at as
often as the much larger tree crowns). A try is kept when no Gaussian centre lies within
``clearance`` of the eye, the target is between ``min_distance`` and ``max_distance`` away,
and moving Gaussians are the dominant label of at least ``min_dynamic_fraction`` of the pixels
(:func:`anigs.render.labels.render_label_map` of the scene at t = 0).

Rendering: a method's clip is :func:`anigs.animate.frames.render_clip` of its model (what the
final stage renders) at the view moved into the reconstruction's frame by the similarity from
the ground-truth cameras to the reconstruction's (:func:`anigs.sfm.align.align_cameras`,
matched by image name); the ground truth is the ground-truth Gaussians displaced by
:func:`anigs.synth.motion.gt_offsets` at the same fraction of the loop.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np
import torch

from anigs.animate.frames import render_clip
from anigs.cameras import Camera, intrinsics_from_fov, look_at
from anigs.gaussians import Gaussians
from anigs.render import render_gaussians
from anigs.render.labels import render_label_map
from anigs.synth.motion import MotionParams, gt_offsets
from anigs.synth.truth import dynamic_label_ids, effects_from_motion


@dataclass(frozen=True)
class Placement:
    """How the evaluation views are placed (the ``fvd_gt`` config section's view keys)."""

    num_views: int = 64
    width: int = 256
    height: int = 192
    fov_deg: float = 70.0
    seed: int = 0
    jitter_m: float = 0.35  # std of the eye's offset from the picked capture camera (m; vertical: a third)
    min_distance: float = 1.0  # eye-to-target distance bounds (m)
    max_distance: float = 8.0
    clearance: float = 0.3  # no Gaussian centre closer to the eye (m)
    min_dynamic_fraction: float = 0.10  # share of pixels whose dominant label moves
    max_tries_per_view: int = 40


def moving_labels(motion: dict[str, Any]) -> list[int]:
    """Label ids that the ground-truth motion moves (``motion.json``)."""
    return dynamic_label_ids(effects_from_motion(motion))


def place_eval_views(gt: Gaussians, labels: np.ndarray, moving: Sequence[int], capture: Sequence[Camera],
                     spec: Placement) -> tuple[list[Camera], dict[str, Any]]:
    """``spec.num_views`` cameras named ``e00``.. in the ground-truth frame, and the placement report.

    Raises ValueError when the scene has no moving Gaussian or too few tries pass.
    """
    from scipy.spatial import cKDTree


    labels = np.asarray(labels)
    if labels.shape != (gt.num,):
        raise ValueError(f"eval views: {labels.shape[0]} labels for {gt.num} Gaussians")
    means = gt.means.detach().cpu().double().numpy()
    present = [int(k) for k in moving if np.any(labels == k)]
    if not present or not capture:
        raise ValueError(f"eval views: nothing to look at (moving labels present: {present}, "
                         f"capture cameras: {len(capture)})")
    members = {k: np.flatnonzero(labels == k) for k in present}
    tree = cKDTree(means)
    K = intrinsics_from_fov(spec.fov_deg, spec.width, spec.height)
    rng = np.random.default_rng(int(spec.seed))
    cams: list[Camera] = []
    fractions: list[float] = []
    rejected = {"clearance": 0, "distance": 0, "dynamic_fraction": 0}
    tries = 0
    while len(cams) < spec.num_views and tries < spec.num_views * spec.max_tries_per_view:
        tries += 1
        base = capture[int(rng.integers(len(capture)))].center
        eye = base + rng.normal(0.0, spec.jitter_m, 3) * np.array([1.0, 1.0, 1.0 / 3.0])
        lab = present[int(rng.integers(len(present)))]
        target = means[members[lab][int(rng.integers(len(members[lab])))]]
        dist = float(np.linalg.norm(target - eye))
        if not spec.min_distance <= dist <= spec.max_distance:
            rejected["distance"] += 1
            continue
        if tree.query(eye)[0] < spec.clearance:
            rejected["clearance"] += 1
            continue
        cam = Camera(K, look_at(eye, target), spec.width, spec.height, f"e{len(cams):02d}")
        lmap = render_label_map(gt, labels, cam)
        frac = float(np.isin(lmap, present).mean())
        if frac < spec.min_dynamic_fraction:
            rejected["dynamic_fraction"] += 1
            continue
        cams.append(cam)
        fractions.append(frac)
    if len(cams) < spec.num_views:
        raise ValueError(f"eval views: only {len(cams)} of {spec.num_views} views passed in {tries} tries "
                         f"(rejected: {rejected}); lower fvd_gt.min_dynamic_fraction or raise max_tries_per_view")
    report = {"tries": tries, "rejected": rejected, "dynamic_fraction": {c.name: f for c, f in zip(cams, fractions)},
              "dynamic_fraction_min": float(min(fractions)), "dynamic_fraction_mean": float(np.mean(fractions)),
              "moving_labels": present}
    return cams, report


def window_starts(num_frames: int, frames: int, windows: int) -> list[int]:
    """``windows`` start frames of ``frames``-frame windows, evenly spread over a clip of ``num_frames``."""
    if frames < 1 or windows < 1:
        raise ValueError(f"window_starts: frames and windows must be >= 1, got {frames}, {windows}")
    if frames > num_frames:
        raise ValueError(f"window_starts: {frames}-frame windows do not fit a {num_frames}-frame clip")
    last = num_frames - frames
    starts = sorted({int(round(x)) for x in np.linspace(0, last, windows)})
    if len(starts) < windows:
        raise ValueError(f"window_starts: {windows} distinct {frames}-frame windows do not fit {num_frames} frames")
    return starts


def gt_clip(gt: Gaussians, offsets: torch.Tensor, cam: Camera, background: Sequence[float]) -> np.ndarray:
    """Ground-truth clip [F,H,W,3] in [0,1]: ``gt`` displaced by ``offsets`` [F,N,3], seen from ``cam``."""
    bg = torch.tensor(list(background), dtype=torch.float32)
    frames = []
    with torch.no_grad():
        for off in offsets:
            g = Gaussians(gt.means + off, gt.quats, gt.log_scales, gt.opacity_logits, gt.sh)
            frames.append(render_gaussians(g, cam, background=bg)[0].clamp(0, 1).cpu().numpy())
    return np.stack(frames)


def gt_offsets_at(gt: Gaussians, labels: np.ndarray, anchors: np.ndarray, motion: dict[str, Any],
                  num_frames: int) -> torch.Tensor:
    """Ground-truth offsets [T,N,3] at frames 0..T-1 of a T-frame model, as the same fractions of the
    ground-truth loop (``t_gt = t * loop / T``; the identity when the model's T is the loop's)."""
    params = MotionParams.from_dict(motion["params"])
    times = torch.arange(num_frames, dtype=torch.float32) * (params.frames / num_frames)
    return gt_offsets(params, gt.means, torch.as_tensor(anchors), torch.as_tensor(labels).long(), times, params.frames)


def model_clip(canonical: Gaussians, deformation, cam: Camera, num_frames: int,
               background: Sequence[float]) -> np.ndarray:
    """A method's clip [T,H,W,3] at frames 0..T-1 (:func:`anigs.animate.frames.render_clip`, as the final stage)."""
    bg = torch.tensor(list(background), dtype=torch.float32, device=canonical.device)
    return render_clip(canonical, deformation, cam, num_frames, bg).clamp(0, 1).cpu().numpy()


def thumbnail_sheet(rows: Sequence[Sequence[np.ndarray]], thumb_width: int = 128) -> np.ndarray:
    """Image [H,W,3] of thumbnails: one row per list of frames [h,w,3] (a 2 px gap between)."""
    import cv2

    thumbs = []
    for row in rows:
        th = [cv2.resize(np.asarray(f, np.float32), (thumb_width, max(1, round(f.shape[0] * thumb_width / f.shape[1]))),
                         interpolation=cv2.INTER_AREA) for f in row]
        h = max(t.shape[0] for t in th)
        gap = np.ones((h, 2, 3), np.float32)
        thumbs.append(np.concatenate([x for t in th for x in (t, gap)][:-1], axis=1))
    width = max(t.shape[1] for t in thumbs)
    thumbs = [np.pad(t, ((0, 2), (0, width - t.shape[1]), (0, 0)), constant_values=1.0) for t in thumbs]
    return np.concatenate(thumbs, axis=0)
