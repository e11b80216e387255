"""The evaluation suite: every metric of one (scene, method, variant), as the ``eval`` stage writes it.

:func:`evaluate_variant` takes two typed sets of inputs, every one optional (a metric whose inputs are
missing is written as not available with the reason):

- :class:`ClipInputs`, the clips half: the method's camera-fixed clips (``.npz`` from
  :mod:`anigs.video`, or ``.mp4``; directories are searched recursively); the masks stage's
  folder (each view's dynamic mask, matched to clips by file stem); per prior the reference clips
  of its ``generate`` (FVD-PRIOR and FID-PRIOR), and FID's own reference where it differs (the
  paper pools the generated frames of all scenes for FID).
- :class:`ModelInputs`, the model half: the animated model and its canonical PLY (multiview
  protocol, ground-truth motion comparison); the training cameras, the capture images (named by
  camera) and the SfM points (``xyz``, ``rgb``) of the multiview protocol; the capture stage's
  folder with the synthetic ground truth (motion statistics).

The schema of the output is documented in :mod:`anigs.reports.tables`.
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from anigs.contract import CaptureFiles, MaskFiles
from anigs.device import get_device, seed_everything
from anigs.metrics import metric_record, not_available
from anigs.metrics.config import EvalConfig
from anigs.metrics.features import (INCEPTION_HINT, Unavailable, describe_i3d, i3d_features, inception_features,
                                    load_detector, load_i3d_detector, pool_frames, sample_windows)
from anigs.metrics.frechet import frechet_distance
from anigs.metrics.model_metrics import gt_metrics, multiview_metrics
from anigs.metrics.motion import clip_motion_metrics, outside_mask_still, resize_mask
from anigs.metrics.still_labels import moving_labelled_still
from anigs.metrics.vbench import vbench_metrics
from anigs.video import check_clip, load_clip, read_mp4

log = logging.getLogger("anigs.eval")


# ----------------------------------------------------------------------------- inputs

def find_clip_files(paths: list[str | Path]) -> list[Path]:
    """Clip files from files and directories (recursive): ``.npz`` clips (with ``frames``), and
    ``.mp4`` files that have no ``.npz`` of the same stem next to them."""
    out: list[Path] = []
    for p in map(Path, paths):
        if p.is_dir():
            files = sorted(p.rglob("*.npz")) + sorted(p.rglob("*.mp4"))
        elif p.exists():
            files = [p]
        else:
            raise FileNotFoundError(f"clip path not found: {p}")
        for f in files:
            if f.suffix == ".npz":
                with np.load(f, allow_pickle=False) as z:
                    if "frames" not in z.files:
                        continue  # not a clip (e.g. points.npz)
            elif f.suffix == ".mp4" and f.with_suffix(".npz") in out:
                continue
            out.append(f)
    return out


def find_clips(paths: list[str | Path]) -> dict[str, Path]:
    """Clip files by view name (file stem); two different clips with one stem are an error."""
    found: dict[str, Path] = {}
    for f in find_clip_files(paths):
        if f.stem in found:
            raise ValueError(f"two clips for view {f.stem!r}: {found[f.stem]} and {f}; "
                             "pass the folders of one method's camera-fixed clips only")
        found[f.stem] = f
    return dict(sorted(found.items()))


def load_any_clip(path: Path) -> np.ndarray:
    if path.suffix == ".mp4":
        return check_clip(read_mp4(path), str(path))
    return load_clip(path)[0]


def clip_fps(path: Path, default: float = 8.0) -> float:
    """The playback rate a clip file records (``meta.fps`` of an ``.npz`` clip), else ``default``
    (VBench's sampling rate: the dynamic-degree proxy then compares consecutive frames)."""
    if path.suffix == ".npz":
        import json

        with np.load(path, allow_pickle=False) as z:  # lazy: only the meta entry is read
            fps = json.loads(str(z["meta"])).get("fps") if "meta" in z.files else None
        return float(fps) if fps else float(default)
    return float(default)


def load_mask_for(view: str, masks: MaskFiles | None, height: int, width: int,
                  threshold: float) -> np.ndarray | None:
    """``view``'s dynamic mask from the masks stage's folder, resized to ``height`` x ``width``
    (bool [H,W]); None without masks or without a mask for that view."""
    if masks is None:
        return None
    return resize_mask(masks.view_mask(view), height, width, threshold) if masks.has_view_mask(view) else None


# ----------------------------------------------------------------------------- metric groups

def weightfree_metrics(clips: dict[str, np.ndarray], masks: MaskFiles | None, cfg: EvalConfig) -> dict[str, Any]:
    """Per-view weight-free metrics, averaged over views with a mask."""
    names = {"static_abs_diff": (False, "intensity/frame"), "static_drift": (False, "intensity"),
             "static_flow": (False, "px/frame"), "dynamic_abs_diff": (True, "intensity/frame"),
             "dynamic_flow": (True, "px/frame"), "dominant_freq": (True, "cycles/frame"),
             "spectral_centroid": (True, "cycles/frame"), "static_outside_mask_still": (True, "fraction")}
    protocol = {"flow": f"OpenCV DIS {cfg.flow_preset}, grey, consecutive frames", "mask_margin_px": cfg.mask_margin_px,
                "spectrum": "Hann window, per-pixel mean removed, DC excluded, mean power over dynamic pixels",
                "still": f"pixels outside the mask dilated by {cfg.still_margin_px} px whose change from frame 0 "
                         f"stays <= {cfg.still_tolerance:.5f} over the clip", "aggregate": "mean over views"}
    if not clips:
        return {k: not_available("no rendered clips given (--final-dir / --clips)", hib, u, protocol)
                for k, (hib, u) in names.items()}
    if masks is None:
        return {k: not_available("no dynamic masks given (--masks)", hib, u, protocol) for k, (hib, u) in names.items()}
    per_view: dict[str, dict[str, Any]] = {}
    missing = []
    for view, clip in clips.items():
        mask = load_mask_for(view, masks, clip.shape[1], clip.shape[2], cfg.mask_threshold)
        if mask is None:
            missing.append(view)
            continue
        per_view[view] = clip_motion_metrics(clip, mask, cfg.mask_margin_px, cfg.flow_preset).to_dict()
        per_view[view]["static_outside_mask_still"] = outside_mask_still(clip, mask, cfg.still_margin_px,
                                                                         cfg.still_tolerance)
    out = {}
    warn = [f"no mask for views {missing} in {masks.root}"] if missing else []
    for k, (hib, unit) in names.items():
        vals = [v[k] for v in per_view.values() if np.isfinite(v[k])]
        samples = {"views": len(vals), "frames": int(sum(v["frames"] for v in per_view.values()))}
        if not per_view:
            out[k] = not_available(f"no mask in {masks.root} matches any clip ({sorted(clips)})", hib, unit, protocol)
        elif not vals:
            out[k] = not_available("region empty or clips too short in every view", hib, unit, protocol, samples)
        else:
            out[k] = metric_record(float(np.mean(vals)), hib, unit, protocol, samples, warn,
                                   per_view={v: d[k] for v, d in per_view.items()})
    return out


def frechet_metrics(kind: str, clips: dict[str, np.ndarray], references: dict[str, list[np.ndarray]],
                    cfg: EvalConfig, device) -> dict[str, Any]:
    """FVD-<prior> or FID-<prior> records for every reference prior."""
    if kind == "fvd":
        path, hint, what = cfg.i3d_path, "", "FVD (I3D)"
        protocol = {"network": "I3D (Kinetics-400), return_features=True, rescale=False",
                    "input": f"short side resized to {cfg.fvd_crop_size}, centre crop {cfg.fvd_crop_size}^2, [-1,1]",
                    "detector_resize": cfg.fvd_detector_resize, "window_frames": cfg.fvd_clip_frames,
                    "window_stride": cfg.fvd_window_stride, "max_clips": cfg.fvd_max_clips,
                    "min_frames": cfg.fvd_min_frames, "weights": str(path)}
    else:
        path, hint, what = cfg.inception_path, INCEPTION_HINT, "FID (Inception)"
        protocol = {"network": "Inception-v3 TorchScript pool features, return_features=True",
                    "input": f"frames resized to {cfg.fid_size}^2 (bicubic), [0,255]", "max_frames": cfg.fid_max_frames,
                    "weights": str(path)}
    if not references:
        return {}
    out: dict[str, Any] = {}
    if not clips:
        return {f"{kind}/{p}": not_available("no rendered clips given", False, "", protocol) for p in references}
    det = load_i3d_detector(path, device) if kind == "fvd" else load_detector(path, what, hint, device)
    if kind == "fvd" and not isinstance(det, Unavailable):
        protocol.update({k: v for k, v in describe_i3d(det).items() if v})
    if isinstance(det, Unavailable):
        return {f"{kind}/{p}": not_available(det.reason, False, "", protocol, expected_path=det.expected_path)
                for p in references}

    def feats(cl: list[np.ndarray]) -> np.ndarray:
        if kind == "fvd":
            wins = sample_windows(cl, cfg.fvd_clip_frames, cfg.fvd_window_stride, cfg.fvd_max_clips)
            f, _ = i3d_features(det, wins, cfg.fvd_crop_size, cfg.fvd_min_frames, cfg.fvd_detector_resize,
                                cfg.batch_size, device)
            return f
        return inception_features(det, pool_frames(cl, cfg.fid_max_frames), cfg.fid_size, cfg.batch_size * 4, device)

    t0 = time.perf_counter()
    test = feats(list(clips.values()))
    for prior, ref_clips in references.items():
        t1 = time.perf_counter()
        try:
            ref = feats(ref_clips)
            res = frechet_distance(test, ref)
        except ValueError as exc:  # e.g. fewer than 2 samples on a side
            out[f"{kind}/{prior}"] = not_available(str(exc), False, "", protocol,
                                                   {"test": len(test), "reference": len(ref_clips)})
            continue
        out[f"{kind}/{prior}"] = metric_record(
            res.value, False, "", dict(protocol, eps_used=res.eps_used,
                                       seconds=round(time.perf_counter() - t1 + (t1 - t0), 3)),
            {"test": res.n1, "reference": res.n2}, res.warnings, feature_dim=res.dim, undersampled=res.undersampled)
    return out


def _load_references(references: dict[str, list[str | Path]] | None) -> dict[str, list[np.ndarray]]:
    refs: dict[str, list[np.ndarray]] = {}
    for prior, paths in (references or {}).items():
        paths = [paths] if isinstance(paths, (str, Path)) else list(paths)
        files = find_clip_files(paths)
        if not files:
            raise FileNotFoundError(f"no reference clips for prior {prior!r} in {[str(p) for p in paths]}")
        refs[prior] = [load_any_clip(f) for f in files]
    return refs


EVAL_PARTS = ("all", "clips", "model")


@dataclass(frozen=True)
class ClipInputs:
    """What the clips half of :func:`evaluate_variant` reads.

    ``clips``: clip files or folders; ``masks``: the masks stage's folder; ``references``: prior ->
    clip files/folders (FVD-prior, and FID-prior unless ``fid_references`` names other clips for
    that prior, e.g. frames pooled over all scenes as in the paper)."""

    clips: list[str | Path] = field(default_factory=list)
    masks: MaskFiles | None = None
    references: dict[str, list[str | Path]] = field(default_factory=dict)
    fid_references: dict[str, list[str | Path]] = field(default_factory=dict)


@dataclass(frozen=True)
class ModelInputs:
    """What the model half of :func:`evaluate_variant` reads: the animated model (``model.pt``) and its
    canonical PLY, the training cameras (``cameras.json``), the capture images and the SfM points
    (``points.npz``) of the multiview protocol, and ``truth``, the capture stage's folder with the
    synthetic ground truth (None on photo scenes)."""

    model: Path | None = None
    canonical: Path | None = None
    cameras: Path | None = None
    images: Path | None = None
    points: Path | None = None
    truth: CaptureFiles | None = None


def evaluate_variant(cfg: EvalConfig, clips: ClipInputs | None = None, model: ModelInputs | None = None,
             part: str = "all") -> dict[str, Any]:
    """Compute every metric whose inputs are given; returns the ``metrics`` mapping of metrics.json.

    ``part``: ``all``; ``clips`` (the metrics of the final clips: weight-free, FVD, FID) or
    ``model`` (those of the model: ground-truth motion, the multiview protocol), so that the two
    halves can run as separate jobs (the model's beside the final renders; the eval stage merges
    the two parts).
    """
    if part not in EVAL_PARTS:
        raise ValueError(f"eval: part must be one of {EVAL_PARTS}, got {part!r}")
    seed_everything(cfg.seed)
    device = get_device(cfg.device)
    c = clips or ClipInputs()
    m = model or ModelInputs()
    metrics: dict[str, Any] = {}
    if part in ("all", "clips"):
        clip_files = find_clips(c.clips) if c.clips else {}
        frames = {v: load_any_clip(p) for v, p in clip_files.items()}
        log.info("eval: %d clips %s", len(frames), list(frames))
        refs = _load_references(c.references)
        fid_refs = dict(refs)
        fid_refs.update(_load_references(c.fid_references))
        t0 = time.perf_counter()
        metrics.update(weightfree_metrics(frames, c.masks, cfg))
        metrics.update(vbench_metrics(frames, {v: clip_fps(p) for v, p in clip_files.items()},
                                      cfg.flow_preset))
        log.info("eval: weight-free metrics %.1f s", time.perf_counter() - t0)
        for kind, r in (("fvd", refs), ("fid", fid_refs)):
            t0 = time.perf_counter()
            metrics.update(frechet_metrics(kind, frames, r, cfg, device))
            log.info("eval: %s %.1f s", kind, time.perf_counter() - t0)
    if part in ("all", "model"):
        t0 = time.perf_counter()
        seed_everything(cfg.seed)  # the same draws whether or not the clips' half ran first
        metrics.update(gt_metrics(m.model, m.canonical, m.truth, m.cameras))
        metrics.update(moving_labelled_still(m.model, m.canonical, m.truth, m.cameras))
        metrics.update(multiview_metrics(cfg, m.model, m.canonical, m.cameras, m.images, m.points, device))
        log.info("eval: model-based metrics %.1f s", time.perf_counter() - t0)
    return metrics
