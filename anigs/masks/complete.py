"""Completing each view's mask with the pixels the lifted dynamic Gaussians dominate there, so
every Gaussian that moves lies inside the masks the later stages composite with."""
from __future__ import annotations

from typing import Sequence

import numpy as np

from anigs.gaussians import Gaussians
from anigs.masks import Frame
from anigs.render.labels import dynamic_masks


def complete_masks(g: Gaussians, dyn: np.ndarray, frames: Sequence[Frame], results: list[dict]) -> list[float]:
    """OR each view's ``dynamic`` mask [H,W] with the render of the dynamic set ``dyn`` [N] (in place);
    returns the fraction of each view's pixels added."""
    added = []
    for res, extra in zip(results, dynamic_masks(g, dyn, [fr.camera for fr in frames])):
        added.append(float((extra & ~res["dynamic"]).mean()))
        res["dynamic"] = res["dynamic"] | extra
    return added
