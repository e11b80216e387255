"""``anigs eval``: every metric of one (scene, method, variant) into ``metrics.json``.

Inputs (all optional except ``--out``; a metric whose inputs are missing is written as not
available with the reason):

- ``--final-dir DIR`` / ``--clips PATH ...``: the method's camera-fixed clips (``.npz`` from
  :mod:`anigs.video`, or ``.mp4``); directories are searched recursively.
- ``--masks DIR``: dynamic masks ``<view>.png`` (or ``.npy``) matched to clips by file stem.
- ``--reference PRIOR=PATH`` (repeatable; paths of one prior pool): the prior's ``generate``
  clips (FVD-PRIOR and FID-PRIOR); ``--fid-reference PRIOR=PATH`` gives FID its own reference
  (the paper pools the generated frames of all scenes for FID).
- ``--model model.pt --canonical canonical.ply``: the animated model (multiview protocol and
  ground-truth motion comparison).
- ``--cameras cameras.json --images DIR --points points.npz``: the training cameras, the
  capture images (named by camera) and the SfM points (``xyz``, ``rgb``): multiview protocol.
- ``--gt-dir results/{scene}/capture/gt``: synthetic ground truth (motion statistics).

The schema of the output is documented in :mod:`anigs.tables`.
"""
from __future__ import annotations

import argparse
import dataclasses
import logging
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from anigs.configs import reject_unknown_keys
from anigs.metrics import metric_record, not_available

log = logging.getLogger("anigs.eval")


@dataclass
class EvalConfig:
    """The ``eval`` config section."""

    device: str = "auto"  # torch device for the feature networks and the multiview fit
    i3d_path: str = ""  # local I3D TorchScript (StyleGAN-V i3d_torchscript.pt); "" = FVD not available
    inception_path: str = ""  # local Inception TorchScript (inception-2015-12-05.pt); "" = FID not available
    fvd_crop_size: int = 256  # clips resized (short side) and centre-cropped to this square
    fvd_clip_frames: int = 16  # frames per FVD sample window (0 = whole clips)
    fvd_window_stride: int = 8  # stride between windows of one clip
    fvd_max_clips: int = 250  # windows per side at most (paper: 250 clips)
    fvd_min_frames: int = 10  # shorter windows are padded by repeating the last frame
    fvd_detector_resize: bool = False  # let the I3D file resize to 224 itself (StyleGAN-V flavour)
    fid_size: int = 299  # Inception input size
    fid_max_frames: int = 2000  # frames per side at most (evenly subsampled)
    batch_size: int = 4  # network batch size
    flow_preset: str = "medium"  # OpenCV DIS preset: ultrafast | fast | medium
    mask_margin_px: int = 2  # dynamic mask dilated by this before taking the static region
    mask_threshold: float = 0.5  # soft / resized masks: dynamic where >= threshold
    multiview: bool = True  # run the Table-3 protocol when its inputs are given
    multiview_capture: bool = True  # also the reference row on the original capture images
    multiview_t: int | None = None  # novel timestep (None = the paper's 21/120 of the clip)
    multiview_train_fraction: float = 0.5  # cameras used for the fit; the rest evaluate
    multiview_split: str = "alternate"  # alternate | random
    multiview_max_cameras: int = 0  # evenly subsample the cameras to at most this many (0 = all)
    multiview_scale: float = 1.0  # image/camera scale for the protocol (speed)
    multiview_fit: dict[str, Any] = field(default_factory=dict)  # anigs.fit.FitConfig keys for the fresh fit
    seed: int = 0

    @staticmethod
    def from_dict(d: dict[str, Any] | None) -> "EvalConfig":
        d = dict(d or {})
        reject_unknown_keys(EvalConfig, d, "eval config", ValueError)
        cfg = EvalConfig(**d)
        cfg.validate()
        return cfg

    def validate(self) -> None:
        from anigs.metrics.motion import FLOW_PRESETS

        if self.flow_preset not in FLOW_PRESETS:
            raise ValueError(f"eval.flow_preset must be one of {FLOW_PRESETS}, got {self.flow_preset!r}")
        for k in ("fvd_crop_size", "fid_size", "batch_size", "fvd_window_stride"):
            if getattr(self, k) < 1:
                raise ValueError(f"eval.{k} must be >= 1, got {getattr(self, k)}")
        for k in ("fvd_clip_frames", "fvd_max_clips", "fvd_min_frames", "fid_max_frames", "mask_margin_px",
                  "multiview_max_cameras"):
            if getattr(self, k) < 0:
                raise ValueError(f"eval.{k} must be >= 0, got {getattr(self, k)}")
        if not 0 < self.multiview_train_fraction < 1:
            raise ValueError(f"eval.multiview_train_fraction must be in (0,1), got {self.multiview_train_fraction}")
        if self.multiview_split not in ("alternate", "random"):
            raise ValueError(f"eval.multiview_split must be 'alternate' or 'random', got {self.multiview_split!r}")
        if not 0 < self.multiview_scale <= 1:
            raise ValueError(f"eval.multiview_scale must be in (0,1], got {self.multiview_scale}")
        if not 0 < self.mask_threshold <= 1:
            raise ValueError(f"eval.mask_threshold must be in (0,1], got {self.mask_threshold}")


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
    from anigs.video import check_clip, load_clip, read_mp4

    if path.suffix == ".mp4":
        return check_clip(read_mp4(path), str(path))
    return load_clip(path)[0]


def load_mask_for(view: str, mask_dir: Path | None, height: int, width: int, threshold: float) -> np.ndarray | None:
    from anigs.metrics.motion import resize_mask

    if mask_dir is None:
        return None
    for ext in (".png", ".npy"):
        p = mask_dir / f"{view}{ext}"
        if p.exists():
            if ext == ".npy":
                m = np.load(p)
            else:
                import imageio.v2 as imageio

                m = np.asarray(imageio.imread(p))
            return resize_mask(m, height, width, threshold)
    return None


# ----------------------------------------------------------------------------- metric groups

def weightfree_metrics(clips: dict[str, np.ndarray], mask_dir: Path | None, cfg: EvalConfig) -> dict[str, Any]:
    """Per-view weight-free metrics, averaged over views with a mask."""
    from anigs.metrics.motion import clip_motion_metrics

    names = {"static_abs_diff": (False, "intensity/frame"), "static_drift": (False, "intensity"),
             "static_flow": (False, "px/frame"), "dynamic_abs_diff": (True, "intensity/frame"),
             "dynamic_flow": (True, "px/frame"), "dominant_freq": (True, "cycles/frame"),
             "spectral_centroid": (True, "cycles/frame")}
    protocol = {"flow": f"OpenCV DIS {cfg.flow_preset}, grey, consecutive frames", "mask_margin_px": cfg.mask_margin_px,
                "spectrum": "Hann window, per-pixel mean removed, DC excluded, mean power over dynamic pixels",
                "aggregate": "mean over views"}
    if not clips:
        return {k: not_available("no rendered clips given (--final-dir / --clips)", hib, u, protocol)
                for k, (hib, u) in names.items()}
    if mask_dir is None:
        return {k: not_available("no dynamic masks given (--masks)", hib, u, protocol) for k, (hib, u) in names.items()}
    per_view: dict[str, dict[str, Any]] = {}
    missing = []
    for view, clip in clips.items():
        mask = load_mask_for(view, mask_dir, clip.shape[1], clip.shape[2], cfg.mask_threshold)
        if mask is None:
            missing.append(view)
            continue
        per_view[view] = clip_motion_metrics(clip, mask, cfg.mask_margin_px, cfg.flow_preset).to_dict()
    out = {}
    warn = [f"no mask for views {missing} in {mask_dir}"] if missing else []
    for k, (hib, unit) in names.items():
        vals = [v[k] for v in per_view.values() if np.isfinite(v[k])]
        samples = {"views": len(vals), "frames": int(sum(v["frames"] for v in per_view.values()))}
        if not per_view:
            out[k] = not_available(f"no mask in {mask_dir} matches any clip ({sorted(clips)})", hib, unit, protocol)
        elif not vals:
            out[k] = not_available("region empty or clips too short in every view", hib, unit, protocol, samples)
        else:
            out[k] = metric_record(float(np.mean(vals)), hib, unit, protocol, samples, warn,
                                   per_view={v: d[k] for v, d in per_view.items()})
    return out


def frechet_metrics(kind: str, clips: dict[str, np.ndarray], references: dict[str, list[np.ndarray]],
                    cfg: EvalConfig, device) -> dict[str, Any]:
    """FVD-<prior> or FID-<prior> records for every reference prior."""
    from anigs.metrics.features import (
        I3D_HINT,
        INCEPTION_HINT,
        Unavailable,
        i3d_features,
        inception_features,
        load_detector,
        pool_frames,
        sample_windows,
    )
    from anigs.metrics.frechet import frechet_distance

    if kind == "fvd":
        path, hint, what = cfg.i3d_path, I3D_HINT, "FVD (I3D)"
        protocol = {"network": "I3D TorchScript (Kinetics-400), return_features=True, rescale=False",
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
    det = load_detector(path, what, hint, device)
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


def gt_metrics(model: Path | None, canonical: Path | None, gt_dir: Path | None, cameras: Path | None) -> dict[str, Any]:
    """Learned vs ground-truth motion statistics (synthetic scene)."""
    import torch

    from anigs.metrics.motion import gt_motion_distances

    keys = {"gt/rms_amplitude_ratio": (None, ""), "gt/amplitude_w1": (False, "scene extent"),
            "gt/frequency_w1": (False, "cycles/frame"), "gt/dominant_freq_learned": (None, "cycles/frame"),
            "gt/dominant_freq_gt": (None, "cycles/frame")}
    protocol = {"amplitude": "per-Gaussian RMS distance from its temporal mean / scene extent (1.1 x max camera "
                             "distance from the mean camera centre, learned and GT frames each)",
                "frequency": "per-Gaussian dominant frequency of the displacement (Hann, DC excluded)",
                "distances": "1-Wasserstein between distributions; ratio of RMS amplitudes (1 = ideal)"}

    def na(reason: str) -> dict[str, Any]:
        return {k: not_available(reason, bool(h), u, protocol) for k, (h, u) in keys.items()}

    if gt_dir is None:
        return {}
    if model is None or canonical is None:
        return na("needs --model and --canonical (the learned animation)")
    from anigs.cameras import load_cameras
    from anigs.deform import load_model
    from anigs.fit import scene_extent
    from anigs.gaussians import Gaussians
    from anigs.io import read_json
    from anigs.synth.motion import MotionParams, gt_clip_offsets

    canon, deformation, _ = load_model(model, canonical)
    if deformation.num_dynamic == 0:
        return na("the learned model has no dynamic Gaussians")
    T = deformation.num_frames
    learned = deformation.trajectories(canon.means, torch.arange(T)).detach().permute(1, 0, 2).double().numpy()
    gt_g = Gaussians.load_ply(gt_dir / "gaussians.ply")
    labels = np.load(gt_dir / "labels.npy")
    anchors = np.load(gt_dir / "anchors.npy")
    params = MotionParams.from_dict(read_json(gt_dir / "motion.json")["params"])
    off = gt_clip_offsets(params, gt_g.means, torch.as_tensor(anchors), torch.as_tensor(labels).long())  # [T',N,3]
    moving = off.abs().amax(dim=(0, 2)) > 0
    gt_traj = (gt_g.means[moving][None] + off[:, moving]).permute(1, 0, 2).double().numpy()
    if cameras is None:
        return na("needs --cameras (learned frame) to make amplitudes scale-free")
    ext_l = scene_extent(load_cameras(cameras))
    ext_g = scene_extent(load_cameras(gt_dir / "cameras.json"))
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
    import imageio.v2 as imageio

    imgs = []
    for cam in cameras:
        cands = [image_dir / cam.name, image_dir / f"{cam.name}.png", image_dir / f"{Path(cam.name).stem}.png",
                 image_dir / f"{Path(cam.name).stem}.jpg"]
        p = next((c for c in cands if c.is_file()), None)
        if p is None:
            raise FileNotFoundError(f"no capture image for camera {cam.name!r} in {image_dir}")
        img = np.asarray(imageio.imread(p))[..., :3].astype(np.float32) / 255.0
        imgs.append(img)
    return imgs


def _resize(img: np.ndarray, w: int, h: int) -> np.ndarray:
    import cv2

    return img if img.shape[:2] == (h, w) else cv2.resize(img, (w, h), interpolation=cv2.INTER_AREA)


def multiview_metrics(cfg: EvalConfig, model: Path | None, canonical: Path | None, cameras_path: Path | None,
                      image_dir: Path | None, points_path: Path | None, device) -> dict[str, Any]:
    """Table-3 protocol: fresh static fit at a novel time (and on the capture), PSNR on held-out cameras."""
    import torch

    from anigs.cameras import load_cameras
    from anigs.metrics.multiview import multiview_consistency, novel_timestep, static_fit_fn

    protocol = {"split": cfg.multiview_split, "train_fraction": cfg.multiview_train_fraction,
                "max_cameras": cfg.multiview_max_cameras, "scale": cfg.multiview_scale, "fit": cfg.multiview_fit,
                "psnr": "mean over held-out cameras"}
    keys = ["multiview/psnr_novel", "multiview/ssim_novel"] + (
        ["multiview/psnr_capture", "multiview/ssim_capture"] if cfg.multiview_capture else [])
    if not cfg.multiview:
        return {}
    missing = [n for n, v in (("--cameras", cameras_path), ("--points", points_path)) if v is None]
    if missing:
        return {k: not_available(f"multiview protocol needs {' and '.join(missing)}", True, "dB", protocol) for k in keys}
    try:
        fit, background = static_fit_fn(dict(cfg.multiview_fit, device=cfg.multiview_fit.get("device", cfg.device)))
    except ModuleNotFoundError as exc:
        return {k: not_available(f"static fit unavailable: {exc}", True, "dB", protocol) for k in keys}
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
    from anigs.animated import render_frame
    from anigs.deform import load_model

    canon, deformation, _ = load_model(model, canonical)
    t = novel_timestep(deformation.num_frames, cfg.multiview_t)
    with torch.no_grad():
        imgs = [render_frame(canon, deformation, c, t, background=background).clamp(0, 1).cpu().numpy()
                for c in scaled]
    records("novel", multiview_consistency(imgs, scaled, fit, pts, cols, **common),
            {"t": t, "num_frames": deformation.num_frames})
    return out


# ----------------------------------------------------------------------------- entry points

def _load_references(references: dict[str, list[str | Path]] | None) -> dict[str, list[np.ndarray]]:
    refs: dict[str, list[np.ndarray]] = {}
    for prior, paths in (references or {}).items():
        paths = [paths] if isinstance(paths, (str, Path)) else list(paths)
        files = find_clip_files(paths)
        if not files:
            raise FileNotFoundError(f"no reference clips for prior {prior!r} in {[str(p) for p in paths]}")
        refs[prior] = [load_any_clip(f) for f in files]
    return refs


def evaluate(cfg: EvalConfig, clip_paths: list[str | Path], mask_dir: str | Path | None = None,
             references: dict[str, list[str | Path]] | None = None, model: str | Path | None = None,
             canonical: str | Path | None = None, cameras: str | Path | None = None,
             images: str | Path | None = None, points: str | Path | None = None,
             gt_dir: str | Path | None = None,
             fid_references: dict[str, list[str | Path]] | None = None) -> dict[str, Any]:
    """Compute every metric whose inputs are given; returns the ``metrics`` mapping of metrics.json.

    ``references``: prior -> clip files/folders (FVD-prior, and FID-prior unless
    ``fid_references`` names other clips for that prior, e.g. frames pooled over all scenes
    as in the paper).
    """
    from anigs.device import get_device, seed_everything

    seed_everything(cfg.seed)
    device = get_device(cfg.device)
    P = (lambda p: None if p in (None, "") else Path(p))
    clip_files = find_clips(clip_paths) if clip_paths else {}
    clips = {v: load_any_clip(p) for v, p in clip_files.items()}
    log.info("eval: %d clips %s", len(clips), list(clips))
    refs = _load_references(references)
    fid_refs = dict(refs)
    fid_refs.update(_load_references(fid_references))
    metrics: dict[str, Any] = {}
    t0 = time.perf_counter()
    metrics.update(weightfree_metrics(clips, P(mask_dir), cfg))
    log.info("eval: weight-free metrics %.1f s", time.perf_counter() - t0)
    for kind, r in (("fvd", refs), ("fid", fid_refs)):
        t0 = time.perf_counter()
        metrics.update(frechet_metrics(kind, clips, r, cfg, device))
        log.info("eval: %s %.1f s", kind, time.perf_counter() - t0)
    t0 = time.perf_counter()
    metrics.update(gt_metrics(P(model), P(canonical), P(gt_dir), P(cameras)))
    metrics.update(multiview_metrics(cfg, P(model), P(canonical), P(cameras), P(images), P(points), device))
    log.info("eval: model-based metrics %.1f s", time.perf_counter() - t0)
    return metrics


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--final-dir", help="folder with the method's camera-fixed clips (.npz/.mp4, recursive)")
    parser.add_argument("--clips", nargs="*", default=[], help="more clip files or folders")
    parser.add_argument("--masks", help="folder of dynamic masks <view>.png")
    parser.add_argument("--reference", action="append", default=[], metavar="PRIOR=PATH",
                        help="reference clips of a prior's generate (repeatable; repeated priors pool): FVD-/FID-PRIOR")
    parser.add_argument("--fid-reference", action="append", default=[], metavar="PRIOR=PATH",
                        help="FID reference clips instead of --reference for that prior (e.g. pooled over scenes)")
    parser.add_argument("--model", help="animated model.pt (multiview protocol, GT motion comparison)")
    parser.add_argument("--canonical", help="canonical.ply the model animates")
    parser.add_argument("--cameras", help="training cameras.json (multiview protocol, learned scene extent)")
    parser.add_argument("--images", help="capture images named by camera (multiview reference row)")
    parser.add_argument("--points", help="SfM points.npz (xyz, rgb) initialising the multiview fits")
    parser.add_argument("--gt-dir", help="synthetic ground truth folder (capture/gt)")
    parser.add_argument("--scene", required=True, help="scene name (table column)")
    parser.add_argument("--method", default="Ours", help="method name (table row)")
    parser.add_argument("--variant", default="full", help="ablation variant id (Table 5)")
    parser.add_argument("--dataset", default="anigs", help="scene group (one FVD table per dataset)")
    parser.add_argument("--out", required=True, help="metrics.json to write")
    parser.add_argument("--params", help="eval config section as JSON or @file")


def run(args: argparse.Namespace) -> int:
    from anigs import __version__
    from anigs.cli import parse_params
    from anigs.io import write_json
    from anigs.tables import SCHEMA

    cfg = EvalConfig.from_dict(parse_params(args.params))
    def pairs(items: list[str], opt: str) -> dict[str, list[str]]:
        out: dict[str, list[str]] = {}
        for item in items:
            if "=" not in item or not item.split("=", 1)[0].strip():
                raise ValueError(f"{opt} expects PRIOR=PATH, got {item!r}")
            prior, path = item.split("=", 1)
            out.setdefault(prior.strip(), []).append(path)
        return out

    refs = pairs(args.reference, "--reference")
    fid_refs = pairs(args.fid_reference, "--fid-reference")
    clip_paths = ([args.final_dir] if args.final_dir else []) + list(args.clips)
    t0 = time.perf_counter()
    metrics = evaluate(cfg, clip_paths, args.masks, refs, args.model, args.canonical, args.cameras, args.images,
                       args.points, args.gt_dir, fid_refs)
    record = {"schema": SCHEMA, "scene": args.scene, "dataset": args.dataset, "method": args.method,
              "variant": args.variant, "anigs_version": __version__, "config": dataclasses.asdict(cfg),
              "inputs": {"clips": clip_paths, "masks": args.masks, "reference": refs, "fid_reference": fid_refs, "model": args.model,
                         "canonical": args.canonical, "cameras": args.cameras, "images": args.images,
                         "points": args.points, "gt_dir": args.gt_dir},
              "seconds": round(time.perf_counter() - t0, 2), "metrics": metrics}
    write_json(args.out, record)
    n_ok = sum(1 for m in metrics.values() if m["available"])
    log.info("eval: %d/%d metrics available -> %s", n_ok, len(metrics), args.out)
    for name, m in metrics.items():
        log.info("  %-26s %s", name, f"{m['value']:.4g}" if m["available"] else f"n/a ({m['reason']})")
    return 0
