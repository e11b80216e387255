"""The final playback of an animated scene: camera-fixed videos with space-time slices, and a
moving-camera video with time running (the paper's figures). The final stage calls these with its
``Outputs`` (``out.path(key, view=...)`` gives every file's place)."""
from __future__ import annotations

import logging

import numpy as np
import torch

from anigs.animate.frames import render_clip
from anigs.animate.playback import moving_camera_path, highlight, most_animated_row_col, pingpong_times, slice_images, \
    static_change
from anigs.cameras import Camera
from anigs.video import save_clip, save_png, write_mp4

log = logging.getLogger("anigs.final")


def view_video(canonical, deformation, cam: Camera, times: torch.Tensor, bg: torch.Tensor, mask: np.ndarray | None,
               out, fps: int, slice_upsample: int) -> dict:
    """Render ``cam``'s clip at ``times`` and write its clip, mp4 and x-t / y-t slices of the most animated
    row/column (inside ``mask``, bool [H,W], when given) to ``out``; returns its ``final.json`` entry."""
    T = len(times)
    clip = render_clip(canonical, deformation, cam, T, bg, times=times).cpu().numpy()
    if mask is not None and mask.shape != clip.shape[1:3]:
        mask = None  # scaled videos: no pixel-exact mask
    save_clip(out.path("clip", view=cam.name), clip, {"camera": cam.to_dict(), "fps": fps})
    write_mp4(out.path("video", view=cam.name), clip, fps=fps)
    row, col, peak = most_animated_row_col(clip, mask)
    xt, yt = slice_images(clip, row, col, slice_upsample)
    save_png(out.path("slice_xt", view=cam.name), xt)
    save_png(out.path("slice_yt", view=cam.name), yt)
    save_png(out.path("slice_frame", view=cam.name), highlight(clip[0], row, col))
    log.info("final: %s (%dx%d, %d frames) peak motion std %.4f", cam.name, cam.width, cam.height, T, peak)
    return {"row": row, "col": col, "peak_temporal_std": peak,
            "static_max_change": static_change(clip, mask) if mask is not None else None,
            "dynamic_fraction": float(mask.mean()) if mask is not None else None}


def path_video(canonical, deformation, cameras: list[Camera], period: int, bg: torch.Tensor, path, cfg) -> dict:
    """The moving-camera video through ``cfg.path_views`` of ``cameras`` with time running
    (``cfg.path_loops`` animation periods of ``period`` frames) to the file ``path``; its summary."""
    cams = moving_camera_path(cameras, cfg.path_frames, cfg.path_views)
    speed = cfg.path_loops * 2 * max(period - 1, 1) / max(cfg.path_frames, 1)
    ptimes = pingpong_times(cfg.path_frames, period, speed)
    frames = []
    with torch.no_grad():
        for cam, t in zip(cams, ptimes):
            frames.append(render_clip(canonical, deformation, cam, 1, bg, times=t[None])[0].cpu().numpy())
    write_mp4(path, np.stack(frames), fps=cfg.fps)
    return {"frames": cfg.path_frames, "loops": cfg.path_loops}
