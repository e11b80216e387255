"""Metrics of the animated model itself (the ``eval`` stage's model-side groups): its motion
against the synthetic ground-truth wind, and the paper's multiview-consistency protocol (Table 3).
"""
from __future__ import annotations

import logging
from dataclasses import asdict, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from anigs.animate.deform import load_model
from anigs.animate.frames import render_frame
from anigs.cameras import load_cameras
from anigs.contract import CaptureFiles
from anigs.geometry.extent import scene_extent
from anigs.images import find_image, load_image
from anigs.metrics import metric_record, not_available
from anigs.metrics.motion import gt_motion_distances
from anigs.metrics.multiview import multiview_consistency, novel_timestep, static_fit_fn
from anigs.synth.motion import MotionParams, gt_clip_offsets

if TYPE_CHECKING:
    from anigs.metrics.config import EvalConfig

log = logging.getLogger("anigs.eval")


def gt_metrics(model: Path | None, canonical: Path | None, truth: CaptureFiles | None,
               cameras: Path | None) -> dict[str, Any]:
    """Learned vs ground-truth motion statistics (synthetic scene: ``truth``, the capture stage's
    folder with its ground truth; None on photo scenes)."""
    import torch


    keys = {"gt/rms_amplitude_ratio": (None, ""), "gt/amplitude_w1": (False, "scene extent"),
            "gt/frequency_w1": (False, "cycles/frame"), "gt/dominant_freq_learned": (None, "cycles/frame"),
            "gt/dominant_freq_gt": (None, "cycles/frame")}
    protocol = {"amplitude": "per-Gaussian RMS distance from its temporal mean / scene extent (1.1 x max camera "
                             "distance from the mean camera centre, learned and GT frames each)",
                "frequency": "per-Gaussian dominant frequency of the displacement (Hann, DC excluded)",
                "distances": "1-Wasserstein between distributions; ratio of RMS amplitudes (1 = ideal)"}

    def na(reason: str) -> dict[str, Any]:
        return {k: not_available(reason, bool(h), u, protocol) for k, (h, u) in keys.items()}

    if truth is None:
        return {}
    if model is None or canonical is None:
        return na("needs --model and --canonical (the learned animation)")
    canon, deformation, _ = load_model(model, canonical)
    if deformation.num_dynamic == 0:
        return na("the learned model has no dynamic Gaussians")
    T = deformation.num_frames
    learned = deformation.trajectories(canon.means, torch.arange(T)).detach().permute(1, 0, 2).double().numpy()
    gt = truth
    gt_g = gt.gt_gaussians()
    labels = gt.gt_labels(gt_g.num)
    anchors = gt.gt_anchors(gt_g.num)
    params = MotionParams.from_dict(gt.gt_motion()["params"])
    off = gt_clip_offsets(params, gt_g.means, torch.as_tensor(anchors), torch.as_tensor(labels).long())  # [T',N,3]
    moving = off.abs().amax(dim=(0, 2)) > 0
    gt_traj = (gt_g.means[moving][None] + off[:, moving]).permute(1, 0, 2).double().numpy()
    if cameras is None:
        return na("needs --cameras (learned frame) to make amplitudes scale-free")
    ext_l = scene_extent(load_cameras(cameras))
    ext_g = scene_extent(gt.gt_cameras())
    d = gt_motion_distances(learned, gt_traj, ext_l, ext_g)
    samples = {"learned_gaussians": d["n_learned"], "gt_gaussians": d["n_gt"], "learned_frames": T,
               "gt_frames": int(off.shape[0])}
    out = {}
    for k, (hib, unit) in keys.items():
        out[k] = metric_record(d[k.split("/", 1)[1]], bool(hib), unit, protocol, samples)
        if hib is None:
            out[k]["higher_is_better"] = None  # a ratio / frequency: closeness to GT matters, not direction
    return out


def _load_images_for(cameras, image_dir: Path) -> list[np.ndarray]:
    """The capture image [H,W,3] of every camera (:func:`anigs.images.find_image`, :func:`~anigs.images.load_image`)."""
    return [load_image(find_image(Path(image_dir), cam.name)) for cam in cameras]


def _resize(img: np.ndarray, w: int, h: int) -> np.ndarray:
    import cv2

    return img if img.shape[:2] == (h, w) else cv2.resize(img, (w, h), interpolation=cv2.INTER_AREA)


def multiview_metrics(cfg: EvalConfig, model: Path | None, canonical: Path | None, cameras_path: Path | None,
                      image_dir: Path | None, points_path: Path | None, device) -> dict[str, Any]:
    """Table-3 protocol: fresh static fit at a novel time (and on the capture), PSNR on held-out cameras."""
    import torch


    protocol = {"split": cfg.multiview_split, "train_fraction": cfg.multiview_train_fraction,
                "max_cameras": cfg.multiview_max_cameras, "scale": cfg.multiview_scale,
                "fit": asdict(cfg.multiview_fit),
                "psnr": "mean over held-out cameras"}
    keys = ["multiview/psnr_novel", "multiview/ssim_novel"] + (
        ["multiview/psnr_capture", "multiview/ssim_capture"] if cfg.multiview_capture else [])
    if not cfg.multiview:
        return {}
    missing = [n for n, v in (("--cameras", cameras_path), ("--points", points_path)) if v is None]
    if missing:
        return {k: not_available(f"multiview protocol needs {' and '.join(missing)}", True, "dB", protocol) for k in keys}
    fit, background = static_fit_fn(replace(cfg.multiview_fit, device=cfg.multiview_fit.device or cfg.device))
    cams = load_cameras(cameras_path)
    if cfg.multiview_max_cameras and len(cams) > cfg.multiview_max_cameras:
        keep = np.unique(np.linspace(0, len(cams) - 1, cfg.multiview_max_cameras).round().astype(int))
        cams = [cams[i] for i in keep]
    scaled = [c.scaled(max(8, int(round(c.width * cfg.multiview_scale))), max(8, int(round(c.height * cfg.multiview_scale))))
              for c in cams]
    with np.load(points_path, allow_pickle=False) as z:
        pts, cols = z["xyz"].astype(np.float32), z["rgb"].astype(np.float32)
    common = dict(train_fraction=cfg.multiview_train_fraction, split=cfg.multiview_split, seed=cfg.seed,
                  background=background)
    out: dict[str, Any] = {}

    def records(tag: str, res, extra: dict[str, Any]) -> None:
        p = dict(protocol, **extra, fit_seconds=round(res.fit_seconds, 2))
        s = {"train_views": res.n_train, "eval_views": res.n_eval}
        out[f"multiview/psnr_{tag}"] = metric_record(res.psnr, True, "dB", p, s,
                                                     per_view={v["camera"]: v["psnr"] for v in res.per_view})
        out[f"multiview/ssim_{tag}"] = metric_record(res.ssim, True, "", p, s)

    if cfg.multiview_capture:
        if image_dir is None:
            out["multiview/psnr_capture"] = not_available("needs --images (the capture)", True, "dB", protocol)
            out["multiview/ssim_capture"] = not_available("needs --images (the capture)", True, "", protocol)
        else:
            imgs = [_resize(im, c.width, c.height) for im, c in zip(_load_images_for(cams, image_dir), scaled)]
            records("capture", multiview_consistency(imgs, scaled, fit, pts, cols, **common), {"images": str(image_dir)})
    if model is None or canonical is None:
        reason = "needs --model and --canonical (the animated model to render at the novel time)"
        out["multiview/psnr_novel"] = not_available(reason, True, "dB", protocol)
        out["multiview/ssim_novel"] = not_available(reason, True, "", protocol)
        return out
    canon, deformation, _ = load_model(model, canonical)
    t = novel_timestep(deformation.num_frames, cfg.multiview_t)
    with torch.no_grad():
        imgs = [render_frame(canon, deformation, c, t, background=background).clamp(0, 1).cpu().numpy()
                for c in scaled]
    records("novel", multiview_consistency(imgs, scaled, fit, pts, cols, **common),
            {"t": t, "num_frames": deformation.num_frames})
    return out


# ----------------------------------------------------------------------------- entry points
