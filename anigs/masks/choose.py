"""Which backend segments the masks stage's frames (``masks.backend``): the effects stage's
chosen effects rendered per view (``effects``), vegetation cues, ground-truth labels or SAM2."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from anigs.cameras import Camera
from anigs.gaussians import Gaussians
from anigs.masks.truth import GroundTruth
from anigs.masks.vegetation import VegetationConfig
from anigs.geometry.ground import GroundPlane


@dataclass
class EffectSets:
    """What the effects stage decided: ``chosen`` effects, ``regions`` int64 [N] (index into
    ``anigs.effects.config.REGIONS``, -1 none) and ``dynamic`` bool [N] (their union)."""

    chosen: list[str]
    regions: np.ndarray
    dynamic: np.ndarray


def _still(frame) -> dict[str, np.ndarray]:
    """The backend of a scene that contains none of the effects: nothing moves."""
    return {"dynamic": np.zeros(frame.image.shape[:2], bool)}


def choose_backend(cfg, g: Gaussians, veg: VegetationConfig, ground: GroundPlane | None,
                   effects: EffectSets | None, truth: GroundTruth | None,
                   recon_cameras: Sequence[Camera] | None) -> Callable:
    """The backend ``cfg.backend`` names (``cfg``: the ``masks`` section), ready to segment frames."""
    if cfg.backend == "effects":
        from anigs.effects.config import EFFECT_REGION, REGIONS
        from anigs.masks.labels_backend import LabelsBackend

        if effects is None:
            raise ValueError("masks.backend 'effects' needs --effects (the effects stage's folder)")
        ids = {e: [REGIONS.index(EFFECT_REGION[e])] for e in effects.chosen}
        return LabelsBackend(g, effects.regions, ids, **dataclasses.asdict(cfg.labels)) if ids else _still
    if cfg.backend == "vegetation":
        from anigs.masks.vegetation import build

        return build(veg, ground=ground)
    if cfg.backend == "labels":
        if truth is None:
            raise ValueError("masks.backend 'labels' needs --labels (and --motion)")
        return truth.backend(g, recon_cameras, dataclasses.asdict(cfg.labels))
    from anigs.masks.sam2 import build

    return build(cfg.sam2, vegetation=cfg.vegetation)


def capture_backend(cfg, backend: Callable, veg: VegetationConfig, ground: GroundPlane | None) -> Callable:
    """The backend for the capture photos: the same one, but for vegetation the ground cut is
    ``capture_ground_layer`` times the layer (a training view sees the fitted ground where it was fitted)."""
    if cfg.backend != "vegetation":
        return backend
    from anigs.masks.vegetation import build

    return build(dataclasses.replace(veg, ground_layer=cfg.capture_ground_layer), ground=ground)
