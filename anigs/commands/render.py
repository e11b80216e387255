"""``anigs render``: final videos (camera-fixed per view, moving camera), clips and slices."""
from __future__ import annotations

import argparse
import dataclasses
import logging
import time
from pathlib import Path

import numpy as np
import torch

log = logging.getLogger("anigs.render")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--canonical", required=True, help="canonical 3DGS PLY")
    p.add_argument("--model", default=None, help="trained model.pt (omit: the static scene)")
    p.add_argument("--views", required=True, help="views.json (camera-fixed videos of every queued view)")
    p.add_argument("--cameras", default=None, help="cameras.json for the moving-camera path (sfm/cameras.json)")
    p.add_argument("--masks", default=None, help="masks folder ({view}.png): slices inside, stillness outside")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--params", default=None, help="final config section as JSON")


def run(args: argparse.Namespace) -> int:
    from anigs.animated import render_clip
    from anigs.cameras import load_cameras
    from anigs.cli import parse_params
    from anigs.deform import load_model
    from anigs.device import get_device
    from anigs.final import (FinalConfig, camera_path, highlight, most_animated_row_col, pingpong_times,
                             slice_images, static_change, to_torch_background)
    from anigs.gaussians import Gaussians
    from anigs.io import read_json, write_json
    from anigs.video import save_clip, save_png, write_mp4
    from anigs.views import cameras_from_views

    cfg = FinalConfig.from_dict(parse_params(args.params))
    dev = get_device(cfg.device)
    t0 = time.perf_counter()
    if args.model:
        canonical, deformation, _ = load_model(args.model, args.canonical)
    else:
        canonical, deformation = Gaussians.load_ply(args.canonical), None
    canonical = canonical.to(dev)
    if deformation is not None:
        deformation = deformation.to(dev)
    T = cfg.frames or (deformation.num_frames if deformation is not None else 1)
    period = deformation.num_frames if deformation is not None else 1
    times = pingpong_times(T, period)
    bg = to_torch_background(cfg.background, dev)
    out = Path(args.out)
    summary: dict = {"config": dataclasses.asdict(cfg), "frames": T, "views": {}}
    for cam in cameras_from_views(read_json(args.views)):
        if cfg.scale != 1.0:
            cam = cam.scaled(max(1, round(cam.width * cfg.scale)), max(1, round(cam.height * cfg.scale)))
        clip = render_clip(canonical, deformation, cam, T, bg, times=times).cpu().numpy()
        mask = None
        if args.masks and (Path(args.masks) / f"{cam.name}.png").exists():
            import imageio.v2 as imageio

            m = np.asarray(imageio.imread(Path(args.masks) / f"{cam.name}.png"))
            mask = (m[..., 0] if m.ndim == 3 else m) > 127
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
        log.info("render: %s (%dx%d, %d frames) peak motion std %.4f", cam.name, cam.width, cam.height, T, peak)
    if args.cameras:
        path = camera_path(load_cameras(args.cameras), cfg.path_frames, cfg.path_views)
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
    log.info("render: wrote %d view videos%s in %.1f s to %s", len(summary["views"]),
             " and path.mp4" if args.cameras else "", summary["seconds"], out)
    return 0
