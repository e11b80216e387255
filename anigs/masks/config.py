"""The ``masks`` config section (:class:`MasksConfig`): the backend, lifting, completion and containment
of the dynamic-region masks (the stage: :mod:`anigs.stages.masks`)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

from anigs.masks.labels_backend import LabelsConfig
from anigs.masks.lift import LiftConfig
from anigs.masks.sam2 import Sam2Config
from anigs.masks.vegetation import VegetationConfig
from anigs.typed_config import Section


@dataclass
class MasksConfig(Section):
    """Config section ``masks``."""

    HANDED = ('background',)  # set once for the whole run (anigs.config.HANDED), not in this section

    backend: str = "effects"                   # effects (the effects stage's regions) | vegetation | labels | sam2
    background: list = field(default_factory=lambda: [0.5, 0.5, 0.5])  # render background (RGB; as final.background)
    vegetation: VegetationConfig = field(default_factory=VegetationConfig)  # the vegetation backend
    labels: LabelsConfig = field(default_factory=LabelsConfig)  # the labels backend (and the effects backend's renders)
    sam2: Sam2Config = field(default_factory=Sam2Config)        # the SAM2 backend
    lift: LiftConfig = field(default_factory=LiftConfig)        # lifting the 2D masks to the Gaussians
    per_effect: bool = True                    # write one mask per effect type when there are several
    compare: bool = True                       # with --labels: IoU / precision / recall vs ground truth
    #: with --labels, --gt-*, --cameras: also vs appearance labels (a diagnostic: 0.25 s per photo, 12 s of the demo's
    #: 24 s masks job; benchmarks/masks.py reports it too)
    appearance: bool = False
    capture_ground_layer: float = 0.5          # with --images: vegetation ground_layer on the capture photos
    complete_masks: bool = True                # add the pixels the lifted dynamic Gaussians dominate to each mask
    #: move only the Gaussians whose footprint stays inside every view's dilated mask; halos and floaters stay still
    #: (anigs.masks.contain)
    contain: bool = True
    #: containment: each view's mask is dilated by this many pixels first (the still-pixel metric forgives 5)
    contain_margin_px: int = 3
    #: containment: most blending weight (in pixels) a moving Gaussian may put outside the dilated mask of any view
    contain_max_outside_px: float = 0.05

    WHERE: ClassVar[str] = "masks config"

    def validate(self) -> None:
        if self.backend not in ("effects", "vegetation", "labels", "sam2"):
            raise ValueError(f"masks.backend must be effects, vegetation, labels or sam2, got {self.backend!r}")
        if len(self.background) != 3:
            raise ValueError(f"masks.background must be [r, g, b], got {self.background}")
        if self.capture_ground_layer < 0:
            raise ValueError(f"masks.capture_ground_layer must be >= 0, got {self.capture_ground_layer}")
        if self.contain_margin_px < 0 or not self.contain_max_outside_px >= 0:
            raise ValueError("masks.contain_margin_px and masks.contain_max_outside_px must be >= 0, got "
                             f"{self.contain_margin_px} and {self.contain_max_outside_px}")
