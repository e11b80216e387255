"""Benchmark the masks stage: the vegetation backend against the ground-truth labels.

    python benchmarks/masks.py results/demo [--params '{"backend": "vegetation", "vegetation": {...}}']
                               [--no-appearance] [--no-capture] [--json]

The scene folder holds ``static/canonical.ply``, ``views/views.json``, ``sfm/cameras.json``
and the synthetic ground truth ``capture/gt/`` (``labels.npy``, ``motion.json``,
``gaussians.ply``, ``cameras.json``). The first frame of each queued view is rendered from the
canonical model and segmented, the capture photos ``sfm/images`` too (unless ``--no-capture``),
the masks of both are lifted to the canonical Gaussians and each queued view's mask is
completed with the render of the lifted set (``complete_masks``), as ``anigs masks --images``
does. Then compared with two yardsticks:

``labels``
    What ``anigs masks --labels`` writes to masks.json: the label masks rendered from the
    ground-truth Gaussians (ground-truth geometry), and for the lifted Gaussians the labels
    transferred to the canonical Gaussians by nearest neighbour.
``appearance``
    The labels of what the canonical model itself shows: each canonical Gaussian takes the
    label it depicts in the capture views (:func:`anigs.render.labels.appearance_labels`), and
    the label masks are rendered through the canonical model. A mask computed on a render of
    the fitted model can only be judged on what that render shows: its floaters and blur are
    not in the ground-truth geometry, and a fitted lawn splat floating next to a grass tuft is
    still lawn (nearest neighbour calls it grass). Costs ~0.3 s per capture view (2 CPU cores).

Prints per-view IoU, mean/min, lifting precision/recall (also of the labels masks themselves,
the best the lifting can do with perfect masks), the ceilings (the appearance label masks
against the labels masks: the best any labelling of what the fitted render shows can score
against ground-truth geometry; the appearance labels against the nearest-neighbour labels)
and wall seconds per step.
"""
from __future__ import annotations

import argparse
import json
import logging
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np


def _pr(pred: np.ndarray, truth: np.ndarray) -> dict:
    from anigs.masks.lift import precision_recall

    pr = precision_recall(pred, truth)
    return {"precision": round(pr["precision"], 4), "recall": round(pr["recall"], 4),
            "lifted": int(pred.sum()), "truth": int(truth.sum())}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", help="scene result folder (e.g. results/demo)")
    ap.add_argument("--params", default=None, help="masks config section as JSON or @file (default backend: vegetation)")
    ap.add_argument("--no-appearance", action="store_true", help="skip the appearance yardstick")
    ap.add_argument("--no-capture", action="store_true", help="segment and lift the queued views only")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--json", action="store_true", help="print the figures as one JSON line too")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")

    import torch

    torch.set_num_threads(args.threads)
    from anigs.cameras import load_cameras
    from anigs.cli import parse_params
    import dataclasses

    from anigs.stages.masks import MasksConfig
    from anigs.masks.capture import capture_frames
    from anigs.masks.labels_backend import roi_from_labels
    from anigs.gaussians import load_ply
    from anigs.io import read_json
    from anigs.masks import compute_masks, get_mask_backend, mask_iou, render_frames
    from anigs.masks.labels_backend import LabelsBackend
    from anigs.sfm.align import align_cameras
    from anigs.render.labels import appearance_labels, dynamic_masks
    from anigs.synth.truth import dynamic_label_ids, effects_from_motion
    from anigs.masks.lift import lift_masks_report
    from anigs.geometry.ground import ground_plane as estimate_ground
    from anigs.views import cameras_from_views

    from anigs.stages import capture as capture_stage, sfm as sfm_stage, static as static_stage
    from anigs.stages import views as views_stage

    scene = Path(args.scene)
    cap, sfm_out = capture_stage.Outputs(scene / "capture"), sfm_stage.Outputs(scene / "sfm")
    paths = {"canonical": static_stage.Outputs(scene / "static").path("canonical"),
             "views": views_stage.Outputs(scene / "views").path("views"),
             "cameras": sfm_out.path("cameras"), "labels": cap.path("gt_labels"),
             "motion": cap.path("gt_motion"), "gt_gaussians": cap.path("gt_gaussians"),
             "gt_cameras": cap.path("gt_cameras")}
    missing = [str(p) for p in paths.values() if not p.exists()]
    if missing:
        raise SystemExit(f"benchmarks/masks.py: missing {', '.join(missing)}")
    params = parse_params(args.params) or {}
    cfg = MasksConfig.from_dict({"backend": "vegetation", **params})
    veg, lift_cfg = cfg.vegetation, cfg.lift
    seconds: dict[str, float] = {}

    t = time.perf_counter()
    g = load_ply(paths["canonical"])
    data = read_json(paths["views"])
    cams = cameras_from_views(data)
    frames = render_frames(g, cams, cfg.background)
    seconds["render"] = time.perf_counter() - t

    t = time.perf_counter()
    up = np.asarray(data.get("up", [0.0, 0.0, 1.0]), float)
    ground = estimate_ground(g.means.detach().double().numpy(), up, cams, veg.ground_margin) if veg.ground else None

    def make_backend(v):
        if cfg.backend == "vegetation":
            return get_mask_backend("vegetation", config=v, ground=ground)
        if cfg.backend == "sam2":
            return get_mask_backend("sam2", config=cfg.sam2, vegetation=cfg.vegetation or None)
        raise SystemExit("benchmarks/masks.py compares a mask backend with the labels: use vegetation or sam2")

    direct = [r["dynamic"] for r in compute_masks(make_backend(veg), frames)]
    seconds["masks"] = time.perf_counter() - t
    sfm_cams = load_cameras(paths["cameras"])
    lift_cams, lift_in = [fr.camera for fr in frames], list(direct)
    images = sfm_out.path("images")
    if not args.no_capture and images.is_dir():
        t = time.perf_counter()
        cap = capture_frames(str(images), sfm_cams, g)
        cap_veg = dataclasses.replace(veg, ground_layer=cfg.capture_ground_layer)
        lift_cams += [f.camera for f in cap]
        lift_in += [r["dynamic"] for r in compute_masks(make_backend(cap_veg), cap)]
        seconds["capture_masks"] = time.perf_counter() - t

    labels = np.load(paths["labels"])
    effects = effects_from_motion(read_json(paths["motion"]))
    ids = dynamic_label_ids(effects)
    gt = load_ply(paths["gt_gaussians"])
    gt_cams = load_cameras(paths["gt_cameras"])
    to_gt, _ = align_cameras(sfm_cams, gt_cams)
    t = time.perf_counter()
    truth = [r["dynamic"] for r in compute_masks(LabelsBackend(gt, labels, effects, to_gaussians_frame=to_gt,
                                                               **asdict(cfg.labels)), frames)]
    nn_dynamic = roi_from_labels(g, str(paths["labels"]), str(paths["motion"]), None, str(paths["gt_gaussians"]),
                                 str(paths["gt_cameras"]), sfm_cams)
    seconds["labels_yardstick"] = time.perf_counter() - t

    app_truth = app_dynamic = None
    if not args.no_appearance:
        t = time.perf_counter()
        app_lab, _, _ = appearance_labels(g, gt, labels, sfm_cams, to_labels_frame=to_gt)
        app_dynamic = np.isin(app_lab, ids)
        app_truth = [r["dynamic"] for r in compute_masks(LabelsBackend(g, app_lab, effects, **asdict(cfg.labels)), frames)]
        seconds["appearance_yardstick"] = time.perf_counter() - t

    t = time.perf_counter()
    cameras = [fr.camera for fr in frames]
    dyn, lift_info = lift_masks_report(g, lift_cams, lift_in, lift_cfg, ground=ground)
    masks = direct
    if cfg.complete_masks:
        masks = [m | d for m, d in zip(direct, dynamic_masks(g, dyn, cameras))]
    seconds["lift"] = time.perf_counter() - t
    ref_dyn, _ = lift_masks_report(g, cameras, truth, lift_cfg, ground=ground)

    views = []
    print(f"scene {scene}  backend {cfg.backend}  views {len(frames)}  capture photos lifted "
          f"{len(lift_cams) - len(frames)}  canonical Gaussians {g.num}")
    if ground is not None:
        print(f"ground plane: offset {ground.offset:.3f}, floor {ground.min_height:.3f}, measured layer "
              f"{ground.layer:.3f}, cut {ground.cut_height(veg.ground_layer, veg.ground_max_margin):.3f} "
              f"(camera height {ground.camera_height:.3f})")
    head = f"{'view':6s} {'mask%':>6s} {'labels%':>7s} {'IoU labels':>10s} {'(direct)':>8s}"
    print(head + (f" {'IoU appearance':>14s} {'ceiling':>7s}" if app_truth is not None else ""))
    for k, fr in enumerate(frames):
        v = {"id": fr.name, "fraction": float(masks[k].mean()), "labels_fraction": float(truth[k].mean()),
             "iou_labels": mask_iou(masks[k], truth[k]), "iou_labels_direct": mask_iou(direct[k], truth[k])}
        line = (f"{fr.name:6s} {100 * v['fraction']:6.1f} {100 * v['labels_fraction']:7.1f} {v['iou_labels']:10.3f} "
                f"{v['iou_labels_direct']:8.3f}")
        if app_truth is not None:
            v["iou_appearance"] = mask_iou(masks[k], app_truth[k])
            v["ceiling_labels"] = mask_iou(app_truth[k], truth[k])
            line += f" {v['iou_appearance']:14.3f} {v['ceiling_labels']:7.3f}"
        views.append(v)
        print(line)
    summary = {}
    for key in ("iou_labels", "iou_labels_direct", "iou_appearance", "ceiling_labels"):
        if key in views[0]:
            vals = [v[key] for v in views]
            summary[key] = {"mean": round(float(np.mean(vals)), 4), "min": round(float(np.min(vals)), 4)}
            print(f"{key:17s} mean {summary[key]['mean']:.3f}  min {summary[key]['min']:.3f}")
    lift = {"labels_nn": _pr(dyn, nn_dynamic), "labels_masks_lifted_vs_nn": _pr(ref_dyn, nn_dynamic)}
    if app_dynamic is not None:
        lift["appearance"] = _pr(dyn, app_dynamic)
        lift["labels_masks_lifted_vs_appearance"] = _pr(ref_dyn, app_dynamic)
        lift["ceiling: appearance_vs_nn"] = _pr(app_dynamic, nn_dynamic)
    for key, v in lift.items():
        print(f"lift {key:36s} precision {v['precision']:.3f}  recall {v['recall']:.3f}  "
              f"({v['lifted']} lifted, {v['truth']} dynamic)")
    print("seconds " + "  ".join(f"{k} {v:.1f}" for k, v in seconds.items()))
    if args.json:
        print(json.dumps({"scene": str(scene), "backend": cfg.backend, "views": views, "summary": summary,
                          "lift": lift, "lift_info": lift_info,
                          "ground": None if ground is None else ground.to_dict(),
                          "seconds": {k: round(v, 2) for k, v in seconds.items()}}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
