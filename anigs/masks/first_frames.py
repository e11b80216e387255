"""The first frame of each queued view, segmented by the masks stage: rendered from the canonical
model, or read from a folder (``{id}.png``, or frame 0 of an ``{id}.npz`` clip)."""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from anigs.cameras import Camera
from anigs.masks import Frame, render_frames
from anigs.images import load_image as read_rgb_png
from anigs.video import load_clip


def first_frames(frames_dir: str | Path | None, g, cams: Sequence[Camera], background) -> list[Frame]:
    """One :class:`~anigs.masks.Frame` per camera: image [H,W,3] float32 in [0,1] and the canonical
    model's depth and alpha [H,W] (the ground cue), the image from ``frames_dir`` when given."""
    rendered = render_frames(g, cams, background)
    if not frames_dir:
        return rendered

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
