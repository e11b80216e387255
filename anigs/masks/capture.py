"""Frames of the capture photos: each photo with the canonical model's depth and alpha at its camera.

Both the masks stage (the lift votes over the photos too) and the views stage on real scenes
(regions of interest lifted from the photos) segment the photos the canonical model was fitted
to; the rendered depth and alpha feed the vegetation backend's ground cue.
"""
from __future__ import annotations

import logging
from pathlib import Path
from typing import Sequence

from anigs.cameras import Camera, camera_for_size
from anigs.images import load_image
from anigs.masks.frame import Frame, render_frames

log = logging.getLogger("anigs.masks")


def capture_frames(images_dir: str | Path, cameras: Sequence[Camera], g) -> list:
    """Frames of the photos in ``images_dir`` (named ``{camera name}`` or ``{stem}.png``) with the
    depth [H,W] and alpha [H,W] of the canonical model ``g`` rendered at each camera.

    Cameras without a photo are skipped with a warning; none at all is an error.
    """
    d = Path(images_dir)
    if not d.is_dir():
        raise FileNotFoundError(f"--images folder not found: {d}")
    out = []
    for cam in cameras:
        path = next((p for p in (d / cam.name, d / (Path(cam.name).stem + ".png")) if p.is_file()), None)
        if path is None:
            log.warning("no capture photo for camera %s in %s: skipped", cam.name, d)
            continue
        img = load_image(path)
        c = camera_for_size(cam, img.shape[0], img.shape[1], what=f"image {path}")
        r = render_frames(g, [c])[0]
        out.append(Frame(img, c, r.depth, r.alpha, c.name))
    if not out:
        raise ValueError(f"none of the {len(cameras)} cameras has a photo in {d}")
    return out
