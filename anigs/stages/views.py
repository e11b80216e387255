"""Stage ``views``: incremental viewpoint expansion -> ``views.json`` + top-down PNG.

The region of interest (the dynamic canonical Gaussians) comes from exactly one of:

``--effects DIR``       the effects stage's folder: its chosen effects' Gaussians (``dynamic``);
``--labels L.npy``      per-Gaussian labels (synthetic scenes) with ``--motion motion.json``;
                        labels of another Gaussian set (``--gt-gaussians``) are transferred by
                        nearest neighbour, after a similarity alignment from ``--gt-cameras`` to
                        ``--cameras`` when given.

Writes ``OUT/views.json`` and ``OUT/topdown.png`` (:class:`Outputs`).
Views whose dynamic region is negligible (``min_dynamic_fraction``, see :mod:`anigs.views`)
are not queued: ``views.json`` lists them under ``dynamic_fraction.dropped`` and numbers the
queued ones v00, v01, ... (:func:`anigs.stages.targets.queued_view_count` counts them). Under the
whole-scene fallback (no ROI) nothing is dropped.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from anigs.cameras import Camera, load_cameras
from anigs.gaussians import Gaussians, load_ply
from anigs.io import write_json
from anigs import contract
from anigs.contract import File
from anigs.stages.effects import Outputs as EffectsOutputs
from anigs.stages.sfm import Outputs as SfmOutputs
from anigs.stages.shared_inputs import GroundTruthInputs
from anigs.stages.targets import queued_view_count
from anigs.views import ViewsConfig, cameras_from_views, plan_views
from anigs.views.topdown import save_topdown

Config = ViewsConfig  # the `views` config section

log = logging.getLogger("anigs.views")


class Outputs(contract.Outputs):
    """The views stage's folder: the view queue."""

    LAYOUT = {
        "views": File("views.json", "the queue: per view id (v00, v01, ...), camera (OpenCV, the view's "
                                    "intrinsics and size), location, coverage, content; the dropped views, "
                                    "up, roi_centroid, the ROI's source, config"),
        "topdown": File("topdown.png", "uint8 RGB: top-down map of the ROI, the candidates and the queue"),
    }

    def report(self) -> dict:
        """``views.json``."""
        return self.json("views")

    def views(self) -> list[Camera]:
        """The queued views' cameras, in queue order, named by view id."""
        return cameras_from_views(self.report())

    def count(self) -> int:
        """The number of queued views (ids v00..v{n-1}; json only)."""
        return queued_view_count(self.path("views"))

    def view_ids(self) -> list[str]:
        """The queued view ids, v00, v01, ..."""
        return [f"v{i:02d}" for i in range(self.count())]



@dataclass
class Inputs(GroundTruthInputs):
    """What the views stage reads: the canonical model, the candidate cameras, and the region of
    interest: the effects stage's, or ground-truth labels (see the module docstring)."""

    cameras: Path = contract.upstream(SfmOutputs, "cameras", "candidate cameras JSON")
    out: Outputs = contract.output_folder(Outputs)
    effects: EffectsOutputs | None = field(default=None, metadata={
        "help": "the effects stage's folder: its dynamic set is the region of interest"})
    points: Path | None = contract.upstream(SfmOutputs, "points", "SfM points (xyz): a sharp Gaussian lies near "
                                            "them (views.near_points)", default=None)
    images: Path | None = contract.upstream(SfmOutputs, "images", "the photos the cameras describe: a view's moving "
                                            "region must be about as sharp as they show it "
                                            "(views.min_motion_sharpness)", default=None)


def region_of_interest(inputs: Inputs, g: Gaussians, cameras: list[Camera]) -> tuple[np.ndarray, str]:
    """(bool [N] region of interest, its source): the effects stage's set, or the labels' moving Gaussians."""
    if (inputs.effects is None) == (inputs.labels is None):
        raise ValueError("views: give exactly one region of interest: --effects DIR or --labels (with --motion)")
    if inputs.effects is not None:
        return inputs.effects.dynamic(g.num), f"effects:{inputs.effects.root}"
    from anigs.masks.labels_backend import roi_from_labels

    roi = roi_from_labels(g, inputs.labels, inputs.motion, None, inputs.gt_gaussians, inputs.gt_cameras, cameras)
    return roi, f"labels:{inputs.labels}"


def run(inputs: Inputs, cfg: ViewsConfig) -> Outputs:
    """Place the view queue around the region of interest; writes ``views.json`` and ``topdown.png``."""
    g = load_ply(inputs.canonical)
    cameras = load_cameras(inputs.cameras)
    roi, source = region_of_interest(inputs, g, cameras)
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
                      points=points, images=inputs.images)
    out = inputs.out
    out.root.mkdir(parents=True, exist_ok=True)
    payload = plan.to_json()
    payload.update({"roi_source": source, "num_gaussians": g.num, "num_roi": int(roi.sum()),
                    "roi_fallback": fallback, "config": {**cfg.__dict__}})
    save_topdown(out.path("topdown"), plan, g.means.detach().double().numpy(), roi, size=cfg.topdown_size)
    write_json(out.path("views"), payload)
    log.info("views: wrote %s (%d views queued%s), %s", out.path("views"), len(plan.views),
             f", {len(plan.dropped)} dropped as negligible" if plan.dropped else "", out.path("topdown").name)
    return out

