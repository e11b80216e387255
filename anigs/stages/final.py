"""Stage ``final``: the animated scene played back for people.

Camera-fixed videos of every queued view, a moving-camera video with time running, and x-t /
y-t space-time slices of the most animated patch (the paper's figures;
:mod:`anigs.animate.final_videos`).

    anigs final --static static/ --model round4/ --views views/ [--sfm sfm/] [--masks masks/] \\
        --out final/ --params '{...final section...}'
"""
from __future__ import annotations

import dataclasses
import logging
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

from anigs.animate.config import FinalConfig
from anigs import contract
from anigs.stages.masks import Outputs as MasksOutputs
from anigs.stages.sfm import Outputs as SfmOutputs
from anigs.stages.static import Outputs as StaticOutputs
from anigs.stages.views import Outputs as ViewsOutputs
from anigs.contract import File
from anigs.stages.update import Outputs as UpdateOutputs
from anigs.animate.final_videos import path_video, view_video
from anigs.animate.playback import pingpong_times
from anigs.cameras import load_cameras
from anigs.device import get_device
from anigs.gaussians import Gaussians
from anigs.io import read_json, write_json
from anigs.views import cameras_from_views

log = logging.getLogger("anigs.final")


Config = FinalConfig  # the `final` config section


class Outputs(contract.Outputs):
    """The final folder of a variant (``final/``)."""

    LAYOUT = {"summary": File("final.json", "per view: row, col, peak_temporal_std, static_max_change, "
                                            "dynamic_fraction; frames, config, path; warnings (a static fit too "
                                            "blurry to animate, with the cheapest change that helps; no view "
                                            "showing the motion sharply, with where more photos would help)"),
              "video": File("{view}.mp4", "camera-fixed video of a view (H.264)"),
              "clips": File("clips/", "the videos' frames as clips (the eval stage reads them)"),
              "clip": File("clips/{view}.npz", "float [T,H,W,3] in [0,1] + metadata (camera, fps)"),
              "slices": File("slices/", "space-time slices"),
              "slice_xt": File("slices/{view}_xt.png", "x-t slice of the most animated row"),
              "slice_yt": File("slices/{view}_yt.png", "y-t slice of the most animated column"),
              "slice_frame": File("slices/{view}_frame.png", "frame 0 with that row and column marked"),
              "path": File("path.mp4", "moving-camera video with time running", optional=True)}

    def videos(self) -> dict[str, Path]:
        """{view: its camera-fixed video} in the folder (the moving-camera video is no view's)."""
        suffix = Path(self.LAYOUT["video"].name).suffix
        return {p.stem: p for p in sorted(self.root.glob(f"*{suffix}")) if p != self.path("path")}

    def clip(self, view: str) -> tuple[np.ndarray, dict]:
        """(frames float32 [T,H,W,3], metadata) of ``view``'s final clip."""
        return super().clip("clip", view=view)


def find_final_videos(results: str | Path, scenes: Sequence[str],
                      variants: Sequence[str] | None = None) -> dict[tuple[str, str], dict[str, Path]]:
    """Camera-fixed videos of the final stage's folders ``results/{scene}/{variant}/final``
    (:meth:`Outputs.videos`; the study's input, :mod:`anigs.study.build`) -> {(scene, variant): {view: path}}.

    ``variants`` None takes every variant folder that has a ``final/`` folder.
    """
    root = Path(results)
    found: dict[tuple[str, str], dict[str, Path]] = {}
    for scene in scenes:
        sdir = root / scene
        if not sdir.is_dir():
            raise FileNotFoundError(f"study: no results folder for scene {scene!r}: {sdir}")
        names = variants if variants is not None else sorted(p.parent.name for p in sdir.glob("*/final"))
        for v in names:
            fdir = sdir / v / "final"
            videos = Outputs(fdir).videos()
            if not videos:
                raise FileNotFoundError(f"study: no camera-fixed videos in {fdir} (run the final stage of "
                                        f"scene {scene!r}, variant {v!r} first)")
            found[(scene, v)] = videos
    return found


@dataclass
class Inputs(contract.Inputs):
    static: StaticOutputs
    views: ViewsOutputs
    out: Path = field(metadata={"help": "the final folder"})
    model: UpdateOutputs | None = field(default=None, metadata={"help": "the model's folder (omit: the static scene)"})
    sfm: SfmOutputs | None = field(default=None, metadata={"help": "the sfm stage's folder: its cameras for the "
                                                                   "moving-camera path"})
    masks: MasksOutputs | None = field(default=None, metadata={"help": "the masks stage's folder: slices inside, "
                                                                       "stillness outside"})


def run(inputs: Inputs, cfg: FinalConfig) -> Outputs:
    """Write the final videos, clips and slices and the ``final.json`` summary."""
    import torch


    dev = get_device(cfg.device)
    t0 = time.perf_counter()
    still = None  # why nothing moves, when the model says so (anigs.animate.still)
    canonical_path = inputs.static.path("canonical")
    if inputs.model is not None:
        canonical, deformation, payload = inputs.model.load(canonical_path)
        if payload.get("extra", {}).get("still"):
            still = payload["extra"]["reason"]
            log.info("final: nothing moves: %s", still)
    else:
        canonical, deformation = Gaussians.load_ply(canonical_path), None
    canonical = canonical.to(dev)
    if deformation is not None:
        deformation = deformation.to(dev)
    T = cfg.frames or (deformation.num_frames if deformation is not None else 1)
    period = deformation.num_frames if deformation is not None else 1
    times = pingpong_times(T, period)
    bg = torch.tensor(cfg.background, dtype=torch.float32, device=dev)
    out = Outputs(inputs.out)
    summary: dict = {"config": dataclasses.asdict(cfg), "frames": T, "views": {},
                     "background": list(cfg.background)}  # behind the splats: what no photo covered shows it
    if still:
        summary["nothing_moves"] = still
    advice = (inputs.views.report().get("motion") or {}).get("advice")  # no view shows the motion sharply
    warnings = [w for w in (inputs.static.fit_warning(), advice) if w]  # the static fit too blurry to animate; the views
    if warnings:
        summary["warnings"] = warnings
        for w in warnings:
            log.warning("final: %s", w)
    masks = inputs.masks
    for cam in cameras_from_views(read_json(inputs.views.path("views"))):
        if cfg.scale != 1.0:
            cam = cam.scaled(max(1, round(cam.width * cfg.scale)), max(1, round(cam.height * cfg.scale)))
        mask = masks.view_mask(cam.name) >= 0.5 if masks is not None and masks.exists("mask", view=cam.name) else None
        summary["views"][cam.name] = view_video(canonical, deformation, cam, times, bg, mask, out, cfg.fps,
                                                cfg.slice_upsample)
    if inputs.sfm is not None:
        summary["path"] = path_video(canonical, deformation, load_cameras(inputs.sfm.path("cameras")), period, bg,
                                     out.path("path"), cfg)
    summary["seconds"] = time.perf_counter() - t0
    write_json(out.path("summary"), summary)
    log.info("final: wrote %d view videos%s in %.1f s to %s", len(summary["views"]),
             f" and {out.path('path').name}" if inputs.sfm is not None else "", summary["seconds"], out.root)
    return out
