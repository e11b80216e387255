"""One analysed photo with the fitted model's renders at its camera: the record the effects steps share
(:func:`anigs.effects.scene_cues.scene_cues` makes them; the photo regions, the lift and rule ``smeared_sheet``
read them). Its own module: it imports no config, so the rules can use it without a circle."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from anigs.cameras import Camera


@dataclass
class PhotoMaps:
    """One photo with the model's renders at its camera (all [H,W] unless noted)."""

    image: np.ndarray        # RGB [H,W,3] float32 in [0,1]
    camera: Camera
    depth: np.ndarray
    alpha: np.ndarray
    variation: np.ndarray    # surface variation of the Gaussians seen
    upness: np.ndarray       # |normal . up|
    reflect: np.ndarray      # multi-view colour spread
    height: np.ndarray | None = None  # height above the ground plane of the Gaussians seen (None: no plane)
    name: str = ""
