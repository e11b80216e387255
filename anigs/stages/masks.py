"""Stage ``masks``: dynamic-region mask per queued view, and the masks lifted to 3D.

For each view of ``views.json`` the first frame is rendered from the canonical model (or
read from ``--frames DIR``: ``{id}.png``, or ``{id}.npz`` clips whose frame 0 is used) and
segmented by the configured backend (``vegetation`` default, ``labels``, ``sam2``).

With ``--images DIR`` (the capture photos the canonical model was fitted to, named after the
cameras of ``--cameras``) the backend also segments the photos (depth and alpha for the
ground cue rendered from the canonical model at each capture camera; the vegetation ground
cut there is ``capture_ground_layer`` times the measured layer: a training view sees the
fitted ground close to where it was fitted), and the lifting votes over the capture views and
the queued views together. A fitted Gaussian is judged by what it shows in the images it was
fitted to, in clean photos, not only in renders from new viewpoints (blurred, with floaters).

With ``complete_masks`` each queued view's mask is then completed with the pixels that the
lifted dynamic Gaussians dominate in that view (the render of the 3D set), so every Gaussian
that moves lies inside the masks the later stages composite with.

With ``contain`` (default) the dynamic set then keeps only the Gaussians whose footprint stays
inside every queued view's mask dilated by ``contain_margin_px`` (at most
``contain_max_outside_px`` of blending weight outside): halos, floaters and needles that reach
into the sky or the walls stay still instead of making them flicker (:mod:`anigs.masks.contain`).
The masks are not changed.

Writes to ``--out``: ``{id}.png`` (dynamic mask, 0/255), ``{id}_{effect}.png`` when the backend
gives several effect types, ``{id}_overlay.png``, ``dynamic.npy`` (bool [N] canonical Gaussians
lifted from the masks), with ``--effects`` ``effect_labels.npy`` (int8 [N]: which effect each
dynamic Gaussian belongs to, :mod:`anigs.masks.effect_labels`) and ``masks.json`` (per-view fractions; with ``--labels``: IoU of each
mask against the ground-truth label masks and precision/recall of the lifted Gaussians; with
``--gt-gaussians``, ``--gt-cameras`` and ``--cameras`` also against the appearance labels:
``iou_appearance`` per view and ``lift_appearance``, see :func:`anigs.masks.labels.appearance_labels`).
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

    backend: str = "effects"                   # effects (the effects stage's regions) | vegetation | labels | sam2
    background: list = field(default_factory=lambda: [0.62, 0.76, 0.92])  # render background (RGB)
    vegetation: dict = field(default_factory=dict)  # VegetationConfig keys
    labels: dict = field(default_factory=dict)      # {threshold, min_alpha} of the labels backend
    sam2: dict = field(default_factory=dict)        # Sam2Config keys
    lift: dict = field(default_factory=dict)        # LiftConfig keys
    per_effect: bool = True                    # write one mask per effect type when there are several
    compare: bool = True                       # with --labels: IoU / precision / recall vs ground truth
    appearance: bool = False                   # with --labels, --gt-*, --cameras: also vs appearance labels (a diagnostic: 0.25 s per photo, 12 s of the demo's 24 s masks job; benchmarks/masks.py reports it too)
    capture_ground_layer: float = 0.5          # with --images: vegetation ground_layer on the capture photos
    complete_masks: bool = True                # add the pixels the lifted dynamic Gaussians dominate to each mask
    contain: bool = True                       # move only the Gaussians whose footprint stays inside every view's dilated mask; halos and floaters stay still (anigs.masks.contain)
    contain_margin_px: int = 3                 # containment: each view's mask is dilated by this many pixels first (the still-pixel metric forgives 5)
    contain_max_outside_px: float = 0.05       # containment: most blending weight (in pixels) a moving Gaussian may put outside the dilated mask of any view

    @staticmethod
    def from_dict(d: dict | None) -> "MasksConfig":
        from anigs.typed_config import from_dict

        cfg = from_dict(MasksConfig, d, "masks config")
        if cfg.backend not in ("effects", "vegetation", "labels", "sam2"):
            raise ValueError(f"masks.backend must be effects, vegetation, labels or sam2, got {cfg.backend!r}")
        if len(cfg.background) != 3:
            raise ValueError(f"masks.background must be [r, g, b], got {cfg.background}")
        if cfg.capture_ground_layer < 0:
            raise ValueError(f"masks.capture_ground_layer must be >= 0, got {cfg.capture_ground_layer}")
        if cfg.contain_margin_px < 0 or not cfg.contain_max_outside_px >= 0:
            raise ValueError("masks.contain_margin_px and masks.contain_max_outside_px must be >= 0, got "
                             f"{cfg.contain_margin_px} and {cfg.contain_max_outside_px}")
        return cfg


Config = MasksConfig  # the `masks` config section


@dataclass
class MasksInputs:
    """What the masks stage reads (see the module docstring for each)."""

    canonical: str
    views: str
    out: str
    frames: str | None = None
    labels: str | None = None
    motion: str | None = None
    gt_gaussians: str | None = None
    gt_cameras: str | None = None
    cameras: str | None = None
    images: str | None = None
    effects: str | None = None


def _load_frames(frames_dir: str | None, g, cams, background) -> list:
    from anigs.images import load_image as read_rgb_png
    from anigs.masks import Frame, render_frames

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


def _read_effects(d: Path, g) -> tuple[list[str], np.ndarray]:
    """The effects stage's chosen effects and its region index per Gaussian (int64 [N], -1 none)."""
    chosen = list(read_json(d / "effects.json")["chosen"])
    regions = np.load(d / "regions.npy").astype(np.int64)
    if regions.shape != (g.num,):
        raise ValueError(f"{d}/regions.npy: shape {regions.shape} does not match the {g.num} Gaussians of the "
                         "canonical model (re-run the effects stage)")
    return chosen, regions


def _effects_backend(effects_dir: str | None, cfg: MasksConfig, g):
    """(backend rendering the chosen effects' Gaussian sets, their union [N]) from the effects stage."""
    from anigs.effects.config import EFFECT_REGION, REGIONS
    from anigs.masks.labels import LabelsBackend

    if not effects_dir:
        raise ValueError("masks.backend 'effects' needs --effects (the effects stage's folder)")
    d = Path(effects_dir)
    chosen, regions = _read_effects(d, g)
    dynamic = np.load(d / "dynamic.npy").astype(bool)
    if dynamic.shape != (g.num,):
        raise ValueError(f"{d}/dynamic.npy: shape {dynamic.shape} does not match the {g.num} Gaussians of the "
                         "canonical model (re-run the effects stage)")
    effects = {e: [REGIONS.index(EFFECT_REGION[e])] for e in chosen}
    return (LabelsBackend(g, regions, effects, **cfg.labels) if effects else None), dynamic


def _labels_backend(args: MasksInputs, cfg: MasksConfig, g, effects):
    """The labels backend (ground-truth Gaussians in their own frame, or the canonical set)."""
    from anigs.masks.labels import LabelsBackend
    from anigs.sfm.align import align_cameras

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


def _appearance_yardstick(args: MasksInputs, cfg: MasksConfig, g, effects, capture_cams, frames):
    """(dynamic flag [N] of the appearance labels, their label masks [H,W] per frame)."""
    from anigs.masks import compute_masks
    from anigs.masks.labels import LabelsBackend
    from anigs.render.labels import appearance_labels
    from anigs.sfm.align import align_cameras
    from anigs.synth.truth import dynamic_label_ids

    labels = np.load(args.labels)
    sim, _ = align_cameras(capture_cams, load_cameras(args.gt_cameras))
    app, _, _ = appearance_labels(g, load_ply(args.gt_gaussians), labels, capture_cams, to_labels_frame=sim)
    masks = [r["dynamic"] for r in compute_masks(LabelsBackend(g, app, effects, **cfg.labels), frames)]
    return np.isin(app, dynamic_label_ids(effects)), masks


def run(inputs: MasksInputs, cfg: MasksConfig) -> dict:
    """Write the masks of every queued view, the lifted dynamic set and ``masks.json``; returns its content."""
    from anigs.images import write_mask_png, write_rgb_png
    from anigs.masks import compute_masks, mask_iou
    from anigs.pixels import overlay
    from anigs.synth.truth import effects_from_motion
    from anigs.masks.lift import LiftConfig, lift_masks_report, precision_recall
    from anigs.geometry.ground import ground_plane as estimate_ground
    from anigs.masks.vegetation import VegetationConfig
    from anigs.views import cameras_from_views

    lift_cfg = LiftConfig.from_dict(cfg.lift)
    g = load_ply(inputs.canonical)
    data = read_json(inputs.views)
    cams = cameras_from_views(data)
    if not cams:
        raise ValueError(f"{inputs.views} lists no views")
    out = Path(inputs.out)
    effects = effects_from_motion(read_json(inputs.motion)) if inputs.motion else None
    if inputs.labels and effects is None:
        raise ValueError("--labels needs --motion motion.json to know which labels move")
    frames = _load_frames(inputs.frames, g, cams, cfg.background)

    info: dict = {"backend": cfg.backend, "views": []}
    veg = VegetationConfig.from_dict(cfg.vegetation)
    up = np.asarray(data.get("up", [0.0, 0.0, 1.0]), float)
    ground = estimate_ground(g.means.detach().double().numpy(), up, cams, veg.ground_margin) if veg.ground else None
    if ground is not None:
        info["ground_plane"] = ground.to_dict()
    effects_dynamic = None
    if cfg.backend == "effects":
        backend, effects_dynamic = _effects_backend(inputs.effects, cfg, g)
        if backend is None:  # the scene contains none of the effects: nothing moves
            backend = lambda fr: {"dynamic": np.zeros(fr.image.shape[:2], bool)}  # noqa: E731
    elif cfg.backend == "vegetation":
        from anigs.masks.vegetation import build

        backend = build(veg, ground=ground)
    elif cfg.backend == "labels":
        if not inputs.labels:
            raise ValueError("masks.backend 'labels' needs --labels (and --motion)")
        backend = _labels_backend(inputs, cfg, g, effects)
    else:
        from anigs.masks.sam2 import build

        backend = build(cfg.sam2, vegetation=cfg.vegetation or None)
    results = compute_masks(backend, frames)

    # the lifting votes over the queued views, and over the capture photos when given
    lift_cams, lift_in = [fr.camera for fr in frames], [r["dynamic"] for r in results]
    capture_cams = load_cameras(inputs.cameras) if inputs.cameras else None
    if inputs.images and effects_dynamic is None:  # (the effects stage's set is not lifted again)
        if capture_cams is None:
            raise ValueError("--images needs --cameras (the cameras of the capture photos, sfm/cameras.json)")
        from anigs.masks.capture import capture_frames

        cap_frames = capture_frames(inputs.images, capture_cams, g)
        cap_backend = backend
        if cfg.backend == "vegetation":
            from anigs.masks.vegetation import build

            cap_backend = build(dataclasses.replace(veg, ground_layer=cfg.capture_ground_layer), ground=ground)
        cap_masks = [r["dynamic"] for r in compute_masks(cap_backend, cap_frames)]
        lift_cams += [f.camera for f in cap_frames]
        lift_in += cap_masks
        info["capture"] = {"images": len(cap_frames), "fraction": float(np.mean([m.mean() for m in cap_masks]))}
        log.info("masks: %d capture photos segmented (dynamic %.1f%%), lifting over them too",
                 len(cap_frames), 100 * info["capture"]["fraction"])
    if effects_dynamic is not None:  # the region of interest is the effects stage's set, not lifted again
        dyn, lift_info = effects_dynamic, {"source": f"effects:{inputs.effects}", "num_dynamic": int(effects_dynamic.sum())}
    else:
        dyn, lift_info = lift_masks_report(g, lift_cams, lift_in, lift_cfg, ground=ground)
    info["lift"] = lift_info
    # the labels and effects backends' masks are renders of the dynamic set itself
    if cfg.complete_masks and cfg.backend not in ("labels", "effects"):
        from anigs.render.labels import dynamic_masks

        added = []
        for res, extra in zip(results, dynamic_masks(g, dyn, [fr.camera for fr in frames])):
            added.append(float((extra & ~res["dynamic"]).mean()))
            res["dynamic"] = res["dynamic"] | extra
        info["completed_fraction"] = added
    if cfg.contain:  # a Gaussian moves only if its footprint stays inside the (dilated) masks of every view
        from anigs.masks.contain import contain_dynamic

        before = dyn
        kept = contain_dynamic(g, dyn, [fr.camera for fr in frames], [r["dynamic"] for r in results],
                               cfg.contain_margin_px, cfg.contain_max_outside_px)
        dyn = kept.dynamic
        info["containment"] = kept.info(before, [fr.name for fr in frames], cfg.contain_margin_px,
                                        cfg.contain_max_outside_px)

    labels = None
    if inputs.effects:  # which effect each dynamic Gaussian belongs to; per-effect masks for every backend
        labels, info["effect_labels"], chosen = _effect_labels(Path(inputs.effects), dyn, g)
        if cfg.backend not in ("labels", "effects") and chosen:
            _add_effect_masks(g, labels, chosen, frames, results, cfg.labels)

    truth = app_truth = app_dynamic = None
    if inputs.labels and cfg.compare:
        truth = results if cfg.backend == "labels" else compute_masks(_labels_backend(inputs, cfg, g, effects), frames)
        if cfg.appearance and inputs.gt_gaussians and inputs.gt_cameras and capture_cams is not None:
            app_dynamic, app_truth = _appearance_yardstick(inputs, cfg, g, effects, capture_cams, frames)

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
        if app_truth is not None:
            entry["iou_appearance"] = mask_iou(m, app_truth[k])
        info["views"].append(entry)
        log.info("masks: %s dynamic %.1f%%%s%s", fr.name, 100 * m.mean(),
                 f" IoU vs labels {entry['iou_vs_labels']:.3f}" if truth is not None else "",
                 f" vs appearance {entry['iou_appearance']:.3f}" if app_truth is not None else "")
    for key, on in (("iou_vs_labels", truth is not None), ("iou_appearance", app_truth is not None)):
        if on:
            vals = [v[key] for v in info["views"]]
            info[key] = {"mean": float(np.mean(vals)), "min": float(np.min(vals))}

    if inputs.labels and cfg.compare:
        from anigs.masks.labels import roi_from_labels

        gt = roi_from_labels(g, inputs.labels, inputs.motion, None, inputs.gt_gaussians,
                             inputs.gt_cameras, capture_cams if capture_cams is not None else cams)
        info["lift_vs_labels"] = {**precision_recall(dyn, gt), "num_gt_dynamic": int(gt.sum()),
                                  "num_lifted": int(dyn.sum())}
        log.info("masks: lifted Gaussians vs labels: precision %.3f recall %.3f",
                 info["lift_vs_labels"]["precision"], info["lift_vs_labels"]["recall"])
        if app_dynamic is not None:
            info["lift_appearance"] = {**precision_recall(dyn, app_dynamic),
                                       "num_appearance_dynamic": int(app_dynamic.sum()), "num_lifted": int(dyn.sum())}
            log.info("masks: lifted Gaussians vs appearance labels: precision %.3f recall %.3f",
                     info["lift_appearance"]["precision"], info["lift_appearance"]["recall"])
    with atomic_path(out / "dynamic.npy") as tmp:
        with open(tmp, "wb") as fh:
            np.save(fh, dyn)
    if labels is not None:
        with atomic_path(out / "effect_labels.npy") as tmp:
            with open(tmp, "wb") as fh:
                np.save(fh, labels)
    info["config"] = dataclasses.asdict(cfg)
    write_json(out / "masks.json", info)
    log.info("masks: wrote %d masks, dynamic.npy (%d of %d Gaussians) to %s", len(frames), int(dyn.sum()), g.num, out)
    return info


def _effect_labels(effects_dir: Path, dyn: np.ndarray, g) -> tuple[np.ndarray, dict, list[str]]:
    """(int8 [N] effect labels of the dynamic set: 0 static, 1 + region index,
    :mod:`anigs.masks.effect_labels`; their counts for ``masks.json``; the chosen effects) from the
    effects stage's regions of its chosen effects."""
    from anigs.effects.config import REGIONS
    from anigs.effects.labels import effect_label_ids, effect_labels

    chosen, regions = _read_effects(effects_dir, g)
    chosen_regions = sorted({effect_label_ids()[e] - 1 for e in chosen})
    labels, counts = effect_labels(dyn, regions, chosen_regions, g.means.detach().double().numpy())
    counts["per_region"] = {REGIONS[k - 1]: int((labels == k).sum()) for k in range(1, len(REGIONS) + 1)}
    log.info("masks: effect labels of the %d dynamic Gaussians: %s (%d from the effects stage's regions, %d from "
             "the nearest labelled one)", int(dyn.sum()), counts["per_region"], counts["from_regions"], counts["nearest"])
    return labels, counts, chosen


def _add_effect_masks(g, labels: np.ndarray, chosen: list[str], frames, results: list[dict], opts: dict) -> None:
    """Per-effect masks for a backend that gives one dynamic mask (vegetation, sam2): the render of
    each chosen effect's dynamic Gaussians (by their effect label), within the backend's mask."""
    from anigs.effects.labels import effect_label_ids
    from anigs.masks.labels import LabelsBackend

    ids = effect_label_ids()
    backend = LabelsBackend(g, labels.astype(np.int64), {e: [ids[e]] for e in chosen}, **opts)
    for fr, res in zip(frames, results):
        for e, m in backend(fr).items():
            if e != "dynamic":
                res[e] = m & res["dynamic"]


# ---- command line: anigs masks ----

def add_arguments(p: argparse.ArgumentParser) -> None:
    from anigs.cli import add_params, add_canonical, add_out

    add_canonical(p)
    p.add_argument("--views", required=True, help="views.json from `anigs views`")
    add_out(p, "output folder")
    add_params(p, "masks")
    p.add_argument("--frames", help="folder with the first frames ({id}.png or {id}.npz clips); "
                                    "default: render the canonical model")
    p.add_argument("--labels", help="per-Gaussian labels .npy: labels backend and/or ground-truth comparison")
    p.add_argument("--motion", help="motion.json: which labels move, per effect type (with --labels)")
    p.add_argument("--gt-gaussians", help="PLY the labels belong to when it is not the canonical set")
    p.add_argument("--gt-cameras", help="cameras in the frame of --gt-gaussians (matched by name to --cameras)")
    p.add_argument("--cameras", help="the reconstruction's cameras (sfm/cameras.json), to align with --gt-cameras "
                                     "and to place the --images")
    p.add_argument("--effects", help="the effects stage's folder (effects.json, regions.npy, dynamic.npy): "
                                     "the effects backend renders its chosen effects' Gaussian sets")
    p.add_argument("--images", help="the capture photos (sfm/images, named after the --cameras): segmented too, and "
                                    "the lifting votes over them and the queued views")


def main(args: argparse.Namespace) -> int:
    from anigs.cli import parse_params

    inputs = MasksInputs(**{f.name: getattr(args, f.name) for f in dataclasses.fields(MasksInputs)})
    run(inputs, MasksConfig.from_dict(parse_params(args.params)))
    return 0
