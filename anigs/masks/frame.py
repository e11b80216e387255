"""One image to segment (:class:`Frame`), the mask backend type, and frames rendered from a Gaussian scene."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np
import torch

from anigs.cameras import Camera
from anigs.render import render_gaussians
from anigs.render.visibility import frustum_subset


@dataclass
class Frame:
    """One image to segment.

    Attributes:
        image: RGB [H,W,3] float in [0,1] (uint8 accepted, converted).
        camera: the camera it was rendered/taken with (needed by ``labels``; optional otherwise).
        depth: rendered expected depth [H,W] (optional; enables the ground cue of ``vegetation``).
        alpha: rendered alpha [H,W] (optional).
        name: identifier used in messages and file names.
        background: RGB [3] the frame was rendered over (optional; with ``alpha`` it lets the
            vegetation backend recover the foreground colour of semi-transparent pixels).
    """

    image: np.ndarray
    camera: Camera | None = None
    depth: np.ndarray | None = None
    alpha: np.ndarray | None = None
    name: str = ""
    background: np.ndarray | None = None

    @property
    def size(self) -> tuple[int, int]:
        """(height, width)."""
        return int(self.image.shape[0]), int(self.image.shape[1])


MaskBackend = Callable[[Frame], dict[str, np.ndarray]]


def render_frames(gaussians, cameras: Sequence[Camera], background: Sequence[float] | None = None) -> list[Frame]:
    """Render ``gaussians`` from each camera: Frames with image, depth and alpha (frustum-culled first)."""
    bg = None if background is None else torch.tensor(list(background), dtype=torch.float32)
    frames = []
    for cam in cameras:
        sub = gaussians.subset(frustum_subset(gaussians, cam))
        with torch.no_grad():
            rgb, alpha, meta = render_gaussians(sub, cam, background=bg)
        frames.append(Frame(rgb.clamp(0, 1).numpy(), cam, meta["depth"].numpy(), alpha.numpy(), cam.name,
                            None if background is None else np.asarray(background, np.float32)))
    return frames
