"""Stage ``views``: incremental viewpoint expansion -> ``views.json`` + top-down PNG.

The regions of interest (dynamic canonical Gaussians) come from exactly one of:

``--dynamic DYN.npy``   bool/int [N] per canonical Gaussian;
``--labels L.npy``      per-Gaussian labels (synthetic scenes) with ``--motion motion.json``
                        (or params ``dynamic_labels``); labels of another Gaussian set
                        (``--gt-gaussians``) are transferred by nearest neighbour, after a
                        similarity alignment from ``--gt-cameras`` to ``--cameras`` when given;
``--masks-dir DIR``     2D masks of the candidate cameras (``{camera name}`` or ``{stem}.png``),
                        lifted to 3D;
``--images DIR``        the capture photos: ``vegetation`` masks are computed (with the
                        canonical depth for the ground cue) and lifted to 3D.

Writes ``OUT/views.json``, ``OUT/topdown.png`` and ``OUT/dynamic.npy`` (the ROI used).
Views whose dynamic region is negligible (``min_dynamic_fraction``, see :mod:`anigs.views`)
are not queued: ``views.json`` lists them under ``dynamic_fraction.dropped`` and numbers the
queued ones v00, v01, ... (:func:`anigs.views.queued_view_count` counts them). Under the
whole-scene fallback (no ROI) nothing is dropped.
"""
from __future__ import annotations

import argparse
import dataclasses
import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from anigs.cameras import Camera, load_cameras
from anigs.gaussians import Gaussians, load_ply
from anigs.io import atomic_path, write_json
from anigs.views import ViewsConfig

Config = ViewsConfig  # the `views` config section

log = logging.getLogger("anigs.views")



@dataclass
class ViewsInputs:
    """What the views stage reads: the canonical model, the candidate cameras, and exactly one
    source of the regions of interest (see the module docstring)."""

    canonical: str
    cameras: str
    out: str
    dynamic: str | None = None
    labels: str | None = None
    masks_dir: str | None = None
    images: str | None = None
    motion: str | None = None
    gt_gaussians: str | None = None
    gt_cameras: str | None = None
    points: str | None = None   # SfM points.npz (xyz): the content test's near-points part


def find_mask(masks_dir: Path, cam: Camera) -> Path | None:
    for name in (cam.name, Path(cam.name).stem + ".png", Path(cam.name).name):
        if name and (masks_dir / name).is_file():
            return masks_dir / name
    return None


def roi_from_masks(g: Gaussians, cameras: list[Camera], masks_dir: str | None, images_dir: str | None,
                   out: Path) -> tuple[np.ndarray, dict]:
    """Dynamic flag [N] lifted from 2D masks of the candidate cameras (read, or computed from photos)."""
    from anigs.images import read_mask_png
    from anigs.masks import compute_masks
    from anigs.cameras import camera_for_size
    from anigs.masks.capture import capture_frames
    from anigs.masks.lift import LiftConfig, lift_masks_report
    from anigs.geometry.ground import ground_plane as estimate_ground
    from anigs.masks.vegetation import VegetationConfig

    lift_cfg, veg_cfg = LiftConfig(), VegetationConfig()
    up = np.array([0.0, 0.0, 1.0])
    ground = estimate_ground(g.means.detach().double().numpy(), up, cameras, veg_cfg.ground_margin) \
        if veg_cfg.ground else None
    cams, masks = [], []
    if masks_dir:
        d = Path(masks_dir)
        if not d.is_dir():
            raise FileNotFoundError(f"--masks-dir not found: {d}")
        for cam in cameras:
            path = find_mask(d, cam)
            if path is None:
                log.warning("views: no mask for camera %s in %s: camera skipped", cam.name, d)
                continue
            m = read_mask_png(path)
            cams.append(camera_for_size(cam, *m.shape, what=f"mask {path}"))
            masks.append(m)
    else:
        frames = capture_frames(images_dir, cameras, g)
        masks = [m["dynamic"] for m in compute_masks("vegetation", frames, config=veg_cfg, ground=ground)]
        cams = [f.camera for f in frames]
    if not cams:
        raise ValueError(f"views: no masks could be matched to the {len(cameras)} cameras")
    roi, info = lift_masks_report(g, cams, masks, lift_cfg, ground=ground)
    log.info("views: lifted %d masks -> %d dynamic Gaussians (%s)", len(cams), int(roi.sum()), info)
    return roi, info


def run(inputs: ViewsInputs, cfg: ViewsConfig, dynamic_labels: list[int] | None = None) -> dict:
    """Place the view queue; writes ``views.json``, ``topdown.png`` and ``dynamic.npy`` and returns
    the ``views.json`` content. ``dynamic_labels``: with ``inputs.labels`` and no motion file,
    the label ids that move."""
    from anigs.views.topdown import save_topdown
    from anigs.views import plan_views

    g = load_ply(inputs.canonical)
    cameras = load_cameras(inputs.cameras)
    out = Path(inputs.out)
    lift_info = None
    if inputs.dynamic:
        roi = np.load(inputs.dynamic)
        if roi.shape != (g.num,):
            raise ValueError(f"--dynamic {inputs.dynamic} has shape {roi.shape}, the canonical set has {g.num} Gaussians")
        roi = roi.astype(bool)
        source = f"dynamic:{inputs.dynamic}"
    elif inputs.labels:
        from anigs.masks.labels import roi_from_labels

        roi = roi_from_labels(g, inputs.labels, inputs.motion, dynamic_labels, inputs.gt_gaussians,
                              inputs.gt_cameras, cameras)
        source = f"labels:{inputs.labels}"
    else:
        roi, lift_info = roi_from_masks(g, cameras, inputs.masks_dir, inputs.images, out)
        source = f"masks:{inputs.masks_dir or inputs.images}"
    log.info("views: %d of %d canonical Gaussians are regions of interest (%s)", int(roi.sum()), g.num, source)
    fallback = None
    if not roi.any():  # nothing moves: the views (for the still final renders) look at the whole scene
        fallback = (f"no region of interest ({source} marks none of the {g.num} Gaussians dynamic): "
                    "the views look at the whole scene, and nothing will move")
        log.warning("views: %s", fallback)
    points = None
    if inputs.points:
        from anigs.sfm.model import load_points

        points = load_points(inputs.points)[0]
    plan = plan_views(g, roi if roi.any() else np.ones_like(roi), cameras, cfg,
                      keep_all=None if fallback is None else "roi_fallback: the ROI is the whole scene",
                      points=points)
    out.mkdir(parents=True, exist_ok=True)
    payload = plan.to_json()
    payload.update({"roi_source": source, "num_gaussians": g.num, "num_roi": int(roi.sum()),
                    "roi_fallback": fallback, "config": {**cfg.__dict__}, "lift": lift_info})
    with atomic_path(out / "dynamic.npy") as tmp:
        with open(tmp, "wb") as fh:
            np.save(fh, roi)
    save_topdown(out / "topdown.png", plan, g.means.detach().double().numpy(), roi,
                 size=cfg.topdown_size)
    write_json(out / "views.json", payload)
    log.info("views: wrote %s (%d views queued%s), topdown.png, dynamic.npy", out / "views.json", len(plan.views),
             f", {len(plan.dropped)} dropped as negligible" if plan.dropped else "")
    return payload


# ---- command line: anigs views ----

def add_arguments(p: argparse.ArgumentParser) -> None:
    from anigs.cli import add_params, add_canonical, add_out

    add_canonical(p)
    p.add_argument("--cameras", required=True, help="candidate cameras JSON (sfm/cameras.json)")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--dynamic", help="bool/int .npy [N]: dynamic flag per canonical Gaussian")
    src.add_argument("--labels", help="per-Gaussian labels .npy (synthetic scenes, e.g. gt/labels.npy)")
    src.add_argument("--masks-dir", help="folder of 2D dynamic masks named after the cameras, lifted to 3D")
    src.add_argument("--images", help="capture images folder: vegetation masks are computed and lifted to 3D")
    p.add_argument("--motion", help="motion.json naming the moving labels (with --labels)")
    p.add_argument("--dynamic-labels", type=int, nargs="+", default=None,
                   help="label ids that move (with --labels, instead of --motion)")
    p.add_argument("--gt-gaussians", help="PLY the --labels belong to when it is not the canonical set")
    p.add_argument("--points", help="SfM points.npz (xyz): a sharp Gaussian lies near them (views.near_points)")
    p.add_argument("--gt-cameras", help="cameras in the frame of --gt-gaussians, matched by name to --cameras "
                                        "to align the frames (default: same frame)")
    add_out(p, "output folder (views.json, topdown.png, dynamic.npy)")
    add_params(p, "views")


def main(args: argparse.Namespace) -> int:
    from anigs.cli import parse_params

    cfg = ViewsConfig.from_dict(parse_params(args.params))  # the views section: nothing else
    inputs = ViewsInputs(**{f.name: getattr(args, f.name) for f in dataclasses.fields(ViewsInputs)})
    run(inputs, cfg, args.dynamic_labels)
    return 0
