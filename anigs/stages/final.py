"""Stage ``final``: the animated scene played back for people.

Camera-fixed videos of every queued view, a moving-camera video with time running, and x-t /
y-t space-time slices of the most animated patch (the paper's figures).

    anigs final --canonical static/canonical.ply --model round4/model.pt --views views/views.json \
        [--cameras sfm/cameras.json] [--masks masks/] --out final/ --params '{...final section...}'
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
import torch

from anigs.typed_config import from_dict

log = logging.getLogger("anigs.final")


@dataclass
class FinalConfig:
    """``final`` config section."""

    frames: int = 0  # frames per video (0 = the model's T); fractional times loop the DCT period
    fps: int = 12
    path_frames: int = 96  # frames of the moving-camera video
    path_loops: int = 2  # how many animation periods the moving camera sees
    path_views: int = 6  # capture cameras the path passes through (evenly picked)
    scale: float = 1.0  # resolution factor of the view videos
    background: list = field(default_factory=lambda: [0.62, 0.76, 0.92])
    slice_upsample: int = 4  # each time step becomes this many rows in slice PNGs
    device: str = "auto"

    @staticmethod
    def from_dict(d: dict[str, Any] | None) -> "FinalConfig":
        return from_dict(FinalConfig, d, "final", KeyError)


Config = FinalConfig  # the `final` config section


def run(canonical_path: str | Path, views_path: str | Path, out: str | Path, cfg: FinalConfig,
        model_path: str | Path | None = None, cameras_path: str | Path | None = None,
        masks_dir: str | Path | None = None) -> dict:
    """Write the final videos, clips and slices into ``out``; returns the ``final.json`` summary."""
    from anigs.animate.deform import load_model
    from anigs.animate.frames import render_clip
    from anigs.animate.playback import camera_path, highlight, most_animated_row_col, pingpong_times, \
        slice_images, static_change
    from anigs.cameras import load_cameras
    from anigs.device import get_device
    from anigs.gaussians import Gaussians
    from anigs.io import read_json, write_json
    from anigs.video import save_clip, save_png, write_mp4
    from anigs.views import cameras_from_views

    dev = get_device(cfg.device)
    t0 = time.perf_counter()
    still = None  # why nothing moves, when the model says so (anigs.animate.still)
    if model_path:
        canonical, deformation, payload = load_model(model_path, canonical_path)
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
    out = Path(out)
    summary: dict = {"config": dataclasses.asdict(cfg), "frames": T, "views": {}}
    if still:
        summary["nothing_moves"] = still
    for cam in cameras_from_views(read_json(views_path)):
        if cfg.scale != 1.0:
            cam = cam.scaled(max(1, round(cam.width * cfg.scale)), max(1, round(cam.height * cfg.scale)))
        clip = render_clip(canonical, deformation, cam, T, bg, times=times).cpu().numpy()
        mask = None
        if masks_dir and (Path(masks_dir) / f"{cam.name}.png").exists():
            from anigs.images import read_mask

            mask = read_mask(Path(masks_dir) / f"{cam.name}.png") >= 0.5
            if mask.shape != clip.shape[1:3]:
                mask = None  # scaled videos: no pixel-exact mask
        save_clip(out / "clips" / f"{cam.name}.npz", clip, {"camera": cam.to_dict(), "fps": cfg.fps})
        write_mp4(out / f"{cam.name}.mp4", clip, fps=cfg.fps)
        row, col, peak = most_animated_row_col(clip, mask)
        xt, yt = slice_images(clip, row, col, cfg.slice_upsample)
        save_png(out / "slices" / f"{cam.name}_xt.png", xt)
        save_png(out / "slices" / f"{cam.name}_yt.png", yt)
        save_png(out / "slices" / f"{cam.name}_frame.png", highlight(clip[0], row, col))
        summary["views"][cam.name] = {"row": row, "col": col, "peak_temporal_std": peak,
                                      "static_max_change": static_change(clip, mask) if mask is not None else None,
                                      "dynamic_fraction": float(mask.mean()) if mask is not None else None}
        log.info("final: %s (%dx%d, %d frames) peak motion std %.4f", cam.name, cam.width, cam.height, T, peak)
    if cameras_path:
        path = camera_path(load_cameras(cameras_path), cfg.path_frames, cfg.path_views)
        speed = cfg.path_loops * 2 * max(period - 1, 1) / max(cfg.path_frames, 1)
        ptimes = pingpong_times(cfg.path_frames, period, speed)
        frames = []
        with torch.no_grad():
            for cam, t in zip(path, ptimes):
                frames.append(render_clip(canonical, deformation, cam, 1, bg, times=t[None])[0].cpu().numpy())
        write_mp4(out / "path.mp4", np.stack(frames), fps=cfg.fps)
        summary["path"] = {"frames": cfg.path_frames, "loops": cfg.path_loops}
    summary["seconds"] = time.perf_counter() - t0
    write_json(out / "final.json", summary)
    log.info("final: wrote %d view videos%s in %.1f s to %s", len(summary["views"]),
             " and path.mp4" if cameras_path else "", summary["seconds"], out)
    return summary


# ---- command line: anigs final ----

def add_arguments(p: argparse.ArgumentParser) -> None:
    from anigs.cli import add_params, add_canonical, add_out

    add_canonical(p, help="canonical 3DGS PLY")
    p.add_argument("--model", default=None, help="trained model.pt (omit: the static scene)")
    p.add_argument("--views", required=True, help="views.json (camera-fixed videos of every queued view)")
    p.add_argument("--cameras", default=None, help="cameras.json for the moving-camera path (sfm/cameras.json)")
    p.add_argument("--masks", default=None, help="masks folder ({view}.png): slices inside, stillness outside")
    add_out(p, "output folder")
    add_params(p, "final")


def main(args: argparse.Namespace) -> int:
    from anigs.cli import parse_params

    run(args.canonical, args.views, args.out, FinalConfig.from_dict(parse_params(args.params)), model_path=args.model,
        cameras_path=args.cameras, masks_dir=args.masks)
    return 0
