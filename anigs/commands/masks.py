"""``anigs masks``: dynamic-region mask per queued view, and the masks lifted to 3D.

For each view of ``views.json`` the first frame is rendered from the canonical model (or
read from ``--frames DIR``: ``{id}.png``, or ``{id}.npz`` clips whose frame 0 is used) and
segmented by the configured backend (``vegetation`` default, ``labels``, ``sam2``).

Writes to ``--out``: ``{id}.png`` (dynamic mask, 0/255), ``{id}_{effect}.png`` when the backend
gives several effect types, ``{id}_overlay.png``, ``dynamic.npy`` (bool [N] canonical Gaussians
lifted from the masks) and ``masks.json`` (per-view fractions; with ``--labels``: IoU of each
mask against the ground-truth label masks and precision/recall of the lifted Gaussians).
"""
from __future__ import annotations

import argparse
import dataclasses
import logging
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from anigs.cameras import load_cameras
from anigs.gaussians import load_ply
from anigs.io import atomic_path, read_json, write_json

log = logging.getLogger("anigs.masks")


@dataclass
class MasksConfig:
    """Config section ``masks``."""

    backend: str = "vegetation"                # vegetation | labels | sam2
    background: list = field(default_factory=lambda: [0.62, 0.76, 0.92])  # render background (RGB)
    vegetation: dict = field(default_factory=dict)  # VegetationConfig keys
    labels: dict = field(default_factory=dict)      # {threshold, min_alpha} of the labels backend
    sam2: dict = field(default_factory=dict)        # Sam2Config keys
    lift: dict = field(default_factory=dict)        # LiftConfig keys
    per_effect: bool = True                    # write one mask per effect type when there are several
    compare: bool = True                       # with --labels: IoU / precision / recall vs ground truth

    @staticmethod
    def from_dict(d: dict | None) -> "MasksConfig":
        from anigs.views import config_from_dict

        cfg = config_from_dict(MasksConfig, d, "masks config")
        if cfg.backend not in ("vegetation", "labels", "sam2"):
            raise ValueError(f"masks.backend must be vegetation, labels or sam2, got {cfg.backend!r}")
        if len(cfg.background) != 3:
            raise ValueError(f"masks.background must be [r, g, b], got {cfg.background}")
        return cfg


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--canonical", required=True, help="canonical 3DGS PLY (static/canonical.ply)")
    p.add_argument("--views", required=True, help="views.json from `anigs views`")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--params", default=None, help="masks config section as JSON or @file")
    p.add_argument("--frames", help="folder with the first frames ({id}.png or {id}.npz clips); "
                                    "default: render the canonical model")
    p.add_argument("--labels", help="per-Gaussian labels .npy: labels backend and/or ground-truth comparison")
    p.add_argument("--motion", help="motion.json: which labels move, per effect type (with --labels)")
    p.add_argument("--gt-gaussians", help="PLY the labels belong to when it is not the canonical set")
    p.add_argument("--gt-cameras", help="cameras in the frame of --gt-gaussians (matched by name to --cameras)")
    p.add_argument("--cameras", help="the reconstruction's cameras (sfm/cameras.json), to align with --gt-cameras")


def _load_frames(frames_dir: str | None, g, cams, background) -> list:
    from anigs.masks import Frame, read_rgb_png, render_frames

    rendered = render_frames(g, cams, background)
    if not frames_dir:
        return rendered
    from anigs.video import load_clip

    d = Path(frames_dir)
    out = []
    for fr in rendered:
        png, npz = d / f"{fr.name}.png", d / f"{fr.name}.npz"
        if png.is_file():
            img = read_rgb_png(png)
        elif npz.is_file():
            img = np.asarray(load_clip(npz)[0][0], np.float32)
        else:
            raise FileNotFoundError(f"no first frame for view {fr.name} in {d} (expected {png.name} or {npz.name})")
        out.append(Frame(img, fr.camera, fr.depth, fr.alpha, fr.name))  # depth/alpha of the canonical model
    return out


def _labels_backend(args, cfg: MasksConfig, g, effects):
    """The labels backend (ground-truth Gaussians in their own frame, or the canonical set)."""
    from anigs.masks.labels import LabelsBackend, align_cameras

    labels = np.load(args.labels)
    if args.gt_gaussians:
        lg = load_ply(args.gt_gaussians)
        sim = None
        if args.gt_cameras:
            if not args.cameras:
                raise ValueError("--gt-cameras needs --cameras (the reconstruction's cameras) to align the frames")
            sim, rms = align_cameras(load_cameras(args.cameras), load_cameras(args.gt_cameras))
            log.info("masks: camera frame -> ground-truth frame: scale %.4g, centre RMS %.3g", sim.scale, rms)
        return LabelsBackend(lg, labels, effects, to_gaussians_frame=sim, **cfg.labels)
    return LabelsBackend(g, labels, effects, **cfg.labels)


def run(args: argparse.Namespace) -> int:
    from anigs.cli import parse_params
    from anigs.masks import compute_masks, mask_iou, overlay, write_mask_png, write_rgb_png
    from anigs.masks.labels import effects_from_motion
    from anigs.masks.lift import LiftConfig, lift_masks_report
    from anigs.masks.vegetation import VegetationConfig, estimate_ground
    from anigs.views import cameras_from_views

    cfg = MasksConfig.from_dict(parse_params(args.params))
    lift_cfg = LiftConfig.from_dict(cfg.lift)
    g = load_ply(args.canonical)
    data = read_json(args.views)
    cams = cameras_from_views(data)
    if not cams:
        raise ValueError(f"{args.views} lists no views")
    out = Path(args.out)
    effects = effects_from_motion(read_json(args.motion)) if args.motion else None
    if args.labels and effects is None:
        raise ValueError("--labels needs --motion motion.json to know which labels move")
    frames = _load_frames(args.frames, g, cams, cfg.background)

    info: dict = {"backend": cfg.backend, "views": []}
    veg = VegetationConfig.from_dict(cfg.vegetation)
    up = np.asarray(data.get("up", [0.0, 0.0, 1.0]), float)
    ground = estimate_ground(g.means.detach().double().numpy(), up, cams, veg.ground_margin) if veg.ground else None
    if ground is not None:
        info["ground_plane"] = ground.to_dict()
    if cfg.backend == "vegetation":
        from anigs.masks.vegetation import build

        backend = build(veg, ground=ground)
    elif cfg.backend == "labels":
        if not args.labels:
            raise ValueError("masks.backend 'labels' needs --labels (and --motion)")
        backend = _labels_backend(args, cfg, g, effects)
    else:
        from anigs.masks.sam2 import build

        backend = build(cfg.sam2, vegetation=cfg.vegetation or None)
    results = compute_masks(backend, frames)

    truth = None
    if args.labels and cfg.compare:
        truth = results if cfg.backend == "labels" else compute_masks(_labels_backend(args, cfg, g, effects), frames)

    for k, (fr, res) in enumerate(zip(frames, results)):
        m = res["dynamic"]
        write_mask_png(out / f"{fr.name}.png", m)
        effects_out = {e: v for e, v in res.items() if e != "dynamic"}
        if cfg.per_effect and len(effects_out) > 1:
            for e, v in effects_out.items():
                write_mask_png(out / f"{fr.name}_{e}.png", v)
        write_rgb_png(out / f"{fr.name}_overlay.png", overlay(fr.image, m))
        entry = {"id": fr.name, "fraction": float(m.mean()),
                 "effects": {e: float(v.mean()) for e, v in effects_out.items()}}
        if truth is not None:
            entry["iou_vs_labels"] = mask_iou(m, truth[k]["dynamic"])
            entry["labels_fraction"] = float(truth[k]["dynamic"].mean())
        info["views"].append(entry)
        log.info("masks: %s dynamic %.1f%%%s", fr.name, 100 * m.mean(),
                 f" IoU vs labels {entry['iou_vs_labels']:.3f}" if truth is not None else "")
    if truth is not None:
        ious = [v["iou_vs_labels"] for v in info["views"]]
        info["iou_vs_labels"] = {"mean": float(np.mean(ious)), "min": float(np.min(ious))}

    dyn, lift_info = lift_masks_report(g, [fr.camera for fr in frames], [r["dynamic"] for r in results], lift_cfg,
                                       ground=ground)
    info["lift"] = lift_info
    if args.labels and cfg.compare:
        from anigs.commands.views import roi_from_labels

        gt = roi_from_labels(g, args.labels, args.motion, None, args.gt_gaussians,
                             args.gt_cameras, load_cameras(args.cameras) if args.cameras else cams)
        tp = int((dyn & gt).sum())
        info["lift_vs_labels"] = {"precision": tp / max(int(dyn.sum()), 1), "recall": tp / max(int(gt.sum()), 1),
                                  "num_gt_dynamic": int(gt.sum()), "num_lifted": int(dyn.sum())}
        log.info("masks: lifted Gaussians vs labels: precision %.3f recall %.3f",
                 info["lift_vs_labels"]["precision"], info["lift_vs_labels"]["recall"])
    with atomic_path(out / "dynamic.npy") as tmp:
        with open(tmp, "wb") as fh:
            np.save(fh, dyn)
    info["config"] = dataclasses.asdict(cfg)
    write_json(out / "masks.json", info)
    log.info("masks: wrote %d masks, dynamic.npy (%d of %d Gaussians) to %s", len(frames), int(dyn.sum()), g.num, out)
    return 0
